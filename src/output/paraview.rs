//! `view.py`: a ParaView Python script written beside a run's `series.pvd` that opens it the
//! way the results read: the body at true scale (a magnified warp would push contact nodes
//! through the rigid obstacle, which is not warped), coloured by von Mises stress and, in a
//! second view of contact scenes, by contact pressure (colour range over the whole period),
//! with the obstacle drawn, at the frame of the largest total contact force.

use std::path::Path;

use crate::{Error, Result};

/// The script, with `CONTACT = True/False` filled in.
const SCRIPT: &str = r#"# ParaView view of this run, written by hbcontact beside the results it opens.
#   GUI:      paraview --script=view.py                       (from this folder)
#   Headless: xvfb-run -a -s "-screen 0 1280x1024x24" pvbatch view.py picture.png
# (xvfb-run needs the 24-bit screen: its default aborts ParaView's OpenGL window.)
# The body is shown at true scale (displacement x 1): the motion is micrometres, and a
# magnified warp would push contact nodes through the rigid obstacle, which is not warped.
# Left: von Mises stress; right (contact scenes): contact pressure, its colour range over the
# whole period. It opens at the frame of the largest total contact force; press play to step
# through the period.
import csv
import os
import sys

from paraview.simple import (AssignViewToLayout, ColorBy, CreateLayout, CreateView,
                             GetAnimationScene, PVDReader, Render, ResetCamera,
                             SaveScreenshot, Show, WarpByVector)

CONTACT = {contact}
HERE = os.path.dirname(os.path.abspath(sys.argv[0])) if sys.argv and sys.argv[0] else os.getcwd()


def body_view(layout, array, association):
    view = CreateView("RenderView")
    AssignViewToLayout(view=view, layout=layout)
    series = PVDReader(FileName=os.path.join(HERE, "series.pvd"))
    warp = WarpByVector(Input=series)
    warp.Vectors = ["POINTS", "displacement"]
    warp.ScaleFactor = 1.0
    display = Show(warp, view)
    names = series.PointData.keys() if association == "POINTS" else series.CellData.keys()
    if array in names:
        ColorBy(display, (association, array))
        display.RescaleTransferFunctionToDataRangeOverTime()
        display.SetScalarBarVisibility(view, True)
    obstacle = os.path.join(HERE, "obstacle.pvd")
    if os.path.exists(obstacle):
        Show(PVDReader(FileName=obstacle), view)
    ResetCamera(view)
    return view


def time_of_largest_contact_force():
    path = os.path.join(HERE, "contact.csv")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rows = [(float(r["total_force"]), float(r["time"])) for r in csv.DictReader(f)]
    return max(rows)[1] if rows else None


layout = CreateLayout("hbcontact")
views = [body_view(layout, "von_mises", "CELLS")]
if CONTACT:
    views.append(body_view(layout, "contact_pressure", "POINTS"))
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
moment = time_of_largest_contact_force()
if moment is not None:
    scene.AnimationTime = moment
for view in views:
    Render(view)
if len(sys.argv) > 1:
    SaveScreenshot(sys.argv[1], layout, ImageResolution=[600 * len(views), 500])
"#;

/// Write `dir/view.py` for a series with (`contact`) or without contact arrays.
pub fn write_view_script(dir: &Path, contact: bool) -> Result<()> {
    let flag = if contact { "True" } else { "False" };
    let path = dir.join("view.py");
    std::fs::write(&path, SCRIPT.replace("{contact}", flag)).map_err(|e| Error::io(&path, e))
}
