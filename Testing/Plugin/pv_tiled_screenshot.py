"""SaveScreenshot larger than the view (ParaView renders it in tiles: tile scale and tile viewport)
against a screenshot of a view of that size. Exit status 0 = pass.

  pvpython pv_tiled_screenshot.py --model M.inr --out OUTDIR [--frames 16]
      [--view 160 120] [--scale 2] [--min-psnr 40]

The PSNR is taken over the pixels the volume covers (either image differs from the background),
not the whole picture. INR_VOLUME_DEBUG=1 is set so the log shows each render's size (the tiled
screenshot renders four tiles at the view's size, the direct one renders at the full size).
"""
import os
import sys

os.environ["INR_VOLUME_DEBUG"] = "1"
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--frames", type=int, default=16)
ap.add_argument("--view", type=int, nargs=2, default=[160, 120])
ap.add_argument("--scale", type=int, default=2)
ap.add_argument("--min-psnr", type=float, default=40.0)
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

check = C.Checks()
full = [args.view[0] * args.scale, args.view[1] * args.scale]

reader = simple.OpenDataFile(args.model)
view = C.setup_view(args.view)
display = C.show_inr(reader, view, seed=7, maximum_frames=args.frames, frames_per_render=args.frames, macrocells=16)
simple.GetAnimationScene().AnimationTime = 2.5
simple.Render(view)

tiled_png = os.path.join(args.out, "pv_tiled_screenshot.png")
direct_png = os.path.join(args.out, "pv_direct_screenshot.png")
print(f"SaveScreenshot {full[0]}x{full[1]} of a {args.view[0]}x{args.view[1]} view", flush=True)
sys.stderr.flush()
simple.SaveScreenshot(tiled_png, view, ImageResolution=full)
sys.stderr.flush()
view.ViewSize = full
simple.Render(view)
print(f"SaveScreenshot {full[0]}x{full[1]} of a {full[0]}x{full[1]} view", flush=True)
simple.SaveScreenshot(direct_png, view, ImageResolution=full)

a, b = C.read_png(tiled_png), C.read_png(direct_png)
check(a.shape == b.shape == (full[1], full[0], 3), f"both screenshots are {full[0]}x{full[1]}: {a.shape}, {b.shape}")
if a.shape == b.shape:
    background = np.round(np.array(C.BACKGROUND) * 255.0)
    covered = (np.abs(a - background).max(axis=2) > 1) | (np.abs(b - background).max(axis=2) > 1)
    n = int(covered.sum())
    mse = float(np.mean((a[covered] - b[covered]) ** 2)) if n else 0.0
    p = 999.0 if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)
    identical = int((np.abs(a - b).max(axis=2) == 0).sum())
    print(f"tiled vs direct: PSNR {p:.2f} dB over {n} covered pixels; {identical} of "
          f"{a.shape[0] * a.shape[1]} pixels identical", flush=True)
    check(n > a.shape[0] * a.shape[1] // 20, "the volume is in view")
    check(p >= args.min_psnr, f"tiled screenshot equals the direct one (PSNR {p:.2f} >= {args.min_psnr})")
status = check.report()
sys.stdout.flush()
if status:  # success: let the script end (sys.exit with live views exits 1 under Xvfb)
    sys.exit(status)
