#!/usr/bin/python3
"""Reads a softshock result.xdmf with meshio's XDMF TimeSeriesReader, as a user would.

Usage: check_xdmf_meshio.py [--dimension D] RESULT.xdmf NODES ELEMENTS T0 T1 [T2 ...]

D is the mesh's dimension: 2 (default; triangles) or 3 (tetrahedra). Checks the mesh (NODES
points with D coordinates equal to /mesh/nodes, one cell block of ELEMENTS cells: "triangle" x 3
in 2-D, "tetra" x 4 in 3-D), that there is one frame per expected time and each frame's <Time>
equals it (relative 1e-12), that the point data "displacement" and "velocity" are NODES x 3 and
equal, bit for bit, the frame's HDF5 datasets (read with h5py; in 2-D their z is 0, format_version
2), and that the six cell scalars have one value per element. Exits 0 when all hold, 1 otherwise
(with the reasons on stderr).

Run with Debian's interpreter (/usr/bin/python3): python3-meshio and python3-h5py are apt
packages that a pyenv or venv Python does not see.
"""

import math
import os
import sys

import h5py
import meshio
import numpy as np

CELL_SCALARS = ("J", "mean_stress", "radial_stress", "hoop_stress", "von_mises", "aspect_ratio")
# meshio's name and nodes per element, by dimension.
CELLS = {2: ("triangle", 3), 3: ("tetra", 4)}


def check(path, dimension, nodes, elements, times):
    problems = []
    cell_type, corners = CELLS[dimension]
    h5_path = os.path.join(os.path.dirname(os.path.abspath(path)), "result.h5")
    with meshio.xdmf.TimeSeriesReader(path) as reader, h5py.File(h5_path, "r") as h5:
        points, cells = reader.read_points_cells()
        if points.shape != (nodes, dimension):
            problems.append(f"points have shape {points.shape}, expected ({nodes}, {dimension})")
        elif not np.array_equal(points, h5["mesh/nodes"][()]):
            problems.append("points differ from /mesh/nodes")
        if len(cells) != 1 or cells[0].type != cell_type:
            problems.append(f"cell blocks {[c.type for c in cells]}, expected one {cell_type!r}")
        elif cells[0].data.shape != (elements, corners):
            problems.append(f"{cell_type} cells have shape {cells[0].data.shape}, expected "
                            f"({elements}, {corners})")
        elif cells[0].data.min() < 0 or cells[0].data.max() >= nodes:
            problems.append(f"{cell_type} node indices out of range")

        frames = sorted(h5["fields"])
        if reader.num_steps != len(times):
            problems.append(f"{reader.num_steps} frames, expected {len(times)}")
        for k in range(min(reader.num_steps, len(times), len(frames))):
            t, point_data, cell_data = reader.read_data(k)
            if not math.isclose(t, times[k], rel_tol=1e-12, abs_tol=0.0):
                problems.append(f"frame {k}: time {t!r}, expected {times[k]!r}")
            for name in ("displacement", "velocity"):
                shape = point_data[name].shape if name in point_data else None
                if shape != (nodes, 3):
                    problems.append(f"frame {k}: point data {name} has shape {shape}")
                    continue
                stored = h5["fields"][frames[k]][name][()]
                # Bit for bit (-0.0 and NaN payloads included): meshio hands out what is stored.
                if stored.tobytes() != np.ascontiguousarray(point_data[name]).tobytes():
                    problems.append(f"frame {k}: point data {name} differs from HDF5 "
                                    f"{frames[k]}/{name}")
                if dimension == 2 and (point_data[name][:, 2] != 0).any():
                    problems.append(f"frame {k}: point data {name} has a non-zero z")
            for name in CELL_SCALARS:
                blocks = cell_data.get(name)
                if blocks is None or len(blocks) != 1 or blocks[0].shape != (elements,):
                    shapes = None if blocks is None else [b.shape for b in blocks]
                    problems.append(f"frame {k}: cell data {name} has shapes {shapes}")
    return problems


def main(argv):
    args = argv[1:]
    dimension = 2
    if args[:1] == ["--dimension"] and len(args) > 1:
        if args[1] not in ("2", "3"):
            print(f"check_xdmf_meshio: --dimension {args[1]}: expected 2 or 3", file=sys.stderr)
            return 2
        dimension, args = int(args[1]), args[2:]
    if len(args) < 5:
        print(__doc__, file=sys.stderr)
        return 2
    path, nodes, elements = args[0], int(args[1]), int(args[2])
    times = [float(t) for t in args[3:]]
    try:
        problems = check(path, dimension, nodes, elements, times)
    except Exception as e:  # a reader failure is a failed check, reported like the others
        problems = [f"meshio could not read {path}: {type(e).__name__}: {e}"]
    for p in problems:
        print(f"check_xdmf_meshio: {p}", file=sys.stderr)
    if not problems:
        print(f"check_xdmf_meshio: {path}: {nodes} nodes, {elements} {CELLS[dimension][0]} "
              f"cells, {len(times)} frames OK")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
