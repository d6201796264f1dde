"""An opaque isosurface and an opaque sphere through it (issue 48): which is in front, pixel by
pixel, in the picture and in the depth buffer.

The model is shown as INR Volume in Blend Mode Isosurface (opacity 1 at the isovalue) with a
Sphere source (flat green, unlit) placed half through the surface; the view is rendered once and
its colour and depth buffers read back. The reference depths come from two renders of their own:
the sphere alone, and ParaView's Contour of the reader's fine preview grid (RES^3) at the same
isovalue (the isosurface as geometry). Pixels where both are drawn are classed by those
references (a margin of --margin of the box's diagonal between the two depths):
  - surface in front (the isosurface nearer than the sphere): the picture shows the surface (not
    the sphere's green) and the depth buffer holds the surface's depth (within --tolerance of the
    diagonal of the contour's), nearer than the sphere's: the isosurface wrote its depth;
  - sphere in front: the picture shows the sphere and the depth buffer the sphere's depth
    (the surface stopped at the sphere's depth and wrote nothing nearer).
Each class must hold on >= --share of its pixels and cover >= 0.5% of the view. Control: the same
checks on ParaView's own Volume of the preview grid in Blend Mode Isosurface, which stops its rays
at the sphere's depth but (VTK 9.2) does not write depth: its "surface in front" depth check must
fail, so the check can fail.
  pvpython pv_isosurface_depth.py --model M_small.inr --out DIR"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--resolution", type=int, default=256)
ap.add_argument("--size", type=int, default=256)
ap.add_argument("--iso-fraction", type=float, default=0.15,
                help="the isovalue's place in the colour map's value range")
ap.add_argument("--margin", type=float, default=0.02,
                help="pixels whose two reference depths are closer than this share of the diagonal are not classed")
ap.add_argument("--tolerance", type=float, default=0.01,
                help="largest depth difference (share of the diagonal) from the contour's")
ap.add_argument("--sphere-offset", type=float, default=0.0)
ap.add_argument("--sphere-radius", type=float, default=0.45)
ap.add_argument("--share", type=float, default=0.95, help="share of a class's pixels that must pass")
args = ap.parse_args()

import numpy as np  # noqa: E402
from paraview import simple  # noqa: E402
from vtkmodules.vtkCommonCore import vtkFloatArray  # noqa: E402
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter  # noqa: E402
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402

C.load_plugin(args.plugin, remote=False)
simple._DisableFirstRenderCameraReset()  # every render below uses the camera set here
name = os.path.basename(args.model)[:-len(".inr")]
tf = json.load(open(args.model[:-len(".inr")] + ".tf.json"))[0]
lo, hi = tf["ValueRange"]
iso = lo + args.iso_fraction * (hi - lo)
size = [args.size, args.size]

reader = simple.OpenDataFile(args.model)
reader.PreviewResolution = args.resolution
reader.UpdatePipeline()
bounds = reader.GetDataInformation().GetBounds()
centre = np.array([0.5 * (bounds[2 * a] + bounds[2 * a + 1]) for a in range(3)])
extent = np.array([bounds[2 * a + 1] - bounds[2 * a] for a in range(3)])
diagonal = float(np.linalg.norm(extent))

view = C.setup_view(size)
towards = np.array([1.3, -1.1, 0.9])
towards /= np.linalg.norm(towards)

display = simple.Show(reader, view)
display.Representation = "INR Volume"
simple.ColorBy(display, ("POINTS", "value"))
lut = simple.GetColorTransferFunction("value")
lut.AutomaticRescaleRangeMode = "Never"
lut.RGBPoints = tf["RGBPoints"]
pwf = simple.GetOpacityTransferFunction("value")
pwf.Points = [lo, 1.0, 0.5, 0.0, hi, 1.0, 0.5, 0.0]  # opaque at every value
display.SetScalarBarVisibility(view, False)
display.BlendMode = "Isosurface"
display.IsosurfaceValues = [iso]
display.InrBackend = 1  # CPU
display.InrMaximumFrames = 1
display.InrFramesPerRender = 1
display.InrConvergenceTarget = 0.0

# The sphere through the surface: centred --sphere-offset of the smallest extent from the box's
# centre towards the camera, radius --sphere-radius of it: the surface hides part of it, the
# rest comes out through the surface.
radius = args.sphere_radius * float(extent.min())
sphere = simple.Sphere(Center=list(centre + args.sphere_offset * float(extent.min()) * towards),
                       Radius=radius, ThetaResolution=64, PhiResolution=64)
sphere_display = simple.Show(sphere, view)
sphere_display.ColorArrayName = ["POINTS", ""]
sphere_display.AmbientColor = sphere_display.DiffuseColor = [0.0, 1.0, 0.0]
sphere_display.Ambient, sphere_display.Diffuse, sphere_display.Specular = 1.0, 0.0, 0.0

contour = simple.Contour(Input=reader, ContourBy=["POINTS", "value"], Isosurfaces=[iso])
contour_display = simple.Show(contour, view)
contour_display.ColorArrayName = ["POINTS", ""]
simple.Hide(contour, view)


def render_and_read(tag):
    """Renders the view and reads back its colour (RGB 0..255, row 0 at the bottom) and depth
    (the window's depth values turned into eye distances; inf where nothing was drawn)."""
    # The same camera every time (Show on an empty view resets it).
    view.CameraFocalPoint = list(centre)
    view.CameraPosition = list(centre + 1.3 * diagonal * towards)
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.CameraViewAngle = 30.0
    camera = view.GetActiveCamera()
    simple.Render(view)
    window = view.GetRenderWindow()
    width, height = window.GetSize()
    grab = vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.ShouldRerenderOff()
    grab.ReadFrontBufferOff()
    grab.Update()
    image = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars()).reshape(height, width, -1)[:, :, :3]
    z = vtkFloatArray()
    window.GetZbufferData(0, 0, width - 1, height - 1, z)
    d = vtk_to_numpy(z).reshape(height, width).astype(np.float64)
    n, f = camera.GetClippingRange()  # the last render's (ParaView sets them for each)
    # Perspective window depth -> eye-space distance along the view direction.
    eye_z = n * f / (f - d * (f - n))
    eye_z[d >= 1.0] = np.inf
    from vtkmodules.vtkIOImage import vtkPNGWriter
    writer = vtkPNGWriter()
    writer.SetFileName(os.path.join(args.out, f"isosurface_depth_{name}_{tag}.png"))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()
    print(f"{tag}: clipping range {n:.4g}..{f:.4g}, {np.isfinite(eye_z).mean() * 100:.1f}% of the pixels have depth")
    return image.astype(np.float64), eye_z


