#!/usr/bin/python3
"""How good is plane strain (docs/verification.md, "How good is plane strain"): the default
baseline (R0 = 90 um, 2 GPa for 8 ns) on a cylinder 50 um thick whose faces are SLIDING (u_z = 0,
the plane-strain limit), BONDED (u = 0: gel stuck to the glass) and FREE, against the 2-D default
run, on two mesh sizes: the 2-D default's in-plane resolution (its ~16.5k-triangle ring disk,
extruded in layers of about its node spacing: ~1.3M tetrahedra) and half of it (~170k).

Prints the figures (early events, energy per unit thickness, A-bar and the dominant rim mode at the
mid-plane and averaged over the thickness, the largest out-of-plane displacement of the faces and
of the body) as
markdown tables, writes them as JSON, and draws docs/img/plane_strain_*.png.

  scripts/plane_strain_study.py [--solver build/solver/softshock-solve] [--out DIR]
      [--end-time 400e-9] [--sizes 170000,1300000] [--threads 2] [--faces SLIDING,BONDED,FREE]
      [--img docs/img]

Each 1.3M-tetrahedron run to 400 ns takes ~6-10 min on this 2-core machine (the figures in
docs/verification.md say how long they took).
"""
import argparse
import json
import os
import sys

import h5py
import numpy as np

from study_runs import run

RADIUS, THICKNESS = 90e-6, 50e-6


def series(out, per_metre):
    """The history of a result: time (ns), energies per metre, A-bar, modes."""
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        ts = f["timeseries"]
        s = {k: ts[k][:] for k in ("time", "kinetic_energy", "elastic_energy", "abar",
                                   "abar_filtered", "rim_mean_radial_displacement")}
        s["modes"] = f["modes/amplitude"][:]
        if "amplitude_z_mean" in f["modes"]:
            s["modes_z_mean"] = f["modes/amplitude_z_mean"][:]
        # The out-of-plane displacement in the frames: the largest |u_z| of the faces (|z| = H/2)
        # and of the whole body, with where (r, z) the body's is.
        uz = []
        if int(f.attrs.get("dimension", 2)) == 3:
            nodes = f["mesh/nodes"][:]
            z, r = nodes[:, 2], np.hypot(nodes[:, 0], nodes[:, 1])
            faces = np.abs(np.abs(z) - THICKNESS / 2) < 1e-12
            for name in sorted(f["fields"].keys()):
                g = f["fields"][name]
                d = np.abs(g["displacement"][:, 2])
                i = int(np.argmax(d))
                uz.append((float(g.attrs["time"]), float(d[faces].max()), float(d[i]),
                           float(r[i]), float(z[i])))
        s["uz"] = uz
    s["energy"] = (s["kinetic_energy"] + s["elastic_energy"]) * per_metre
    return s


