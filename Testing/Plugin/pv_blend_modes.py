"""Blend modes and cropping against ParaView's own Volume representation: the INR Volume image of
a model in one mode (Isosurface, Slice, or Composite with Use Cropping) against ParaView's Volume
of the reader's fine preview grid (the network evaluated on a RES^3 lattice, default 256^3) in
the same mode, with the same colour map, opacity, camera and the same ParaView property names
(BlendMode, IsosurfaceValues, SliceFunction, UseCropping, CroppingOrigin, CroppingScale) set
once on the display and shared by both representations. Prints the PSNR over the pixels either
image covers and fails below the bound; a control (another isovalue, a shifted plane, another
crop box: the INR image against ParaView's picture of the changed setting) must score clearly
lower, so the comparison can fail.
  pvpython pv_blend_modes.py --model M_small.inr --mode isosurface|slice|crop --out DIR"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--mode", choices=("isosurface", "slice", "crop"), required=True)
ap.add_argument("--resolution", type=int, default=256)
ap.add_argument("--size", type=int, default=192)
ap.add_argument("--frames", type=int, default=192, help="composite frames (crop)")
ap.add_argument("--min-psnr", type=float, default=38.0)
ap.add_argument("--iso-fraction", type=float, default=0.15,
                help="isosurface: the isovalue's place in the colour map's value range")
ap.add_argument("--control-margin", type=float, default=6.0,
                help="the control must score at least this many dB below the bound")
ap.add_argument("--shade", action="store_true",
                help="lit (Shade) under one headlight: the network's gradient against VTK's of the grid")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

C.load_plugin(args.plugin, remote=False)
name = os.path.basename(args.model)[:-len(".inr")]
tf = json.load(open(args.model[:-len(".inr")] + ".tf.json"))[0]
lo, hi = tf["ValueRange"]

size = [args.size, args.size]
reader = simple.OpenDataFile(args.model)
reader.PreviewResolution = args.resolution
reader.UpdatePipeline()
bounds = reader.GetDataInformation().GetBounds()
centre = [0.5 * (bounds[2 * a] + bounds[2 * a + 1]) for a in range(3)]
extent = [bounds[2 * a + 1] - bounds[2 * a] for a in range(3)]
diagonal = float(np.linalg.norm(extent))

view = C.setup_view(size)
display = simple.Show(reader, view)
display.Representation = "INR Volume"
# An oblique camera (for the slice: looking down on the plane, which faces +z).
view.CameraFocalPoint = centre
towards = [0.4, -0.3, 1.0] if args.mode == "slice" else [1.3, -1.1, 0.9]
view.CameraPosition = [centre[a] + towards[a] * diagonal for a in range(3)]
view.CameraViewUp = [0.0, 1.0, 0.0] if args.mode == "slice" else [0.0, 0.0, 1.0]
view.CameraViewAngle = 30.0
view.ResetCamera(False)  # the model's box fills the view; kept for ParaView's Volume below
simple.ColorBy(display, ("POINTS", "value"))
lut = simple.GetColorTransferFunction("value")
lut.AutomaticRescaleRangeMode = "Never"
lut.ColorSpace = tf.get("ColorSpace", "RGB")
lut.RGBPoints = tf["RGBPoints"]
pwf = simple.GetOpacityTransferFunction("value")
display.SetScalarBarVisibility(view, False)
if args.shade:
    view.UseLight = 0  # the light kit off; one headlight of intensity 1 (VTK's default lighting)
    light = simple.AddLight(view=view)
    light.Coords = "Headlight"
    light.Intensity = 1.0
    for prop, value in (("Shade", 1), ("Ambient", 0.2), ("Diffuse", 0.8), ("Specular", 0.0)):
        display.SetPropertyWithName(prop, value)
display.InrBackend = 1  # CPU
display.InrSeed = 5
display.InrConvergenceTarget = 0.0

if args.mode == "isosurface":
    # An opaque surface; the control is another isovalue.
    iso = lo + args.iso_fraction * (hi - lo)
    control_iso = lo + (args.iso_fraction + 0.1) * (hi - lo)
    pwf.Points = [lo, 1.0, 0.5, 0.0, hi, 1.0, 0.5, 0.0]
    display.BlendMode = "Isosurface"
    display.IsosurfaceValues = [iso]
    frames = 1
    what = f"isovalue {iso:.4g}"
elif args.mode == "slice":
    # An oblique plane through the centre, opaque (VTK's slice blend weights the colours by the
    # scalar opacity: 1 everywhere shows the colour map itself); the control is the plane
    # shifted by a tenth of the box's diagonal.
    pwf.Points = [lo, 1.0, 0.5, 0.0, hi, 1.0, 0.5, 0.0]
    display.BlendMode = "Slice"
    normal = [0.3, 0.4, 1.0]
    display.SliceFunction = "Plane"
    display.SliceFunction.Origin = centre
    display.SliceFunction.Normal = normal
    n = np.array(normal) / np.linalg.norm(normal)
    control_origin = list(np.array(centre) + 0.1 * diagonal * n)
    frames = 1
    what = f"plane through the centre, normal {normal}"
else:
    # Composite, cropped to a box of ParaView's CroppingOrigin / CroppingScale (planes
    # origin + bounds * scale); the control is the uncropped picture.
    pwf.Points = tf["Points"]
    display.ScalarOpacityUnitDistance = diagonal / 64.0
    display.InrEstimator = 1
    display.UseCropping = 1
    # The box keeps the upper 55% of x and the lower 70% of z: it cuts the model open.
    scale = [0.55, 1.0, 0.7]
    origin = [bounds[1] * (1.0 - scale[0]), 0.0, bounds[4] * (1.0 - scale[2])]
    display.CroppingOrigin = origin
    display.CroppingScale = scale
    frames = args.frames
    what = f"crop origin {[round(v, 4) for v in origin]} scale {scale}"

display.InrMaximumFrames = frames
display.InrFramesPerRender = frames
out = os.path.join(args.out, f"blend_{args.mode}{'_shaded' if args.shade else ''}_{name}")
inr_png = out + "_inr.png"
simple.SaveScreenshot(inr_png, view, ImageResolution=size)
state = C.info(display, "InrRefinementState")
frames_done = C.info(display, "InrAccumulatedFrames")

display.SetRepresentationType("Volume")
vol_png = out + "_paraview_volume.png"
simple.SaveScreenshot(vol_png, view, ImageResolution=size)
# The control: ParaView's picture of a changed setting.
if args.mode == "isosurface":
    display.IsosurfaceValues = [control_iso]
    control = f"isovalue {control_iso:.4g}"
elif args.mode == "slice":
    display.SliceFunction.Origin = control_origin
    control = "plane shifted by a tenth of the diagonal"
else:
    display.UseCropping = 0
    control = "uncropped"
control_png = out + "_paraview_volume_control.png"
simple.SaveScreenshot(control_png, view, ImageResolution=size)

a, b, c = C.read_png(inr_png), C.read_png(vol_png), C.read_png(control_png)
p = C.psnr_over_volume(a, b)
pc = C.psnr_over_volume(a, c)
bg = np.array(C.BACKGROUND) * 255.0
covered = float(np.mean(np.any(np.abs(a - bg) > 8, axis=2)))
checks = C.Checks()
msg = (f"{args.mode}{' shaded' if args.shade else ''} {name} ({what}): INR Volume vs ParaView Volume ({args.resolution}^3 preview): "
       f"PSNR {p:.2f} dB over the covered pixels (bound >= {args.min_psnr}); control ({control}) "
       f"{pc:.2f} dB; volume covers {100 * covered:.0f}% of the image; INR state: {state}")
print(msg, flush=True)
with open(out + ".txt", "w") as f:
    f.write(msg + "\n")
checks(covered > 0.03, f"the INR image shows the model ({100 * covered:.1f}% of the pixels)")
checks(p >= args.min_psnr, f"PSNR {p:.2f} dB >= {args.min_psnr}")
checks(pc < args.min_psnr - args.control_margin,
       f"control {pc:.2f} dB < {args.min_psnr - args.control_margin} (the comparison can fail)")
checks(frames_done == frames, f"INR image of {frames_done} frame(s), asked {frames}")
status = checks.report()
sys.stdout.flush()
if status:  # (an exit with live views ends in GLXBadContext, status 1: only on failure)
    sys.exit(status)
