"""The INR Volume panel through paraview.simple (issue 12, items 2 and 3):
 - the five property groups ParaView loaded, in order, with the new options where they belong;
 - the defaults ParaView gives each new property are the XML's and reach the engine unchanged
   (read back through the information property InrMacrocellsInUse);
 - each new property set by its documented Python name reaches the engine (skip block and bounds
   padding rebuild the macrocells; ghost passes and macrocell refinement keep the accumulation);
 - invalid values are refused with an error naming the property, the previous value kept;
 - Progressive Refinement off: one frame per render, reported as converged (nothing re-renders);
 - ParaView's own progress handler (what moves the GUI's progress bar) sees the macrocell builds
   of a render and the reader's preview resampling.
Exit status 0 = pass.

  pvpython pv_panel_options.py --model M.inr --xml InrVolumeRepresentation.xml [--plugin InrVolume.so]
"""
import argparse
import os
import sys
import time
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--model", required=True)
ap.add_argument("--xml", required=True)
ap.add_argument("--plugin", default="")
args = ap.parse_args()

from paraview import servermanager, simple  # noqa: E402
from vtkmodules.util.misc import calldata_type  # noqa: E402
from vtkmodules.vtkCommonCore import VTK_STRING, vtkOutputWindow  # noqa: E402

C.load_plugin(args.plugin, remote=False)
check = C.Checks()

# Errors reported through VTK (vtkErrorMacro) while the script runs.
errors = []


@calldata_type(VTK_STRING)
def on_error(obj, event, text):
    errors.append(text)


vtkOutputWindow.GetInstance().AddObserver("ErrorEvent", on_error)

# What ParaView's progress handler reports (its LastProgress / LastProgressText are only valid
# inside its ProgressEvent).
progress_handler = servermanager.ActiveConnection.Session.GetProgressHandler()
progress = []


def on_progress(handler, event):
    progress.append((handler.GetLastProgressText() or "", handler.GetLastProgress()))


progress_handler.AddObserver("ProgressEvent", on_progress)


def in_use(display):
    """InrMacrocellsInUse ("dims=8x8x8 slices=16 skip_block=4 ...") as a dict of strings."""
    text = C.info(display, "InrMacrocellsInUse")
    return dict(item.split("=", 1) for item in text.split())


def expect_in_use(display, want, what):
    got = in_use(display)
    bad = {k: (got.get(k), v) for k, v in want.items() if got.get(k) is None or float(got[k]) != float(v)}
    check(not bad, f"{what}: engine holds {got}" + (f", mismatches (got, want): {bad}" if bad else ""))


SIZE = [64, 48]
reader = simple.OpenDataFile(args.model)
view = C.setup_view(SIZE)
display = C.show_inr(reader, view, seed=3, maximum_frames=64, frames_per_render=1, macrocells=8)
# One frame per render (the checks below count frames render by render): no time budget.
display.InrRefinementTimeBudget = 0.0

# --- The panel ParaView loaded: five groups in order, the new options in theirs.
proxy = display.SMProxy
groups = {}
order = []
for i in range(proxy.GetNumberOfPropertyGroups()):
    g = proxy.GetPropertyGroup(i)
    members = [g.GetProperty(k) for k in range(g.GetNumberOfProperties())]
    groups[g.GetXMLLabel()] = members
    order.append(g.GetXMLLabel())
inr_groups = [label for label in order if label in ("Rendering", "Macrocells", "Shadows", "Query reduction",
                                                    "Refinement")]
check(inr_groups == ["Rendering", "Macrocells", "Shadows", "Query reduction", "Refinement"],
      f"the INR Volume groups in panel order: {inr_groups}")
placement = {"InrSkipBlock": "Macrocells", "InrBoundsPadding": "Macrocells", "InrGhostPasses": "Macrocells",
             "InrRefineMacrocells": "Macrocells", "InrMacrocellsInUse": "Macrocells",
             "InrProgressiveRefinement": "Refinement", "InrBackend": "Rendering", "InrShadows": "Shadows",
             "InrTraversal": "Rendering"}
for name, label in placement.items():
    check(proxy.GetProperty(name) in groups.get(label, []), f"{name} is in the {label!r} group")

