#!/usr/bin/python3
"""Tables and pictures of the late-time verification study (scripts/late-time-study).

Usage: late_time_study.py WORKDIR [--pictures DOCS_IMG_DIR]
Reads WORKDIR/<run>/result.h5 and WORKDIR/<run>/summary.json for the runs the driver made:
  robust_<N>, thesis_<N>  (examples/baseline.json and examples/thesis_p1.json, 800 ns;
                          robust_264000 too when present, the reference for A-bar(t))
  before_<N>              (optional: the same baseline from a solver before the late-time work)
  seed<m>_<N>             (1 % of mode m in the pulse, smooth rim, 450 ns)
  pbar_<P>, beta<b>_*     (stronger pulses; other element stabilisations)
  lumped_<N>, lumpedseed<m>_<N>  (optional: the default and the seeded runs with the lumped
                          mass, element.mass_blend = 0, the default before 2026-12-02 evening;
                          lumped_264000 their A-bar(t) reference)
and prints markdown tables (docs/verification.md quotes them).
"""
import json
import os
import sys

import h5py
import numpy as np


def load(path):
    f = h5py.File(os.path.join(path, "result.h5"), "r")
    ts = {k: f["timeseries"][k][:] for k in f["timeseries"]}
    modes = f["modes/amplitude"][:]
    summary = json.load(open(os.path.join(path, "summary.json")))
    return f, ts, modes, summary


def nearest(t, when):
    return int(np.argmin(np.abs(t - when)))


def last_frame_aspect_ratio(f):
    """Largest longest-edge^2 / (2 area) of the deformed mesh in the last frame."""
    xy = f["mesh/nodes"][:][:, :2]
    tri = f["mesh/triangles"][:]
    last = sorted(f["fields"].keys())[-1]
    p = xy + f["fields"][last]["displacement"][:][:, :2]
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    e1, e2, e3 = b - a, c - a, c - b
    area2 = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    longest = np.max([np.sum(e * e, axis=1) for e in (e1, e2, e3)], axis=0)
    return float(np.max(longest / area2))


def late_min_dt(ts, after=300e-9):
    """Smallest time step after `after`: over every step (min_dt, the smallest step since the
    previous sample) where the result has it, else over the samples' dt (results from before
    the min_dt series, e.g. the before_* runs)."""
    t = ts["time"]
    if "min_dt" in ts:
        return ts["min_dt"][1:][t[:-1] >= after].min()
    return ts["dt"][t >= after].min()


