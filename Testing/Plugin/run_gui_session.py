"""A new user's GUI session in a real window (issue 28): no warning, no GL error.

    pvpython run_gui_session.py --paraview PARAVIEW --model MODEL.inr --out DIR [--view-size WxH]
                                [--gradient-opacity G,A,...]

Starts `paraview --script=gui_session_setup.py --test-script=DIR/gui_session.xml` (the recorded
session, written from gui_session.xml.in): File > Open, Apply, INR Volume; two time steps (Next
Frame: new macrocell slices build); a camera drag on the view; a property change in the panel
(Ray Budget = stbn); an invalid value typed in the panel (Budget Fraction 0: replaced by its
minimum, 0.01, no error); a renderer rebuild in the panel (Backend = CPU); a pause after each step.
The setup script records every message of VTK's output window (what ParaView's Output Messages
window pops up for) and every render. Checks:
  - paraview ran the whole recorded session (exit status 0, every widget found), with its panel
    checks: as INR Volume, INR Volume's rows shown and surface rows (Opacity, Line Width) hidden;
    switched to Surface at the end, the reverse;
  - NO warning and NO error reached the output window: no "Error in cache state", no OpenGL error
    (the plugin's or VTK's), nothing else (each message is printed);
  - every step reached the view: the model is shown as INR Volume, the view time moved twice, the
    drag gave interactive frames, the ray budget reached the engine (stbn in use), the rebuild
    happened (Backend In Use changed) and the view refined after each of them (several frames);
  - the panel's state reads like a person would: Convergence Estimate "NN.N dB" or a dash (never
    -inf), Refinement State "refining ..." / "interacting ..." as the session goes;
  - the model's own colours: the *.tf.json preset beside the model is the colour and opacity
    map from the first INR Volume render on (no restart: frames 1, 2, 3, ... after Apply);
  - the last still image is not empty;
  - Apply's event-loop stall (the one the first INR Volume render starts in) holds no INR Volume
    frame (the first image is drawn in a turn of the event loop of its own);
  - what the user waits for (issue 28): per step, the longest render (from the view's StartEvent
    to its EndEvent: pipeline update, preparation and drawing, during which the event loop is
    blocked) after Apply, each time step and the renderer rebuild is at most 250 ms; the first
    image after choosing INR Volume within 1 s. Printed as measured; judged only with
    --judge-times (a quiet machine: times on a shared one, CI's included, are not test
    material). The longest stall of the Qt event loop (the plugin's watch,
    INR_VOLUME_EVENT_LOOP_LOG, less this test's own observer) is printed beside it.
"""
import argparse
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

VIEWPORT = ("pqClientMainWindow/centralwidget/MultiViewWidget/CoreWidget/qt_tabwidget_stackedwidget/"
            "MultiViewWidget1/Container/Frame.0/CentralWidgetFrame/Viewport")
PANEL = ("pqClientMainWindow/propertiesDock/propertiesPanel/scrollArea/qt_scrollarea_viewport/"
         "scrollAreaWidgetContents/DisplayFrame/ProxyPanel")

# Issue 28's targets for what a user waits for (see the step checks below).
BLOCK_BOUND_MS = 250.0
FIRST_IMAGE_MS = 1000.0

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--paraview", required=True)
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--view-size", default="960x600")
ap.add_argument("--settle-ms", type=int, default=7000, help="pause after each step")
ap.add_argument("--drag-steps", type=int, default=10)
ap.add_argument("--timeout", type=float, default=400, help="seconds paraview may run")
ap.add_argument("--gradient-opacity", default="",
                help="G,A,... : the representation's Gradient Opacity, set after its first INR Volume "
                     "render (the whole session then runs with it; a manual check, no ctest)")
ap.add_argument("--judge-times", action="store_true",
                help="fail on renders over the bounds (a quiet machine); else they are printed")
args = ap.parse_args()
if not os.environ.get("DISPLAY"):
    print("plugin_gui_session skipped: no X display (DISPLAY unset; Tools/xvfb.sh starts Xvfb)")
    sys.exit(77)
here = os.path.dirname(os.path.abspath(__file__))
os.makedirs(args.out, exist_ok=True)
for f in os.listdir(args.out):
    if f.startswith("gui_session"):
        os.remove(os.path.join(args.out, f))

drag = []
for i in range(1, args.drag_steps + 1):
    x = 0.50 + 0.20 * i / args.drag_steps
    y = 0.50 + 0.05 * i / args.drag_steps
    drag.append(f'  <pqevent object="{VIEWPORT}" command="mouseMove" arguments="({x:.3f},{y:.3f},0,1,0)" />')
    drag.append('  <pqevent object="pqClientMainWindow" command="process_events" arguments="120" />')
