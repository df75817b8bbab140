"""Plots of softshock results (matplotlib, Agg backend: files only, no display needed).

Functions take the arrays the Client returns. The module is also the `softshock` CLI's PNG
helper (`python3 -m softshock_client.plots field-raster|abar|modes|grid-heatmap ...`) and makes
the demo's figures (`python3 -m softshock_client.plots job ID --out-dir out`). It imports numpy
and matplotlib only; the `job` command loads the gRPC client lazily.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Mapping, Optional, Sequence, Tuple

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
from matplotlib import colors  # noqa: E402

# Symbols for the field names the daemon serves (docs/model.md).
FIELD_LABELS = {
    "J": "J = det F",
    "mean_stress": "mean stress σ_m",
    "hoop_stress": "hoop stress σ_θθ",
    "radial_stress": "radial stress σ_rr",
    "von_mises": "von Mises stress σ_vM",
    "displacement": "|displacement|",
    "velocity": "|velocity|",
    "damage": "phase-field damage d",
}


def _time_axis(time_s: np.ndarray, time_scale: Optional[float]) -> Tuple[np.ndarray, str]:
    """Nondimensional t̄ = t c0 / R0 when the time scale R0/c0 is known, else nanoseconds."""
    if time_scale:
        return np.asarray(time_s) / time_scale, r"$\bar{t} = t\,c_0/R_0$  (–)"
    return np.asarray(time_s) * 1e9, "time t (ns)"


def _save(fig, path: str) -> str:
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_abar(series_list, path: str, labels: Optional[Sequence[str]] = None,
              time_scale: Optional[float] = None, title: str = "Rim shape measure Ā(t)") -> str:
    """Ā(t) = (max r − min r) / R0 of the rim for one or several runs.

    series_list: a series dict from Client.series() (with "time" and "abar"), or a list of them.
    time_scale: R0/c0 in s (summary["groups"]["time_scale_s"]) to plot against t̄ instead of ns.
    """
    if isinstance(series_list, Mapping):
        series_list = [series_list]
    fig, ax = plt.subplots(figsize=(7, 4))
    xlabel = "time t (ns)"
    for i, s in enumerate(series_list):
        x, xlabel = _time_axis(s["time"], time_scale)
        label = labels[i] if labels is not None and i < len(labels) else None
        ax.plot(x, s["abar"], lw=1.4, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Ā = (max r − min r) / R₀  (–)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if labels:
        ax.legend()
    return _save(fig, path)


def plot_mode_heatmap(modes, path: str, time_scale: Optional[float] = None,
                      title: str = "Fourier modes of the rim displacement") -> str:
    """Heat map of mode amplitude (mode number × time), log colour scale.

    modes: (time in s, mode numbers, amplitude array T x C) as Client.modes() returns.
    """
    time_s, mode_numbers, amplitude = modes
    amplitude = np.abs(np.asarray(amplitude, dtype=float))
    x, xlabel = _time_axis(time_s, time_scale)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    positive = amplitude[np.isfinite(amplitude) & (amplitude > 0)]
    if positive.size:
        # Four decades below the peak: the modes of interest grow from round-off-level seeds.
        vmax = positive.max()
        norm = colors.LogNorm(vmin=max(positive.min(), vmax * 1e-4), vmax=vmax)
        shown = np.where(amplitude > 0, amplitude, np.nan)
    else:
        norm, shown = None, amplitude
    mesh = ax.pcolormesh(x, np.asarray(mode_numbers), shown.T, shading="nearest", norm=norm,
                         cmap="magma")
    cbar = fig.colorbar(mesh, ax=ax)
    cbar.set_label("amplitude / R₀  (–)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("mode number m  (–)")
    ax.set_title(title)
    return _save(fig, path)


def plot_field_raster(array, extent, name: str, units: str, time: float, path: str,
                      frame: Optional[int] = None) -> str:
    """A field raster over the deformed body, axes in µm; NaN (outside the body) is left blank.

    array: (ny, nx) scalars or (ny, nx, 2) vectors (plotted as magnitude); row j is y.
    extent: (x_min, x_max, y_min, y_max) in m.
    """
    data = np.asarray(array, dtype=float)
    if data.ndim == 3:
        data = np.hypot(data[..., 0], data[..., 1])
    if data.ndim != 2:
        raise ValueError(f"expected a 2-D raster, got shape {data.shape}")
    x0, x1, y0, y1 = (float(v) * 1e6 for v in extent)
    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    finite = data[np.isfinite(data)]
    cmap = plt.get_cmap("viridis").copy()
    norm = None
    if finite.size and finite.min() < 0 < finite.max():
        # Signed stresses: a diverging map centred on zero separates tension from compression;
        # symmetric limits keep equal colours for equal magnitudes of either sign.
        cmap = plt.get_cmap("RdBu_r").copy()
        norm = colors.CenteredNorm(vcenter=0.0)
    cmap.set_bad(alpha=0.0)
    image = ax.imshow(np.ma.masked_invalid(data), origin="lower", extent=(x0, x1, y0, y1),
                      cmap=cmap, norm=norm, interpolation="nearest")
    cbar = fig.colorbar(image, ax=ax)
    label = FIELD_LABELS.get(name, name)
    cbar.set_label(f"{label} ({units})" if units else label)
    ax.set_xlabel("x (µm)")
    ax.set_ylabel("y (µm)")
    ax.set_aspect("equal")
    when = f"t = {time * 1e9:.4g} ns" + (f" (frame {frame})" if frame is not None else "")
    ax.set_title(f"{label}{' [' + units + ']' if units else ''}, {when}")
    return _save(fig, path)


# Axis labels for grid axes: the groups of physics.md section 7 by symbol, spec fields with
# their units.
# Mathtext: DejaVu has no combining overline over every letter (t̄ would lose its bar).
GROUP_LABELS = {
    "pbar": r"$\bar{P} = P/\kappa$  (–)",
    "tbar_pulse": r"$\bar{t}_\mathrm{pulse} = t_\mathrm{pulse}\,c_0/R_0$  (–)",
    "mubar": r"$\bar{\mu} = \mu/\kappa$  (–)",
    "gamma": r"$\bar{\gamma}$ (Tait exponent $n - 1$)  (–)",
    "c1": r"$C_1$ (quadratic viscosity)  (–)",
    "c2": r"$C_2$ (linear viscosity)  (–)",
}
FIELD_UNITS = {
    "load.pressure": "Pa", "load.duration": "s", "material.density": "kg/m³",
    "material.bulk_modulus": "Pa", "material.shear_modulus": "Pa", "material.tait_gamma": "–",
    "viscosity.c1": "–", "viscosity.c2": "–", "geometry.disk.radius": "m",
    "geometry.rounded_square.side": "m", "geometry.rounded_square.corner_radius": "m",
    "geometry.target_elements": "–", "run.end_time": "s", "run.cfl": "–",
}
QUANTITY_LABELS = {
    "max_abar_first_cycle": r"max $\bar{{A}}$ over $0 \leq \bar{{t}} \leq 4$",
    "max_abar": r"max $\bar{{A}}$ over the run",
    "abar_end": r"$\bar{{A}}$ at the end",
    "max_abar_filtered_first_cycle": r"max filtered $\bar{{A}}$ over $0 \leq \bar{{t}} \leq 4$",
    "max_abar_filtered": r"max filtered $\bar{{A}}$ over the run",
    "abar_filtered_end": r"filtered $\bar{{A}}$ at the end",
    "max_aspect_ratio": "largest element aspect ratio",
    "abar_at": r"$\bar{{A}}$ at $\bar{{t}}$ = {tbar:g}",
    "dominant_mode_end": "dominant rim mode at the end",
    "energy_injected_J_per_m": "energy injected",
    "energy_after_pulse_J_per_m": "energy after the pulse",
    "shock_at_center_s": "shock arrival at the centre",
    "wall_time_s": "wall time",
}


def axis_label(name: str) -> str:
    """Label of a grid axis: the group's symbol, or the spec field with its unit."""
    if name.lower() in GROUP_LABELS:
        return GROUP_LABELS[name.lower()]
    unit = FIELD_UNITS.get(name)
    return f"{name} ({unit})" if unit else name


