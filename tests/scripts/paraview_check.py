"""pvbatch script: open a .pvd, check its time steps and a point array, warp by it, save a PNG.
With OBSTACLE.pvd, also open the obstacle (one time-independent step of line cells) and show
it in the same view.

usage: pvbatch paraview_check.py SERIES.pvd OUT.png ARRAY EXPECTED_STEPS [OBSTACLE.pvd]
(warp scale: PARAVIEW_CHECK_SCALE, default 100)
"""
import os
import sys

from paraview.simple import (GetAnimationScene, GetActiveViewOrCreate, PVDReader, Render,
                             SaveScreenshot, Show, UpdatePipeline, WarpByVector, ColorBy)

pvd, png, array, steps = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
reader = PVDReader(FileName=pvd)
UpdatePipeline()
times = list(reader.TimestepValues)
if len(times) != steps:
    print(f"paraview_check: FAIL: {len(times)} time steps, expected {steps}")
    sys.exit(1)
names = reader.PointData.keys()
if array not in names:
    print(f"paraview_check: FAIL: point array {array} missing; have {names}")
    sys.exit(1)
warp = WarpByVector(Input=reader)
warp.Vectors = ["POINTS", array]
# Results move by micrometres (×100 shows them); mode shapes are scaled to 1 and want a
# fraction of the body's size: PARAVIEW_CHECK_SCALE overrides.
warp.ScaleFactor = float(os.environ.get("PARAVIEW_CHECK_SCALE", "100.0"))
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [800, 600]
display = Show(warp, view)
ColorBy(display, ("POINTS", array, "Magnitude"))
obstacle_cells = None
if len(sys.argv) > 5:
    obstacle = PVDReader(FileName=sys.argv[5])
    UpdatePipeline(proxy=obstacle)
    info = obstacle.GetDataInformation()
    obstacle_cells = info.GetNumberOfCells()
    if obstacle_cells < 1 or info.GetNumberOfPoints() < 2:
        print(f"paraview_check: FAIL: obstacle has {obstacle_cells} cells")
        sys.exit(1)
    Show(obstacle, view)
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.AnimationTime = times[len(times) // 4]
view.ResetCamera()
Render(view)
SaveScreenshot(png, view, ImageResolution=[800, 600])
if not os.path.exists(png) or os.path.getsize(png) < 10000:
    print("paraview_check: FAIL: no screenshot")
    sys.exit(1)
print(f"paraview_check: OK: {len(times)} steps, arrays {names}, obstacle cells {obstacle_cells}, screenshot {png}")