def figures(summary, s):
    t = s["time"]

    def at(name, time_s):  # NaN past the end of a run that stopped early
        if time_s > t[-1] * (1 + 1e-9):
            return float("nan")
        return float(s[name][int(np.argmin(np.abs(t - time_s)))])

    def mode_at(key, time_s):
        row = s[key][int(np.argmin(np.abs(t - time_s)))]
        return int(np.argmax(row[2:]) + 2) if len(row) > 2 else 0

    reflections = summary.get("rim_reflections_s") or []
    end = float(t[-1])
    out = {
        "status": summary["status"] + (f" ({summary['failure']} at {t[-1] * 1e9:.0f} ns)"
                                       if summary.get("failure") else ""),
        "elements": summary["elements"], "steps": summary["steps"],
        "minutes": round(summary["seconds"] / 60, 1),
        "shock_at_center_ns": (summary["shock_at_center_s"] or float("nan")) * 1e9,
        "rim_reflections_ns": [r * 1e9 for r in reflections[:3]],
        "energy_70ns_J_per_m": at("energy", 70e-9),
        "energy_end_J_per_m": float(s["energy"][-1]),
        "abar_filtered_200ns": at("abar_filtered", 200e-9),
        "abar_filtered_end": float(s["abar_filtered"][-1]),
        "max_abar_filtered": float(s["abar_filtered"].max()),
        "dominant_mode_end": mode_at("modes", end),
        "end_ns": end * 1e9,
    }
    if "modes_z_mean" in s:
        out["dominant_mode_z_mean_end"] = mode_at("modes_z_mean", end)
    if s["uz"]:
        out["max_face_uz_um"] = max(u[1] for u in s["uz"]) * 1e6
        t_uz, _, u_max, r_uz, z_uz = max(s["uz"], key=lambda u: u[2])
        out["max_uz_um"] = u_max * 1e6
        out["max_uz_where"] = f"{t_uz * 1e9:.0f} ns, r {r_uz * 1e6:.1f}, z {z_uz * 1e6:.1f} µm"
        out["uz_by_frame_um"] = {f"{u[0] * 1e9:.0f} ns": round(u[2] * 1e6, 3) for u in s["uz"]}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--solver", default="build/solver/softshock-solve")
    ap.add_argument("--out", default="out/plane_strain")
    ap.add_argument("--end-time", type=float, default=400e-9)
    ap.add_argument("--sizes", default="170000,1300000")
    ap.add_argument("--faces", default="SLIDING,BONDED,FREE")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--img", default="docs/img")
    args = ap.parse_args()
    run_block = {"end_time": args.end_time, "output_interval": 100e-9, "threads": args.threads}

    results = {}
    two_d = os.path.join(args.out, "2d_default")
    summary = run(args.solver, {"run": run_block}, two_d, 1)
    results["2-D default (16.5k triangles)"] = (figures(summary, series(two_d, 1.0)),
                                                 series(two_d, 1.0))
    print(f"2-D: {results['2-D default (16.5k triangles)'][0]}", file=sys.stderr, flush=True)
    for size in [int(n) for n in args.sizes.split(",")]:
        for faces in args.faces.split(","):
            label = f"{faces} {size // 1000}k"
            out = os.path.join(args.out, label.replace(" ", "_"))
            spec = {"geometry": {"cylinder": {"radius": RADIUS, "thickness": THICKNESS,
                                              "faces": faces},
                                 "target_elements": size},
                    "run": run_block}
            summary = run(args.solver, spec, out, args.threads)
            s = series(out, 1.0 / THICKNESS)
            results[label] = (figures(summary, s), s)
            print(f"{label}: {results[label][0]}", file=sys.stderr, flush=True)

    with open(os.path.join(args.out, "figures.json"), "w") as f:
        json.dump({k: v[0] for k, v in results.items()}, f, indent=1)
    print("| run | status | elements | steps | min | centre (ns) | rim reflections (ns) | energy "
          "at 70 ns (J/m) | energy at end (J/m) | Ā filtered 200 ns | Ā filtered end | dominant "
          "mode (mid-plane / z-mean) | max face u_z (µm) | max body u_z (µm) | where |")
    print("|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---|---:|---:|---|")
    for label, (r, _) in results.items():
        refl = ", ".join(f"{x:.1f}" for x in r["rim_reflections_ns"])
        modes = f"{r['dominant_mode_end']}" + (f" / {r['dominant_mode_z_mean_end']}"
                                               if "dominant_mode_z_mean_end" in r else "")
        # A run stopped before the shock could cross the disk (~40 ns) has no centre time: what the
        # summary's detector saw there is the stopping run's, not the shock's.
        centre = (f"{r['shock_at_center_ns']:.2f}" if r["end_ns"] > 50 else "–")
        print(f"| {label} | {r['status']} | {r['elements']:,} | {r['steps']:,} | {r['minutes']} | "
              f"{centre} | {refl} | {r['energy_70ns_J_per_m']:.4f} | "
              f"{r['energy_end_J_per_m']:.4f} | {r['abar_filtered_200ns']:.4f} | "
              f"{r['abar_filtered_end']:.4f} | {modes} | "
              f"{r.get('max_face_uz_um', float('nan')):.3f} | "
              f"{r.get('max_uz_um', float('nan')):.2f} | {r.get('max_uz_where', '')} |")
    for label, (r, _) in results.items():
        if "uz_by_frame_um" in r:
            print(f"{label}: largest |u_z| by frame (µm): {r['uz_by_frame_um']}")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(args.img, exist_ok=True)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for label, (_, s) in results.items():
        t = s["time"] * 1e9
        style = "k-" if label.startswith("2-D") else ("-" if "1300" in label or label.endswith(
            f"{max(int(n) for n in args.sizes.split(',')) // 1000}k") else "--")
        axes[0].plot(t, s["energy"], style, label=label, lw=1)
        axes[1].plot(t, s["abar_filtered"], style, label=label, lw=1)
        axes[2].plot(t, s["rim_mean_radial_displacement"] * 1e6, style, label=label, lw=1)
    axes[0].set_ylabel("kinetic + stored energy per unit thickness (J/m)")
    axes[1].set_ylabel("Ā, filtered (mid-plane rim)")
    axes[2].set_ylabel("rim mean radial displacement (µm)")
    for ax in axes:
        ax.set_xlabel("t (ns)")
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7)
    fig.suptitle("Plane strain against a 50 µm gel layer: sliding, bonded and free faces")
    fig.tight_layout()
    fig.savefig(os.path.join(args.img, "plane_strain_history.png"), dpi=110)
    print(f"wrote {os.path.join(args.img, 'plane_strain_history.png')}", file=sys.stderr)


if __name__ == "__main__":
    main()