# A loaded machine builds the fine macrocells (on the worker thread) and refines more slowly: each
# step's pause grows with the load at the start (up to 3x), so the image it checks has come.
cores = os.cpu_count() or 1
load_at_start = os.getloadavg()[0]
settle_ms = int(args.settle_ms * min(3.0, max(1.0, load_at_start / cores)))
print(f"pause after each step: {settle_ms} ms (load average {load_at_start:.1f} on {cores} cores)")
xml = open(os.path.join(here, "gui_session.xml.in")).read()
xml = (xml.replace("@MODEL@", os.path.abspath(args.model)).replace("@VIEWPORT@", VIEWPORT)
       .replace("@PANEL@", PANEL).replace("@DRAG@", "\n".join(drag))
       .replace("@SETTLE_MS@", str(settle_ms)))
xml_path = os.path.join(args.out, "gui_session.xml")
with open(xml_path, "w") as f:
    f.write(xml)

event_loop_log = os.path.join(args.out, "gui_session_event_loop.txt")
env = dict(os.environ, INR_GUI_OUT=args.out, INR_GUI_VIEW_SIZE=args.view_size,
           INR_VOLUME_EVENT_LOOP_LOG=event_loop_log, INR_VOLUME_LOD_LOG="1")
if args.gradient_opacity:
    env["INR_GUI_GRADIENT_OPACITY"] = args.gradient_opacity
cmd = [args.paraview, "--dr", f"--script={os.path.join(here, 'gui_session_setup.py')}",
       f"--test-script={xml_path}", "--exit"]
load_before = os.getloadavg()[0]
p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                   timeout=args.timeout)
with open(os.path.join(args.out, "gui_session_paraview.log"), "w") as f:
    f.write(p.stdout)

check = C.Checks()
check(p.returncode == 0, f"paraview exit status {p.returncode}")
check("Success =  true" in p.stdout or "Success = true" in p.stdout,
      "the recorded session played to the end (every widget found)")

# --- Messages of VTK's output window: there must be none.
path = os.path.join(args.out, "gui_session_messages.txt")
text = open(path).read() if os.path.exists(path) else None
check(text is not None, "the output window was observed")
blocks = [b.strip() for b in (text or "").split("--- ") if b.strip()]
kinds = {}
for b in blocks:
    first = b.splitlines()[0]
    body = " ".join(b.splitlines()[1:])
    key = ("Error in cache state" if "Error in cache state" in body else
           "OpenGL error" if re.search(r"OpenGL errors?|GL error|glGetError|1282", body) else first)
    kinds[key] = kinds.get(key, 0) + 1
for b in blocks[:6]:
    print("message:", b[:600].replace("\n", " | "))
print(f"{len(blocks)} message(s) in the output window: {kinds}")
check(not any(k == "Error in cache state" for k in kinds), f"no 'Error in cache state' ({kinds.get('Error in cache state', 0)})")
check(not any(k == "OpenGL error" for k in kinds), f"no OpenGL error ({kinds.get('OpenGL error', 0)})")
check(not blocks, f"no warning or error at all in the output window ({len(blocks)})")

# --- The steps reached the view.
# observer: (end, ms) of what the test's own render observer cost (taken out of the stalls).
renders, observer = C.read_render_log(os.path.join(args.out, "gui_session_renders.txt"))
for r in renders:
    r.setdefault("budget", "-")
inr = [r for r in renders if r.get("inr") == "1"]
if args.gradient_opacity:
    set_line = open(os.path.join(args.out, "gui_session_renders.txt")).read().count("gradient_opacity set")
    check(set_line == 1, f"Gradient Opacity set on the representation once ({set_line})")
print(f"{len(renders)} renders, {len(inr)} with INR Volume shown")
check(len(inr) >= 5, "the model was shown as INR Volume")
times = []
for r in inr:
    if not times or times[-1] != r["time"]:
        times.append(r["time"])
check(len(times) >= 3, f"the view time moved twice ({times})")
drag = [r for r in inr if r["interactive"] == "1" and float(r["rate"]) >= 1.0]
check(len(drag) >= 3, f"the camera drag rendered interactive frames ({len(drag)})")
stbn = [i for i, r in enumerate(inr) if r["budget"] == "stbn"]
check(bool(stbn), "the panel's Ray Budget = stbn reached the engine")
# Budget Fraction 0 typed in the panel: replaced by the property's minimum (0.01) at once, so
# the engine never refuses it (no error above) and uses rho=0.01.
rho = [r.get("reduction", "") for r in inr[stbn[0]:]] if stbn else []
check(any("rho=0.01_" in x for x in rho), "Budget Fraction 0 typed in the panel becomes 0.01 in the engine")
backends = []
for r in inr:
    if not backends or backends[-1] != r["backend"]:
        backends.append(r["backend"])
