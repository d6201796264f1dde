"""What the ParaView benchmark scripts share (pvpython): a shipped model shown as the GUI shows
it with its suggested colour map, the representation's read-back state, the window as drawn."""
import json
import os
import sys

from paraview import simple


def apply_tf(tf_path):
    """The model's suggested MODEL.tf.json (a ParaView colour-map preset) on the "value" LUT."""
    lut = simple.GetColorTransferFunction("value")
    lut.AutomaticRescaleRangeMode = "Never"
    with open(tf_path) as f:
        preset = json.load(f)
    preset = preset[0] if isinstance(preset, list) else preset
    lut.RGBPoints = preset["RGBPoints"]
    if "ColorSpace" in preset:
        lut.ColorSpace = preset["ColorSpace"]
    if "Points" in preset:
        simple.GetOpacityTransferFunction("value").Points = preset["Points"]


def show_model(view, model_path, backend, before_colouring=None):
    """Opens `model_path` with the INR Volume reader and shows it as "INR Volume" in `view`:
    coloured by "value" with its MODEL.tf.json where there is one, no scalar bar, `backend`
    (InrBackend: 0 auto, 1 CPU, 2 CUDA), an opacity unit distance of 5% of the box, the camera
    reset from an oblique direction. `before_colouring(display)` runs before anything renders.
    Returns (reader, display, (t0, t1))."""
    reader = simple.OpenDataFile(model_path)
    if reader is None or reader.GetXMLName() != "InrVolumeReader":
        sys.exit(f"{model_path}: not opened by the INR Volume reader (is the plugin loaded?)")
    reader.UpdatePipelineInformation()
    trange = list(reader.GetProperty("TimeRange"))
    times = tuple(trange) if len(trange) == 2 else (0.0, 0.0)
    display = simple.Show(reader, view)
    display.SetRepresentationType("INR Volume")
    if before_colouring:
        before_colouring(display)
    simple.ColorBy(display, ("POINTS", "value"))
    tf_path = os.path.splitext(model_path)[0] + ".tf.json"
    if os.path.exists(tf_path):
        apply_tf(tf_path)
    display.SetScalarBarVisibility(view, False)
    display.InrBackend = backend
    b = reader.GetDataInformation().GetBounds()
    display.ScalarOpacityUnitDistance = 0.05 * max(b[1] - b[0], b[3] - b[2], b[5] - b[4])
    simple.ResetCamera(view)
    view.CameraPosition = [c + d for c, d in zip(view.CameraFocalPoint, [0.8, 0.6, 2.0])]
    view.CameraViewUp = [0.0, 1.0, 0.0]
    simple.ResetCamera(view)
    return reader, display, times


class RepresentationState:
    """Information properties of the INR Volume representation, pulled after a render (they
    live on the "INR Volume" sub-proxy: the display proxy exposes only the panel's properties)."""

    def __init__(self, display):
        self.proxy = display.SMProxy.GetProperty("InrConverged").GetParent()

    def get(self, name):
        prop = self.proxy.GetProperty(name)
        self.proxy.UpdatePropertyInformation(prop)
        return prop.GetElement(0)


def _grab_filter(view):
    """A filter reading the window as last drawn (no render of its own)."""
    from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter
    g = vtkWindowToImageFilter()
    g.SetInput(view.GetRenderWindow())
    g.ShouldRerenderOff()
    g.ReadFrontBufferOff()
    g.Update()
    return g


def save_window(view, path):
    """The window as last drawn, as a PNG: an interactive frame stays as it was shown."""
    from vtkmodules.vtkIOImage import vtkPNGWriter
    grabbed = _grab_filter(view)  # kept alive while the writer reads it
    writer = vtkPNGWriter()
    writer.SetFileName(path)
    writer.SetInputConnection(grabbed.GetOutputPort())
    writer.Write()


def grab(view):
    """The window as last drawn (no render), RGB floats, row 0 at the bottom."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    grabbed = _grab_filter(view)
    image = grabbed.GetOutput()
    w, h, _ = image.GetDimensions()
    return vtk_to_numpy(image.GetPointData().GetScalars()).reshape(h, w, -1)[:, :, :3].astype(float)
