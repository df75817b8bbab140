#!/usr/bin/env python3
"""Kernel grind times on a noisy machine: alternated rounds, medians, per-round thread speed-ups.

On a shared or virtual machine one bench_solver run's figure moves by 15-30 % from minute to
minute, so a single run cannot tell two builds apart, nor give a thread speed-up. This script runs
each given bench_solver binary in turn (GrindTime and GrindTime3D cases), `--rounds` times, so that every binary sees the same
phases of the machine, and prints per binary and case the median and the smallest wall grind
time (ns per element-step) and, for each mesh size, the two-thread speed-up of every round (the
one-thread and two-thread cases of one invocation ran back to back) with its median, and, for
every binary after the first, its ratio to the first in each round (the two ran back to back) with
the median, the quartiles and in how many rounds it was the slower: a difference of a few per cent
shows there where the medians of separate runs cannot show it.

  python3 bench/kernel_rounds.py --rounds 8 build/bench/bench_solver [/tmp/old/bench_solver ...]

Prints the load average before and after (record it with the figures, docs/performance.md).
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

CASE = re.compile(r"^BM_GrindTime(?:3D)?/target_elements:(\d+)/threads:(\d+)/\S*\s.*?"
                  r"wall_ns_per_elem_step=([0-9.eE+-]+)")


def run_once(binary, case_filter):
    out = subprocess.run([binary, f"--benchmark_filter={case_filter}"], check=True,
                         capture_output=True, text=True).stdout
    figures = {}
    for line in out.splitlines():
        m = CASE.match(line)
        if m:
            figures[(int(m.group(1)), int(m.group(2)))] = float(m.group(3))
    if not figures:
        sys.exit(f"{binary}: no GrindTime case matched {case_filter!r}")
    return figures


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binaries", nargs="+", help="bench_solver executables to compare")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--filter", default="GrindTime/target_elements:(16500|264000)/threads:[12]/",
                    help="Google Benchmark filter (GrindTime cases)")
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit("--rounds must be >= 1")

    print("load average before: %.2f %.2f %.2f" % os.getloadavg())
    names = [f"{i}:{b}" for i, b in enumerate(args.binaries)]
    rounds = {n: [] for n in names}
    for r in range(args.rounds):
        for name, binary in zip(names, args.binaries):
            rounds[name].append(run_once(binary, args.filter))
        print(f"round {r + 1}/{args.rounds} done", file=sys.stderr)
    print("load average after:  %.2f %.2f %.2f" % os.getloadavg())

    print("\n| binary | elements | threads | median wall ns/element-step | smallest |")
    print("|---|---|---|---|---|")
    for name in names:
        cases = sorted({c for figures in rounds[name] for c in figures})
        for elements, threads in cases:
            values = [f[(elements, threads)] for f in rounds[name] if (elements, threads) in f]
            print(f"| {name} | {elements} | {threads} | {statistics.median(values):.2f} | "
                  f"{min(values):.2f} |")

    print("\n| binary | elements | two-thread speed-up per round | median |")
    print("|---|---|---|---|")
    for name in names:
        sizes = sorted({e for figures in rounds[name] for (e, t) in figures if t == 2})
        for elements in sizes:
            ratios = [f[(elements, 1)] / f[(elements, 2)] for f in rounds[name]
                      if (elements, 1) in f and (elements, 2) in f]
            if ratios:
                listed = ", ".join(f"{x:.2f}" for x in ratios)
                print(f"| {name} | {elements} | {listed} | {statistics.median(ratios):.2f} |")

    if len(names) > 1:
        first = names[0]
        print(f"\n| binary | elements | threads | ratio to {first}: median | quartiles | slower in |")
        print("|---|---|---|---|---|---|")
        for name in names[1:]:
            cases = sorted({c for figures in rounds[name] for c in figures})
            for case in cases:
                ratios = sorted(a[case] / b[case] for a, b in zip(rounds[name], rounds[first])
                                if case in a and case in b)
                if not ratios:
                    continue
                n = len(ratios)
                slower = sum(r > 1 for r in ratios)
                print(f"| {name} | {case[0]} | {case[1]} | {statistics.median(ratios):.3f} | "
                      f"{ratios[n // 4]:.3f}-{ratios[(3 * n) // 4]:.3f} | {slower} of {n} |")


if __name__ == "__main__":
    main()
