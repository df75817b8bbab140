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
    /usr/bin/python3 bench/peer_side_by_side.py build/bench/bench_solver --rounds 3 \
        [--plot docs/img/pass_split.png]

--plot draws each case's step pass by pass (bench_solver's pass_*_ns, medians over the rounds)
against DOLFINx's step and the 12x budget it sets. Figures are recorded in docs/performance.md
with the load average.
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
    """Per case: median wall ns per element-step of 3 repetitions, and its passes (name: ns)."""
    pattern = "^(" + "|".join(re.escape(c) + "/" for c in CASES.values()) + ")"
    out = subprocess.run([bench, f"--benchmark_filter={pattern}", "--benchmark_repetitions=3",
                          "--benchmark_report_aggregates_only=true"],
                         capture_output=True, text=True, check=True).stdout
    figures = {}
    for name, case in CASES.items():
        for line in out.splitlines():
            if line.startswith(case + "/") and "_median" in line:
                wall = float(line.split("wall_ns_per_elem_step=")[1].split()[0])
                passes = {m[1]: float(m[2])
                          for m in re.finditer(r"pass_(\w+?)_ns=([0-9.eE+-]+)", line)}
                figures[name] = (wall, passes)
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
    ap.add_argument("--plot", help="PNG of the passes against DOLFINx's step (needs matplotlib)")
    args = ap.parse_args()
    bench = os.path.abspath(args.bench)
    os.environ.setdefault("PEER_OUT", "/tmp/peer_dolfinx")  # the peer's meshes/ (read-only folder)
    if not os.path.exists(os.path.join(os.environ["PEER_OUT"], "meshes", "disk_16k.msh")):
        subprocess.run(["/usr/bin/python3", "make_meshes.py", "16k"], cwd=args.peer, check=True,
                       capture_output=True)
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    series = {name: [] for name in [*CASES, "dolfinx"]}
    passes = {name: {} for name in CASES}  # case -> pass -> one figure a round
    with tempfile.TemporaryDirectory() as work:
        for r in range(args.rounds):
            for name, (wall, split) in ours(bench).items():
                series[name].append(wall)
                for p, ns in split.items():
                    passes[name].setdefault(p, []).append(ns)
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
    for name in CASES:
        print(f"  {name}, passes (median ns/element-step): " +
              ", ".join(f"{p} {statistics.median(v):.2f}" for p, v in passes[name].items()))
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.plot:
        plot(args.plot, {n: {p: statistics.median(v) for p, v in ps.items()}
                         for n, ps in passes.items()},
             {n: statistics.median(series[n]) for n in CASES}, d)
        print(f"wrote {args.plot}")


# The passes in step order, with the names docs/performance.md uses.
PASSES = [("predict_and_load", "predictor + load"), ("nodal_areas", "nodal areas"),
          ("nodal_state", "nodal Tait state"), ("stabilization", "stabilisation"),
          ("stabilized_state", "stabilised state"), ("element_forces", "element forces"),
          ("correct", "corrector"), ("mass_blend_difference", "mass blend, element pass"),
          ("mass_blend_correct", "mass blend, corrector")]


def plot(path, split, wall, dolfinx_ns):
    """Stacked bars of each case's passes (ns/element-step), DOLFINx's step/12 as the budget; the
    element loop last, so that the bar shows what the other passes alone leave of the budget."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 3.6))
    colours = plt.get_cmap("tab10")
    names = list(split)
    order = [p for p in PASSES if p[0] != "element_forces"] + [("element_forces", "element forces")]
    for row, name in enumerate(names):
        left = 0.0
        for k, (key, label) in enumerate(order):
            ns = split[name].get(key, 0.0)
            if ns > 0:
                ax.barh(row, ns, left=left, color=colours(k), edgecolor="white",
                        label=label if row == 0 or key not in split[names[0]] else None)
                left += ns
        ax.text(wall[name] + 0.3, row, f"{wall[name]:.1f} ns step ({dolfinx_ns / wall[name]:.1f}x)",
                va="center", fontsize=9)
    budget = dolfinx_ns / 12
    ax.axvline(budget, color="black", linestyle="--", linewidth=1)
    ax.text(budget, -0.5, f" 12x DOLFINx's step: {budget:.1f} ns", fontsize=9, va="bottom")
    ax.set_yticks(range(len(names)), [f"{n} (16.5k)" for n in names])
    ax.set_xlim(0, max(wall.values()) * 1.35)
    ax.set_ylim(len(names) - 0.5, -0.75)
    ax.set_title("One step, pass by pass (the element loop last)", fontsize=10)
    ax.set_xlabel(f"ns per element-step, one thread (DOLFINx's tuned step: {dolfinx_ns:.1f} ns)")
    ax.legend(fontsize=7, ncol=5, loc="upper center", bbox_to_anchor=(0.5, -0.25))
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
