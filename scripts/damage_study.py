#!/usr/bin/python3
"""The disk with phase-field damage (docs/verification.md, "Phase-field damage"): the default
baseline (R0 = 90 um, 2 GPa for 8 ns) with each damage model at its defaults (l = eps = 5 um,
eps_f = 2 MPa, G = 10 J/m^2).

Part 0, the load's release without damage (to 16 ns on 4k and the meshes below): the largest
tension and J beyond 60 um and where, against the outermost element's centroid radius.

Part 1, convergence (to --short-end, default 60 ns) on four ring meshes (16.5k, 66k, 150k, 264k
triangles: l = 2.9, 5.7, 8.5, 11.4 elements): when damage starts, when the centre goes into
tension, the largest damage in the outer ring (r > 80 um: the release's overshoot there) before
--eval-time (56 ns), the centre's damaged zone (radius, area with d >= 1/2, the radius opened to
J > 1.1) and the damage dissipation at --eval-time, and when and how much the rim is damaged.

Part 2, the late answer (to --long-end, default 400 ns) on --long-mesh (default 66k) with no
damage and each model: the centre's damaged zone against time, A-bar(t), the dominant rim mode,
the rim's reflections; docs/img/damage_zone.png and docs/img/damage_abar.png.

Part 3, the update's interval (model 1 to 100 ns on --interval-sizes, default 66k, 150k, 264k):
N_d = 1, 2, 4 on each, and N_d = 1 at half the default cfl (half the interval in time) on all but
the finest: the outer ring's damage (elements beyond 45 um) at 64 / 72 / 100 ns and its inner
edge, the centre zone and the damage dissipation at 100 ns, the mean step; --jobs runs at once.
Part 1 runs at N_d = 4 (DOCUMENTED_UPDATE_EVERY), as its table was made; part 2 at the default.

Prints markdown tables and writes --out/figures.json.

  scripts/damage_study.py [--solver build/solver/softshock-solve] [--out DIR] [--threads 2]
      [--sizes 16500,66000,150000,264000] [--short-end 60e-9] [--eval-time 56e-9] [--long-mesh 66000]
      [--long-end 400e-9] [--img docs/img] [--skip-long] [--interval-sizes 66000,150000,264000]
      [--jobs 2] [--only-interval]
"""
import argparse
import json
import os

import h5py
import numpy as np

from study_runs import run

RIM_RING_M = 80e-6  # the outer ring where the release's overshoot sits (r > 80 um)
CENTRE_M = 60e-6  # the centre's damaged zone: damaged nodes within 60 um of the centre
OUTER_RING_M = 45e-6  # part 3: the outer ring's damage, elements beyond 45 um


# Part 1 as documented: N_d = 4, the default until 2026-12-06 (part 3 measures N_d; part 2 runs at
# the default).
DOCUMENTED_UPDATE_EVERY = 4


def spec(elements, end, model, output_interval, update_every=DOCUMENTED_UPDATE_EVERY, cfl=None):
    s = {"geometry": {"target_elements": elements},
         "run": {"end_time": end, "output_interval": output_interval}}
    if cfl is not None:
        s["run"]["cfl"] = cfl
    if model != "NONE":
        s["damage"] = {"model": model}
        if update_every is not None:  # None: the default
            s["damage"]["update_every"] = update_every
    return s


def zone_radius(r, inside):
    """The radius of the zone around the centre where `inside` holds: the first 1 um ring out from
    the centre in which fewer than half the points are inside (0 if the centre is not)."""
    rings = np.floor(r / 1e-6).astype(int)
    count = np.bincount(rings)
    hits = np.bincount(rings, weights=inside.astype(float), minlength=count.size)
    for k in range(count.size):
        if count[k] and hits[k] < 0.5 * count[k]:
            return k * 1e-6
    return count.size * 1e-6


def reference_mesh(f):
    """The result's reference mesh: node radii, triangles, centroid radii and areas."""
    nodes, tri = f["mesh/nodes"][:], f["mesh/triangles"][:]
    centroid = nodes[tri].mean(axis=1)
    e1, e2 = nodes[tri[:, 1]] - nodes[tri[:, 0]], nodes[tri[:, 2]] - nodes[tri[:, 0]]
    return (np.hypot(nodes[:, 0], nodes[:, 1]), tri, np.hypot(centroid[:, 0], centroid[:, 1]),
            0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]))