check(len(backends) >= 2, f"the panel's Backend change rebuilt the renderer ({backends})")


# The state a user reads in the panel: an estimate in dB or a dash, never -inf; a refinement state
# that says what happens.
estimates = sorted({r.get("estimate", "") for r in inr})
print("convergence estimates seen:", estimates[:4], "...", estimates[-3:])
check(bool(inr) and all(re.fullmatch(r"\d+\.\d_dB|\u2014|no_noise_left", r.get("estimate", "")) for r in inr),
      "Convergence Estimate reads as 'NN.N dB' or a dash (never -inf)")
check(any(r.get("estimate", "").endswith("_dB") for r in inr), "Convergence Estimate becomes known (dB)")
states = {r.get("state", "").split(":")[0] for r in inr}
print("refinement states seen:", sorted(states))
check({"refining", "interacting"} <= states, f"Refinement State says refining and interacting ({sorted(states)})")


# The model's own colours: the *.tf.json beside the model is the colour and opacity map from the
# first INR Volume render on, and applying it did not restart the image (the frames after Apply
# grow without a reset until the first time step).
tf_path = os.path.splitext(os.path.abspath(args.model))[0] + ".tf.json"
if os.path.exists(tf_path):
    import json
    preset = json.load(open(tf_path))[0]
    want = (",".join(f"{v:.6g}" for v in preset["RGBPoints"]) + "/" +
            ",".join(f"{v:.6g}" for v in preset["Points"]))
    first = inr[0].get("lut", "-") if inr else "-"
    check(first == want, f"the first INR Volume render uses the model's {os.path.basename(tf_path)} "
          f"(colour map {first[:60]}...)")
    check(all(r.get("lut") == want for r in inr), "the model's colour map stays during the session")
    # (Renders that find the worker's refinement step still running show the image they have:
    # the same count again, or 0 before the first full-resolution frame.)
    apply_frames = []
    for r in inr:
        if r["time"] == inr[0]["time"] and r["interactive"] == "0" and int(r["frames"]) > 0:
            if not apply_frames or apply_frames[-1] != int(r["frames"]):
                apply_frames.append(int(r["frames"]))
    check(bool(apply_frames) and apply_frames == list(range(1, len(apply_frames) + 1)),
          f"after Apply the image accumulates from frame 1 without a restart ({apply_frames[:8]}...)")
else:
    print(f"note: no {tf_path}: the model's own colours are not checked")


def refined(segment):
    # Frames of what the view shows: the full-resolution image, or (while the fine macrocells of
    # a new time build in the background) the reduced image of the coarse ones.
    return max((int(r["frames"]) for r in segment), default=0)


# After each step the view refines by itself (frames accumulate): the time steps, the drag, the
# property change and the rebuild.
marks = [("apply", 0)]
for t in times[1:]:
    marks.append((f"time {t}", next(i for i, r in enumerate(inr) if r["time"] == t)))
if drag:
    marks.append(("drag", inr.index(drag[-1]) + 1))
if stbn:
    marks.append(("ray budget", stbn[0]))
if len(backends) >= 2:
    marks.append(("rebuild", next(i for i, r in enumerate(inr) if r["backend"] == backends[-1])))
marks.sort(key=lambda m: m[1])
# Stalls of the event loop (the plugin's watch, INR_VOLUME_EVENT_LOOP_LOG): each belongs to the
# step in whose time it ended (a stall that began in Apply's pipeline update and ended after the
# first render is Apply's), each less what the test's own render observer spent inside it.
watched = C.read_event_loop_stalls(event_loop_log, observer)
stalls = [(end, ms) for _, end, ms in watched]
# Apply's stall: the one in which the first INR Volume render started (the representation
# change, in Apply's turn of the event loop); None when it held the loop under the watch's 40 ms.
first_inr = float(inr[0]["start"]) if inr else None
apply_stall = next(((b, e) for b, e, _ in watched if first_inr is not None and b <= first_inr <= e), None)
check(os.path.exists(event_loop_log), "the plugin's event-loop watch ran (INR_VOLUME_EVENT_LOOP_LOG)")
first_start = min((float(r["start"]) for r in renders if float(r.get("start", 0)) > 0), default=0.0)
longest = {}
for k, ((name, start), (_, end)) in enumerate(zip(marks, marks[1:] + [("end", len(inr))])):
    segment = inr[start:end]
    blocks_ms = [float(r["block_ms"]) for r in segment]
    t0 = first_start if k == 0 else float(segment[0]["start"]) if segment else 0.0
    t1 = float(inr[end]["start"]) if end < len(inr) else float("inf")
    stall_ms = [ms for t, ms in stalls if t0 <= t < t1]
    longest[name] = (max(blocks_ms, default=0.0), max(stall_ms, default=0.0))
    print(f"step {name}: {len(segment)} renders, longest render {max(blocks_ms, default=0):.0f} ms, "
          f"longest event-loop stall {max(stall_ms, default=0):.0f} ms "
          f"({sum(ms > BLOCK_BOUND_MS for ms in blocks_ms + stall_ms)} over {BLOCK_BOUND_MS:.0f} ms), "
          f"frames reached {refined(segment)}")
    check(refined(segment) >= 3, f"the view refined after '{name}' (frames {refined(segment)})")
