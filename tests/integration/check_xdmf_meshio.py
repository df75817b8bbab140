#!/usr/bin/python3
"""Reads a softshock result.xdmf with meshio's XDMF TimeSeriesReader, as a user would.

Usage: check_xdmf_meshio.py RESULT.xdmf NODES ELEMENTS T0 T1 [T2 ...]

Checks the mesh (NODES points, one triangle block of ELEMENTS cells), that there is one frame
per expected time and each frame's <Time> equals it (relative 1e-12), that the point data
"displacement" and "velocity" are NODES x 3 with z = 0 (format_version 2) and that the five
cell scalars have one value per triangle. Exits 0 when all hold, 1 otherwise (with the reasons on stderr).

Run with Debian's interpreter (/usr/bin/python3): python3-meshio and python3-h5py are apt
packages that a pyenv or venv Python does not see.
"""

import math
import sys

import meshio

CELL_SCALARS = ("J", "mean_stress", "radial_stress", "hoop_stress", "von_mises", "aspect_ratio")


def check(path, nodes, elements, times):
    problems = []
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        if points.shape != (nodes, 2):
            problems.append(f"points have shape {points.shape}, expected ({nodes}, 2)")
        if len(cells) != 1 or cells[0].type != "triangle":
            problems.append(f"cell blocks {[c.type for c in cells]}, expected one 'triangle'")
        elif cells[0].data.shape != (elements, 3):
            problems.append(f"triangles have shape {cells[0].data.shape}, expected ({elements}, 3)")
        elif cells[0].data.min() < 0 or cells[0].data.max() >= nodes:
            problems.append("triangle node indices out of range")

        if reader.num_steps != len(times):
            problems.append(f"{reader.num_steps} frames, expected {len(times)}")
        for k in range(min(reader.num_steps, len(times))):
            t, point_data, cell_data = reader.read_data(k)
            if not math.isclose(t, times[k], rel_tol=1e-12, abs_tol=0.0):
                problems.append(f"frame {k}: time {t!r}, expected {times[k]!r}")
            for name in ("displacement", "velocity"):
                shape = point_data[name].shape if name in point_data else None
                if shape != (nodes, 3):
                    problems.append(f"frame {k}: point data {name} has shape {shape}")
                elif (point_data[name][:, 2] != 0).any():
                    problems.append(f"frame {k}: point data {name} has a non-zero z")
            for name in CELL_SCALARS:
                blocks = cell_data.get(name)
                if blocks is None or len(blocks) != 1 or blocks[0].shape != (elements,):
                    shapes = None if blocks is None else [b.shape for b in blocks]
                    problems.append(f"frame {k}: cell data {name} has shapes {shapes}")
    return problems


def main(argv):
    if len(argv) < 6:
        print(__doc__, file=sys.stderr)
        return 2
    path, nodes, elements = argv[1], int(argv[2]), int(argv[3])
    times = [float(t) for t in argv[4:]]
    try:
        problems = check(path, nodes, elements, times)
    except Exception as e:  # a reader failure is a failed check, reported like the others
        problems = [f"meshio could not read {path}: {type(e).__name__}: {e}"]
    for p in problems:
        print(f"check_xdmf_meshio: {p}", file=sys.stderr)
    if not problems:
        print(f"check_xdmf_meshio: {path}: {nodes} nodes, {elements} triangles, "
              f"{len(times)} frames OK")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