def is_sphere(image):
    return (image[..., 1] > 200) & (image[..., 0] < 60) & (image[..., 2] < 60)


os.makedirs(args.out, exist_ok=True)
simple.Hide(reader, view)
_, sphere_z = render_and_read("sphere_alone")
simple.Hide(sphere, view)
simple.Show(contour, view)
_, contour_z = render_and_read("contour_alone")
simple.Hide(contour, view)
simple.Show(reader, view)
simple.Show(sphere, view)
inr_image, inr_z = render_and_read("inr_volume_with_sphere")
display.SetRepresentationType("Volume")
display.BlendMode = "Isosurface"
volume_image, volume_z = render_and_read("paraview_volume_with_sphere")

margin = args.margin * diagonal
# (Both drawn at the pixel: the surface hides the sphere there, or the sphere comes out of it.)
both = np.isfinite(contour_z) & np.isfinite(sphere_z)
surface_front = both & (contour_z < sphere_z - margin)
sphere_front = both & (sphere_z < contour_z - margin)
pixels = surface_front.size
checks = C.Checks()
checks(surface_front.mean() >= 0.005 and sphere_front.mean() >= 0.005,
       f"the scene has both: surface in front on {100 * surface_front.mean():.1f}% of the view, "
       f"sphere in front on {100 * sphere_front.mean():.1f}%")


def judge(image, z, what, control=False):
    """The two classes' checks on one picture; returns the share of surface-in-front pixels
    whose depth is the surface's."""
    tol = args.tolerance * diagonal
    shows_surface = ~is_sphere(image[surface_front])
    depth_surface = np.abs(z[surface_front] - contour_z[surface_front]) <= tol
    shows_sphere = is_sphere(image[sphere_front])
    depth_sphere = np.abs(z[sphere_front] - sphere_z[sphere_front]) <= tol
    say = (lambda ok, text: print(("control: " if ok else "control (fails as it must): ") + text)) if control else checks
    say(shows_surface.mean() >= args.share,
        f"{what}: surface in front: the picture shows the surface on {100 * shows_surface.mean():.1f}% of those pixels")
    say(shows_sphere.mean() >= args.share,
        f"{what}: sphere in front: the picture shows the sphere on {100 * shows_sphere.mean():.1f}% of those pixels")
    say(depth_sphere.mean() >= args.share,
        f"{what}: sphere in front: the depth buffer holds the sphere's depth on {100 * depth_sphere.mean():.1f}% of those pixels")
    if not control:
        checks(depth_surface.mean() >= args.share,
               f"{what}: surface in front: the depth buffer holds the surface's depth (within "
               f"{args.tolerance} of the diagonal of the contour's) on {100 * depth_surface.mean():.1f}% of those pixels")
    err = np.abs(z[surface_front] - contour_z[surface_front])
    err = err[np.isfinite(err)]
    print(f"{what}: depth against the contour's where the surface is in front: median "
          f"{np.median(err) / diagonal if err.size else float('nan'):.2e}, 95th percentile "
          f"{np.percentile(err, 95) / diagonal if err.size else float('nan'):.2e} of the diagonal")
    return float(depth_surface.mean())


judge(inr_image, inr_z, "INR Volume")
written = judge(volume_image, volume_z, "ParaView's Volume (control)", control=True)
checks(written < args.share,
       f"control: ParaView's Volume, which does not write depth, fails the surface-depth check "
       f"({100 * written:.1f}% of the pixels), so the check can fail")
status = checks.report()
sys.stdout.flush()
if status:
    sys.exit(status)
