#!/usr/bin/python3
"""Compares two result.h5 files dataset by dataset: every dataset of A must exist in B with the
same shape; prints the largest relative difference per dataset (|a - b| / max |a|) and exits 1
when any exceeds --rtol (default 0: bitwise). Used to show that a change leaves a run's answer
unchanged (docs/performance.md, docs/verification.md).

  scripts/compare_results.py A/result.h5 B/result.h5 [--rtol 1e-12] [--quiet]
"""
import argparse
import sys

import h5py
import numpy as np


def datasets(f):
    out = {}
    f.visititems(lambda name, obj: out.__setitem__(name, obj) if isinstance(obj, h5py.Dataset)
                 else None)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rtol", type=float, default=0.0)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    worst, failures, compared = 0.0, [], 0
    with h5py.File(args.a, "r") as fa, h5py.File(args.b, "r") as fb:
        da, db = datasets(fa), datasets(fb)
        for name in sorted(da):
            if name not in db:
                failures.append(f"{name}: missing in B")
                continue
            a, b = np.asarray(da[name][()]), np.asarray(db[name][()])
            if a.shape != b.shape:
                failures.append(f"{name}: shape {a.shape} vs {b.shape}")
                continue
            compared += 1
            if a.dtype.kind not in "fiu":
                if not np.array_equal(a, b):
                    failures.append(f"{name}: differs")
                continue
            a, b = a.astype(np.float64), b.astype(np.float64)
            if np.array_equal(a, b, equal_nan=True):
                rel = 0.0
            else:
                scale = np.nanmax(np.abs(a)) if a.size else 0.0
                rel = float(np.nanmax(np.abs(a - b)) / scale) if scale > 0 else float("inf")
            worst = max(worst, rel)
            if rel > args.rtol:
                failures.append(f"{name}: relative difference {rel:.3g}")
            elif not args.quiet and rel > 0:
                print(f"{name}: {rel:.3g}")
        for name in sorted(set(db) - set(da)):
            failures.append(f"{name}: only in B")
    for line in failures:
        print(line)
    print(f"{compared} datasets compared, largest relative difference {worst:.3g}"
          f" ({'identical' if worst == 0 else 'within ' + str(args.rtol) if not failures else 'FAIL'})")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
