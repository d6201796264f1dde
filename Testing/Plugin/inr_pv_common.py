"""Shared helpers of the ParaView plugin tests (pvpython / pvbatch / paraview --script)."""
import os

# The scene every scripted test renders: the plugin test model, a fixed camera, a fixed
# colour map (ParaView's Cool to Warm) and opacity ramp, ParaView's default background.
CAMERA = dict(position=[4.6, -4.6, 3.6], focal_point=[1.0, 0.0, 0.5], view_up=[0.0, 0.0, 1.0],
              view_angle=30.0)
OPACITY_POINTS = [0.55, 0.0, 0.5, 0.0, 0.85, 0.5, 0.5, 0.0, 1.17, 1.0, 0.5, 0.0]
VALUE_RANGE = [-0.14, 1.17]
BACKGROUND = [0.32, 0.34, 0.43]
UNIT_DISTANCE = 0.1


def argument_parser():
    """The arguments of the scripted plugin tests: --model M.inr, --out DIR and --plugin
    InrVolume.so (optional: already loaded through PV_PLUGIN_PATH); scripts add their own."""
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--plugin", default="")
    return ap


class Checks:
    """A test's checks: check(ok, what) prints "ok:"/"FAIL:" lines; report() prints the RESULT line
    and returns the exit status (1 when any check failed)."""

    def __init__(self):
        self.failures = []

    def __call__(self, ok, what):
        print(("ok: " if ok else "FAIL: ") + what, flush=True)
        if not ok:
            self.failures.append(what)

    def report(self):
        print("RESULT:", "PASS" if not self.failures else "FAIL " + "; ".join(self.failures), flush=True)
        return 1 if self.failures else 0


class TimedChecks:
    """Checks of wall-clock times (frame times, event-loop stalls). A test does not fail on them by
    default: a shared or loaded machine (CI's included) makes any absolute bound flaky, and the
    project measures performance with benchmarks (Benchmarks/paraview/), not timed assertions.
    They are printed as measured and met or missed; with judge=True (a test's --judge-times, for a
    developer on a quiet machine) they are checks like the others."""

    def __init__(self, check, judge):
        self.check = check
        self.judge = judge

    def __call__(self, ok, what):
        if self.judge:
            self.check(ok, what)
        else:
            print(f"measured ({'met' if ok else 'missed'}; judged only with --judge-times): {what}",
                  flush=True)


def read_render_log(path):
    """The GUI setup script's render log (gui_session_setup.py, INR_GUI_OUT): a list of each
    render's key=value fields, and (end, ms) of what the script's own observer cost after each
    (screenshots, state reads). Empty when the file is missing."""
    renders, observer = [], []
    for line in open(path) if os.path.exists(path) else []:
        kv = dict(item.split("=", 1) for item in line.split()[1:] if "=" in item)
        if line.startswith("observer"):
            observer.append((float(kv["end"]), float(kv["log_ms"])))
        elif line.startswith("render"):
            renders.append(kv)
    return renders, observer


def read_event_loop_stalls(path, observer=()):
    """The plugin's event-loop watch (INR_VOLUME_EVENT_LOOP_LOG): (begin, end, ms) per stall on
    CLOCK_MONOTONIC, ms less what the setup script's observer (read_render_log) spent inside it.
    Empty when the file is missing."""
    stalls = []
    for line in open(path) if os.path.exists(path) else []:
        kv = dict(item.split("=", 1) for item in line.split() if "=" in item)
        end, ms = float(kv["end"]), float(kv["block_ms"])
        begin = end - ms / 1000.0
        stalls.append((begin, end, ms - sum(cost for t, cost in observer if begin <= t <= end)))
    return stalls


def load_plugin(path, remote):
    """Loads the plugin on the client (and the server); already loaded (PV_PLUGIN_PATH) is fine."""
    from paraview import simple
    if not path:
        return
    for where in ([False, True] if remote else [False]):
        try:
            simple.LoadPlugin(path, remote=where, ns=globals())
        except RuntimeError as e:
            print(f"note: LoadPlugin(remote={where}): {e} (already loaded through PV_PLUGIN_PATH?)")


def setup_view(size):
    from paraview import simple
    view = simple.GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(size)
    view.OrientationAxesVisibility = 0
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    view.Background = BACKGROUND
    view.CameraPosition = CAMERA["position"]
    view.CameraFocalPoint = CAMERA["focal_point"]
    view.CameraViewUp = CAMERA["view_up"]
    view.CameraViewAngle = CAMERA["view_angle"]
    view.CameraParallelProjection = 0
    return view


