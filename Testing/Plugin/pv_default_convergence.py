"""Does the plugin's DEFAULT stop rule give a clean image? (issue 11, item 6)

A real model opened the way a GUI user gets it (File > Open, Apply: shown as "INR Volume",
coloured by "value" with ParaView's default colour map and opacity ramp, the animation at the
data's first time, the camera reset; every INR Volume property at its default, so the default
Convergence Target and Maximum Frames decide when to stop) is rendered by calling Render() until
the representation reports InrConverged == 1. The model's suggested *.tf.json is NOT applied (a
user has to import it; the other plugin tests do not either). A reference of the same view with
another seed, no convergence target and 128 frames is rendered next, then the background alone.
The converged image must be >= 40 dB PSNR against the reference over the pixels the volume covers
(either image differs from the background-only image), the default run must have taken at least
the minimum frames of inr::RefinementOptions and fewer than 128. The reference's own estimated
error must be at least 20 dB below the bound's, so that the measurement is the default run's error
(128 frames, not more: RESULTS-archive, "A shorter reference for the default-convergence test").
Exit status 0 = pass.

Images are 8-bit screenshots (SaveScreenshot at the view's own size, so the accumulation is not
restarted; ParaView 5.11's view proxies have no float capture and the mapper exposes no float
image): rounding both images adds about 1/6 LSB^2 to the MSE (~56 dB on its own, ~0.1 dB off a
40 dB result). The reference carries its own noise as well (printed: its estimated PSNR and the
measurement with that noise removed); the assertion is on the raw measurement.

  pvpython pv_default_convergence.py --model M.inr --refinement-header Refinement.h --out DIR
      [--plugin InrVolume.so] [--size 200 150] [--tf MODEL.tf.json] [--black-background]

--tf and --black-background are for diagnostics (ctest runs neither): the renderer's estimate is
of the premultiplied image, i.e. over black, so over the default background the measured PSNR is
higher than the estimate; a sparser colour map may need more than the default Maximum Frames.
"""
import argparse
import os
import re
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--model", required=True)
ap.add_argument("--refinement-header", required=True,
                help="Kernels/Backends/Refinement.h (the default minimum frames is read from it)")
ap.add_argument("--out", required=True)
ap.add_argument("--plugin", default="")
ap.add_argument("--size", type=int, nargs=2, default=[200, 150])
ap.add_argument("--tf", default="", help="diagnostics: apply this ParaView colour-map preset "
                "(e.g. the model's suggested MODEL.tf.json) instead of the default colour map")
ap.add_argument("--black-background", action="store_true",
                help="diagnostics: black background instead of the default palette's")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

MIN_PSNR = 40.0
REFERENCE_FRAMES = 128
REFERENCE_MARGIN_DB = 20.0  # the reference's estimate at least this far above MIN_PSNR
REFERENCE_SEED = 977

C.load_plugin(args.plugin, remote=False)
check = C.Checks()


with open(args.refinement_header) as f:
    m = re.search(r"\bint\s+minimumFrames\s*=\s*(\d+)\s*;", f.read())
if not m:
    sys.exit(f"{args.refinement_header}: no 'int minimumFrames = N;' in RefinementOptions")
min_frames = int(m.group(1))

t_start = time.time()
size = list(args.size)
reader = simple.OpenDataFile(args.model)
check(reader is not None and reader.GetXMLName() == "InrVolumeReader",
      "OpenDataFile picks the INR Volume reader")
view = simple.GetActiveViewOrCreate("RenderView")
view.ViewSize = size
view.OrientationAxesVisibility = 0  # keep the axes out of the pixels compared
display = simple.Show(reader, view)
check(display.Representation == "INR Volume", "shown as 'INR Volume' by default")
# What the GUI's Apply does beyond Show(): colour by the point array (default colour map and
# opacity ramp, rescaled to the data), snap the animation to the data's time, reset the camera.
simple.ColorBy(display, ("POINTS", "value"))
display.RescaleTransferFunctionToDataRange(True, False)
display.SetScalarBarVisibility(view, False)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
simple.ResetCamera(view)
if args.tf:
    import json
    with open(args.tf) as f:
        preset = json.load(f)
    preset = preset[0] if isinstance(preset, list) else preset
    simple.GetColorTransferFunction("value").RGBPoints = preset["RGBPoints"]
    simple.GetOpacityTransferFunction("value").Points = preset["Points"]
if args.black_background:
    view.UseColorPaletteForBackground = 0
    view.Background = [0, 0, 0]
lut = simple.GetColorTransferFunction("value")
print(f"scene: time {view.ViewTime:g}, colour range [{lut.RGBPoints[0]:g}, {lut.RGBPoints[-4]:g}], "
      f"opacity points {list(simple.GetOpacityTransferFunction('value').Points)}", flush=True)

defaults = {p: display.GetPropertyValue(p) for p in
            ("InrConvergenceTarget", "InrMaximumFrames", "InrFramesPerRender", "InrSeed",
             "InrRayBudget", "InrPruneEpsilon", "InrReproject")}
