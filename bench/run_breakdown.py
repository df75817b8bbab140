#!/usr/bin/python3
"""Where one run's time goes, as a process (a benchmark, not a test).

Runs softshock-solve N times on a spec (default: the base spec of examples/pbar_tpulse_grid.json,
the baseline disk to t-bar = 4) with a private mesh cache that the first run fills, and prints
per run the whole-process wall and CPU time beside steps x elements x kernel grind time (the
element passes alone, wall time measured inside the run), their ratios, the meshing time and the
cache outcome, and the load average. On a shared machine compare CPU with CPU: the process's
wall time includes what other processes took from it. Also times start-up alone: a spec that fails validation once the process has
loaded (exit 2), which every run pays before it meshes or steps.

Two yardsticks for the kernel: the run's own (`kernel_grind_ns` of its summary: wall time of the
element passes and the nodal passes between them, measured inside the run; the stricter one), and,
with --bench, the kernel benchmark's (bench_solver's GrindTime at 16.5k, one thread: whole steps,
predictor and correctors included, without set-up, diagnostics or output), run before every
solver run so that both see the same phases of the machine. The issue's target (process <= 1.3 x
steps x elements x kernel grind; "now ~3.2x" with the benchmark's 23-28 ns) is stated against
the second.

    cmake --build build --target softshock-solve
    /usr/bin/python3 bench/run_breakdown.py --runs 5 [--bench build/bench/bench_solver]

Figures are recorded in docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--solve", default=os.path.join(ROOT, "build", "solver", "softshock-solve"))
    parser.add_argument("--grid", default=os.path.join(ROOT, "examples", "pbar_tpulse_grid.json"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--no-cache", action="store_true", help="mesh every run (no cache)")
    parser.add_argument("--bench", help="bench_solver executable: also the ratio to its grind time")
    args = parser.parse_args()

    with open(args.grid, encoding="utf-8") as f:
        spec = json.load(f)["base_spec"]
    work = tempfile.mkdtemp(prefix="softshock-breakdown-")
    spec_path = os.path.join(work, "spec.json")
    with open(spec_path, "w", encoding="utf-8") as f:
        json.dump(spec, f)
    cache = ["--no-mesh-cache"] if args.no_cache else ["--mesh-cache", os.path.join(work, "meshes")]

    # Start-up alone: the process loads, parses the spec and exits 2 (invalid CFL).
    bad = os.path.join(work, "bad.json")
    with open(bad, "w", encoding="utf-8") as f:
        json.dump({"run": {"cfl": 2}}, f)
    starts = []
    for _ in range(20):
        t0 = time.perf_counter()
        subprocess.run([args.solve, "--spec", bad, "--out", os.path.join(work, "x")],
                       capture_output=True, check=False)
        starts.append(time.perf_counter() - t0)
    print(f"process start (exit 2 after parsing): median {statistics.median(starts) * 1e3:.1f} ms"
          f" over {len(starts)}")

    print(f"{'run':>3} {'wall s':>7} {'cpu s':>6} {'run s':>6} {'kernel s':>8} {'wall/k':>6} "
          f"{'cpu/k':>5} {'grind ns':>8} {'kernel ns':>9} {'mesh s':>7} cache  load")
    ratios, cpu_ratios, bench_ratios, bench_grinds = [], [], [], []
    for k in range(args.runs):
        if args.bench:
            bench_grinds.append(bench_grind_ns(args.bench))
        out = os.path.join(work, f"out{k}")
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run([args.solve, "--spec", spec_path, "--out", out, "--quiet", *cache],
                           capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime
        if r.returncode != 0:
            print(r.stderr, file=sys.stderr)
            return 1
        s = json.loads(r.stdout)
        kernel_total = s["steps"] * s["elements"] * s["kernel_grind_ns"] * 1e-9
        ratio, cpu_ratio = wall / kernel_total, cpu / kernel_total
        if k > 0 or args.no_cache:
            ratios.append(ratio)
            cpu_ratios.append(cpu_ratio)
            if args.bench:
                bench_ratios.append(wall / (s["steps"] * s["elements"] * bench_grinds[-1] * 1e-9))
        print(f"{k:>3} {wall:>7.3f} {cpu:>6.3f} {s['wall_time_s']:>6.3f} {kernel_total:>8.3f} "
              f"{ratio:>6.2f} {cpu_ratio:>5.2f} {s['grind_ns']:>8.1f} {s['kernel_grind_ns']:>9.1f} "
              f"{s['meshing_time_s']:>7.3f} {s['mesh_cache']:<6} {os.getloadavg()[0]:.2f}")
    if ratios:
        print(f"process / (steps x elements x kernel grind), runs with a cached mesh: median "
              f"wall {statistics.median(ratios):.2f}, CPU {statistics.median(cpu_ratios):.2f}")
    if bench_ratios:
        print(f"kernel benchmark (GrindTime 16.5k, 1 thread) before each run: "
              f"{', '.join(f'{g:.1f}' for g in bench_grinds)} ns; process wall / (steps x elements "
              f"x that run's benchmark grind): median {statistics.median(bench_ratios):.2f} "
              f"({', '.join(f'{r:.2f}' for r in bench_ratios)})")
    return 0


def bench_grind_ns(bench: str) -> float:
    """One bench_solver GrindTime run at 16.5k, one thread: its wall ns per element-step."""
    out = subprocess.run([bench, "--benchmark_filter=GrindTime/target_elements:16500/threads:1/"],
                         capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        if "wall_ns_per_elem_step=" in line:
            return float(line.split("wall_ns_per_elem_step=")[1].split()[0])
    raise SystemExit(f"{bench}: no GrindTime figure in its output")


if __name__ == "__main__":
    sys.exit(main())