def robustness_table(work, kinds=("before", "thesis", "robust")):
    print("| run | elements | steps | smallest Δt after 300 ns, every step (ps) |"
          " largest aspect ratio at 800 ns | Ā(800 ns) raw / filtered |"
          " dominant mode at 800 ns | solver wall time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for kind in kinds:
        for n in (4000, 16500, 66000, 264000):
            d = os.path.join(work, "%s_%d" % (kind, n))
            if not os.path.exists(os.path.join(d, "result.h5")):
                continue
            f, ts, modes, s = load(d)
            # The final sample's largest aspect ratio (equal to the last frame's, which results
            # from before the max_aspect_ratio series, and the study's 264k runs, lack or skip).
            aspect = (ts["max_aspect_ratio"][-1] if "max_aspect_ratio" in ts
                      else last_frame_aspect_ratio(f))
            print("| %s | %d | %d | %.1f | %.1f | %.3f / %.3f | %d | %.1f |" % (
                kind, s["elements"], s["steps"], late_min_dt(ts) * 1e12,
                aspect, ts["abar"][-1],
                ts["abar_filtered"][-1] if "abar_filtered" in ts else float("nan"),
                s["dominant_mode_end"], s["wall_time_s"]))


def abar_table(work, kind="robust"):
    """Raw A-bar(t) of the default run on each mesh against the finest one present."""
    runs = [(n, os.path.join(work, "%s_%d" % (kind, n))) for n in (4000, 16500, 66000, 264000)]
    runs = [(n, d) for n, d in runs if os.path.exists(os.path.join(d, "result.h5"))]
    if not runs:
        return
    times = (300, 400, 500, 600, 700, 800)
    def series(d):
        ts = h5py.File(os.path.join(d, "result.h5"), "r")["timeseries"]
        t, a = ts["time"][:], ts["abar"][:]
        return [a[nearest(t, x * 1e-9)] for x in times]
    ref = series(runs[-1][1])
    print("| elements | " + " | ".join("%d ns" % x for x in times) + " |")
    print("|---|" + "---|" * len(times))
    for n, d in runs:
        row = series(d)
        print("| %d | " % n + " | ".join("%.3f (%+.0f %%)" % (v, 100 * (v / r - 1))
                                        for v, r in zip(row, ref)) + " |")


def convergence_table(work, prefix="seed"):
    print("| m | elements | A_m(70 ns) | G_m(250 ns) | G_m(450 ns) | crest 1 | crest 2 |"
          " noise / seeded (instantaneous) |")
    print("|---|---|---|---|---|---|---|---|")
    for m in (8, 16):
        for n in (16500, 66000, 264000):
            d = os.path.join(work, "%s%d_%d" % (prefix, m, n))
            if not os.path.exists(os.path.join(d, "result.h5")):
                continue
            f = h5py.File(os.path.join(d, "result.h5"), "r")
            t = f["modes/time"][:]
            a = f["modes/amplitude"][:]
            a70 = a[nearest(t, 70e-9), m]
            g250 = a[nearest(t, 250e-9), m] / a70
            g450 = a[nearest(t, 450e-9), m] / a70
            # The seeded mode rings through zero at each inversion: growth is read on the crests
            # of its two cycles, noise against its running maximum (docs/verification.md).
            crests = [a[(t >= lo) & (t <= hi), m].max()
                      for lo, hi in ((150e-9, 245e-9), (350e-9, 445e-9))]
            envelope = np.maximum.accumulate(a[:, m])
            noise = instantaneous = 0.0
            for k in range(len(t)):
                if t[k] < 70e-9:
                    continue
                row = a[k].copy()
                row[:2] = 0
                row[::m] = 0  # the seed and its harmonics
                noise = max(noise, row.max() / envelope[k])
                instantaneous = max(instantaneous, row.max() / a[k, m])
            print("| %d | %d | %.3e | %.3f | %.3f | %.3e | %.3e | %.3f (%.2f) |" % (
                m, n, a70, g250, g450, crests[0], crests[1], noise, instantaneous))


def pictures(work, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    for n in (16500, 66000):
        d = os.path.join(work, "robust_%d" % n)
        if not os.path.exists(os.path.join(d, "result.h5")):
            continue
        f = h5py.File(os.path.join(d, "result.h5"), "r")
        xy = f["mesh/nodes"][:][:, :2]
        tri = f["mesh/triangles"][:]
        frames = {round(f["fields"][k].attrs["time"] * 1e9): k for k in f["fields"]}
        fig, axes = plt.subplots(1, 3, figsize=(15, 5.2))
        for ax, when in zip(axes, (300, 500, 800)):
            fr = f["fields"][frames[when]]
            p = (xy + fr["displacement"][:][:, :2]) * 1e6
            pc = PolyCollection(p[tri], array=fr["mean_stress"][:] / 1e6, cmap="coolwarm",
                                edgecolors="k", linewidths=0.05 if n > 20000 else 0.1)
            pc.set_clim(-300, 300)
            ax.add_collection(pc)
            ax.set_xlim(-110, 110)
            ax.set_ylim(-110, 110)
            ax.set_aspect("equal")
            ax.set_title("%d elements, %d ns" % (n, when))
            ax.set_xlabel("x (µm)")
        fig.colorbar(pc, ax=axes, label="mean stress (MPa)", shrink=0.8)
        out = os.path.join(out_dir, "late_time_%dk.png" % (n // 1000))
        fig.savefig(out, dpi=90, bbox_inches="tight")
        print("wrote", out)


def abar_picture(work, out_dir):
    """Raw A-bar(t) of the default run on every mesh present: where 16.5k leaves 66k and 264k."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4))
    drawn = False
    for n in (4000, 16500, 66000, 264000):
        d = os.path.join(work, "robust_%d" % n)
        if not os.path.exists(os.path.join(d, "result.h5")):
            continue
        _, ts, _, s = load(d)
        ax.plot(ts["time"] * 1e9, ts["abar"], label="%d elements" % s["elements"])
        drawn = True
    if not drawn:
        return
    ax.set_xlabel("t (ns)")
    ax.set_ylabel(r"raw $\bar{A}$")
    ax.set_title("default run (baseline load) under refinement")
    ax.legend()
    out = os.path.join(out_dir, "abar_refinement.png")
    fig.savefig(out, dpi=90, bbox_inches="tight")
    print("wrote", out)


def pbar_runs(work):
    """The default run on 16.5k elements at each pulse pressure (P-bar = P / 2 GPa) present."""
    runs = [(0.5 * p, os.path.join(work, "pbar_%s" % tag)) for p, tag in
            ((1.0, "1e9"), (2.5, "2.5e9"), (3.0, "3e9"), (4.0, "4e9"))]
    runs.append((1.0, os.path.join(work, "robust_16500")))
    return sorted((pbar, d) for pbar, d in runs if os.path.exists(os.path.join(d, "result.h5")))


def pbar_table(work):
    print("| P̄ | steps | smallest Δt after 300 ns, every step (ps) |"
          " largest aspect ratio, any time / at 800 ns | first above 10 (ns) |"
          " smallest J of the element setting Δt | raw Ā(800 ns) |"
          " solver wall (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for pbar, d in pbar_runs(work):
        f, ts, modes, s = load(d)
        above = s["aspect_ratio_above_10_s"]
        print("| %g | %d | %.1f | %.1f / %.1f | %s | %.3f | %.3f | %.1f |" % (
            pbar, s["steps"], late_min_dt(ts) * 1e12, s["max_aspect_ratio"],
            ts["max_aspect_ratio"][-1], "never" if above < 0 else "%.0f" % (above * 1e9),
            ts["dt_element_j"][1:].min(), ts["abar"][-1], s["wall_time_s"]))


def beta_table(work):
    """The element stabilisation beta against the figures it trades: the beta<b>_* runs the driver
    made, beside the default's own (robust_16500 / robust_66000 / pbar_2.5e9 / pbar_3e9, whose
    beta is read from the spec they ran)."""
    print("| β | steps (16.5k) | smallest Δt after 300 ns, every step (ps) |"
          " largest aspect ratio, any time /"
          " of an element setting Δt after 300 ns | raw Ā(800 ns) 16.5k | 66k | 66k from 16.5k |"
          " largest aspect ratio, 66k | P̄ = 1.25: steps / largest aspect ratio |"
          " P̄ = 1.5: steps / largest aspect ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    runs = ("16500", "66000", "pbar_2.5e9", "pbar_3e9")
    default_dirs = [os.path.join(work, n) for n in ("robust_16500", "robust_66000") + runs[2:]]
    rows = {}
    if os.path.exists(os.path.join(default_dirs[0], "spec.json")):
        spec = json.load(open(os.path.join(default_dirs[0], "spec.json")))
        rows[float(spec["element"]["stabilization"])] = (default_dirs, True)
    for name in os.listdir(work):
        if name.startswith("beta") and name.endswith("_16500"):
            b = name[len("beta"):-len("_16500")]
            rows[float(b)] = ([os.path.join(work, "beta%s_%s" % (b, r)) for r in runs], False)
    for b, (dirs, is_default) in sorted(rows.items()):
        if not all(os.path.exists(os.path.join(d, "result.h5")) for d in dirs):
            continue
        (_, ts, _, s), (_, _, _, fine), (_, _, _, p125), (_, _, _, p15) = map(load, dirs)
        late = ts["time"] >= 300e-9
        print("| %g%s | %d | %.1f | %.1f / %.1f | %.4f | %.4f | %+.1f %% | %.1f | %d / %.1f |"
              " %d / %.1f |" % (
                  b, " (default)" if is_default else "", s["steps"],
                  late_min_dt(ts) * 1e12, s["max_aspect_ratio"],
                  ts["dt_element_aspect_ratio"][late].max(), s["abar_end"], fine["abar_end"],
                  100 * (fine["abar_end"] / s["abar_end"] - 1), fine["max_aspect_ratio"],
                  p125["steps"], p125["max_aspect_ratio"], p15["steps"], p15["max_aspect_ratio"]))


def pbar_picture(work, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    runs = pbar_runs(work)
    if not runs:
        return
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for pbar, d in runs:
        _, ts, _, _ = load(d)
        t = ts["time"] * 1e9
        top.plot(t, ts["abar"], label=r"$\bar{P}$ = %g" % pbar)
        bottom.semilogy(t, ts["max_aspect_ratio"], label=r"$\bar{P}$ = %g" % pbar)
    top.set_ylabel(r"raw $\bar{A}$")
    bottom.axhline(15, color="k", lw=0.8, ls="--", label="15 (the issue's limit at 800 ns)")
    bottom.set_ylabel("largest aspect ratio")
    bottom.set_xlabel("t (ns)")
    top.legend()
    bottom.legend(fontsize=8)
    top.set_title("default formulation, 16.5k elements: stronger pulses")
    out = os.path.join(out_dir, "pbar_envelope.png")
    fig.savefig(out, dpi=90, bbox_inches="tight")
    print("wrote", out)


def main():
    work = sys.argv[1]
    print("## Robustness (800 ns)\n")
    robustness_table(work)
    print("\n## Raw A-bar(t) of the default run against the finest mesh\n")
    abar_table(work)
    print("\n## Seeded growth\n")
    convergence_table(work)
    if os.path.exists(os.path.join(work, "lumped_264000", "result.h5")):
        print("\n## The lumped mass (element.mass_blend = 0)\n")
        robustness_table(work, kinds=("lumped",))
        print()
        abar_table(work, kind="lumped")
        print()
        convergence_table(work, prefix="lumpedseed")
    print("\n## Stronger pulses (16.5k, 800 ns)\n")
    pbar_table(work)
    print("\n## The element stabilisation beta (16.5k and 66k, 800 ns)\n")
    beta_table(work)
    if "--pictures" in sys.argv:
        out_dir = sys.argv[sys.argv.index("--pictures") + 1]
        pictures(work, out_dir)
        abar_picture(work, out_dir)
        pbar_picture(work, out_dir)


if __name__ == "__main__":
    main()
