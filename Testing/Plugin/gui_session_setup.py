# Runs inside the ParaView GUI before the recorded session (paraview --script=gui_session_setup.py
# --test-script=gui_session.xml, see run_gui_session.py). It opens nothing itself: the recorded
# test opens the model through File > Open and Apply, as a person would. It
#  - records every message that reaches VTK's output window (what ParaView's Output Messages
#    window shows and pops up for): warnings and errors, GL errors and "Error in cache state"
#    included, to INR_GUI_OUT/gui_session_messages.txt (one block per message);
#  - logs every render of the view (INR_GUI_OUT/gui_session_renders.txt): its wall time from the
#    view proxy's StartEvent to its EndEvent (pipeline update, the representations' preparation
#    and the window's render: the event loop waits that long), when it started (CLOCK_MONOTONIC
#    seconds, the clock of the plugin's event-loop watch), the view time, and the INR Volume
#    state read back from the representation (frames, interactive, image size, backend and query
#    reduction in use);
#  - with INR_GUI_GRADIENT_OPACITY set ("G,A,..."), sets the representation's Gradient Opacity
#    after its first INR Volume render, so the rest of the session runs with it;
#  - keeps screenshots of what the view shows, read back without rendering again: the still
#    image of each step (view time, ray budget, backend) at 1, 8 and 32 frames
#    (gui_session_step<N>.png).
import os
import time
from paraview import simple
from vtkmodules.vtkCommonCore import vtkOutputWindow
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter
from vtkmodules.vtkIOImage import vtkPNGWriter

out = os.environ["INR_GUI_OUT"]
size = [int(v) for v in os.environ.get("INR_GUI_VIEW_SIZE", "960x600").split("x")]
view = simple.GetActiveViewOrCreate("RenderView")
try:
    simple.GetLayout(view).SetSize(*size)
except Exception as e:  # noqa: BLE001
    print("layout size not set:", e)
view.OrientationAxesVisibility = 0

messages = open(os.path.join(out, "gui_session_messages.txt"), "w")


def on_message(obj, event, data=None):
    messages.write(f"--- {event}\n{data if data is not None else ''}\n")
    messages.flush()


for event in ("WarningEvent", "ErrorEvent"):
    # The observer must take the call data (the message text) as a string.
    on_message.CallDataType = "string0"
    vtkOutputWindow.GetInstance().AddObserver(event, on_message)

log = open(os.path.join(out, "gui_session_renders.txt"), "w")
state = {"start": None, "steps": {}}


def inr_state():
    """The INR Volume sub-proxy of the representation shown as INR Volume, or None."""
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
    grab = vtkWindowToImageFilter()
    grab.SetInput(view.GetRenderWindow())
    grab.ShouldRerenderOff()
    grab.ReadFrontBufferOff()
    grab.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(os.path.join(out, name))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


def colour_map():
    """The colour and opacity points of the view's "value" colour map, comma-separated (or -)."""
    from paraview import servermanager
    pxm = servermanager.ProxyManager()
    for name, proxy in pxm.GetProxiesInGroup("lookup_tables").items():
        if name[0].startswith("value"):
            rgb = list(proxy.RGBPoints)
            opacity = list(proxy.ScalarOpacityFunction.Points)
            return ",".join(f"{v:.6g}" for v in rgb) + "/" + ",".join(f"{v:.6g}" for v in opacity)
    return "-"


def on_start(obj, event):
    state["start"] = time.perf_counter()
    state["start_t"] = time.monotonic()


def on_end(obj, event):
    # The whole render as the event loop waits for it: the view proxy's StartEvent (before the
    # pipeline update and the representations' render requests) to its EndEvent. What this
    # observer itself costs (reading the state back, screenshots) is logged as log_ms and
    # end= (CLOCK_MONOTONIC): the test takes it out of the event loop's stalls.
    ms = 1000.0 * (time.perf_counter() - state["start"]) if state["start"] else -1.0
    state["start"] = None
    began = time.perf_counter()
    try:
        log_render(ms)
    finally:
        log.write(f"observer log_ms={1000.0 * (time.perf_counter() - began):.1f} end={time.monotonic():.6f}\n")
        log.flush()


def inr_representation():
    """The view's representation shown as INR Volume (the Python proxy), or None."""
    for rep in view.Representations:
        try:
            if rep.Representation == "INR Volume":
                return rep
        except AttributeError:
            continue
    return None


def log_render(ms):
    inr = inr_state()
    # INR_GUI_GRADIENT_OPACITY ("G,A,..."): the representation's Gradient Opacity, set once, after
    # its first render as INR Volume (as a user would set it in the panel), so every later step
    # of the session runs with it.
    nodes = os.environ.get("INR_GUI_GRADIENT_OPACITY")
    if inr is not None and nodes and not state.get("gradient_opacity"):
        state["gradient_opacity"] = True
        inr_representation().InrGradientOpacity = [float(v) for v in nodes.split(",")]
        log.write(f"gradient_opacity set {nodes}\n")
    if inr is None:
        log.write(f"render block_ms={ms:.1f} inr=0 time={view.ViewTime:g} "
                  f"start={state.get('start_t', 0):.6f}\n")
        log.flush()
        return
    w, h = get(inr, "InrLastImageWidth"), get(inr, "InrLastImageHeight")
    frames = get(inr, "InrAccumulatedFrames")
    interactive = get(inr, "InrLastRenderInteractive")
    backend = get(inr, "InrBackendInUse").replace(" ", "_")
    reduction = get(inr, "InrQueryReductionInUse")
    budget = reduction.split(" ")[0] if reduction else "-"
    log.write(f"render block_ms={ms:.1f} inr=1 interactive={interactive} image={w}x{h} "
              f"frames={frames} mapper_ms={get(inr, 'InrLastRenderTime'):.1f} "
              f"rate={view.GetRenderWindow().GetDesiredUpdateRate():g} time={view.ViewTime:g} "
              f"{budget} backend={backend} "
              f"estimate={get(inr, 'InrConvergenceEstimateText').replace(' ', '_')} "
              f"state={get(inr, 'InrRefinementState').replace(' ', '_')} "
              f"lut={colour_map()} reduction={reduction.replace(' ', '_')} "
              f"start={state.get('start_t', 0):.6f}\n")
    log.flush()
    # The still image of each step (view time, ray budget, backend) at a few frame counts: what
    # the user sees while the step settles.
    if not interactive and w == size[0] and h == size[1] and frames in (1, 8, 32):
        step = state["steps"].setdefault((view.ViewTime, budget, backend), len(state["steps"]))
        shot(f"gui_session_step{step}.png")


view.SMProxy.AddObserver("StartEvent", on_start)
view.SMProxy.AddObserver("EndEvent", on_end)
