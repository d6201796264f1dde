"""Render an INR Volume model through ParaView at a few times (pvpython or pvbatch).

    pvpython Tools/paraview/render_inr.py MODEL.inr [--times 0 5 10 | --count 3]
        [--out DIR] [--size 512 512] [--frames 64] [--shadows] [--tf COLORMAP.json]
        [--plugin PATH/InrVolume.so]

Loads the plugin (PV_PLUGIN_PATH autoloads it too), opens the model (OpenDataFile finds the
reader by the .inr extension), shows it as "INR Volume", colours it by "value" with the colour
map of --tf (a ParaView colour-map export, e.g. a model's suggested MODEL.tf.json) or else
ParaView's Cool to Warm over the model's value range with an opacity ramp over its upper half,
then for
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
ap.add_argument("--frames", type=int, default=64)
ap.add_argument("--shadows", action="store_true")
ap.add_argument("--tf", default="", help="ParaView colour-map JSON (RGBPoints, Points) to use")
ap.add_argument("--plugin", default="", help="InrVolume.so, if not autoloaded via PV_PLUGIN_PATH")
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
display.InrConvergenceTarget = 0.0
display.InrShadows = 1 if args.shadows else 0

# A three-quarter view from the front (+z), up +y, framing the box.
simple.ResetCamera(view)
view.CameraPosition = [c + d for c, d in zip(view.CameraFocalPoint, [0.8, 0.6, 2.0])]
view.CameraViewUp = [0.0, 1.0, 0.0]
simple.ResetCamera(view)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
os.makedirs(args.out, exist_ok=True)
for i, t in enumerate(times):
    scene.AnimationTime = t
    path = os.path.join(args.out, f"inr_t{i}.png")
    simple.SaveScreenshot(path, view, ImageResolution=args.size)
    prop = display.SMProxy.GetProperty("InrAccumulatedFrames")
    display.SMProxy.UpdatePropertyInformation(prop)
    backend = display.SMProxy.GetProperty("InrBackendInUse")
    display.SMProxy.UpdatePropertyInformation(backend)
    print(f"t = {t:g}: {path} ({prop.GetElement(0)} frames, backend {backend.GetElement(0)})",
          flush=True)
sys.stdout.flush()
