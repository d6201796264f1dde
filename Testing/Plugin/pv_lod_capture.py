"""Interactive level of detail versus captures, through paraview.simple: with the default
*Interactive Level Of Detail* (camera interaction and time changes) and one frame per render, a
render after a time change (moving the animation time renders the view) draws a reduced frame,
the next render without a time change is full size, and SaveScreenshot as the first render after a
time change renders the full-size still image (captures are never reduced). Exit status 0 = pass.

  pvpython pv_lod_capture.py --model M.inr --out DIR [--plugin InrVolume.so]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
args = ap.parse_args()

from paraview import simple  # noqa: E402

C.load_plugin(args.plugin, remote=False)
check = C.Checks()
os.makedirs(args.out, exist_ok=True)

SIZE = [320, 240]
reader = simple.OpenDataFile(args.model)
view = C.setup_view(SIZE)
display = simple.Show(reader, view)
display.Representation = "INR Volume"
C.apply_colormap(display, view)
display.InrFramesPerRender = 1
display.InrMacrocellResolution = 8
# A budget no frame can meet, so a reduced frame is chosen whenever the render counts as interactive.
display.InrInteractiveFrameTime = 10
# On the CPU: a GPU meets even that budget at full size (seen on an H100), and then rightly draws
# the time change as a full-size still frame; the capture rules under test are the same.
display.InrBackend = 1
check(display.SMProxy.GetProperty("InrInteractiveLevelOfDetail").GetElement(0) == 2, "default level of detail: camera and time changes")
trange = list(reader.GetProperty("TimeRange"))
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
times = [trange[0] + f * (trange[1] - trange[0]) for f in (0.0, 0.3, 0.6)]


# The read-backs of the last render are never shown, so not exposed on the display: they live on
# the INR Volume sub-proxy.
inr = display.SMProxy.GetProperty("InrConverged").GetParent()


def last():
    values = []
    for name in ("InrLastRenderInteractive", "InrLastImageWidth", "InrLastImageHeight"):
        prop = inr.GetProperty(name)
        inr.UpdatePropertyInformation(prop)
        values.append(int(prop.GetElement(0)))
    return tuple(values)


scene.AnimationTime = times[0]
simple.Render(view)
# Moving the animation time renders the view (as the time slider does in the GUI).
scene.AnimationTime = times[1]
interactive, w, h = last()
check(interactive == 1 and w < SIZE[0] and h < SIZE[1],
      f"the render after a time change is a reduced frame (interactive {interactive}, {w}x{h})")
simple.Render(view)
interactive, w, h = last()
check(interactive == 0 and [w, h] == SIZE,
      f"the next render without a time change is full size (interactive {interactive}, {w}x{h})")
# A new view time without a render, then a capture: the capture is the render that sees the
# time change, and it must be the full-size still image.
view.ViewTime = times[2]
png = os.path.join(args.out, "lod_capture.png")
simple.SaveScreenshot(png, view, ImageResolution=SIZE)
interactive, w, h = last()
check(interactive == 0 and [w, h] == SIZE,
      f"SaveScreenshot right after a time change renders the full-size still image (interactive {interactive}, {w}x{h})")
check(os.path.exists(png), "the screenshot was written")
status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
