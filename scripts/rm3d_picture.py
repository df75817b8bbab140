#!/usr/bin/python3
"""The model's 3-D Richtmyer-Meshkov demonstration (examples/richtmyer_meshkov_3d.json): a box
whose free top carries the bi-sinusoidal corrugation a cos(kx x) cos(ky y), hit from below by the
2 GPa pulse. Draws the deformed free surface (coloured by height) and two vertical sections (the
walls y = 0 and x = 0, symmetry planes through rows of peaks) coloured by mean stress at 0, 20, 30
and 40 ns from the result file (h5py and matplotlib only), into docs/img/richtmyer_meshkov_3d.png.

  build/solver/softshock-solve --spec examples/richtmyer_meshkov_3d.json --out out/rm3d
  scripts/rm3d_picture.py out/rm3d/result.h5 [--out docs/img/richtmyer_meshkov_3d.png]
"""
import argparse

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def section(points, tets, values, axis, level):
    """The tetrahedra's section by the plane coordinate[axis] = level: one polygon per cut
    tetrahedron (in the other two coordinates) with its element value."""
    d = points[:, axis] - level
    keep = [a for a in range(3) if a != axis]
    polys, vals = [], []
    for e, t in enumerate(tets):
        below = [i for i in t if d[i] < 0]
        above = [i for i in t if d[i] >= 0]
        if not below or not above:
            continue
        pts = []
        for a in below:
            for b in above:
                s = d[a] / (d[a] - d[b])
                p = points[a] + s * (points[b] - points[a])
                pts.append(p[keep])
        pts = np.array(pts)
        c = pts.mean(axis=0)
        order = np.argsort(np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0]))
        polys.append(pts[order] * 1e6)
        vals.append(values[e])
    return polys, np.array(vals)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("result")
    ap.add_argument("--out", default="docs/img/richtmyer_meshkov_3d.png")
    ap.add_argument("--times", default="0,20e-9,30e-9,40e-9")
    ap.add_argument("--depth", type=float, default=25e-6,
                    help="how far below the surface the sections reach (m)")
    args = ap.parse_args()
    with h5py.File(args.result, "r") as f:
        nodes = f["mesh/nodes"][:]
        tets = f["mesh/tetrahedra"][:]
        faces = f["mesh/boundary_faces"][:]
        names = sorted(f["fields"].keys())
        times = np.array([f["fields"][n].attrs["time"] for n in names])
        wanted = [float(t) for t in args.times.split(",")]
        frames = []
        for t in wanted:
            g = f["fields"][names[int(np.argmin(np.abs(times - t)))]]
            frames.append((float(g.attrs["time"]), g["displacement"][:], g["mean_stress"][:]))
    lx, ly = nodes[:, 0].max(), nodes[:, 1].max()
    # The free surface: boundary faces whose reference outward normal points up (+z).
    a, b, c = (nodes[faces[:, i]] for i in range(3))
    top = faces[np.cross(b - a, c - a)[:, 2] > 0]
    # Pa: the shock is 2 GPa, the tension after its reflection a tenth of that; the scale saturates
    # in the shock to show the tension.
    vmax = 0.25e9
    norm = matplotlib.colors.Normalize(-vmax, vmax)
    cmap = plt.get_cmap("RdBu_r")
    fig = plt.figure(figsize=(16, 12))
    for k, (t, disp, stress) in enumerate(frames):
        x = nodes + disp
        ax = fig.add_subplot(3, len(frames), k + 1, projection="3d")
        # Coloured by height (the stress at the free surface is ~0): the shape, which inverts.
        zt = x[np.unique(top), 2] * 1e6
        height = x[top][:, :, 2].mean(axis=1) * 1e6
        ax.add_collection3d(Poly3DCollection(x[top] * 1e6, facecolors=plt.get_cmap("viridis")(
            (height - zt.min()) / max(zt.max() - zt.min(), 1e-9)), edgecolors="none"))
        ax.set_xlim(0, lx * 1e6)
        ax.set_ylim(0, ly * 1e6)
        ax.set_zlim(zt.min() - 0.1, zt.max() + 0.1)
        ax.set_box_aspect((1, 1, 0.6))
        ax.set_title(f"free surface, {t * 1e9:.0f} ns\nheight range {zt.max() - zt.min():.2f} µm",
                     fontsize=9)
        ax.set_xlabel("x (µm)", fontsize=7)
        ax.set_ylabel("y (µm)", fontsize=7)
        ax.tick_params(labelsize=6)
        for row, (axis, label) in enumerate(((1, "y = 0 (peaks x = 0, 10, 20)"),
                                             (0, "x = 0 (peaks y = 0, 20)"))):
            # A plane just inside the wall (a symmetry plane), so tetrahedra on it are cut.
            polys, vals = section(x, tets, stress, axis, 1e-4 * (ly if axis == 1 else lx))
            ax2 = fig.add_subplot(3, len(frames), (row + 1) * len(frames) + k + 1)
            pc = PolyCollection(polys, array=vals, cmap=cmap, norm=norm, edgecolor="none")
            ax2.add_collection(pc)
            ax2.set_xlim(0, (lx if axis == 1 else ly) * 1e6)
            ax2.set_ylim(zt.min() - args.depth * 1e6, zt.max() + 0.5)
            ax2.set_aspect("equal")
            ax2.set_title(f"{label}, {t * 1e9:.0f} ns", fontsize=8)
            ax2.tick_params(labelsize=6)
            ax2.set_xlabel(("x" if axis == 1 else "y") + " (µm)", fontsize=7)
            ax2.set_ylabel("z (µm)", fontsize=7)
    fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=fig.axes, shrink=0.5,
                 extend="both", label="mean stress (Pa, tension +)")
    fig.suptitle("3-D Richtmyer-Meshkov: free surface a cos(kx x) cos(ky y), kx = 2 ky, hit by "
                 "2 GPa for 8 ns from below (examples/richtmyer_meshkov_3d.json)\ntop: the free "
                 "surface coloured by height (z stretched); below: sections coloured by mean stress")
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