# Apply's stall (ParaView's Apply: pipeline update, representation, panel) holds no INR Volume
# frame: the GUI's first render of the mapper is put off one turn of the event loop, so the first
# image is drawn in a turn of its own (before: the engine, the macrocells and the first frame ran
# inside Apply's stall, 0.8-1 s in all).
if apply_stall:
    b, e = apply_stall
    drawn = [r for r in inr if b <= float(r["start"]) <= e and int(r["frames"]) > 0]
    check(not drawn, f"Apply's event-loop stall ({1000 * (e - b):.0f} ms) holds no INR Volume frame "
          f"({len(drawn)} render(s) with frames in it)")
else:
    print("Apply's first INR Volume render was in no logged event-loop stall (none over 40 ms)")

# What a user waits for (issue 28): no render and no other stall of the event loop longer than
# the bound while Apply, a time step or a renderer rebuild settles (the long macrocell builds run
# on a worker thread; the view keeps an image meanwhile).
# The renders' times are printed, and judged only with --judge-times (a quiet machine): on a
# machine doing little else no render after Apply, a time step or a rebuild may exceed the bound
# (a render that waits for a whole full-resolution frame, or builds slices, does: 0.7-1.4 s before
# the worker thread took them). A loaded machine (CI's is shared) makes any such bound flaky. The
# event loop's stalls are printed: they also hold ParaView's own work (Apply's, as long as for a
# plain grid: Benchmarks/paraview/apply_stall.py).
load = max(load_before, os.getloadavg()[0])
print(f"load average {load:.1f} on {cores} cores")
timed = C.TimedChecks(check, args.judge_times)


for name, (render_ms, stall_ms) in longest.items():
    if name == "apply" or name.startswith("time") or name == "rebuild":
        timed(render_ms <= BLOCK_BOUND_MS,
              f"no render after '{name}' holds the event loop over {BLOCK_BOUND_MS:.0f} ms "
              f"(longest {render_ms:.0f} ms; longest stall of the event loop {stall_ms:.0f} ms, not judged)")
# The first image once INR Volume is chosen (coarse is fine): from the moment the GUI took the
# representation change (the start of the event-loop stall the first INR Volume render ends,
# else that render's start) to the end of the first render that drew frames.
first_image = next((r for r in inr if int(r["frames"]) > 0), None)
if first_image and inr:
    chosen = apply_stall[0] if apply_stall else float(inr[0]["start"])
    first_ms = 1000.0 * (float(first_image["start"]) - chosen) + float(first_image["block_ms"])
    print(f"first INR Volume image {first_ms:.0f} ms after the representation change was taken")
    timed(first_ms <= FIRST_IMAGE_MS,
          f"first image after choosing INR Volume within "
          f"{FIRST_IMAGE_MS:.0f} ms ({first_ms:.0f} ms)")
# The fine macrocells of the last time were built (in the background in the GUI) and the view
# shows the full-resolution image at that time.
last_still = [r for r in inr if r["time"] == times[-1] and r["interactive"] == "0" and
              r["image"] == args.view_size]
check(bool(last_still), f"full-resolution still renders at the last time ({len(last_still)})")
all_ms = [float(r["block_ms"]) for r in renders if float(r["block_ms"]) >= 0]
print(f"longest render of the session (event loop blocked): {max(all_ms, default=0):.0f} ms "
      f"(not judged; {sum(ms > 250 for ms in all_ms)} of {len(all_ms)} renders over 250 ms)")

shots = sorted(f for f in os.listdir(args.out) if f.startswith("gui_session_step") and f.endswith(".png"))
print("screenshots:", shots)
if shots:
    import numpy as np
    last = max(shots, key=lambda f: os.path.getmtime(os.path.join(args.out, f)))
    a = C.read_png(os.path.join(args.out, last))
    differs = float(np.mean(np.any(np.abs(a - a[0, 0]) > 8, axis=2)))
    check(differs >= 0.01, f"{last} is not empty ({100 * differs:.1f}% of pixels differ from the background)")
else:
    check(False, "still screenshots saved")
if check.failures:
    print(p.stdout[-3000:])
sys.stdout.flush()
os._exit(check.report())