def apply_colormap(display, view):
    from paraview import simple
    simple.ColorBy(display, ("POINTS", "value"))
    lut = simple.GetColorTransferFunction("value")
    lut.ApplyPreset("Cool to Warm", True)
    lut.AutomaticRescaleRangeMode = "Never"
    lut.RescaleTransferFunction(*VALUE_RANGE)
    pwf = simple.GetOpacityTransferFunction("value")
    pwf.Points = OPACITY_POINTS
    display.ScalarOpacityUnitDistance = UNIT_DISTANCE
    display.SetScalarBarVisibility(view, False)


def show_inr(reader, view, seed, maximum_frames, frames_per_render, macrocells=None):
    """Shows `reader` as INR Volume in `view` with the tests' colour map, a fixed seed, no
    convergence stop (exactly `maximum_frames` at most) and `frames_per_render` frames per render;
    `macrocells` per axis when given. Returns the display."""
    from paraview import simple
    display = simple.Show(reader, view)
    display.Representation = "INR Volume"
    apply_colormap(display, view)
    display.InrSeed = seed
    # The baselines are delta-tracking images (the paper's estimator, recorded with independent
    # sub-pixel jitter before other estimators became the default): the comparisons pin both. The
    # default is covered by plugin_default_convergence and the GUI tests.
    display.InrEstimator = 0
    display.InrStratifiedJitter = 0
    display.InrConvergenceTarget = 0.0
    display.InrMaximumFrames = maximum_frames
    display.InrFramesPerRender = frames_per_render
    if macrocells is not None:
        display.InrMacrocellResolution = macrocells
    return display


def info(display, name):
    """An information-only property of the INR Volume representation, pulled from the server."""
    proxy = display.SMProxy
    prop = proxy.GetProperty(name)
    proxy.UpdatePropertyInformation(prop)
    return prop.GetElement(0)


def read_png(path):
    import numpy as np
    from vtkmodules.vtkIOImage import vtkPNGReader
    from vtkmodules.util.numpy_support import vtk_to_numpy
    if not os.path.exists(path):
        raise FileNotFoundError(path)
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    a = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, -1)
    return a[:, :, :3].astype(np.float64)


def psnr(a, b):
    """PSNR (8-bit RGB) over the whole image: for baselines of the same view, where the maximum
    absolute error is checked beside it (compare)."""
    import numpy as np
    mse = float(np.mean((a - b) ** 2))
    return 999.0 if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def psnr_over_volume(a, b):
    """PSNR (8-bit RGB) over the pixels where either image shows the volume (differs from the
    view's BACKGROUND by more than 2 in a channel): the background would dilute the error."""
    import numpy as np
    bg = np.array(BACKGROUND) * 255.0
    covered = np.any(np.abs(a - bg) > 2, axis=2) | np.any(np.abs(b - bg) > 2, axis=2)
    if not covered.any():
        return 0.0  # nothing shown: no evidence either way
    mse = float(np.mean((a[covered] - b[covered]) ** 2))
    return 999.0 if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def compare(out_png, baseline, min_psnr, max_abs):
    """Strict comparison of two 8-bit RGB images; returns (ok, message)."""
    import numpy as np
    a, b = read_png(out_png), read_png(baseline)
    if a.shape != b.shape:
        return False, f"size {a.shape} differs from baseline {b.shape}"
    p = psnr(a, b)
    m = int(np.max(np.abs(a - b)))
    ok = p >= min_psnr and m <= max_abs
    return ok, f"PSNR {p:.2f} dB (>= {min_psnr}), max abs error {m} (<= {max_abs})"


def refine_in_one_render(display, frames, seed=7, macrocells=16):
    """The scripted tests' INR Volume settings: seed, no convergence target, `frames` frames
    accumulated within each render (so one render or screenshot gives the refined image); delta
    tracking, as the baselines were recorded (see show_inr)."""
    display.InrSeed = seed
    display.InrEstimator = 0
    display.InrStratifiedJitter = 0
    display.InrConvergenceTarget = 0.0
    display.InrMaximumFrames = frames
    display.InrFramesPerRender = frames
    display.InrMacrocellResolution = macrocells
