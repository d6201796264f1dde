"""How close the reduced frame shown right after a time change is to the converged still image,
with one frame (InrInteractiveFreshFrames 1) or several frames at a lower resolution (e.g. 4).

    pvpython Benchmarks/paraview/fresh_frames.py --plugin BUILD/lib/paraview-plugins/InrVolume/InrVolume.so
        [--model M.inr] [--size 640 384] [--frame-time 100] [--fresh 1 4] [--repeats 5]
        [--reference-frames 256] [--csv fresh_frames.csv]

One render view of --size (needs X; run under Xvfb), CPU backend, the model's suggested
MODEL.tf.json colour map. The reference is a --reference-frames still image at time T (55% of
the range). Then, per --fresh value (the list is run twice, interleaved, so a drift of the
machine's load shows), --repeats times: the view goes to another time A (20% of the range,
rendered twice: the reduced time-change frame, then a still one) and back to T, whose render
is a time-change interactive frame; that frame, as the window shows it (read back without
rendering again, upscaled as drawn), is compared with the reference: PSNR over the pixels the
volume covers in the reference (differs from the background corner pixel by more than 2).
Prints a table (median PSNR, median render ms, image sizes) and writes every frame to --csv.
"""
import argparse
import csv
import math
import os
import statistics
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "..", "Testing", "Data", "real"))

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--plugin", default="", help="InrVolume.so (unless PV_PLUGIN_PATH autoloads it)")
ap.add_argument("--model", default=os.path.join(DATA, "siren_cylinder_vorticity.inr"))
ap.add_argument("--size", type=int, nargs=2, default=[640, 384])
ap.add_argument("--frame-time", type=float, default=100.0, help="InrInteractiveFrameTime (ms)")
ap.add_argument("--fresh", type=int, nargs="+", default=[1, 4], help="InrInteractiveFreshFrames values")
ap.add_argument("--repeats", type=int, default=5)
ap.add_argument("--reference-frames", type=int, default=256)
ap.add_argument("--csv", default="fresh_frames.csv")
args = ap.parse_args()

from paraview import simple  # noqa: E402

sys.path.insert(0, HERE)
import pv_bench_common  # noqa: E402

if args.plugin:
    simple.LoadPlugin(args.plugin, remote=False, ns=globals())

view = simple.GetActiveViewOrCreate("RenderView")
view.ViewSize = args.size
view.OrientationAxesVisibility = 0
reader, display, (t0, t1) = pv_bench_common.show_model(view, args.model, 1)
get = pv_bench_common.RepresentationState(display).get


def grab():
    return pv_bench_common.grab(view)


time_t = t0 + 0.55 * (t1 - t0)
time_a = t0 + 0.20 * (t1 - t0)
view.ViewTime = time_t
display.InrFramesPerRender = args.reference_frames
display.InrMaximumFrames = args.reference_frames
display.InrConvergenceTarget = 0
simple.Render(view)
reference = grab()
covered = np.any(np.abs(reference - reference[0, 0]) > 2, axis=2)
print(f"reference: {get('InrAccumulatedFrames')} frames, {int(covered.sum())} covered pixels", flush=True)
display.InrFramesPerRender = 1
display.InrMaximumFrames = 2048
display.InrConvergenceTarget = 41
display.InrInteractiveFrameTime = args.frame_time

rows = []
for rnd in range(2):
    for fresh in args.fresh:
        display.InrInteractiveFreshFrames = fresh
        for i in range(args.repeats):
            view.ViewTime = time_a
            simple.Render(view)
            simple.Render(view)
            view.ViewTime = time_t
            simple.Render(view)
            mse = float(np.mean((grab()[covered] - reference[covered]) ** 2))
            rows.append(dict(fresh=fresh, round=rnd, repeat=i, interactive=get("InrLastRenderInteractive"),
                             width=get("InrLastImageWidth"), height=get("InrLastImageHeight"),
                             frames=get("InrAccumulatedFrames"), mapper_ms=round(get("InrLastRenderTime"), 2),
                             psnr_db=round(10 * math.log10(255.0 ** 2 / mse), 2) if mse > 0 else 999.0))

with open(args.csv, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
    w.writeheader()
    w.writerows(rows)
print()
print(f"Time-change frame vs {args.reference_frames}-frame still image, {os.path.basename(args.model)}, "
      f"{args.size[0]}x{args.size[1]} view, budget {args.frame_time:g} ms")
print(f"{'fresh frames':>12s} {'n':>3s} {'PSNR median':>12s} {'min':>6s} {'max':>6s} {'ms median':>10s}  images x frames")
for fresh in args.fresh:
    rs = [r for r in rows if r["fresh"] == fresh and r["interactive"]]
    if not rs:
        print(f"{fresh:12d}   0 (no interactive frames)")
        continue
    p = [r["psnr_db"] for r in rs]
    sizes = sorted({f"{r['width']}x{r['height']}x{r['frames']}" for r in rs})
    print(f"{fresh:12d} {len(rs):3d} {statistics.median(p):12.1f} {min(p):6.1f} {max(p):6.1f} "
          f"{statistics.median(r['mapper_ms'] for r in rs):10.1f}  {' '.join(sizes)}")
print(f"CSV: {args.csv}")
sys.stdout.flush()
