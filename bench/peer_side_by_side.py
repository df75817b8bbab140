#!/usr/bin/python3
"""The kernel against DOLFINx's explicit step, on the default element and on the peer's own physics.

../shared/peer_dolfinx/side_by_side.sh times bench_solver's BM_GrindTime (16.5k disk, one thread:
the default element -- average nodal pressure with its stabilisation, the mass blend, both
viscosities) against DOLFINx 0.5's "full" step with tuned JIT flags, alternated. This script
alternates the same DOLFINx step with two of our cases in each round: that one, and
BM_GrindTimePeerPhysics (plain P1, lumped mass, the thesis's artificial viscosity, no
Kelvin-Voigt: the physics the DOLFINx step computes, as near as the spec's options come), so the
ratio on equal work and what the default element's extra passes cost come from one sitting.

    apt-get install -y python3-dolfinx python3-gmsh python3-numpy python3-mpi4py openmpi-bin
    /usr/bin/python3 bench/peer_side_by_side.py build/bench/bench_solver --rounds 3

Figures are recorded in docs/performance.md with the load average.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
PEER = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "peer_dolfinx"))
CASES = {"default element": "BM_GrindTime/target_elements:16500/threads:1",
         "peer physics": "BM_GrindTimePeerPhysics/target_elements:16500"}


def ours(bench):
    """Median wall ns per element-step of 3 repetitions, per case."""
    pattern = "^(" + "|".join(re.escape(c) + "/" for c in CASES.values()) + ")"
    out = subprocess.run([bench, f"--benchmark_filter={pattern}", "--benchmark_repetitions=3",
                          "--benchmark_report_aggregates_only=true"],
                         capture_output=True, text=True, check=True).stdout
    figures = {}
    for name, case in CASES.items():
        for line in out.splitlines():
            if line.startswith(case + "/") and "_median" in line:
                figures[name] = float(line.split("wall_ns_per_elem_step=")[1].split()[0])
    if len(figures) != len(CASES):
        sys.exit(f"{bench}: missing cases in its output:\n{out}")
    return figures


def dolfinx(peer, work, round_no):
    out = os.path.join(work, f"dolfinx_{round_no}.json")
    subprocess.run(["/usr/bin/python3", "bench_dolfinx.py", "--mesh", "16k", "--variants", "full",
                    "--jit", "native-noerrno", "--steps", "100", "--warmup", "10", "--out", out],
                   cwd=peer, capture_output=True, text=True, check=True,
                   env={**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"})
    with open(out, encoding="utf-8") as f:
        runs = json.load(f)["runs"]
    return [r for r in runs if r["variant"] == "full"][0]["ns_per_elem_step"]["step"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bench", help="bench_solver executable")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--peer", default=PEER, help="the peer_dolfinx folder")
    args = ap.parse_args()
    bench = os.path.abspath(args.bench)
    os.environ.setdefault("PEER_OUT", "/tmp/peer_dolfinx")  # the peer's meshes/ (read-only folder)
    if not os.path.exists(os.path.join(os.environ["PEER_OUT"], "meshes", "disk_16k.msh")):
        subprocess.run(["/usr/bin/python3", "make_meshes.py", "16k"], cwd=args.peer, check=True,
                       capture_output=True)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    series = {name: [] for name in [*CASES, "dolfinx"]}
    with tempfile.TemporaryDirectory() as work:
        for r in range(args.rounds):
            for name, value in ours(bench).items():
                series[name].append(value)
            series["dolfinx"].append(dolfinx(args.peer, work, r))
            print(f"round {r}: " + ", ".join(f"{k} {v[-1]:.1f}" for k, v in series.items()),
                  flush=True)
    # Each round's own ratio as well: the machine's phase moves both sides of one round alike,
    # while the medians of the two series may come from different phases.
    d = statistics.median(series["dolfinx"])
    print(f"median ns/element-step: dolfinx {d:.1f}")
    for name in CASES:
        s = statistics.median(series[name])
        per_round = [x / y for x, y in zip(series["dolfinx"], series[name])]
        print(f"  softshock, {name}: {s:.1f}; ratio of the medians {d / s:.1f}x; per round "
              f"{', '.join(f'{r:.1f}' for r in per_round)}x, median {statistics.median(per_round):.1f}x")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
