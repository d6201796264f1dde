"""Gradient opacity through ParaView: the INR Volume's "Gradient Opacity" property (InrGradientOpacity,
(|grad f|, factor) pairs) reaches the engine through the volume property, changes the picture over
the volume (flat regions fade, so less of it shows), and clearing it gives back the picture without
it (same seed and frames; equal up to the noise of 128 frames: the ray budget adapts to the frames
rendered in between). Exit status 0 = pass.

  pvpython pv_gradient_opacity.py --model M.inr --out OUTDIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--factor-at", type=float, default=2.0,
                help="gradient magnitude where the factor reaches 1 (it is 0 at 0)")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

check = C.Checks()
size = [160, 160]
reader = simple.OpenDataFile(args.model)
view = C.setup_view(size)
display = C.show_inr(reader, view, seed=7, maximum_frames=128, frames_per_render=128, macrocells=16)


def shot(name):
    simple.Render(view)
    path = os.path.join(args.out, name + ".png")
    simple.SaveScreenshot(path, view, ImageResolution=size)
    return C.read_png(path)


check(list(display.InrGradientOpacity) == [], "off by default")
plain = shot("pv_gradient_opacity_off")
display.InrGradientOpacity = [0.0, 0.0, args.factor_at, 1.0]
faded = shot("pv_gradient_opacity_on")
display.InrGradientOpacity = []
again = shot("pv_gradient_opacity_cleared")

background = np.round(np.array(C.BACKGROUND) * 255.0)


def covered(img):
    return np.abs(img - background).max(axis=2) > 1


either = covered(plain) | covered(faded)
p = C.psnr_over_volume(faded, plain)
print(f"gradient opacity on vs off: PSNR {p:.2f} dB over the volume; covered pixels off "
      f"{int(covered(plain).sum())}, on {int(covered(faded).sum())}; mean brightness over the volume "
      f"off {plain[either].mean():.1f}, on {faded[either].mean():.1f}", flush=True)
check(covered(plain).sum() > size[0] * size[1] // 10, "the volume is in view")
check(p < 30.0, f"the gradient opacity changes the picture (PSNR {p:.2f} < 30 dB)")
check(np.abs(faded[either] - background).sum() < np.abs(plain[either] - background).sum(),
      "with flat regions faded, less of the volume shows over the background")
back = C.psnr_over_volume(again, plain)
print(f"cleared vs never set: PSNR {back:.2f} dB over the volume", flush=True)
check(back >= 30.0 and back >= p + 8.0,
      f"clearing it gives back the picture without it (PSNR {back:.2f} >= 30 dB and >= on vs off + 8 dB)")

status = check.report()
sys.stdout.flush()
if status:  # success: let the script end (sys.exit with live views exits 1 under Xvfb)
    sys.exit(status)
