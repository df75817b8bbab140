"""Opens a softshock result.xdmf in ParaView as a user would, and renders every time step.

Run with pvbatch (scripts/test-paraview does, under xvfb-run):
    pvbatch render_result.py RESULT.xdmf OUT_DIR

Uses the reader ParaView picks by itself for .xdmf, applies Warp By Vector on `displacement`
(scale 1), colours by the cell array `mean_stress`, steps through every time and writes
OUT_DIR/step_KKK.png. 2-D results (Triangle topology) are viewed in 2-D, 3-D results
(Tetrahedron topology) from an oblique 3-D camera. Checks on the way: the default reader is an
Xdmf3 reader, it gives as many points and cells as the XDMF file declares and every cell is a
VTK triangle (2-D) or tetrahedron (3-D), `displacement` has 3 components, Warp By Vector
preselects it, and at the last step the warped points equal reference + displacement. Exits 1
with the reason on a failed check.
"""
import os
import sys
import xml.etree.ElementTree as ET

from paraview import servermanager
from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, OpenDataFile,
                             Render, SaveScreenshot, Show, WarpByVector)
from vtkmodules.numpy_interface import dataset_adapter as dsa


def fail(message):
    print(f"render_result: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def first_block(data):
    """The unstructured grid of a fetched output (a multiblock when the reader makes one)."""
    while data is not None and data.IsA("vtkMultiBlockDataSet"):
        data = data.GetBlock(0)
    return data


# VTK cell type (vtkCellType.h) of each XDMF topology softshock writes.
VTK_CELL = {"Triangle": 5, "Tetrahedron": 10}


def declared_mesh(xdmf):
    """(topology type, elements, nodes) of the first grid, as the XDMF file declares them."""
    root = ET.parse(xdmf).getroot()
    topo, geom = root.find(".//Topology"), root.find(".//Geometry/DataItem")
    if topo is None or geom is None:
        fail(f"{xdmf} has no Topology or Geometry")
    return (topo.get("TopologyType"), int(topo.get("NumberOfElements")),
            int(geom.get("Dimensions").split()[0]))


def main(xdmf, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    topology, elements, nodes = declared_mesh(xdmf)
    if topology not in VTK_CELL:
        fail(f"unexpected TopologyType {topology!r}")
    three_d = topology == "Tetrahedron"
    print(f"render_result: {topology} mesh, {elements} cells, {nodes} points")
    reader = OpenDataFile(xdmf)
    reader_name = reader.GetXMLName()
    print(f"render_result: default reader {reader_name}")
    if not reader_name.startswith("Xdmf3Reader"):
        fail(f"expected an Xdmf3 reader by default, ParaView chose {reader_name}")
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    if len(times) < 2:
        fail(f"expected several time steps, got {times}")
    reader.UpdatePipeline(times[0])  # array information exists only once data were read
    info = reader.PointData.GetArray("displacement")
    if info is None or info.GetNumberOfComponents() != 3:
        fail("displacement is missing or not a 3-component point array")
    grid = first_block(servermanager.Fetch(reader))
    if grid is None or grid.GetNumberOfPoints() != nodes or grid.GetNumberOfCells() != elements:
        fail(f"the reader gave {grid and grid.GetNumberOfPoints()} points and "
             f"{grid and grid.GetNumberOfCells()} cells, the file declares {nodes} and {elements}")
    cell_types = {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())}
    if cell_types != {VTK_CELL[topology]}:
        fail(f"VTK cell types {sorted(cell_types)}, expected {{{VTK_CELL[topology]}}} ({topology})")

    warp = WarpByVector(Input=reader)
    if list(warp.Vectors) != ["POINTS", "displacement"]:
        fail(f"Warp By Vector preselected {list(warp.Vectors)}, not displacement")
    warp.ScaleFactor = 1.0

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [800, 800]
    display = Show(warp, view)
    ColorBy(display, ("CELLS", "mean_stress"))
    display.SetScalarBarVisibility(view, True)
    if three_d:
        # Oblique, z up, so the sides and the top of the body are in view.
        x0, x1, y0, y1, z0, z1 = reader.GetDataInformation().GetBounds()
        centre = [(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2]
        size = max(x1 - x0, y1 - y0, z1 - z0)
        view.InteractionMode = "3D"
        view.CameraFocalPoint = centre
        view.CameraPosition = [centre[0] + 1.6 * size, centre[1] - 2.2 * size,
                               centre[2] + 1.4 * size]
        view.CameraViewUp = [0, 0, 1]
    else:
        view.InteractionMode = "2D"
    view.ResetCamera()
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    for k, t in enumerate(times):
        scene.AnimationTime = t
        display.RescaleTransferFunctionToDataRange(False, True)
        Render(view)
        SaveScreenshot(os.path.join(out_dir, f"step_{k:03d}.png"), view,
                       ImageResolution=[800, 800])
    print(f"render_result: {len(times)} steps, t = {times[0]:g} .. {times[-1]:g} s, "
          f"PNGs in {out_dir}")

    # The warped geometry at the last step is the deformed body: reference + displacement.
    warp.UpdatePipeline(times[-1])
    reader.UpdatePipeline(times[-1])
    warped = dsa.WrapDataObject(first_block(servermanager.Fetch(warp)))
    ref = dsa.WrapDataObject(first_block(servermanager.Fetch(reader)))
    u = ref.PointData["displacement"]
    error = abs(warped.Points - (ref.Points + u)).max()
    scale = abs(u).max()
    print(f"render_result: max |warped - (reference + u)| = {error:.3g} m, max |u| = {scale:.3g} m")
    if not scale > 0:
        fail("the last step has no displacement")
    if error > 1e-12 * max(1.0, abs(ref.Points).max()):
        fail("warped points differ from reference + displacement")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1], sys.argv[2])