# --- Defaults: ParaView's values are the XML's, and the engine holds them after the first render.
root = ET.parse(args.xml).getroot()
xml_defaults = {e.get("name"): e.get("default_values") for e in root.iter() if e.get("default_values") is not None}
new_options = ["InrSkipBlock", "InrBoundsPadding", "InrGhostPasses", "InrRefineMacrocells",
               "InrProgressiveRefinement"]
for name in new_options:
    got = display.GetPropertyValue(name)
    check(float(got) == float(xml_defaults[name]), f"{name} starts at the XML default {xml_defaults[name]} ({got})")
traversal = proxy.GetProperty("InrTraversal")  # an enumeration: its integer through the SM property
check(traversal.GetElement(0) == int(xml_defaults["InrTraversal"]),
      f"InrTraversal starts at the XML default {xml_defaults['InrTraversal']} ({traversal.GetElement(0)})")
check(display.InrTraversal.GetData() == "Auto", f"InrTraversal reads as Auto ({display.InrTraversal.GetData()})")
simple.Render(view)
expect_in_use(display, {"skip_block": xml_defaults["InrSkipBlock"],
                        "bounds_padding": xml_defaults["InrBoundsPadding"],
                        "ghost_passes": xml_defaults["InrGhostPasses"],
                        "refine": xml_defaults["InrRefineMacrocells"], "slices": xml_defaults["InrTemporalSlices"]},
              "the XML defaults reach the engine")
check(in_use(display).get("dims") == "8x8x8", f"InrMacrocellResolution = 8 reaches the engine ({in_use(display)})")

# --- Each option by its Python name.
display.InrSkipBlock = 8
display.InrBoundsPadding = 0.05
simple.Render(view)
expect_in_use(display, {"skip_block": 8, "bounds_padding": 0.05}, "InrSkipBlock = 8, InrBoundsPadding = 0.05")
check(C.info(display, "InrAccumulatedFrames") == 1, "a macrocell rebuild starts a new image")
simple.Render(view)
before = C.info(display, "InrAccumulatedFrames")
display.InrGhostPasses = 3
display.InrRefineMacrocells = 0
simple.Render(view)
expect_in_use(display, {"ghost_passes": 3, "refine": 0}, "InrGhostPasses = 3, InrRefineMacrocells = 0")
after = C.info(display, "InrAccumulatedFrames")
check(after == before + 1, f"ghost passes and refinement keep the engine and the image ({before} -> {after} frames)")
display.InrSkipBlock = 0
display.InrRefineMacrocells = 1
simple.Render(view)
expect_in_use(display, {"skip_block": 0, "refine": 1}, "InrSkipBlock = 0 (off), InrRefineMacrocells = 1")

# --- Invalid values: refused, named, the previous value kept.
for name, bad, key, kept in (("InrSkipBlock", 3, "skip_block", 0), ("InrBoundsPadding", -0.5, "bounds_padding", 0.05),
                             ("InrGhostPasses", 5000, "ghost_passes", 3)):
    del errors[:]
    display.SetPropertyWithName(name, bad)
    simple.Render(view)
    expect_in_use(display, {key: kept}, f"{name} = {bad} is refused, {key} stays {kept}")
    named = [e for e in errors if name in e and "refused" in e]
    check(len(named) == 1, f"{name} = {bad}: one error naming the property: {named or errors}")
    display.SetPropertyWithName(name, kept)
simple.Render(view)
del errors[:]
simple.Render(view)
check(not errors, f"valid values again: no more errors ({errors})")

# --- GPU traversal: a new one rebuilds the renderer (a new image); the CPU backend runs the DDA
# whatever is chosen, so the choice never fails here.
simple.Render(view)
check(C.info(display, "InrAccumulatedFrames") > 1, "accumulating before the traversal change")
del errors[:]
# The panel offers OptiX only where this build has it (the plugin's XML is generated without the
# entry otherwise); a script can still ask for it by number (value 2: the engine falls back).
domain = traversal.GetDomain("enum")
entries = [domain.GetEntryText(i) for i in range(domain.GetNumberOfEntries())]
print(f"GPU Traversal entries offered by this build: {entries}")
check(entries[:2] == ["Auto", "DDA"], f"GPU Traversal offers Auto and DDA ({entries})")
if "OptiX" in entries:
    display.InrTraversal = "OptiX"
else:
    traversal.SetElement(0, 2)
    display.SMProxy.UpdateVTKObjects()
