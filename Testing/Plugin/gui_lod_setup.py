# Runs inside the ParaView GUI before the recorded test (paraview --script=gui_lod_setup.py
# --test-script=gui_lod.xml): fixes the render view at INR_GUI_VIEW_SIZE (preview mode, as
# View > Preview does) and, after every render of the view, logs one line to INR_GUI_OUT/
# gui_lod_renders.txt (interactive flag, image size, accumulated frames, mapper ms, update ms, the
# render window's desired update rate) and keeps screenshots of what the window shows, read back
# without rendering again: the first interactive frame of the camera drag
# (gui_lod_interactive.png), the first of the animation playback (gui_lod_playback.png) and the
# latest full-resolution still frame (gui_lod_still.png). It opens nothing: the recorded test
# opens the model through File > Open and Apply, as a person would.
import os
import time
from paraview import simple
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter
from vtkmodules.vtkIOImage import vtkPNGWriter

out = os.environ["INR_GUI_OUT"]
size = [int(v) for v in os.environ.get("INR_GUI_VIEW_SIZE", "1280x768").split("x")]
view = simple.GetActiveViewOrCreate("RenderView")
try:
    simple.GetLayout(view).SetSize(*size)
except Exception as e:  # noqa: BLE001
    print("layout size not set:", e)
view.OrientationAxesVisibility = 0
log = open(os.path.join(out, "gui_lod_renders.txt"), "w")
state = {"interactive_shot": False, "playback_shot": False, "drag_seen": False, "still": 0}


def inr_state():
    """The INR Volume sub-proxy of the first representation shown as INR Volume, or None."""
    for rep in view.Representations:
        try:
            if rep.Representation != "INR Volume":
                continue
        except AttributeError:
            continue
        return rep.SMProxy.GetProperty("InrConverged").GetParent()
    return None


def get(proxy, name):
    prop = proxy.GetProperty(name)
    proxy.UpdatePropertyInformation(prop)
    return prop.GetElement(0)


def shot(name):
    window = view.GetRenderWindow()
    grab = vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.ShouldRerenderOff()
    grab.ReadFrontBufferOff()
    grab.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(os.path.join(out, name))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


def on_start(obj, event):
    state["start"] = time.perf_counter()


def on_end(obj, event):
    # The window's whole render (the event loop waits that long during a drag).
    block_ms = 1000.0 * (time.perf_counter() - state["start"]) if state.get("start") else -1.0
    state["start"] = None
    inr = inr_state()
    if inr is None:
        return
    rate = view.GetRenderWindow().GetDesiredUpdateRate()
    interactive = get(inr, "InrLastRenderInteractive")
    w, h = get(inr, "InrLastImageWidth"), get(inr, "InrLastImageHeight")
    frames = get(inr, "InrAccumulatedFrames")
    log.write(f"render interactive={interactive} image={w}x{h} frames={frames} "
              f"ms={get(inr, 'InrLastRenderTime'):.1f} update_ms={get(inr, 'InrLastUpdateTime'):.1f} "
              f"rate={rate:g} time={view.ViewTime:g} block_ms={block_ms:.1f}\n")
    log.flush()
    if interactive and rate >= 1.0:
        state["drag_seen"] = True
        if not state["interactive_shot"]:
            shot("gui_lod_interactive.png")
            state["interactive_shot"] = True
    elif interactive and state["drag_seen"] and not state["playback_shot"]:
        shot("gui_lod_playback.png")
        state["playback_shot"] = True
    elif not interactive and w == size[0] and h == size[1] and frames > 0:
        state["still"] += 1
        if state["still"] % 4 == 1 or frames in (2, 4, 8, 16, 32, 64):
            shot("gui_lod_still.png")


view.GetRenderWindow().AddObserver("StartEvent", on_start)
view.GetRenderWindow().AddObserver("EndEvent", on_end)
