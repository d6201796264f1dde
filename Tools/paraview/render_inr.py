"""Render an INR Volume model through ParaView at a few times (pvpython or pvbatch).

    pvpython Tools/paraview/render_inr.py MODEL.inr [--times 0 5 10 | --count 3]
        [--out DIR] [--size 512 512] [--frames 64] [--converge DB] [--shadows] [--tf COLORMAP.json]
        [--plugin PATH/InrVolume.so] [--frame-resolution 24]

Loads the plugin (PV_PLUGIN_PATH autoloads it too), opens the model (OpenDataFile finds the
reader by the .inr extension), shows it as "INR Volume", colours it by "value" with the colour
map of --tf (a ParaView colour-map export, e.g. a model's suggested MODEL.tf.json) or else
ParaView's Cool to Warm over the model's value range with an opacity ramp over its upper half,
frames the camera on the part the opacity map shows (--frame-resolution), then for
each time: sets the animation time, accumulates --frames frames in one render and saves
DIR/inr_t<i>.png. Prints the accumulated frames and the backend used.
"""
import argparse
import math
import os
import sys

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("model")
ap.add_argument("--times", type=float, nargs="*", default=None, help="world times to render")
ap.add_argument("--count", type=int, default=3, help="evenly spaced times over the range")
ap.add_argument("--out", default="example-output")
ap.add_argument("--size", type=int, nargs=2, default=[512, 512])
ap.add_argument("--frames", type=int, default=64, help="frames per picture (the most, with --converge)")
ap.add_argument("--converge", type=float, default=0.0,
                help="stop a picture's accumulation once its estimated PSNR over the volume's pixels "
                     "reaches this many dB (0: always --frames)")
ap.add_argument("--shadows", action="store_true")
ap.add_argument("--tf", default="", help="ParaView colour-map JSON (RGBPoints, Points) to use")
ap.add_argument("--plugin", default="", help="InrVolume.so, if not autoloaded via PV_PLUGIN_PATH")
ap.add_argument("--frame-resolution", type=int, default=24,
                help="lattice (per axis) on which the camera finds the visible part to frame; 0: the whole box")
args = ap.parse_args()

from paraview import simple  # noqa: E402

if args.plugin:
    simple.LoadPlugin(args.plugin, remote=False, ns=globals())

reader = simple.OpenDataFile(args.model)
if reader is None or reader.GetXMLName() != "InrVolumeReader":
    sys.exit(f"{args.model}: not opened by the INR Volume reader (is the plugin loaded?)")
reader.UpdatePipelineInformation()
trange = list(reader.GetProperty("TimeRange"))
t0, t1 = trange if len(trange) == 2 else (0.0, 0.0)
times = args.times if args.times else [t0 + (t1 - t0) * i / max(1, args.count - 1)
                                      for i in range(args.count)]

view = simple.GetActiveViewOrCreate("RenderView")
view.ViewSize = args.size
view.OrientationAxesVisibility = 0
display = simple.Show(reader, view)
display.SetRepresentationType("INR Volume")

# The model's value range travels in the field data ("InrValueRange").
reader.UpdatePipeline(times[0])
vr = reader.GetDataInformation().DataInformation.GetArrayInformation("InrValueRange", 2)
lo, hi = vr.GetComponentRange(0) if vr else (0.0, 1.0)
simple.ColorBy(display, ("POINTS", "value"))
lut = simple.GetColorTransferFunction("value")
pwf = simple.GetOpacityTransferFunction("value")
lut.AutomaticRescaleRangeMode = "Never"
if args.tf:
    import json
    with open(args.tf) as f:
        preset = json.load(f)
    preset = preset[0] if isinstance(preset, list) else preset
    lut.RGBPoints = preset["RGBPoints"]  # as exported: values in the model's units
    if "ColorSpace" in preset:
        lut.ColorSpace = preset["ColorSpace"]
    if "Points" in preset:
        pwf.Points = preset["Points"]
else:
    lut.ApplyPreset("Cool to Warm", True)
    lut.RescaleTransferFunction(lo, hi)
    mid = lo + 0.5 * (hi - lo)
    pwf.Points = [lo, 0.0, 0.5, 0.0, mid, 0.0, 0.5, 0.0, hi, 0.8, 0.5, 0.0]
display.SetScalarBarVisibility(view, False)
display.ScalarOpacityUnitDistance = 0.05 * max(
    b1 - b0 for b0, b1 in zip(reader.GetDataInformation().GetBounds()[0::2],
                              reader.GetDataInformation().GetBounds()[1::2]))

