"""2D transfer function (Use Transfer2D, the gradient magnitude as its second axis) against ParaView's
own Volume representation: the INR Volume image of a model with a 2D transfer function of two
boxes (ParaView's TransferFunction2D proxy: a faint blue box over the flat half of the gradient
magnitudes, an orange one over the steep half, both over the upper part of the value range) against
ParaView's Volume of the reader's fine preview grid (the network on a RES^3 lattice, default 256^3)
with the same 2D transfer function, camera and properties set once on the display. Prints the PSNR
over the pixels either image covers and fails below the bound; a control (ParaView's picture with
the two boxes' colours and opacities swapped between the gradient halves) must score clearly lower,
so the comparison can fail.

What VTK 9.2's GPU ray caster does with a 2D transfer function, and so what the test sets up to
compare like with like: it looks the image up with the value over the grid's value range (its
first and last pixels at the range's ends) and |grad f| times the grid's mean spacing over
[0, 0.25 x the value range] (central differences of the grid), and it applies the image's opacity
per sample step (no unit-distance correction), its step in a still render (vtkSmartVolumeMapper,
LockSampleDistanceToInputSpacing) half the grid's mean spacing. So the 2D transfer function's
Range is the grid's value range by [0, 0.25 x value range / mean spacing] (|grad f| per world
unit, as the engine reads it), and the Scalar Opacity Unit Distance, which the engine applies to
the 2D opacity as to the 1D one, is half the grid's mean spacing.
  pvpython pv_transfer2d.py --model M_small.inr --out DIR"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--resolution", type=int, default=256)
ap.add_argument("--size", type=int, default=192)
ap.add_argument("--frames", type=int, default=256)
ap.add_argument("--min-psnr", type=float, default=38.0)
ap.add_argument("--control-margin", type=float, default=6.0,
                help="the control must score at least this many dB below the bound")
ap.add_argument("--texture", type=int, default=256, help="the 2D transfer function's image size (square)")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import servermanager, simple  # noqa: E402
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402

C.load_plugin(args.plugin, remote=False)
name = os.path.basename(args.model)[:-len(".inr")]
size = [args.size, args.size]

# Where the gradient magnitudes lie: the median |grad f| (per world unit) over the upper part of
# the value range, from a coarse preview (central differences), splits the boxes.
probe = simple.OpenDataFile(args.model)
probe.PreviewResolution = 64
probe.UpdatePipeline()
coarse = servermanager.Fetch(probe)
dims = coarse.GetDimensions()
values = vtk_to_numpy(coarse.GetPointData().GetArray("value")).reshape(dims[2], dims[1], dims[0])
gz, gy, gx = np.gradient(values, *(coarse.GetSpacing()[::-1]))
magnitude = np.sqrt(gx * gx + gy * gy + gz * gz)
simple.Delete(probe)
del coarse

reader = simple.OpenDataFile(args.model)
reader.PreviewResolution = args.resolution
reader.UpdatePipeline()
info = reader.GetDataInformation()
bounds = info.GetBounds()
extent = info.GetExtent()
spacing = [(bounds[2 * a + 1] - bounds[2 * a]) / (extent[2 * a + 1] - extent[2 * a]) for a in range(3)]
lo, hi = reader.PointData["value"].GetRange()
g_top = 0.25 * (hi - lo) / float(np.mean(spacing))  # the gradient axis VTK's mapper uses
x0 = lo + 0.4 * (hi - lo)
upper = values >= x0
g_split = float(np.median(magnitude[upper])) if upper.any() else 0.5 * g_top
g_high = min(float(np.percentile(magnitude[upper], 99.5)) if upper.any() else g_top, g_top)
print(f"{name}: values [{lo:.4g}, {hi:.4g}], spacing {[round(s, 5) for s in spacing]}, gradient axis "
      f"[0, {g_top:.4g}], median |grad f| over the upper values {g_split:.4g}, 99.5% {g_high:.4g}", flush=True)

centre = [0.5 * (bounds[2 * a] + bounds[2 * a + 1]) for a in range(3)]
diagonal = float(np.linalg.norm([bounds[2 * a + 1] - bounds[2 * a] for a in range(3)]))
view = C.setup_view(size)
display = simple.Show(reader, view)
display.Representation = "INR Volume"
view.CameraFocalPoint = centre
towards = [1.3, -1.1, 0.9]
view.CameraPosition = [centre[a] + towards[a] * diagonal for a in range(3)]
view.CameraViewUp = [0.0, 0.0, 1.0]
view.CameraViewAngle = 30.0
view.ResetCamera(False)
simple.ColorBy(display, ("POINTS", "value"))
display.SetScalarBarVisibility(view, False)


def boxes(flat, steep):
    """Two boxes over the upper values: (colour, opacity) `flat` below the median magnitude,
    `steep` above it (ParaView's Boxes: x, y, width, height, r, g, b, a)."""
    width = hi - x0
    return ([x0, 0.0, width, g_split] + list(flat)) + ([x0, g_split, width, g_high - g_split] + list(steep))


faint_blue, strong_orange = (0.2, 0.5, 1.0, 0.02), (1.0, 0.55, 0.1, 0.08)
tf2d = simple.GetTransferFunction2D("value")
tf2d.AutomaticRescaleRangeMode = "Never"
tf2d.OutputDimensions = [args.texture, args.texture]
tf2d.Range = [lo, hi, 0.0, g_top]
tf2d.Boxes = boxes(faint_blue, strong_orange)
display.TransferFunction2D = tf2d
display.UseTransfer2D = 1
display.UseGradientForTransfer2D = 1
display.ScalarOpacityUnitDistance = 0.5 * float(np.mean(spacing))  # VTK's step (see above)
display.InrBackend = 1  # CPU
display.InrSeed = 5
display.InrEstimator = 1
display.InrConvergenceTarget = 0.0
display.InrMaximumFrames = args.frames
display.InrFramesPerRender = args.frames

out = os.path.join(args.out, f"transfer2d_{name}")
inr_png = out + "_inr.png"
simple.SaveScreenshot(inr_png, view, ImageResolution=size)
state = C.info(display, "InrRefinementState")
frames_done = C.info(display, "InrAccumulatedFrames")

display.SetRepresentationType("Volume")
vol_png = out + "_paraview_volume.png"
simple.SaveScreenshot(vol_png, view, ImageResolution=size)
# The control: ParaView's picture with the boxes' looks swapped between the gradient halves.
tf2d.Boxes = boxes(strong_orange, faint_blue)
control_png = out + "_paraview_volume_control.png"
simple.SaveScreenshot(control_png, view, ImageResolution=size)

a, b, c = C.read_png(inr_png), C.read_png(vol_png), C.read_png(control_png)
p = C.psnr_over_volume(a, b)
pc = C.psnr_over_volume(a, c)
bg = np.array(C.BACKGROUND) * 255.0
covered = float(np.mean(np.any(np.abs(a - bg) > 8, axis=2)))
checks = C.Checks()
msg = (f"transfer2d {name}: INR Volume vs ParaView Volume ({args.resolution}^3 preview), same 2D transfer function "
       f"({args.texture}^2): PSNR {p:.2f} dB over the covered pixels (bound >= {args.min_psnr}); control (boxes "
       f"swapped between the gradient halves) {pc:.2f} dB; volume covers {100 * covered:.0f}% of the image; "
       f"INR state: {state}")
print(msg, flush=True)
with open(out + ".txt", "w") as f:
    f.write(msg + "\n")
checks(covered > 0.03, f"the INR image shows the model ({100 * covered:.1f}% of the pixels)")
checks(p >= args.min_psnr, f"PSNR {p:.2f} dB >= {args.min_psnr}")
checks(pc < args.min_psnr - args.control_margin,
       f"control {pc:.2f} dB < {args.min_psnr - args.control_margin} (the comparison can fail)")
checks(frames_done == args.frames, f"INR image of {frames_done} frame(s), asked {args.frames}")
status = checks.report()
sys.stdout.flush()
if status:  # (an exit with live views ends in GLXBadContext, status 1: only on failure)
    sys.exit(status)
