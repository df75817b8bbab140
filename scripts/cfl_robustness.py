#!/usr/bin/env python3
"""Does the answer depend on the Courant number away from the default? (docs/verification.md,
"The time step").

Runs the default spec and variants of it (material, pulse shape and strength, viscosity,
element, mesh size) to END ns at cfl 0.3, 0.7 and 0.9 with softshock-solve, and prints, per
variant, the largest relative difference of the raw A-bar at any history sample against cfl 0.3
and the energy balance at the end (% of the external work). About 30 s on 2 cores. Finished
runs in the work directory are reused: give a fresh --work after changing the solver. The runs
have no aspect-ratio stop (run.max_aspect_ratio 0): P-bar = 10 passes the default's 100 at 46 ns,
and the question here is the time step's, over the whole interval.

Usage: scripts/cfl_robustness.py [--solve build/solver/softshock-solve] [--work DIR] [--end 100]
"""
import argparse
import copy
import json
import os
import subprocess
import sys

import h5py
import numpy as np

VARIANTS = {
    "default": {},
    "P-bar 0.1": {"load": {"pressure": 2e8}},
    "P-bar 5": {"load": {"pressure": 1e10}},
    "P-bar 10": {"load": {"pressure": 2e10}},
    "pulse 60 ns": {"load": {"duration": 60e-9}},
    "GAUSSIAN pulse": {"load": {"shape": "GAUSSIAN"}},
    "LINEAR pulse": {"load": {"shape": "LINEAR"}},
    "seed m = 16, 5 %": {"load": {"perturbation": {"mode": 16, "amplitude": 0.05}}},
    "mu 1e8 Pa": {"material": {"shear_modulus": 1e8}},
    "gamma 1": {"material": {"tait_gamma": 1}},
    "gamma 10": {"material": {"tait_gamma": 10}},
    "eta 0": {"material": {"shear_viscosity": 0}},
    "eta 10 Pa s": {"material": {"shear_viscosity": 10}},
    "no artificial viscosity": {"viscosity": {"c1": 0, "c2": 0}},
    "plain P1": {"element": {"formulation": "P1"}},
    "beta 0": {"element": {"stabilization": 0}},
    "4k elements": {"geometry": {"target_elements": 4000}},
}
CFLS = (0.3, 0.7, 0.9)


def merge(base, extra):
    for key, value in extra.items():
        if isinstance(value, dict):
            merge(base.setdefault(key, {}), value)
        else:
            base[key] = value
    return base


def run(solve, work, name, cfl, end_s):
    out = os.path.join(work, "%s_cfl%g_%gns" % (name.replace(" ", "_"), cfl, end_s * 1e9))
    if not os.path.exists(os.path.join(out, "result.h5")):
        os.makedirs(out, exist_ok=True)
        spec = merge({"run": {"end_time": end_s, "output_interval": 0, "cfl": cfl,
                              "max_aspect_ratio": 0}},
                     copy.deepcopy(VARIANTS[name]))
        with open(os.path.join(out, "spec.json"), "w") as f:
            json.dump(spec, f)
        done = subprocess.run([solve, "--spec", os.path.join(out, "spec.json"), "--out", out,
                               "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        if done.returncode != 0:
            sys.exit("%s at cfl %g failed: %s" % (name, cfl, done.stderr.strip()))
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        ts = f["timeseries"]
        balance = (ts["kinetic_energy"][-1] + ts["elastic_energy"][-1] +
                   ts["dissipated_energy"][-1] - ts["external_work"][-1]) / ts["external_work"][-1]
        return ts["time"][:], ts["abar"][:], 100.0 * balance


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--solve", default="build/solver/softshock-solve")
    ap.add_argument("--work", default="/tmp/cfl-robustness")
    ap.add_argument("--end", type=float, default=100.0, help="end time, ns")
    args = ap.parse_args()
    if not os.access(args.solve, os.X_OK):
        sys.exit("no softshock-solve at %s (build first, or pass --solve)" % args.solve)
    print("| variant | cfl 0.7: largest \\|ΔĀ\\|/Ā (at) | cfl 0.9: largest \\|ΔĀ\\|/Ā (at) |"
          " energy balance, cfl 0.3 / 0.7 / 0.9 (%) |")
    print("|---|---|---|---|")
    for name in VARIANTS:
        t, ref, ref_balance = run(args.solve, args.work, name, CFLS[0], args.end * 1e-9)
        cells, balances = [], [ref_balance]
        for cfl in CFLS[1:]:
            _, abar, balance = run(args.solve, args.work, name, cfl, args.end * 1e-9)
            n = min(len(abar), len(ref))
            rel = np.abs(abar[1:n] - ref[1:n]) / ref[1:n]
            k = int(np.argmax(rel)) + 1
            cells.append("%.1f %% (%.0f ns)" % (100.0 * rel[k - 1], t[k] * 1e9))
            balances.append(balance)
        print("| %s | %s | %s |" % (name, " | ".join(cells),
                                    " / ".join("%+.2f" % b for b in balances)))


if __name__ == "__main__":
    main()
