"""Plots of softshock results (matplotlib, Agg backend: files only, no display needed).

Functions take the arrays the Client returns. The module is also the `softshock` CLI's PNG
helper (`python3 -m softshock_client.plots field-raster ...`) and makes the demo's figures
(`python3 -m softshock_client.plots job ID --out-dir out`). It imports numpy and matplotlib
only; the `job` command loads the gRPC client lazily.
"""

from __future__ import annotations

import argparse
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
}


def _time_axis(time_s: np.ndarray, time_scale: Optional[float]) -> Tuple[np.ndarray, str]:
    """Nondimensional t̄ = t c0 / R0 when the time scale R0/c0 is known, else nanoseconds."""
    if time_scale:
        return np.asarray(time_s) / time_scale, "t̄ = t c₀ / R₀"
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
    time_scale: R0/c0 in s (summary["groups"]["time_scale"]) to plot against t̄ instead of ns.
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
        time_scale = summary.get("groups", {}).get("time_scale") or None
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
    return _job_plots(args)


if __name__ == "__main__":
    sys.exit(main())