def zones(out):
    """Per frame: time, the outer ring's largest d, the centre zone's radius (zone_radius of the
    nodes with d >= 1/2), the number of such nodes within CENTRE_M, the opened cavity's radius
    (zone_radius of the elements at J > 1.1), the largest J within CENTRE_M, and the reference area
    of elements with mean d >= 1/2 within CENTRE_M and beyond RIM_RING_M."""
    rows = []
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        r, tri, rc, area = reference_mesh(f)
        for name in sorted(f["fields"].keys()):
            g = f["fields"][name]
            if "damage" not in g:
                continue
            d = g["damage"][:].ravel()
            j = g["J"][:].ravel()
            centre = (r < CENTRE_M) & (d >= 0.5)
            damaged = d[tri].mean(axis=1) >= 0.5
            rows.append((float(g.attrs["time"]), float(d[r > RIM_RING_M].max()),
                         zone_radius(r, d >= 0.5), int(centre.sum()), zone_radius(rc, j > 1.1),
                         float(j[rc < CENTRE_M].max()),
                         float(area[damaged & (rc < CENTRE_M)].sum()),
                         float(area[damaged & (rc > RIM_RING_M)].sum())))
    return rows


def history(out):
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        ts = f["timeseries"]
        h = {k: ts[k][:] for k in ts.keys()}
        h["modes"] = f["modes/amplitude"][:]
    return h


def centre_tension_from(h):
    """When the centre goes into tension (> 1 MPa) after the shock's focus (its largest
    compression); the precursor before the shock is a few pascals."""
    s, t = h["center_mean_stress"], h["time"]
    focus = int(np.argmin(s))
    after = np.nonzero(s[focus:] > 1e6)[0]
    return float(t[focus + after[0]]) if after.size else float("nan")


def release_study(a):
    """Part 0: no damage, to 16 ns, frames every ns: the largest mean stress (tension > 0) and J of
    the elements beyond 60 um after the load's release, and where (the outermost element?)."""
    rows = []
    for n in [4000] + a.sizes:
        out = os.path.join(a.out, f"release_{n}")
        s = run(a.solver, {"geometry": {"target_elements": n},
                           "run": {"end_time": 16e-9, "output_interval": 1e-9}}, out, a.threads)
        with h5py.File(os.path.join(out, "result.h5"), "r") as f:
            nodes, tri = f["mesh/nodes"][:], f["mesh/triangles"][:]
            centroid = nodes[tri].mean(axis=1)
            rc = np.hypot(centroid[:, 0], centroid[:, 1])
            outer = rc > 60e-6
            best = (-np.inf, 0.0, 0.0, 0.0)
            for name in f["fields"]:
                g = f["fields"][name]
                if g.attrs["time"] < 8e-9:  # before the release
                    continue
                stress, j = g["mean_stress"][:].ravel(), g["J"][:].ravel()
                i = int(np.argmax(np.where(outer, stress, -np.inf)))
                if stress[i] > best[0]:
                    best = (float(stress[i]), float(g.attrs["time"]), float(rc[i]),
                            float(j[outer].max()))
        rows.append({"elements": s["elements"], "largest_tension_MPa": best[0] / 1e6,
                     "at_ns": best[1] * 1e9, "at_radius_um": best[2] * 1e6,
                     "outermost_centroid_um": float(rc.max()) * 1e6, "largest_j": best[3]})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def short_study(a):
    rows = []
    for n in a.sizes:
        for model in ("TALAMINI", "GIOVANARDI"):
            out = os.path.join(a.out, f"short_{model.lower()}_{n}")
            s = run(a.solver, spec(n, a.short_end, model, 2e-9), out, a.threads)
            h, z = history(out), zones(out)
            # The centre's figures at --eval-time (before the wave reflected at the rim damages
            # it, ~60 ns), the rim's at the end.
            k = int(np.argmin([abs(x[0] - a.eval_time) for x in z]))
            i = int(np.argmin(np.abs(h["time"] - a.eval_time)))
            rows.append({
                "model": model, "elements": s["elements"], "steps": s["steps"],
                "minutes": round(s["seconds"] / 60, 1), "solves": s.get("damage_solves", 0),
                "onset_ns": (s.get("damage_onset_s") or float("nan")) * 1e9,
                "rim_max_d_before_eval": max(x[1] for x in z[:k + 1]),
                "centre_radius_um": z[k][2] * 1e6,
                "open_radius_um": z[k][4] * 1e6,
                "centre_area_um2": z[k][6] * 1e12,
                "dissipation_mJ_per_m": float(h["damage_dissipation"][i]) * 1e3,
                "rim_damage_from_ns": next((x[0] * 1e9 for x in z if x[1] >= 0.5), float("nan")),
                "rim_area_end_um2": z[-1][7] * 1e12,
                "centre_tension_from_ns": centre_tension_from(h) * 1e9,
            })
            print(json.dumps(rows[-1]), flush=True)
    return rows


