"""The pictures of Docs/paraview.md's blend-mode section: for each mode (composite, isosurface,
slice, cropping) INR Volume beside ParaView's own Volume of the reader's RES^3 preview grid (the
network resampled), same colour map, opacity, camera and ParaView properties, CPU backend, in
pvpython. Writes DIR/blend_<mode>.png (the two pictures side by side, INR Volume on the left) and
prints the PSNR over the pixels either covers (as the tests plugin_blend_* measure it).

  PV_PLUGIN_PATH=build/lib/paraview-plugins/InrVolume \\
    pvpython --force-offscreen-rendering Tools/paraview/blend_pictures.py \\
      --model Testing/Data/real/ffn_mri_head_small.inr --out Docs/paraview-blend

A few minutes on 2 cores (the composite pictures accumulate --frames frames)."""
import argparse
import json
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "..", "Testing", "Plugin"))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--modes", default="composite,isosurface,slice,crop")
ap.add_argument("--resolution", type=int, default=256, help="ParaView's Volume: the preview grid's points per axis")
ap.add_argument("--size", type=int, default=320, help="each picture's width and height")
ap.add_argument("--frames", type=int, default=256, help="frames of the composite pictures")
ap.add_argument("--zoom", type=float, default=1.6, help="camera dolly after fitting the model's box")
ap.add_argument("--unit-distance", type=float, default=200.0,
                help="Scalar Opacity Unit Distance = the box's diagonal / this (composite pictures)")
ap.add_argument("--iso-fraction", type=float, default=0.15,
                help="the isovalue's place in the colour map's value range")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402

name = os.path.basename(args.model)[:-len(".inr")]
tf = json.load(open(args.model[:-len(".inr")] + ".tf.json"))[0]
lo, hi = tf["ValueRange"]
size = [args.size, args.size]
os.makedirs(args.out, exist_ok=True)
simple._DisableFirstRenderCameraReset()

reader = simple.OpenDataFile(args.model)
reader.PreviewResolution = args.resolution
reader.UpdatePipeline()
bounds = reader.GetDataInformation().GetBounds()
centre = [0.5 * (bounds[2 * a] + bounds[2 * a + 1]) for a in range(3)]
extent = [bounds[2 * a + 1] - bounds[2 * a] for a in range(3)]
diagonal = float(np.linalg.norm(extent))

view = C.setup_view(size)
display = simple.Show(reader, view)
simple.ColorBy(display, ("POINTS", "value"))
lut = simple.GetColorTransferFunction("value")
lut.AutomaticRescaleRangeMode = "Never"
lut.ColorSpace = tf.get("ColorSpace", "RGB")
lut.RGBPoints = tf["RGBPoints"]
pwf = simple.GetOpacityTransferFunction("value")
display.SetScalarBarVisibility(view, False)
# Lit under one headlight (VTK's default lighting) for the isosurface; the others unlit.
view.UseLight = 0
light = simple.AddLight(view=view)
light.Coords = "Headlight"
light.Intensity = 1.0


def camera(mode):
    view.CameraFocalPoint = centre
    towards = [0.4, -0.3, 1.0] if mode == "slice" else [1.3, -1.1, 0.9]
    view.CameraPosition = [centre[a] + towards[a] * diagonal for a in range(3)]
    view.CameraViewUp = [0.0, 1.0, 0.0] if mode == "slice" else [0.0, 0.0, 1.0]
    view.CameraViewAngle = 30.0
    view.ResetCamera(False)
    view.GetActiveCamera().Dolly(args.zoom)  # the box's corners may leave the picture


def setup(mode):
    """ParaView's properties of `mode` on the display (shared by both representations); the
    frames INR Volume accumulates and a caption."""
    display.BlendMode = "Composite"
    display.UseCropping = 0
    display.Shade = 0
    if mode in ("composite", "crop"):
        pwf.Points = tf["Points"]
        display.ScalarOpacityUnitDistance = diagonal / args.unit_distance
        if mode == "crop":
            # The box keeps the upper 55% of x and the lower 70% of z: it cuts the model open.
            display.UseCropping = 1
            scale = [0.55, 1.0, 0.7]
            display.CroppingOrigin = [bounds[1] * (1.0 - scale[0]), 0.0, bounds[4] * (1.0 - scale[2])]
            display.CroppingScale = scale
            return args.frames, f"composite cropped (origin {list(display.CroppingOrigin)}, scale {scale})"
        return args.frames, "composite"
    pwf.Points = [lo, 1.0, 0.5, 0.0, hi, 1.0, 0.5, 0.0]  # opaque at every value
    if mode == "isosurface":
        iso = lo + args.iso_fraction * (hi - lo)
        display.BlendMode = "Isosurface"
        display.IsosurfaceValues = [iso]
        for prop, value in (("Shade", 1), ("Ambient", 0.2), ("Diffuse", 0.8), ("Specular", 0.0)):
            display.SetPropertyWithName(prop, value)
        return 1, f"isosurface {iso:.4g}, shaded"
    display.BlendMode = "Slice"
    display.SliceFunction = "Plane"
    display.SliceFunction.Origin = centre
    display.SliceFunction.Normal = [0.3, 0.4, 1.0]
    return 1, "slice through the centre, normal (0.3, 0.4, 1)"


def side_by_side(left, right, path):
    a, b = C.read_png(left), C.read_png(right)
    gap = np.full((a.shape[0], 4, 3), 255.0)
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.util.numpy_support import numpy_to_vtk
    both = np.concatenate([a, gap, b], axis=1).astype(np.uint8)[::-1]  # VTK's row 0 is the bottom
    image = vtkImageData()
    image.SetDimensions(both.shape[1], both.shape[0], 1)
    image.GetPointData().SetScalars(numpy_to_vtk(both.reshape(-1, 3), deep=True))
    writer = vtkPNGWriter()
    writer.SetFileName(path)
    writer.SetInputData(image)
    writer.Write()


for mode in args.modes.split(","):
    display.SetRepresentationType("INR Volume")
    display.InrBackend = 1  # CPU
    display.InrSeed = 5
    display.InrConvergenceTarget = 0.0
    display.InrEstimator = 1
    camera(mode)
    frames, caption = setup(mode)
    display.InrMaximumFrames = frames
    display.InrFramesPerRender = frames
    inr_png = os.path.join(args.out, f"_{mode}_inr.png")
    simple.SaveScreenshot(inr_png, view, ImageResolution=size)
    display.SetRepresentationType("Volume")
    setup(mode)
    volume_png = os.path.join(args.out, f"_{mode}_paraview_volume.png")
    simple.SaveScreenshot(volume_png, view, ImageResolution=size)
    out = os.path.join(args.out, f"blend_{mode}.png")
    side_by_side(inr_png, volume_png, out)
    p = C.psnr_over_volume(C.read_png(inr_png), C.read_png(volume_png))
    for f in (inr_png, volume_png):
        os.remove(f)
    print(f"{out}: {name}, {caption}: INR Volume ({frames} frame{'s' if frames > 1 else ''}) vs "
          f"ParaView's Volume of the {args.resolution}^3 preview: {p:.1f} dB over the covered "
          f"pixels, {os.path.getsize(out) // 1024} kB", flush=True)