# Progressive refinement in a script: one render accumulates FramesPerRender frames.
display.InrMaximumFrames = args.frames
display.InrFramesPerRender = args.frames
display.InrConvergenceTarget = args.converge
display.InrShadows = 1 if args.shadows else 0


def visible_bounds(resolution, share=0.98):
    """The box around what the transfer function shows at any of the times: the reader's preview
    grid (the network on a resolution^3 lattice) at each time, each point weighted by its opacity,
    and per axis the range that holds `share` of the weight (a noisy network's scattered faint
    points do not stretch it to the whole box), grown by one lattice cell. None when nothing is
    visible (then the whole box)."""
    from paraview import servermanager
    from vtkmodules.util.numpy_support import vtk_to_numpy
    import numpy as np
    opacity_of = pwf.GetClientSideObject()  # the vtkPiecewiseFunction the mapper reads
    saved = reader.PreviewResolution
    reader.PreviewResolution = resolution
    coords, weights, spacing = [], [], None
    for t in times:
        reader.UpdatePipeline(t)
        grid = servermanager.Fetch(reader)
        array = grid.GetPointData().GetArray("value") if grid else None
        if array is None or array.GetNumberOfTuples() == 0:
            continue
        values = vtk_to_numpy(array)
        w = np.array([opacity_of.GetValue(float(v)) for v in values])
        nx, ny, _ = grid.GetDimensions()
        ids = np.arange(values.size)
        ijk = np.stack([ids % nx, (ids // nx) % ny, ids // (nx * ny)], axis=1)
        spacing = np.array(grid.GetSpacing())
        coords.append(np.array(grid.GetOrigin()) + ijk * spacing)
        weights.append(w)
    reader.PreviewResolution = saved
    if not weights or sum(w.sum() for w in weights) <= 0.0:
        return None
    xyz, w = np.concatenate(coords), np.concatenate(weights)
    tail = 0.5 * (1.0 - share) * w.sum()
    box = reader.GetDataInformation().GetBounds()
    bounds = []
    for a in range(3):
        order = np.argsort(xyz[:, a])
        cumulative = np.cumsum(w[order])
        lo = xyz[order[np.searchsorted(cumulative, tail)], a] - spacing[a]
        hi = xyz[order[min(len(order) - 1, np.searchsorted(cumulative, cumulative[-1] - tail))], a] + spacing[a]
        bounds += [max(lo, box[2 * a]), min(hi, box[2 * a + 1])]
    return [float(b) for b in bounds]


# A three-quarter view from the front (+z), up +y, framing what the transfer function shows (a
# camera that fits the whole box leaves a small volume in a corner of the picture).
frame = visible_bounds(args.frame_resolution) if args.frame_resolution > 0 else None
if frame:
    print("framing the visible part: bounds " + " ".join(f"{b:.4g}" for b in frame), flush=True)
box = list(reader.GetDataInformation().GetBounds())
frame = frame or box
centre = [0.5 * (frame[2 * a] + frame[2 * a + 1]) for a in range(3)]
radius = 0.5 * math.sqrt(sum((frame[2 * a + 1] - frame[2 * a]) ** 2 for a in range(3)))
direction = [0.8, 0.6, 2.0]
norm = math.sqrt(sum(d * d for d in direction))
# As vtkRenderer::ResetCamera: the bounding sphere of the framed box fits the view angle.
distance = radius / math.sin(math.radians(view.CameraViewAngle) / 2.0)
view.CameraFocalPoint = centre
view.CameraPosition = [c + distance * d / norm for c, d in zip(centre, direction)]
view.CameraViewUp = [0.0, 1.0, 0.0]
view.CenterOfRotation = centre
# paraview.simple resets the camera on a view's first render unless told not to: that reset
# would frame the whole box again.
simple._DisableFirstRenderCameraReset()
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
os.makedirs(args.out, exist_ok=True)
for i, t in enumerate(times):
    scene.AnimationTime = t
    path = os.path.join(args.out, f"inr_t{i}.png")
    simple.SaveScreenshot(path, view, ImageResolution=args.size)
    prop = display.SMProxy.GetProperty("InrAccumulatedFrames")
    estimate = display.SMProxy.GetProperty("InrConvergenceEstimate")
    display.SMProxy.UpdatePropertyInformation(prop)
    backend = display.SMProxy.GetProperty("InrBackendInUse")
    display.SMProxy.UpdatePropertyInformation(backend)
    display.SMProxy.UpdatePropertyInformation(estimate)
    print(f"t = {t:g}: {path} ({prop.GetElement(0)} frames, estimated {estimate.GetElement(0):.1f} dB "
          f"over the volume's pixels, backend {backend.GetElement(0)})", flush=True)
sys.stdout.flush()