simple.Render(view)
check(traversal.GetElement(0) == 2, f"InrTraversal = 'OptiX' is value 2 ({traversal.GetElement(0)})")
check(C.info(display, "InrAccumulatedFrames") == 1, "InrTraversal = OptiX rebuilds the renderer (a new image)")
check(not errors, f"InrTraversal = OptiX: no error ({errors})")
display.InrTraversal = "Auto"
simple.Render(view)

# --- Progressive refinement off: exactly one frame per render, never "still refining".
display.InrFramesPerRender = 4
display.InrProgressiveRefinement = 0
display.InrSeed = 4  # a new seed restarts the image
simple.Render(view)
frames = C.info(display, "InrAccumulatedFrames")
check(frames == 1, f"refinement off: one frame per render, Frames Per Render ignored ({frames})")
check(C.info(display, "InrConverged") == 1, "refinement off: reported as stopped (the GUI does not re-render)")
simple.Render(view)
frames = C.info(display, "InrAccumulatedFrames")
check(frames == 2, f"refinement off: the next render adds one more ({frames})")
display.InrProgressiveRefinement = 1
simple.Render(view)
frames = C.info(display, "InrAccumulatedFrames")
check(frames == 4, f"refinement on again: Frames Per Render honoured ({frames})")
check(C.info(display, "InrConverged") == 0, "refinement on again: still refining below Maximum Frames")

# --- ParaView's progress handler sees the macrocell builds of a render and the reader's preview.
# It forwards at most one event per 0.1 s (vtkPVProgressHandler's interval in a client): each
# step starts with a pause, so its first event (0 %) always gets through.
def building(events):
    return [p for text, p in events if text == "INR macrocells"]


del progress[:]
time.sleep(0.3)
display.InrMacrocellResolution = 128  # a rebuild: 2 slices of 128^3 cells
simple.Render(view)
seen = building(progress)
check(len(seen) >= 1 and seen == sorted(seen),
      f"resolution change: ParaView's progress handler saw the build ({seen} %, non-decreasing)")
del progress[:]
time.sleep(0.3)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.AnimationTime = 9.3  # slices not built yet
simple.Render(view)
seen = building(progress)
check(len(seen) >= 1 and seen == sorted(seen), f"time change: ParaView's progress handler saw the build ({seen} %)")
del progress[:]
time.sleep(0.3)
reader.PreviewResolution = 160  # about a second of sampling here: several 0.1 s intervals
reader.UpdatePipeline(9.3)
seen = [p for text, p in progress if text.startswith("INR Volume reader")]
check(len(seen) >= 1, f"preview resampling: ParaView's progress handler saw the reader ({seen} %)")
# Where the preview ran: Auto takes the GPU where a usable one is, else the CPU with the reason.
reader.UpdatePropertyInformation()
in_use = reader.GetPropertyValue("PreviewBackendInUse")
check(reader.PreviewBackend == "Auto", f"Preview Backend defaults to Auto ({reader.PreviewBackend})")
check(in_use.startswith("CUDA: ") or in_use.startswith("CPU (CUDA unavailable: "),
      f"Preview Backend In Use under Auto names the GPU or why not: {in_use!r}")
if in_use.startswith("CPU (CUDA unavailable: "):
    # CUDA asked for without a usable GPU: the preview (and the model downstream) still comes, on
    # the CPU, and the property says why.
    reader.PreviewBackend = "CUDA"
    reader.PreviewResolution = 10
    reader.UpdatePipeline(9.3)
    reader.UpdatePropertyInformation()
    cuda_in_use = reader.GetPropertyValue("PreviewBackendInUse")
    data = reader.GetPointDataInformation().GetArray("value")
    check(cuda_in_use.startswith("CPU (preview on the GPU requested but CUDA is unavailable"),
          f"Preview Backend CUDA without a GPU: on the CPU, saying why ({cuda_in_use!r})")
    check(data is not None and data.GetNumberOfTuples() == 1000,
          f"Preview Backend CUDA without a GPU: the 10^3 preview is there "
          f"({data.GetNumberOfTuples() if data is not None else None} values)")
reader.PreviewBackend = "CPU"
reader.PreviewResolution = 12
reader.UpdatePipeline(9.3)
reader.UpdatePropertyInformation()
in_use = reader.GetPropertyValue("PreviewBackendInUse")
check(in_use == "CPU", f"Preview Backend CPU: the preview ran on the CPU ({in_use!r})")

status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
