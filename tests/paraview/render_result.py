"""Opens a softshock result.xdmf in ParaView as a user would, and renders every time step.

Run with pvbatch (scripts/test-paraview does, under xvfb-run):
    pvbatch render_result.py RESULT.xdmf OUT_DIR

Uses the reader ParaView picks by itself for .xdmf, applies Warp By Vector on `displacement`
(scale 1), colours by the cell array `mean_stress`, steps through every time and writes
OUT_DIR/step_KKK.png. Checks on the way: the default reader is an Xdmf3 reader, `displacement`
has 3 components, Warp By Vector preselects it, and at the last step the warped points equal
reference + displacement. Exits 1 with the reason on a failed check.
"""
import os
import sys

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


def main(xdmf, out_dir):
    os.makedirs(out_dir, exist_ok=True)
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

    warp = WarpByVector(Input=reader)
    if list(warp.Vectors) != ["POINTS", "displacement"]:
        fail(f"Warp By Vector preselected {list(warp.Vectors)}, not displacement")
    warp.ScaleFactor = 1.0

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [800, 800]
    display = Show(warp, view)
    ColorBy(display, ("CELLS", "mean_stress"))
    display.SetScalarBarVisibility(view, True)
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