def quantity_label(quantity: str, units: str = "", tbar: float = 0.0) -> str:
    """Colour-bar label of a grid reduction's quantity, with its unit ("–" for none)."""
    text = QUANTITY_LABELS.get(quantity, quantity).format(tbar=tbar)
    unit = units if units and units != "1" else "–"
    return f"{text}  ({unit})"


def _tick_labels(values) -> list:
    return [f"{v:.4g}" for v in values]


def plot_grid_heatmap(reduction, path: str, title: Optional[str] = None) -> str:
    """Heat map of a grid reduction: one axis = a line plot, two = a heat map (first axis
    along x), three = one panel per value of the first axis. Cells are evenly spaced with
    tick labels at the axis values (geomspace axes stay readable); NaN cells (no result) are
    blank.

    reduction: what Client.grid_reduction() returns (or a dict with axes [{name, values}],
    values, quantity, units, tbar).
    """
    if isinstance(reduction, Mapping):
        names = [a["name"] for a in reduction["axes"]]
        axes_values = [np.asarray([float(v) for v in a.get("values", [])]) for a in
                       reduction["axes"]]
        values = np.asarray([float(v) for v in reduction.get("values", [])], dtype=float)
        quantity = reduction.get("quantity", "")
        units = reduction.get("units", "")
        tbar = float(reduction.get("tbar", 0.0) or 0.0)
        grid_id = reduction.get("gridId", reduction.get("grid_id", ""))
    else:
        names, axes_values = list(reduction.axis_names), list(reduction.axis_values)
        values, quantity = np.asarray(reduction.values, dtype=float), reduction.quantity
        units, tbar, grid_id = reduction.units, reduction.tbar, reduction.grid_id
    shape = tuple(len(v) for v in axes_values)
    values = values.reshape(shape)
    label = quantity_label(quantity, units, tbar)
    title = title or f"{QUANTITY_LABELS.get(quantity, quantity).format(tbar=tbar)}" + (
        f", grid {grid_id}" if grid_id else "")
    finite = values[np.isfinite(values)]
    vmin = float(finite.min()) if finite.size else None
    vmax = float(finite.max()) if finite.size else None
    if len(shape) == 1:
        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(axes_values[0], values, "o-", lw=1.4)
        ax.set_xlabel(axis_label(names[0]))
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.set_title(title)
        return _save(fig, path)
    panels = [values] if len(shape) == 2 else [values[k] for k in range(shape[0])]
    if len(panels) > 16:
        raise ValueError(f"a 3-axis grid plots one panel per value of its first axis; "
                         f"{len(panels)} is too many (at most 16)")
    x_name, y_name = names[-2], names[-1]
    x_values, y_values = axes_values[-2], axes_values[-1]
    cols = min(4, len(panels))
    rows = (len(panels) + cols - 1) // cols
    fig, axs = plt.subplots(rows, cols, figsize=(4.8 * cols + 1.2, 4.2 * rows), squeeze=False)
    cmap = plt.get_cmap("viridis").copy()
    cmap.set_bad(color="#dddddd")
    image = None
    for k, panel in enumerate(panels):
        ax = axs[k // cols][k % cols]
        # Row j of the image is y value j: transpose so x runs along the first axis shown.
        image = ax.imshow(np.ma.masked_invalid(panel.T), origin="lower", aspect="auto",
                          cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
        step_x = max(1, len(x_values) // 12)
        step_y = max(1, len(y_values) // 12)
        ax.set_xticks(range(0, len(x_values), step_x))
        ax.set_xticklabels(_tick_labels(x_values[::step_x]), rotation=45, ha="right")
        ax.set_yticks(range(0, len(y_values), step_y))
        ax.set_yticklabels(_tick_labels(y_values[::step_y]))
        ax.set_xlabel(axis_label(x_name))
        ax.set_ylabel(axis_label(y_name))
        if len(shape) == 3:
            ax.set_title(f"{names[0]} = {axes_values[0][k]:.4g}")
    for k in range(len(panels), rows * cols):
        axs[k // cols][k % cols].axis("off")
    cbar = fig.colorbar(image, ax=axs, shrink=0.9)
    cbar.set_label(label)
    fig.suptitle(title)
    return _save(fig, path)


def _load_json(path: str):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def _load_npy(path: str) -> np.ndarray:
    return np.load(path, allow_pickle=False)


def _job_plots(args) -> int:
    from .client import Client  # needs the generated stubs; only this command does

    token = None
    if args.token_file:
        with open(args.token_file, encoding="utf-8") as f:
            token = f.read().strip()
    with Client(args.server, token=token, tls_ca=args.tls_ca) as c:
        summary = c.summary(args.id)
        time_scale = summary.get("groups", {}).get("time_scale_s") or None
        series = c.series(args.id, names=["abar"])
        modes = c.modes(args.id)
    out = []
    out.append(plot_abar(series, os.path.join(args.out_dir, "abar.png"), time_scale=time_scale,
                         title=f"Ā(t), job {args.id}"))
    out.append(plot_mode_heatmap(modes, os.path.join(args.out_dir, "modes.png"),
                                 time_scale=time_scale,
                                 title=f"Rim Fourier modes, job {args.id}"))
    for p in out:
        print(p)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """`python3 -m softshock_client.plots`: the CLI's PNG helper and the `job ID` plots."""
    parser = argparse.ArgumentParser(prog="python3 -m softshock_client.plots",
                                     description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)

    fr = sub.add_parser("field-raster", help="plot a raster stored as .npy (the CLI's helper)")
    fr.add_argument("--npy", required=True)
    # Separate options, passed as --x-min=VALUE: argparse would read a negative value given
    # as its own word as an option name.
    for bound in ("x-min", "x-max", "y-min", "y-max"):
        fr.add_argument(f"--{bound}", type=float, required=True, help="extent in m")
    fr.add_argument("--name", required=True)
    fr.add_argument("--units", default="")
    fr.add_argument("--time", type=float, required=True, help="in s")
    fr.add_argument("--frame", type=int)
    fr.add_argument("--out", required=True)

    ab = sub.add_parser("abar", help="Ā(t) of several runs from a JSON file (the CLI's helper)")
    ab.add_argument("--json", required=True,
                    help='{"series": [{"label", "time", "abar"}], "time_scale": s or null}')
    ab.add_argument("--out", required=True)

    md = sub.add_parser("modes", help="mode heat map from .npy files (the CLI's helper)")
    md.add_argument("--time-npy", required=True, help="times in s")
    md.add_argument("--amplitude-npy", required=True, help="T x C amplitudes / R0")
    md.add_argument("--mode-min", type=int, default=0)
    md.add_argument("--time-scale", type=float, default=0.0, help="R0/c0 in s (0 = plot in ns)")
    md.add_argument("--title", default="Fourier modes of the rim displacement")
    md.add_argument("--out", required=True)

    gh = sub.add_parser("grid-heatmap", help="heat map of a grid reduction (protobuf JSON)")
    gh.add_argument("--json", required=True)
    gh.add_argument("--out", required=True)

    jp = sub.add_parser("job", help="Ā(t) and mode heat map of a job, fetched from softshockd")
    jp.add_argument("id")
    jp.add_argument("--server", default=None)
    jp.add_argument("--token-file")
    jp.add_argument("--tls-ca")
    jp.add_argument("--out-dir", default="out")

    args = parser.parse_args(argv)
    if args.command == "field-raster":
        extent = (args.x_min, args.x_max, args.y_min, args.y_max)
        plot_field_raster(_load_npy(args.npy), extent, args.name, args.units, args.time,
                          args.out, frame=args.frame)
        return 0
    if args.command == "abar":
        data = _load_json(args.json)
        series = [{"time": np.asarray(s["time"], dtype=float),
                   "abar": np.asarray(s["abar"], dtype=float)} for s in data["series"]]
        labels = [s.get("label", "") for s in data["series"]]
        plot_abar(series, args.out, labels=labels if len(series) > 1 else None,
                  time_scale=data.get("time_scale") or None,
                  title=data.get("title") or "Rim shape measure Ā(t)")
        return 0
    if args.command == "modes":
        amplitude = _load_npy(args.amplitude_npy)
        modes = (_load_npy(args.time_npy),
                 np.arange(args.mode_min, args.mode_min + amplitude.shape[1]), amplitude)
        plot_mode_heatmap(modes, args.out, time_scale=args.time_scale or None, title=args.title)
        return 0
    if args.command == "grid-heatmap":
        plot_grid_heatmap(_load_json(args.json), args.out)
        return 0
    return _job_plots(args)


if __name__ == "__main__":
    sys.exit(main())
