#!/usr/bin/python3
"""The solver's step against time on the step-estimate study's runs (docs/reliability.md, "Time
steps"): each run's smallest step per history sample over its dt_load, from the CSV files that
`step_estimate_study CASES --trace DIR` writes, with the passage marked. Writes one PNG.

  build/bench/step_estimate_study bench/step_estimate_cases.txt --trace /tmp/trace
  bench/plot_step_traces.py /tmp/trace docs/img/step_traces.png [RUN ...]
"""
import os
import sys

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DEFAULT_RUNS = ["d16@1600", "c20@1600", "c20b@800", "c50b@400"]
LABELS = {"d16@1600": "disk, 16.5k triangles", "c20@1600": "cylinder 20 um, 20k tets, sliding",
          "c20b@800": "cylinder 20 um, 20k tets, bonded",
          "c50b@400": "cylinder 50 um, 53k tets, bonded"}


def read(path):
    """The header's figures (dt_load_ns, dt_rest_ns, passage_ns, steps) and the columns."""
    with open(path) as f:
        words = f.readline().lstrip("# ").split()
    head = {words[i]: float(words[i + 1]) for i in range(0, len(words), 2)}
    data = np.loadtxt(path, delimiter=",", skiprows=2, ndmin=2)
    return head, data[1:, 0], data[1:, 2]  # the first sample has no interval before it


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    folder, png, runs = sys.argv[1], sys.argv[2], sys.argv[3:] or DEFAULT_RUNS
    fig, ax = plt.subplots(figsize=(7.2, 3.8))
    for name in runs:
        head, t, smallest = read(os.path.join(folder, name + ".csv"))
        line, = ax.plot(t, smallest / head["dt_load_ns"], lw=0.8,
                        label=f"{LABELS.get(name, name)}: dt_rest = {head['dt_rest_ns'] / head['dt_load_ns']:.1f} dt_load")
        ax.axvline(head["passage_ns"], color=line.get_color(), ls=":", lw=0.8)
    ax.set_xlabel("t (ns); dotted: the end of the passage")
    ax.set_ylabel("smallest step per 1 ns sample / dt_load")
    ax.set_yscale("log")
    ticks = [0.3, 0.5, 1, 2, 3, 5]
    ax.set_yticks(ticks, [str(x) for x in ticks])
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=120)


if __name__ == "__main__":
    main()
