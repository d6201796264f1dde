"""Consistency: the converged INR Volume image against ParaView's own Volume representation of
the same model resampled at 128^3 (the reader's preview grid), same colour map, opacity, unit
distance and camera. Prints the PSNR and fails below the bound.
  pvpython pv_consistency.py --model M.inr --plugin InrVolume.so --out DIR"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--frames", type=int, default=256)
ap.add_argument("--resolution", type=int, default=128)
ap.add_argument("--min-psnr", type=float, default=38.0)  # measured 44.5 dB here
args = ap.parse_args()

from paraview import simple  # noqa: E402
C.load_plugin(args.plugin, remote=False)
size = [160, 160]
reader = simple.OpenDataFile(args.model)
reader.PreviewResolution = args.resolution
view = C.setup_view(size)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
display = simple.Show(reader, view)
C.apply_colormap(display, view)
display.InrSeed = 3
display.InrConvergenceTarget = 0.0
display.InrMaximumFrames = args.frames
display.InrFramesPerRender = args.frames
scene.AnimationTime = 2.5
inr_png = os.path.join(args.out, "consistency_inr.png")
simple.SaveScreenshot(inr_png, view, ImageResolution=size)

display.SetRepresentationType("Volume")
C.apply_colormap(display, view)
vol_png = os.path.join(args.out, "consistency_paraview_volume.png")
simple.SaveScreenshot(vol_png, view, ImageResolution=size)

a, b = C.read_png(inr_png), C.read_png(vol_png)
p = C.psnr(a, b)
import numpy as np  # noqa: E402
bg = np.array(C.BACKGROUND) * 255.0
covered = np.mean(np.any(np.abs(a - bg) > 8, axis=2))
msg = (f"INR Volume ({args.frames} frames) vs ParaView Volume ({args.resolution}^3 resampled): "
       f"PSNR {p:.2f} dB (bound >= {args.min_psnr}); volume covers {100 * covered:.0f}% of the image")
print(msg, flush=True)
with open(os.path.join(args.out, "consistency.txt"), "w") as f:
    f.write(msg + "\n")
ok = p >= args.min_psnr and covered > 0.05
print("RESULT:", "PASS" if ok else "FAIL", flush=True)
sys.stdout.flush()
if not ok:
    sys.exit(1)
