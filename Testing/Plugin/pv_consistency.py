"""Consistency: the converged INR Volume image against ParaView's own Volume representation of
the same model resampled at 128^3 (the reader's preview grid), same colour map, opacity, unit
distance and camera. Prints the PSNR over the pixels either image covers (the background would
dilute it) and fails below the bound. With --shade both are shaded (Shade,
Ambient, Diffuse, Specular, SpecularPower of the representation), by default under ParaView's
headlight alone (the light kit off: VTK's default-lighting path, the light the engine's headlight
reproduces); with --lights kit under the view's default lights, ParaView's light kit (VTK's
light-list path, which the engine takes from the view's lights).
  pvpython pv_consistency.py --model M.inr --plugin InrVolume.so --out DIR [--shade [--lights kit]]"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--frames", type=int, default=256)
ap.add_argument("--resolution", type=int, default=128)
ap.add_argument("--min-psnr", type=float, default=38.0)  # the measured value is printed; Benchmarks/RESULTS.md has it
ap.add_argument("--shade", action="store_true")
ap.add_argument("--lights", choices=("headlight", "kit"), default="headlight")
args = ap.parse_args()
suffix = ("_shaded" + ("_kit" if args.lights == "kit" else "")) if args.shade else ""

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
if args.shade and args.lights == "headlight":
    view.UseLight = 0  # the light kit off; one headlight of intensity 1 instead
    light = simple.AddLight(view=view)
    light.Coords = "Headlight"
    light.Intensity = 1.0
elif args.shade:
    view.UseLight = 1  # the view's default: ParaView's light kit
if args.shade:
    for name, value in (("Shade", 1), ("Ambient", 0.2), ("Diffuse", 0.8), ("Specular", 0.2), ("SpecularPower", 10.0)):
        display.SetPropertyWithName(name, value)
display.InrSeed = 3
display.InrConvergenceTarget = 0.0
display.InrMaximumFrames = args.frames
display.InrFramesPerRender = args.frames
scene.AnimationTime = 2.5
inr_png = os.path.join(args.out, f"consistency{suffix}_inr.png")
simple.SaveScreenshot(inr_png, view, ImageResolution=size)

display.SetRepresentationType("Volume")
C.apply_colormap(display, view)
vol_png = os.path.join(args.out, f"consistency{suffix}_paraview_volume.png")
simple.SaveScreenshot(vol_png, view, ImageResolution=size)

a, b = C.read_png(inr_png), C.read_png(vol_png)
p = C.psnr_over_volume(a, b)
unshaded = None
if args.shade:  # the comparison can fail: shading must change ParaView's own picture clearly
    display.Shade = 0
    flat_png = os.path.join(args.out, f"consistency{suffix}_paraview_volume_unshaded.png")
    simple.SaveScreenshot(flat_png, view, ImageResolution=size)
    unshaded = C.psnr_over_volume(a, C.read_png(flat_png))
import numpy as np  # noqa: E402
bg = np.array(C.BACKGROUND) * 255.0
covered = np.mean(np.any(np.abs(a - bg) > 8, axis=2))
msg = (f"{('shaded (' + args.lights + ') ') if args.shade else ''}INR Volume ({args.frames} frames) vs ParaView Volume ({args.resolution}^3 resampled): "
       f"PSNR {p:.2f} dB over the volume's pixels (bound >= {args.min_psnr}); volume covers {100 * covered:.0f}% of the image"
       + (f"; against ParaView's unshaded Volume {unshaded:.2f} dB" if unshaded is not None else ""))
print(msg, flush=True)
with open(os.path.join(args.out, f"consistency{suffix}.txt"), "w") as f:
    f.write(msg + "\n")
ok = p >= args.min_psnr and covered > 0.05 and (unshaded is None or unshaded < args.min_psnr - 6.0)
print("RESULT:", "PASS" if ok else "FAIL", flush=True)
sys.stdout.flush()
if not ok:
    sys.exit(1)