def long_study(a):
    runs = {}
    for model in ("NONE", "TALAMINI", "GIOVANARDI"):
        out = os.path.join(a.out, f"long_{model.lower()}_{a.long_mesh}")
        s = run(a.solver, spec(a.long_mesh, a.long_end, model, 5e-9, None), out, a.threads)
        h = history(out)
        z = zones(out) if model != "NONE" else []
        mode = int(np.argmax(h["modes"][-1][2:]) + 2)
        runs[model] = {"summary": s, "history": h, "zones": z}
        print(json.dumps({"model": model, "minutes": round(s["seconds"] / 60, 1),
                          "status": s["status"], "max_abar_filtered": s["max_abar_filtered"],
                          "abar_filtered_end": s["abar_filtered_end"], "dominant_mode_end": mode,
                          "rim_reflections_ns": [x * 1e9 for x in (s.get("rim_reflections_s") or [])[:3]],
                          "largest_centre_radius_um": max((x[2] for x in z), default=0) * 1e6,
                          "largest_open_radius_um": max((x[4] for x in z), default=0) * 1e6,
                          "open_radius_end_um": z[-1][4] * 1e6 if z else 0.0,
                          "largest_j_centre": max((x[5] for x in z), default=0),
                          "dissipation_mJ_per_m":
                          float(h["damage_dissipation"][-1]) * 1e3 if "damage_dissipation" in h
                          else 0.0}), flush=True)
    return runs


def outer_ring(out, times):
    """The outer ring's damage (elements whose mean d >= 1/2 with centroids beyond OUTER_RING_M):
    its reference area at each of `times`, its inner edge at the last frame -- the first 1 um
    ring out from OUTER_RING_M in which at least half the elements are damaged -- and the centre
    zone's area (damaged elements within OUTER_RING_M) at the last frame."""
    with h5py.File(os.path.join(out, "result.h5"), "r") as f:
        _, tri, rc, area = reference_mesh(f)
        frames = {float(f["fields"][k].attrs["time"]): k for k in f["fields"]}
        ring = rc > OUTER_RING_M
        areas, damaged = [], None
        for t in times:
            name = frames[min(frames, key=lambda x: abs(x - t))]
            damaged = f["fields"][name]["damage"][:].ravel()[tri].mean(axis=1) >= 0.5
            areas.append(float(area[damaged & ring].sum()))
    rings = np.floor(rc / 1e-6).astype(int)
    count = np.bincount(rings)
    hits = np.bincount(rings, weights=(damaged & ring).astype(float), minlength=count.size)
    edge = next((k for k in range(int(OUTER_RING_M / 1e-6), count.size)
                 if count[k] and hits[k] >= 0.5 * count[k]), -1)
    return areas, edge * 1e-6, float(area[damaged & ~ring].sum())


