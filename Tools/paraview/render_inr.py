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


def visible_bounds(resolution):
    """The box around what the transfer function shows at any of the times: the reader's preview
    grid (the network on a resolution^3 lattice) at each time, points whose opacity reaches 2% of
    the map's peak, grown by one lattice cell. None when nothing is visible (then the whole box)."""
    from paraview import servermanager
    from vtkmodules.util.numpy_support import vtk_to_numpy
    import numpy as np
    opacity_of = pwf.GetClientSideObject()  # the vtkPiecewiseFunction the mapper reads
    node_values = list(pwf.Points)[1::4]
    threshold = 0.02 * max(node_values) if node_values else 0.0
    saved = reader.PreviewResolution
    reader.PreviewResolution = resolution
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for t in times:
        reader.UpdatePipeline(t)
        grid = servermanager.Fetch(reader)
        array = grid.GetPointData().GetArray("value") if grid else None
        if array is None or array.GetNumberOfTuples() == 0:
            continue
        values = vtk_to_numpy(array)
        visible = np.array([opacity_of.GetValue(float(v)) > threshold for v in values])
        if not visible.any():
            continue
        nx, ny, _ = grid.GetDimensions()
        ids = np.nonzero(visible)[0]
        ijk = np.stack([ids % nx, (ids // nx) % ny, ids // (nx * ny)], axis=1)
        origin, spacing = np.array(grid.GetOrigin()), np.array(grid.GetSpacing())
        lo = np.minimum(lo, origin + (ijk.min(axis=0) - 1) * spacing)
        hi = np.maximum(hi, origin + (ijk.max(axis=0) + 1) * spacing)
    reader.PreviewResolution = saved
    if not np.isfinite(lo).all():
        return None
    box = reader.GetDataInformation().GetBounds()
    lo = np.maximum(lo, box[0::2])
    hi = np.minimum(hi, box[1::2])
    return [float(x) for pair in zip(lo, hi) for x in pair]


# A three-quarter view from the front (+z), up +y, framing what the transfer function shows (a
# camera that fits the whole box leaves a small volume in a corner of the picture).
frame = visible_bounds(args.frame_resolution) if args.frame_resolution > 0 else None
if frame:
    print("framing the visible part: bounds " + " ".join(f"{b:.4g}" for b in frame), flush=True)
simple.ResetCamera(view)
view.CameraFocalPoint = [0.5 * (frame[2 * a] + frame[2 * a + 1]) for a in range(3)] if frame \
    else view.CameraFocalPoint
view.CameraPosition = [c + d for c, d in zip(view.CameraFocalPoint, [0.8, 0.6, 2.0])]
view.CameraViewUp = [0.0, 1.0, 0.0]
if frame:
    view.ResetCamera(frame)
else:
    simple.ResetCamera(view)
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
