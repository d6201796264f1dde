"""A translucent surface with an INR Volume under ParaView's defaults (depth peeling, and depth
peeling for volumes, on). VTK would render volumes inside its depth peels, which only the GPU
ray-cast mapper supports (the INR image blended into the peels came out as garbage); the INR
Volume representation sets that renderer flag aside while it is visible, so the picture equals
the one with "Depth Peeling for Volumes" off: the volume composited over the translucent surface,
opaque geometry depth-composited. Exit status 0 = pass.

  pvpython pv_translucent.py --model M.inr --out OUTDIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--min-psnr", type=float, default=40.0)
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

check = C.Checks()
size = [200, 160]
reader = simple.OpenDataFile(args.model)
view = C.setup_view(size)
check(view.DepthPeeling == 1 and view.DepthPeelingForVolumes == 1,
      "ParaView's defaults: depth peeling, also for volumes")
display = C.show_inr(reader, view, seed=7, maximum_frames=16, frames_per_render=16, macrocells=16)
simple.GetAnimationScene().AnimationTime = 2.5
sphere = simple.Sphere(Center=[1.6, -1.2, 0.9], Radius=0.5, ThetaResolution=48, PhiResolution=48)
surface = simple.Show(sphere, view)
surface.Opacity = 0.5
surface.DiffuseColor = [1.0, 1.0, 0.0]


def shot(name):
    simple.Render(view)
    path = os.path.join(args.out, name + ".png")
    simple.SaveScreenshot(path, view, ImageResolution=size)
    return C.read_png(path)


peeled = shot("pv_translucent_peeling")
renderer = view.GetClientSideObject().GetRenderer()
check(not renderer.GetUseDepthPeelingForVolumes(),
      "the renderer's depth peeling for volumes is set aside while the INR Volume is visible")
view.DepthPeelingForVolumes = 0  # what the representation sets aside: volumes after the peels
plain = shot("pv_translucent_volumes_not_peeled")
background = np.round(np.array(C.BACKGROUND) * 255.0)
covered = (np.abs(peeled - background).max(axis=2) > 1) | (np.abs(plain - background).max(axis=2) > 1)
mse = float(np.mean((peeled[covered] - plain[covered]) ** 2)) if covered.any() else 0.0
p = 999.0 if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)
print(f"depth peeling for volumes on vs off: PSNR {p:.2f} dB over {int(covered.sum())} covered pixels", flush=True)
check(covered.sum() > peeled.shape[0] * peeled.shape[1] // 20, "volume and surface in view")
check(p >= args.min_psnr, f"depth peeling for volumes on gives the picture with it off (PSNR {p:.2f} >= {args.min_psnr})")

view.DepthPeelingForVolumes = 1
simple.Hide(reader, view)
simple.Render(view)
check(renderer.GetUseDepthPeelingForVolumes(), "hiding the INR Volume gives the flag back")

status = check.report()
sys.stdout.flush()
if status:  # success: let the script end (sys.exit with live views exits 1 under Xvfb)
    sys.exit(status)
