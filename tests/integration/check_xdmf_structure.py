#!/usr/bin/python3
"""Checks a softshock result.xdmf against what ParaView's default reader (Xdmf3ReaderS) needs.

Usage: check_xdmf_structure.py RESULT.xdmf

The mesh's dimension is result.h5's root attribute `dimension` (2 when absent: files written
before 3-D results). Holds when: the document is XDMF 3 with one Temporal collection (or, for a
run without frames, one Uniform "mesh" grid); every grid has, in 2-D, Triangle topology whose
NumberOfElements and Dimensions ("E 3") match /mesh/triangles and XY geometry from /mesh/nodes
("N 2"), in 3-D Tetrahedron topology matching /mesh/tetrahedra ("E 4") and XYZ geometry from
/mesh/nodes ("N 3"); every Vector attribute is node-centred with 3 components ("N 3", the
shape Warp By Vector accepts) and every Scalar attribute cell-centred ("E"); each DataItem's
Dimensions equal the shape of the HDF5 dataset it names; frame times increase and equal the
frames' HDF5 `time` attributes; displacement and velocity are present. Exits 0 when all hold,
1 otherwise (reasons on stderr).

Debian's interpreter (/usr/bin/python3): it needs python3-h5py.
"""

import os
import sys
import xml.etree.ElementTree as ET

import h5py

VECTORS = ("displacement", "velocity")
# By dimension: topology type, its dataset and nodes per element; geometry type and columns.
MESH = {2: ("Triangle", "/mesh/triangles", 3, "XY", 2),
        3: ("Tetrahedron", "/mesh/tetrahedra", 4, "XYZ", 3)}


def dims_of(item):
    return tuple(int(d) for d in item.get("Dimensions", "").split())


def check_item(item, h5, where, problems):
    """The DataItem is an HDF reference whose Dimensions equal the dataset's shape."""
    if item is None:
        problems.append(f"{where}: no DataItem")
        return None
    if item.get("Format") != "HDF":
        problems.append(f"{where}: DataItem Format {item.get('Format')!r}, expected 'HDF'")
        return None
    file_name, _, dataset = (item.text or "").strip().partition(":")
    if file_name != os.path.basename(h5.filename) or dataset not in h5:
        problems.append(f"{where}: {item.text!r} does not name a dataset of {h5.filename}")
        return None
    if dims_of(item) != h5[dataset].shape:
        problems.append(f"{where}: Dimensions {dims_of(item)} but {dataset} has shape "
                        f"{h5[dataset].shape}")
    return dataset


def check_grid(grid, h5, dimension, nodes, elements, problems):
    name = grid.get("Name")
    topology, connectivity, corners, geometry, columns = MESH[dimension]
    topo = grid.find("Topology")
    if topo is None or topo.get("TopologyType") != topology:
        problems.append(f"grid {name}: topology is not {topology}")
    else:
        if topo.get("NumberOfElements") != str(elements):
            problems.append(f"grid {name}: NumberOfElements {topo.get('NumberOfElements')}")
        dataset = check_item(topo.find("DataItem"), h5, f"grid {name} topology", problems)
        if dataset and dataset != connectivity:
            problems.append(f"grid {name}: topology from {dataset}, expected {connectivity}")
        elif dataset and dims_of(topo.find("DataItem")) != (elements, corners):
            problems.append(f"grid {name}: topology is not E x {corners}")
    geom = grid.find("Geometry")
    if geom is None or geom.get("GeometryType") != geometry:
        problems.append(f"grid {name}: geometry is not {geometry}")
    else:
        dataset = check_item(geom.find("DataItem"), h5, f"grid {name} geometry", problems)
        if dataset and dataset != "/mesh/nodes":
            problems.append(f"grid {name}: geometry from {dataset}, expected /mesh/nodes")
        elif dataset and dims_of(geom.find("DataItem")) != (nodes, columns):
            problems.append(f"grid {name}: geometry is not N x {columns}")
    seen = set()
    for attr in grid.findall("Attribute"):
        aname, kind, center = attr.get("Name"), attr.get("AttributeType"), attr.get("Center")
        seen.add(aname)
        item = attr.find("DataItem")
        check_item(item, h5, f"grid {name} attribute {aname}", problems)
        if kind == "Vector":
            if center != "Node" or item is None or dims_of(item) != (nodes, 3):
                problems.append(f"grid {name}: vector {aname} is not a node-centred N x 3 array "
                                f"(Center {center}, Dimensions {item is not None and dims_of(item)})")
        elif kind == "Scalar":
            if center != "Cell" or item is None or dims_of(item) != (elements,):
                problems.append(f"grid {name}: scalar {aname} is not cell-centred with E values")
        else:
            problems.append(f"grid {name}: attribute {aname} has AttributeType {kind!r}")
    return seen


def check(path):
    problems = []
    root = ET.parse(path).getroot()
    if root.tag != "Xdmf" or root.get("Version") != "3.0":
        return [f"root is <{root.tag} Version={root.get('Version')!r}>, expected Xdmf 3.0"]
    h5_path = os.path.join(os.path.dirname(os.path.abspath(path)), "result.h5")
    with h5py.File(h5_path, "r") as h5:
        dimension = int(h5.attrs.get("dimension", 2))
        if dimension not in MESH:
            return [f"result.h5 has dimension {dimension}, expected 2 or 3"]
        nodes = h5["mesh/nodes"].shape[0]
        elements = h5[MESH[dimension][1]].shape[0]
        top = root.findall("Domain/Grid")
        if len(top) != 1:
            return [f"{len(top)} top-level grids, expected 1"]
        frames = sorted(h5["fields"])
        if not frames:
            if top[0].get("GridType") != "Uniform":
                problems.append("a run without frames must be one Uniform grid")
            check_grid(top[0], h5, dimension, nodes, elements, problems)
            return problems
        if top[0].get("GridType") != "Collection" or top[0].get("CollectionType") != "Temporal":
            return ["the top-level grid is not a Temporal collection"]
        grids = top[0].findall("Grid")
        if [g.get("Name") for g in grids] != frames:
            problems.append(f"grids {[g.get('Name') for g in grids]} != HDF5 frames {frames}")
        times = []
        for grid in grids:
            time = grid.find("Time")
            times.append(float(time.get("Value")) if time is not None else float("nan"))
            group = h5["fields"].get(grid.get("Name"))
            if group is not None and times[-1] != group.attrs["time"]:
                problems.append(f"grid {grid.get('Name')}: Time {times[-1]!r} != HDF5 time "
                                f"{group.attrs['time']!r}")
            missing = set(VECTORS) - check_grid(grid, h5, dimension, nodes, elements, problems)
            if missing:
                problems.append(f"grid {grid.get('Name')}: no attribute {sorted(missing)}")
        if any(b <= a for a, b in zip(times, times[1:])):
            problems.append(f"frame times do not increase: {times}")
    return problems


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        problems = check(argv[1])
    except Exception as e:  # an unreadable file is a failed check, reported like the others
        problems = [f"cannot check {argv[1]}: {type(e).__name__}: {e}"]
    for p in problems:
        print(f"check_xdmf_structure: {p}", file=sys.stderr)
    if not problems:
        print(f"check_xdmf_structure: {argv[1]} OK")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
