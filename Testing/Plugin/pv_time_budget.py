"""Refinement by time (issue 27, item 2), through paraview.simple: with one frame per render (the
GUI's refinement) a render adds the frames that fit in *Refinement Time Budget*, the first always;
budget 0 adds exactly one; scripts that ask for N frames per render get exactly N whatever the
budget (as before the budget existed). The budget here (2 s) is far above one frame of the small
view, so the test asserts frame counts, never times. Exit status 0 = pass.

  pvpython pv_time_budget.py --model M.inr --out DIR [--plugin InrVolume.so]
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

reader = simple.OpenDataFile(args.model)
view = C.setup_view([64, 48])
display = C.show_inr(reader, view, seed=3, maximum_frames=2048, frames_per_render=1, macrocells=8)
check(display.InrRefinementTimeBudget == 50, "the default budget is 50 ms")
display.InrReproject = 0  # a camera move restarts the image (instead of reprojecting it)


# The read-backs of the last render live on the INR Volume sub-proxy (not exposed on the display).
inr = display.SMProxy.GetProperty("InrConverged").GetParent()


def last_render_ms():
    prop = inr.GetProperty("InrLastRenderTime")
    inr.UpdatePropertyInformation(prop)
    return prop.GetElement(0)


def frames():
    return int(C.info(display, "InrAccumulatedFrames"))


def render_adds():
    before = frames()
    simple.Render(view)
    return frames() - before


simple.Render(view)  # builds the engine (macrocells) outside the measured renders
display.InrRefinementTimeBudget = 300.0
added = render_adds()
print(f"budget 300 ms, one frame per render: one render added {added} frames "
      f"(its render took {last_render_ms():.0f} ms)")
check(added > 1, f"with a time budget one render accumulates more than one frame ({added})")

display.InrRefinementTimeBudget = 0.0
view.CameraPosition = [p * 1.01 for p in view.CameraPosition]  # restarts the accumulation
simple.Render(view)
check(frames() == 1, f"budget 0: the first render after a restart holds one frame ({frames()})")
added = [render_adds() for _ in range(3)]
check(added == [1, 1, 1], f"budget 0: one frame per render, as before the budget ({added})")

# A script asking for N-frame images: exactly N per render whatever the budget.
display.InrRefinementTimeBudget = 300.0
display.InrFramesPerRender = 16
display.InrMaximumFrames = 16
view.CameraPosition = [p * 1.01 for p in view.CameraPosition]  # restarts the accumulation
simple.Render(view)
check(frames() == 16, f"FramesPerRender 16, MaximumFrames 16: a 16-frame image ({frames()})")
display.InrMaximumFrames = 2048
view.CameraPosition = [p * 1.01 for p in view.CameraPosition]
simple.Render(view)
check(frames() == 16,
      f"FramesPerRender 16 with the budget on and MaximumFrames 2048: still exactly 16 ({frames()})")
status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