print("defaults:", defaults, f"minimumFrames {min_frames}", flush=True)


def render_until_converged(limit):
    renders = 0
    while renders < limit:
        simple.Render(view)
        renders += 1
        if C.info(display, "InrConverged") == 1:
            break
    return renders


# The default run.
t0 = time.time()
renders = render_until_converged(2 * REFERENCE_FRAMES)
t_default = time.time() - t0
frames = C.info(display, "InrAccumulatedFrames")
estimate = C.info(display, "InrConvergenceEstimate")
converged = C.info(display, "InrConverged")
print(f"default: {frames} frames in {renders} renders, {t_default:.2f} s, estimate {estimate:.2f} dB, "
      f"backend {C.info(display, 'InrBackendInUse')}", flush=True)
check(converged == 1, "the default run converged (InrConverged == 1)")
test_png = os.path.join(args.out, "default_convergence_test.png")
simple.SaveScreenshot(test_png, view, ImageResolution=size)
check(C.info(display, "InrAccumulatedFrames") == frames,
      "the screenshot shows the converged image (no frames added or restarted)")
if frames >= defaults["InrMaximumFrames"]:
    print(f"note: stopped at Maximum Frames ({frames}), not at the convergence target", flush=True)

# The reference: another seed, no target, REFERENCE_FRAMES frames.
t0 = time.time()
display.InrSeed = REFERENCE_SEED
display.InrConvergenceTarget = 0.0
display.InrMaximumFrames = REFERENCE_FRAMES
display.InrFramesPerRender = 1
# One frame per render for this check: with the default Refinement Time Budget a fast backend
# (seen on an H100) adds many frames in one render.
budget = display.InrRefinementTimeBudget
display.InrRefinementTimeBudget = 0
simple.Render(view)
check(C.info(display, "InrAccumulatedFrames") == 1, "the reference starts from scratch (new seed)")
display.InrRefinementTimeBudget = budget
display.InrFramesPerRender = REFERENCE_FRAMES
render_until_converged(REFERENCE_FRAMES)
ref_frames = C.info(display, "InrAccumulatedFrames")
ref_estimate = C.info(display, "InrConvergenceEstimate")
t_reference = time.time() - t0
check(ref_frames == REFERENCE_FRAMES and C.info(display, "InrConverged") == 1,
      f"reference converged after {ref_frames} frames (estimate {ref_estimate:.2f} dB, {t_reference:.2f} s)")
check(ref_estimate >= MIN_PSNR + REFERENCE_MARGIN_DB,
      f"the reference's own estimated error ({ref_estimate:.2f} dB) is at least {REFERENCE_MARGIN_DB:.0f} dB "
      f"below the bound's ({MIN_PSNR:.0f} dB)")
ref_png = os.path.join(args.out, "default_convergence_reference.png")
simple.SaveScreenshot(ref_png, view, ImageResolution=size)

# The background alone: which pixels the volume covers.
simple.Hide(reader, view)
bg_png = os.path.join(args.out, "default_convergence_background.png")
simple.SaveScreenshot(bg_png, view, ImageResolution=size)

img, ref, bg = C.read_png(test_png), C.read_png(ref_png), C.read_png(bg_png)
covered = (np.abs(ref - bg).max(axis=2) > 0) | (np.abs(img - bg).max(axis=2) > 0)
n_covered = int(covered.sum())
check(n_covered > 0.005 * covered.size, f"the volume covers {n_covered} pixels "
      f"({100.0 * n_covered / covered.size:.1f}% of {size[0]}x{size[1]})")
mse = float(np.mean((img[covered] - ref[covered]) ** 2)) / 255.0 ** 2 if n_covered else 0.0
psnr = 999.0 if mse == 0 else -10.0 * np.log10(mse)
ref_mse = 10.0 ** (-ref_estimate / 10.0)
without_ref = -10.0 * np.log10(mse - ref_mse) if mse > ref_mse else float("inf")
diff = np.abs(img - ref)[covered]
print(f"PSNR over the volume's pixels: {psnr:.2f} dB ({without_ref:.2f} dB without the reference's "
      f"estimated noise); max abs error {int(diff.max()) if n_covered else 0}/255", flush=True)

check(psnr >= MIN_PSNR, f"default stop rule: {psnr:.2f} dB >= {MIN_PSNR} dB over the volume")
check(frames >= min_frames, f"default run took {frames} >= {min_frames} frames (minimum frames)")
check(frames < REFERENCE_FRAMES, f"default run took {frames} < {REFERENCE_FRAMES} frames")

print(f"SUMMARY: frames {frames}, estimate {estimate:.2f} dB, PSNR {psnr:.2f} dB, "
      f"default run {t_default:.1f} s, reference {t_reference:.1f} s, total {time.time() - t_start:.1f} s",
      flush=True)
status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
