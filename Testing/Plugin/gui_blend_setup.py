# Runs inside the ParaView GUI before the recorded blend-mode session (paraview
# --script=gui_blend_setup.py --test-script=gui_blend.xml, see run_gui_blend.py). It opens nothing
# itself (the recorded test opens the model through File > Open and Apply). It
#  - records every message that reaches VTK's output window (what ParaView's Output Messages
#    window shows and pops up for) to INR_GUI_OUT/gui_blend_messages.txt (one block per message);
#  - logs every render of the view (INR_GUI_OUT/gui_blend_renders.txt): its wall time from the view
#    proxy's StartEvent to its EndEvent, the representation type, ParaView's BlendMode,
#    IsosurfaceValues, UseCropping with its CroppingOrigin, the slice plane's normal and the INR Volume refinement state read back from the
#    representation;
#  - keeps, for each new setting (mode, isovalues, cropping, plane) shown as INR Volume, the view's first
#    still image with frames (gui_blend_view_<n>.png, read back without rendering again) and a
#    picture of the whole screen, panel included (gui_blend_screen_<n>.png, when Pillow can grab
#    the X display).
import os
import threading
import time
from paraview import simple
from vtkmodules.vtkCommonCore import vtkOutputWindow
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter
from vtkmodules.vtkIOImage import vtkPNGWriter

out = os.environ["INR_GUI_OUT"]
size = [int(v) for v in os.environ.get("INR_GUI_VIEW_SIZE", "640x480").split("x")]
view = simple.GetActiveViewOrCreate("RenderView")
try:
    simple.GetLayout(view).SetSize(*size)
except Exception as e:  # noqa: BLE001
    print("layout size not set:", e)
view.OrientationAxesVisibility = 0

messages = open(os.path.join(out, "gui_blend_messages.txt"), "w")


def on_message(obj, event, data=None):
    messages.write(f"--- {event}\n{data if data is not None else ''}\n")
    messages.flush()


for event in ("WarningEvent", "ErrorEvent"):
    on_message.CallDataType = "string0"  # the message text as a string
    vtkOutputWindow.GetInstance().AddObserver(event, on_message)

log = open(os.path.join(out, "gui_blend_renders.txt"), "w")
state = {"start": None, "keys": {}}
BLEND_MODES = {0: "Composite", 5: "Isosurface", 6: "Slice"}  # vtkVolumeMapper's blend modes


def shown():
    """The view's image representation (the Python proxy) and its type, or (None, '')."""
    for rep in view.Representations:
        try:
            return rep, rep.SMProxy.GetProperty("Representation").GetElement(0)
        except AttributeError:
            continue
    return None, ""


def get(proxy, name):
    prop = proxy.GetProperty(name)
    proxy.UpdatePropertyInformation(prop)
    return prop.GetElement(0)


def view_shot(name):
    grab = vtkWindowToImageFilter()
    grab.SetInput(view.GetRenderWindow())
    grab.ShouldRerenderOff()
    grab.ReadFrontBufferOff()
    grab.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(os.path.join(out, name))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


def screen_shot(name):
    try:
        from PIL import ImageGrab
        ImageGrab.grab(xdisplay=os.environ.get("DISPLAY")).save(os.path.join(out, name))
    except Exception as e:  # noqa: BLE001  (a picture for people; the test does not need it)
        log.write(f"note screen grab failed: {e}\n")


def on_start(obj, event):
    state["start"] = time.perf_counter()


def on_end(obj, event):
    ms = 1000.0 * (time.perf_counter() - state["start"]) if state["start"] else -1.0
    state["start"] = None
    rep, kind = shown()
    if rep is None:
        return
    blend = BLEND_MODES.get(rep.SMProxy.GetProperty("BlendMode").GetElement(0), "other")
    values = rep.SMProxy.GetProperty("IsosurfaceValues")
    iso = ",".join(f"{values.GetElement(i):.6g}" for i in range(values.GetNumberOfElements()))
    crop = rep.SMProxy.GetProperty("UseCropping").GetElement(0)
    if crop:
        origin = rep.SMProxy.GetProperty("CroppingOrigin")
        crop = "1:" + ",".join(f"{origin.GetElement(i):.3g}" for i in range(3))
    plane = rep.SMProxy.GetProperty("SliceFunction").GetProxy(0)
    normal = plane.GetProperty("Normal") if plane else None
    normal = ",".join(f"{normal.GetElement(i):.3g}" for i in range(3)) if normal else "-"
    line = (f"render block_ms={ms:.1f} type={kind.replace(' ', '_')} blend={blend} iso={iso or '-'} crop={crop} "
            f"normal={normal} time={view.ViewTime:.6g}")
    if kind == "INR Volume":
        inr = rep.SMProxy.GetProperty("InrConverged").GetParent()
        frames = get(inr, "InrAccumulatedFrames")
        interactive = get(inr, "InrLastRenderInteractive")
        line += (f" mapper_ms={get(inr, 'InrLastRenderTime'):.1f} frames={frames} interactive={interactive}"
                 f" state={get(inr, 'InrRefinementState').replace(' ', '_')}")
        key = (blend, iso, crop, normal)
        if not interactive and frames >= 1 and key not in state["keys"]:
            n = state["keys"][key] = len(state["keys"])
            view_shot(f"gui_blend_view_{n}.png")
            # The screen a moment later: the panel and the window have been repainted by then.
            threading.Timer(1.5, screen_shot, args=(f"gui_blend_screen_{n}.png",)).start()
            line += f" shot={n}"
    log.write(line + "\n")
    log.flush()


view.SMProxy.AddObserver("StartEvent", on_start)
view.SMProxy.AddObserver("EndEvent", on_end)
