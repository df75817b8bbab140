#!/usr/bin/python3
"""The 3-D solver's refinement and orientation study (docs/verification.md, "Three dimensions"):
the default baseline (R0 = 90 um, 2 GPa for 8 ns) on a cylinder with sliding faces -- exactly
plane strain, so the 2-D default's figures are the reference -- on three sizes of the default
mesh (the 2-D rings extruded) and on two other meshes of the middle size (the same rings turned by
0.3 rad, and Gmsh's Delaunay tetrahedra), to the end of the first cycle (t-bar = 4, 254 ns).
Prints a markdown table of the early events, the energy left after the first pass, the first
cycle's largest A-bar (filtered, mid-plane) and the dominant rim mode, and writes the figures as
JSON.

  scripts/verification_3d.py [--solver build/solver/softshock-solve] [--out DIR]
                             [--thickness 10e-6] [--sizes 25000,100000,400000] [--end-time 260e-9]
"""
import argparse
import json
import os
import subprocess
import sys
import time

import h5py
import numpy as np


def run(solver, spec, out):
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "spec.json")
    with open(path, "w") as f:
        json.dump(spec, f)
    started = time.monotonic()
    p = subprocess.run([solver, "--spec", path, "--out", out, "--quiet"], capture_output=True,
                       text=True)
    if p.returncode != 0:
        raise SystemExit(f"{out}: softshock-solve failed ({p.returncode}): {p.stderr[-2000:]}")
    summary = json.loads(p.stdout.strip().splitlines()[-1])
    summary["seconds"] = time.monotonic() - started
    return summary


def figures(summary, out, thickness):
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        ts = f["timeseries"]
        t = ts["time"][:]
        energy = ts["kinetic_energy"][:] + ts["elastic_energy"][:]
        k70 = int(np.argmin(np.abs(t - 70e-9)))
        modes = f["modes/amplitude"][:]
        abar_f = ts["abar_filtered"][:]
    reflections = summary.get("rim_reflections_s") or [float("nan")]
    return {
        "elements": summary["elements"],
        "steps": summary["steps"],
        "seconds": round(summary["seconds"], 1),
        "shock_at_center_ns": summary["shock_at_center_s"] * 1e9,
        "first_rim_reflection_ns": reflections[0] * 1e9,
        "energy_left_70ns_J_per_m": energy[k70] / thickness,
        "max_abar_filtered_first_cycle": float(abar_f.max()),
        "dominant_mode_end": int(np.argmax(modes[-1][2:]) + 2) if modes.shape[1] > 2 else 0,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--solver", default="build/solver/softshock-solve")
    ap.add_argument("--out", default="out/verification_3d")
    ap.add_argument("--thickness", type=float, default=10e-6)
    ap.add_argument("--sizes", default="25000,100000,400000")
    ap.add_argument("--end-time", type=float, default=260e-9)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    middle = sizes[len(sizes) // 2]

    def spec(elements, **geometry):
        g = {"cylinder": {"radius": 90e-6, "thickness": args.thickness, "faces": "SLIDING"},
             "target_elements": elements}
        g.update(geometry)
        return {"geometry": g, "run": {"end_time": args.end_time, "output_interval": 0}}

    cases = [(f"rings {n}", spec(n)) for n in sizes]
    cases += [(f"rings {middle} turned 0.3 rad", spec(middle, mesh_rotation=0.3)),
              (f"Gmsh Delaunay {middle}", spec(middle, mesher="FRONTAL_DELAUNAY"))]
    rows = {}
    for label, s in cases:
        out = os.path.join(args.out, label.replace(" ", "_"))
        rows[label] = figures(run(args.solver, s, out), out, args.thickness)
        print(f"{label}: {rows[label]}", file=sys.stderr, flush=True)
    with open(os.path.join(args.out, "figures.json"), "w") as f:
        json.dump(rows, f, indent=1)
    print(f"| mesh | tetrahedra | steps | run (s) | shock at centre (ns) | first rim reflection "
          f"(ns) | energy at 70 ns (J/m) | max Ā filtered, t̄ ≤ 4 | dominant mode at "
          f"{args.end_time * 1e9:.0f} ns |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, r in rows.items():
        print(f"| {label} | {r['elements']:,} | {r['steps']:,} | {r['seconds']} | "
              f"{r['shock_at_center_ns']:.2f} | {r['first_rim_reflection_ns']:.2f} | "
              f"{r['energy_left_70ns_J_per_m']:.4f} | {r['max_abar_filtered_first_cycle']:.4f} | "
              f"{r['dominant_mode_end']} |")


if __name__ == "__main__":
    main()
