"""GUI test of the interactive level of detail, through the real window (issue 12 items 1 and 5).

    pvpython run_gui_lod.py --paraview PARAVIEW --model MODEL.inr --out DIR [--target-ms 100]

Starts `paraview --script=gui_lod_setup.py --test-script=DIR/gui_lod.xml` (the recorded test,
written from gui_lod.xml.in with the model's path): File > Open, Apply, INR Volume, a pause, a
camera drag on the view (mouse press, moves, release), a pause, animation playback (Play) to the
end time, Last Frame, a pause. The mapper logs every render (INR_VOLUME_LOD_LOG=1); the setup
script logs each render's state and keeps screenshots. Checks:
  - the view has the requested size (the timing claim is for it) and the model shows up
    (the last still screenshot is not empty);
  - the drag was rendered as reduced interactive frames, with no full-resolution render in
    between, not even while the mouse rests mid-drag with its button down (--pause-ms: the GUI
    refines the reduced image there), no window render over 250 ms, and their logged times
    meet the target: median <= target, 90th percentile <= 1.5 x target. These time checks are
    printed as measured and judged only with --judge-times (a quiet machine; CI's is shared and
    Benchmarks/paraview/interactive_lod.py measures properly); always judged: drag frames cost
    at most half a full-resolution frame; no full-resolution render mid-drag is judged unless the
    machine is loaded beyond twice its cores;
  - playback rendered time changes as interactive frames and their times meet the same target,
    first visits of a time included: the coarse interactive macrocell slices were built ahead
    (InrInteractiveMacrocellsAhead, in the first still render), so no playback frame builds
    slices (its macrocell update, working grid and majorants, stays under 10 ms);
  - each playback time step was rendered once (the animation tick's own render: the GUI's
    refinement waits while the animation plays), on the coarse interactive macrocells;
  - after the interaction stopped the view refined by itself at full resolution (accumulated
    frames grew to at least 1 after the last interactive frame, and to at least 2 — the
    refinement goes on past its first step — unless the machine is loaded beyond twice its cores;
    --settle-ms leaves time for two full-resolution frames of the shipped default estimator on 2
    cores, RESULTS-archive.md "Test bounds (the debiased march as the default)").
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

VIEWPORT = ("pqClientMainWindow/centralwidget/MultiViewWidget/CoreWidget/qt_tabwidget_stackedwidget/"
            "MultiViewWidget1/Container/Frame.0/CentralWidgetFrame/Viewport")

# Issue 28: no multi-hundred-ms hitch during a drag, its pauses included.
DRAG_BLOCK_BOUND_MS = 250.0

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--paraview", required=True)
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--target-ms", type=float, default=100.0)
ap.add_argument("--judge-times", action="store_true",
                help="fail on frame times over the target (a quiet machine); else they are printed")
ap.add_argument("--view-size", default="1280x768")
ap.add_argument("--drag-steps", type=int, default=12)
ap.add_argument("--pause-ms", type=int, default=1500,
                help="the mouse rests this long in the middle of the drag, button down (0: no pause)")
ap.add_argument("--play-ms", type=int, default=20000, help="pause while the animation plays")
ap.add_argument("--timeout", type=float, default=240, help="seconds paraview may run")
ap.add_argument("--settle-ms", type=int, default=40000, help="pause after the interaction")
args = ap.parse_args()
here = os.path.dirname(os.path.abspath(__file__))
os.makedirs(args.out, exist_ok=True)
for f in os.listdir(args.out):
    if f.startswith("gui_lod"):
        os.remove(os.path.join(args.out, f))

drag = []
for i in range(1, args.drag_steps + 1):
    x = 0.50 + 0.20 * i / args.drag_steps
    y = 0.50 + 0.05 * i / args.drag_steps
    drag.append(f'  <pqevent object="{VIEWPORT}" command="mouseMove" arguments="({x:.3f},{y:.3f},0,1,0)" />')
    drag.append('  <pqevent object="pqClientMainWindow" command="process_events" arguments="120" />')
    if i == args.drag_steps // 2 and args.pause_ms > 0:
        # The mouse rests mid-drag, its button still down.
        drag.append(f'  <pqevent object="pqClientMainWindow" command="process_events" arguments="{args.pause_ms}" />')
xml = open(os.path.join(here, "gui_lod.xml.in")).read()
xml = (xml.replace("@MODEL@", os.path.abspath(args.model)).replace("@VIEWPORT@", VIEWPORT)
       .replace("@DRAG@", "\n".join(drag)).replace("@PLAY_MS@", str(args.play_ms))
       .replace("@SETTLE_MS@", str(args.settle_ms)))
xml_path = os.path.join(args.out, "gui_lod.xml")
with open(xml_path, "w") as f:
    f.write(xml)

env = dict(os.environ, INR_GUI_OUT=args.out, INR_GUI_VIEW_SIZE=args.view_size, INR_VOLUME_LOD_LOG="1")
cmd = [args.paraview, "--dr", f"--script={os.path.join(here, 'gui_lod_setup.py')}",
       f"--test-script={xml_path}", "--exit"]
load_before = os.getloadavg()[0]
p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=args.timeout)
load_after = os.getloadavg()[0]
with open(os.path.join(args.out, "gui_lod_paraview.log"), "w") as f:
    f.write(p.stdout)

check = C.Checks()
# Frame times and event-loop holds are printed, and judged only with --judge-times (a quiet
# machine; Benchmarks/paraview/interactive_lod.py measures them properly): on a machine shared
# with builds or other tests every frame is slower and GUI events arrive late enough for the
# refinement timer to fire between them. A relative check stands in: interactive frames must cost
# well under the full-resolution frames.
cores = os.cpu_count() or 1
load = max(load_before, load_after)
print(f"load average {load:.1f} on {cores} cores")
timed = C.TimedChecks(check, args.judge_times)


check(p.returncode == 0, f"paraview exit status {p.returncode}")
lod = re.compile(r"INR Volume LOD: (interactive|still) frame (\d+)x(\d+) of (\d+)x(\d+) \(scale [\d.]+\), "
                 r"([\d.]+) ms \(budget ([\d.]+) ms; macrocell update ([\d.]+) ms")
frames_log = []
for line in p.stdout.splitlines():
    m = lod.search(line)
    if m:
        frames_log.append(dict(kind=m.group(1), w=int(m.group(2)), h=int(m.group(3)), vw=int(m.group(4)),
                               vh=int(m.group(5)), ms=float(m.group(6)), update=float(m.group(8)),
                               coarse=line.rstrip().endswith("coarse macrocells"),
                               worker="refining on the worker" in line))
renders = []
path = os.path.join(args.out, "gui_lod_renders.txt")
if os.path.exists(path):
    for line in open(path):
        kv = dict(item.split("=", 1) for item in line.split()[1:])
        w, h = kv["image"].split("x")
        renders.append(dict(interactive=int(kv["interactive"]), w=int(w), h=int(h), frames=int(kv["frames"]),
                            ms=float(kv["ms"]), update=float(kv["update_ms"]), rate=float(kv["rate"]),
                            time=float(kv["time"]), block=float(kv.get("block_ms", -1))))
print(f"{len(frames_log)} renders logged by the mapper, {len(renders)} by the view observer")
vw, vh = (int(v) for v in args.view_size.split("x"))
check(bool(frames_log) and all(f["vw"] == vw and f["vh"] == vh for f in frames_log[-5:]),
      f"the view is {args.view_size} (mapper saw {frames_log[-1]['vw']}x{frames_log[-1]['vh']})"
      if frames_log else "the mapper rendered")


def describe(values):
    v = sorted(values)
    return (f"n={len(v)} median {statistics.median(v):.1f} p90 {v[int(0.9 * (len(v) - 1))]:.1f} "
            f"max {v[-1]:.1f} ms") if v else "none"


def meets(values):
    v = sorted(values)
    return bool(v) and statistics.median(v) <= args.target_ms and v[int(0.9 * (len(v) - 1))] <= 1.5 * args.target_ms


drag = [r for r in renders if r["interactive"] and r["rate"] >= 1.0]
first_drag = next((i for i, r in enumerate(renders) if r["interactive"] and r["rate"] >= 1.0), None)
last_drag = max((i for i, r in enumerate(renders) if r["interactive"] and r["rate"] >= 1.0), default=None)
print("camera drag:", describe([r["ms"] for r in drag]),
      "images", sorted({f"{r['w']}x{r['h']}" for r in drag}))
check(len(drag) >= 5, f"the camera drag gave interactive renders ({len(drag)})")
check(all(r["w"] < vw for r in drag), "drag frames are reduced")
timed(meets([r["ms"] for r in drag]), f"drag frame times meet {args.target_ms:g} ms (median; p90 <= 1.5x)")
if first_drag is not None:
    # The drag includes a rest of the mouse with its button down (--pause-ms): the GUI refines the
    # reduced image there instead of rendering a full-resolution frame that the resumed drag
    # would wait for.
    between = [r for r in renders[first_drag:last_drag + 1] if not r["interactive"]]
    # What the refinement behaviour decides, not a time: judged unless the machine is loaded
    # beyond twice its cores (there GUI events arrive late enough for the refinement timer to fire
    # between them), or with --judge-times.
    (check if args.judge_times or load <= 2.0 * cores else timed)(
        not between, f"no full-resolution render during the drag, its pause included ({len(between)})")
    blocks = [r["block"] for r in renders[first_drag:last_drag + 1]]
    print("window renders during the drag:", describe(blocks))
    timed(max(blocks) <= DRAG_BLOCK_BOUND_MS,
          f"no render during the drag holds the event loop over {DRAG_BLOCK_BOUND_MS:g} ms "
          f"(longest {max(blocks):.0f} ms)")

# A full-resolution frame: a still render's own, or (the GUI refines on a worker thread) the time
# per frame of a refinement step the worker finished.
still_full = [f["ms"] for f in frames_log if f["kind"] == "still" and f["w"] == f["vw"] and not f["worker"]]
for line in p.stdout.splitlines():
    m = re.search(r"step joined: (\d+) frames, ([\d.]+) ms", line)
    if m and int(m.group(1)) > 0:
        still_full.append(float(m.group(2)) / int(m.group(1)))
if drag and still_full:
    ratio = statistics.median([r["ms"] for r in drag]) / statistics.median(still_full)
    check(ratio <= 0.5, f"drag frames cost at most half a full-resolution frame (median ratio {ratio:.2f})")

play = [r for r in renders[(last_drag or 0) + 1:] if r["interactive"] and r["rate"] < 1.0]
print("playback (time changes):", describe([r["ms"] for r in play]),
      "| without slice builds:", describe([r["ms"] - r["update"] for r in play]),
      "| slice builds:", describe([r["update"] for r in play if r["update"] > 1.0]))
check(len(play) >= 3, f"playback rendered time changes as interactive frames ({len(play)})")
timed(meets([r["ms"] for r in play]), f"playback frame times meet {args.target_ms:g} ms (first visits included)")
check(bool(play) and max(r["update"] for r in play) < 10.0,
      "no playback frame builds macrocell slices (built ahead; update < 10 ms)")
# One render per playback tick: every time the animation visited before the last one was
# rendered exactly once (the tick's own render, a reduced frame); the GUI's refinement waits for
# playback to end instead of rendering the new time again at full resolution.
after_drag = renders[(last_drag or 0) + 1:]
runs = []  # [time, renders] of consecutive renders at one time, from the first time change on
for r in after_drag:
    if runs and runs[-1][0] == r["time"]:
        runs[-1][1] += 1
    elif runs or r["time"] != after_drag[0]["time"]:
        runs.append([r["time"], 1])
ticks = runs[:-1]
print("playback renders per time step:", [n for _, n in ticks])
check(len(ticks) >= 3 and all(n == 1 for _, n in ticks),
      f"one render per playback tick ({sum(n > 1 for _, n in ticks)} of {len(ticks)} steps rendered more than once)")
# Time-change frames render on the coarse interactive macrocells (InrInteractiveMacrocellResolution
# 8 < 32): the mapper's log marks them; every coarse frame is a reduced interactive one.
coarse = [f for f in frames_log if f["coarse"]]
print(f"mapper frames on the coarse macrocells: {len(coarse)}")
check(len(coarse) >= len(ticks) and all(f["kind"] == "interactive" for f in coarse),
      f"playback frames render on the coarse macrocells ({len(coarse)} coarse, {len(ticks)} ticks)")
times = [r["time"] for r in renders]
check(bool(times) and times[-1] > times[0], f"time moved to the end ({times[0] if times else None} -> "
      f"{times[-1] if times else None})")

last_interactive = max((i for i, r in enumerate(renders) if r["interactive"]), default=-1)
after = [r for r in renders[last_interactive + 1:] if r["w"] == vw and r["h"] == vh]
print("after the interaction:", len(after), "still renders, accumulated frames",
      [r["frames"] for r in after][:6], "...", [r["frames"] for r in after][-3:])
check(bool(after) and max(r["frames"] for r in after) >= 1, "the view refined after the interaction stopped")
# The second frame is a question of time: on a machine loaded beyond twice its cores a
# full-resolution frame can take most of --settle-ms (the README's test command beside one busy
# process did that; RESULTS-archive, "Test bounds (the debiased march as the default)").
(check if args.judge_times or load <= 2.0 * cores else timed)(
    bool(after) and max(r["frames"] for r in after) >= 2, "the refinement went on past its first frame")

# The interactive screenshot is one sample per pixel of a reduced image: sparse, so a lower bar.
for name, least in (("gui_lod_still.png", 0.01), ("gui_lod_interactive.png", 0.002)):
    png = os.path.join(args.out, name)
    if not os.path.exists(png):
        check(False, f"{name} saved")
        continue
    import numpy as np
    a = C.read_png(png)
    differs = float(np.mean(np.any(np.abs(a - a[0, 0]) > 8, axis=2)))
    print(f"{name}: {a.shape[1]}x{a.shape[0]}, {100 * differs:.1f}% of pixels differ from the background")
    check(differs >= least, f"{name} is not empty")
if check.failures:
    print(p.stdout[-3000:])
sys.stdout.flush()
os._exit(check.report())