def interval_study(a):
    """Part 3: the update's interval, model 1 to 100 ns on --interval-sizes: N_d = 1, 2, 4, and N_d
    = 1 at half the default cfl (half the interval in time) on all but the finest."""
    from concurrent.futures import ThreadPoolExecutor
    cases = [(n, k, None) for n in a.interval_sizes for k in (1, 2, 4)]
    cases += [(n, 1, 0.375) for n in a.interval_sizes[:-1]]

    def one(case):
        n, k, cfl = case
        out = os.path.join(a.out, f"interval_{n}_nd{k}" + (f"_cfl{cfl}" if cfl else ""))
        s = run(a.solver, spec(n, 100e-9, "TALAMINI", 2e-9, k, cfl), out, 1)
        h = history(out)
        areas, edge, centre = outer_ring(out, (64e-9, 72e-9, 100e-9))
        late = (h["time"] >= 56e-9) & (h["time"] <= 100e-9)
        return {"elements": s["elements"], "update_every": k, "cfl": cfl or 0.75,
                "steps": s["steps"], "solves": s.get("damage_solves", 0),
                "minutes": round(s["seconds"] / 60, 2),
                "outer_64_72_100_um2": "/".join(f"{x * 1e12:,.0f}" for x in areas),
                "outer_edge_100_um": edge * 1e6, "centre_area_100_um2": centre * 1e12,
                "dissipation_100_mJ_per_m": float(h["damage_dissipation"][-1]) * 1e3,
                "mean_dt_56_100_ns": float(np.mean(h["dt"][late])) * 1e9}

    with ThreadPoolExecutor(a.jobs) as pool:
        rows = list(pool.map(one, sorted(cases, key=lambda c: -c[0] * (2 if c[2] else 1) / c[1] ** 0.7)))
    for r in rows:
        print(json.dumps(r), flush=True)
    return rows


def pictures(runs, img):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    colours = {"NONE": "k", "TALAMINI": "tab:red", "GIOVANARDI": "tab:blue"}
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for model, r in runs.items():
        if r["zones"]:
            t = [x[0] * 1e9 for x in r["zones"]]
            ax.plot(t, [x[2] * 1e6 for x in r["zones"]], colours[model],
                    label=f"{model.lower()}: d ≥ 1/2")
            ax.plot(t, [x[4] * 1e6 for x in r["zones"]], colours[model], ls="--",
                    label=f"{model.lower()}: opened, J > 1.1")
    ax.set_xlabel("t (ns)")
    ax.set_ylabel("radius of the centre's zone (µm)")
    ax.set_title("The centre's damaged zone (default disk, 66k triangles)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(img, "damage_zone.png"), dpi=120)
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for model, r in runs.items():
        h = r["history"]
        ax.plot(h["time"] * 1e9, h["abar_filtered"], colours[model], label=model.lower())
    ax.set_xlabel("t (ns)")
    ax.set_ylabel("Ā filtered")
    ax.set_title("Rim roughness with and without damage")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(img, "damage_abar.png"), dpi=120)


def table(rows):
    keys = list(rows[0].keys())
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v)
                                for v in r.values()) + " |")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solver", default="build/solver/softshock-solve")
    p.add_argument("--out", default="damage-study")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--sizes", default="16500,66000,150000,264000")
    p.add_argument("--short-end", type=float, default=60e-9)
    p.add_argument("--eval-time", type=float, default=56e-9)
    p.add_argument("--long-mesh", type=int, default=66000)
    p.add_argument("--long-end", type=float, default=400e-9)
    p.add_argument("--img", default="docs/img")
    p.add_argument("--skip-long", action="store_true")
    p.add_argument("--interval-sizes", default="66000,150000,264000")
    p.add_argument("--jobs", type=int, default=2, help="part 3's runs at once (one thread each)")
    p.add_argument("--only-interval", action="store_true", help="part 3 alone")
    a = p.parse_args()
    a.sizes = [int(x) for x in a.sizes.split(",")]
    a.interval_sizes = [int(x) for x in a.interval_sizes.split(",")]
    if a.only_interval:
        table(interval_study(a))
        return
    figures = {"release": release_study(a)}
    table(figures["release"])
    figures["short"] = short_study(a)
    table(figures["short"])
    figures["interval"] = interval_study(a)
    table(figures["interval"])
    if not a.skip_long:
        runs = long_study(a)
        pictures(runs, a.img)
        figures["long"] = {m: {"zones": r["zones"], "summary": r["summary"]}
                           for m, r in runs.items()}
    with open(os.path.join(a.out, "figures.json"), "w") as f:
        json.dump(figures, f, indent=1)


if __name__ == "__main__":
    main()
