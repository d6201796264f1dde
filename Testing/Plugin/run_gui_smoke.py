"""GUI smoke test: paraview --script=gui_smoke.py --test-script=gui_pause.xml --exit.
Checks: the screenshot exists and is not empty (enough pixels differ from the background), the
representation is INR Volume, and during the pause the view kept refining by itself (the
accumulated frame count grew beyond 1 without any script render). With --refinement off
(Progressive Refinement off) the view must not re-render by itself: the frame count stays at the
script's own renders.
  pvpython run_gui_smoke.py --paraview PARAVIEW --model M.inr --out DIR [--refinement off]"""
import argparse
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--paraview", required=True)
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--refinement", choices=["on", "off"], default="on")
ap.add_argument("--time-budget", type=float, default=None,
                help="Refinement Time Budget (ms) instead of the default, to measure what it does")
args = ap.parse_args()
here = os.path.dirname(os.path.abspath(__file__))
for f in ("gui_smoke.png", "gui_frames.txt"):
    if os.path.exists(os.path.join(args.out, f)):
        os.remove(os.path.join(args.out, f))
env = dict(os.environ, INR_GUI_OUT=args.out, INR_GUI_MODEL=args.model,
           INR_GUI_REFINEMENT="1" if args.refinement == "on" else "0",
           INR_GUI_TIME_BUDGET="" if args.time_budget is None else str(args.time_budget))
cmd = [args.paraview, "--dr", f"--script={os.path.join(here, 'gui_smoke.py')}",
       f"--test-script={os.path.join(here, 'gui_pause.xml')}", "--exit"]
p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                   timeout=400)
print(p.stdout[-4000:])
fail = []
png = os.path.join(args.out, "gui_smoke.png")
if not os.path.exists(png):
    fail.append("no screenshot")
else:
    import numpy as np
    a = C.read_png(png)
    corner = a[0, 0]
    differs = float(np.mean(np.any(np.abs(a - corner) > 8, axis=2)))
    print(f"screenshot {a.shape[1]}x{a.shape[0]}: {100 * differs:.1f}% of pixels differ from the background")
    if differs < 0.02:
        fail.append("screenshot is empty")
frames = []
stamps = []  # (frames, wall time) after each render of the view
text = ""
if os.path.exists(os.path.join(args.out, "gui_frames.txt")):
    text = open(os.path.join(args.out, "gui_frames.txt")).read()
    for line in text.splitlines():
        parts = line.split()
        if parts and parts[0].isdigit():
            frames.append(int(parts[0]))
            m = re.search(r"t=([\d.]+)", line)
            if m:
                stamps.append((int(parts[0]), float(m.group(1))))
# Time from the first render that shows a frame to the first that holds the most frames (the
# refinement's end: Maximum Frames), and the renders it took: what the time budget changes.
shown = [(f, t) for f, t in stamps if f > 0]
if shown:
    top = max(f for f, _ in shown)
    end = next(i for i, (f, _) in enumerate(shown) if f == top)
    print(f"refinement: frames {shown[0][0]} -> {top} in {shown[end][1] - shown[0][1]:.2f} s over "
          f"{end} renders (time budget {args.time_budget if args.time_budget is not None else 'default'})")
print("representation lines:", [l for l in text.splitlines() if l.startswith("representation")])
print("accumulated frames seen after renders:", frames[:8], "...", frames[-3:] if frames else [])
if "representation INR Volume" not in text.replace("'", ""):
    fail.append("not shown as INR Volume")
if args.refinement == "on" and (not frames or max(frames) < 10):
    fail.append("the GUI did not keep refining by itself (max frames %s)" % (max(frames) if frames else None))
# Off: only the script's renders (Render, SaveScreenshot) and ParaView's own (window shown,
# layout) add frames, one each: a handful (4 seen here), against the 48 of Maximum Frames that
# the refining GUI reaches during the pause.
if args.refinement == "off" and (not frames or max(frames) >= 10):
    fail.append("refinement off, yet the view kept refining (max frames %s)" % (max(frames) if frames else None))
if p.returncode != 0:
    fail.append(f"paraview exit status {p.returncode}")
print("RESULT:", "PASS" if not fail else "FAIL: " + "; ".join(fail))
sys.stdout.flush()
os._exit(0 if not fail else 1)
