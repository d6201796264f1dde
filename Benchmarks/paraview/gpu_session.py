"""What a ParaView user with a GPU gets: the INR Volume representation in pvpython, as the GUI
drives it (issue "ParaView on a GPU"), per model, each with its suggested MODEL.tf.json.

    pvpython Benchmarks/paraview/gpu_session.py [--plugin .../InrVolume.so] [--inr BUILD/bin/inr]
        [--models A.inr ...] [--size 1024 1024] [--drag-size 1280 768] [--backend cuda]
        [--time-changes 3] [--animation-steps 24] [--animation-checks 4] [--cpu-compare-size 384]
        [--out DIR]

Phases (the view re-rendered the way ParaView's GUI does it: still renders while the image
refines, interactive renders while the camera is dragged):
  1. time change -> converged: the view goes to a new time, then still renders until the
     representation says InrConverged (its own stop rule: Convergence Target, Maximum Frames);
     the wall time from the time change, the renders it took and each render's wall time.
     Beside it the engine's own time for the same image: `inr render --converge TARGET` with the
     view's camera, the TF, the opacity unit distance and the size (--inr; same GPU).
  2. drag: --drag-steps interactive renders at --drag-size, 5 degrees of azimuth each.
  3. animation: --animation-steps times over the range, one still render each (what Play in
     the VCR toolbar does), twice (the first pass builds the macrocell slices of each time it
     visits, the second is what a looping Play shows); steps per second; --animation-checks of
     the second pass's images are compared with that time's converged image (PSNR over the
     volume's pixels, 8-bit screenshots).
  4. the CUDA image against the CPU image of the same scene, both converged to 44 dB at
     --cpu-compare-size (PSNR over the volume's pixels; both carry their own noise).
  5. --single-frames renders of exactly one frame each (time budget 0, no stop rule): the view's
     and the mapper's time per render, i.e. the frame plus the image's way to the screen (run
     with INR_CUDA_GL_INTEROP=0 for the host round trip).
Prints tables, writes every render to DIR/gpu_session.csv and a summary to DIR/gpu_session.json,
and screenshots of the converged images to DIR.
"""
import argparse
import csv
import json
import math
import os
import re
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "..", "Testing", "Data", "real"))
PAPER_MODELS = ["siren_cylinder_vorticity.inr", "ffn_mri_head.inr", "coordnet_cylinder_u.inr"]
BACKENDS = {"auto": 0, "cpu": 1, "cuda": 2}

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--plugin", default="", help="InrVolume.so (unless PV_PLUGIN_PATH autoloads it)")
ap.add_argument("--inr", default="", help="the inr program, for the engine's own time (phase 1)")
ap.add_argument("--models", nargs="*", default=[os.path.join(DATA, m) for m in PAPER_MODELS])
ap.add_argument("--size", type=int, nargs=2, default=[1024, 1024])
ap.add_argument("--drag-size", type=int, nargs=2, default=[1280, 768])
ap.add_argument("--drag-steps", type=int, default=24)
ap.add_argument("--backend", choices=list(BACKENDS), default="cuda")
ap.add_argument("--time-changes", type=int, default=3)
ap.add_argument("--converge-seconds", type=float, default=60.0)
ap.add_argument("--animation-steps", type=int, default=24)
ap.add_argument("--animation-checks", type=int, default=4)
ap.add_argument("--single-frames", type=int, default=24, help="phase 5: renders of one frame each")
ap.add_argument("--cpu-compare-size", type=int, default=384, help="0: skip phase 4")
ap.add_argument("--out", default=".")
args = ap.parse_args()

from paraview import simple  # noqa: E402

sys.path.insert(0, HERE)
from pv_bench_common import RepresentationState as State, show_model  # noqa: E402
import pv_bench_common  # noqa: E402

if args.plugin:
    simple.LoadPlugin(args.plugin, remote=False, ns=globals())
os.makedirs(args.out, exist_ok=True)

view = simple.GetActiveViewOrCreate("RenderView")
view.OrientationAxesVisibility = 0
view.ViewSize = args.size
simple.Render(view)
# Which OpenGL ParaView got (the GPU's, or Mesa's software renderer).
gl = [line.strip() for line in view.GetRenderWindow().ReportCapabilities().splitlines()
      if line.strip().lower().startswith(("opengl vendor", "opengl renderer", "opengl version"))]
print("; ".join(gl), flush=True)
rows = []
summary = {"size": args.size, "drag_size": args.drag_size, "backend": args.backend, "opengl": gl,
           "image_transfer_env": os.environ.get("INR_CUDA_GL_INTEROP", ""), "models": {}}


def grab():
    return pv_bench_common.grab(view)


def psnr_over(a, b, mask):
    mse = float(np.mean((a[mask] - b[mask]) ** 2)) if mask.any() else 0.0
    return 10 * math.log10(255.0 ** 2 / mse) if mse > 0 else 99.0


def volume_pixels(image):
    return np.any(np.abs(image - image[0, 0]) > 2, axis=2)


def render(kind, model, phase, step, state, still=True):
    t0 = time.perf_counter()
    (view.SMProxy.StillRender if still else view.SMProxy.InteractiveRender)()
    ms = 1000.0 * (time.perf_counter() - t0)
    row = dict(model=model, phase=phase, step=step, view_ms=round(ms, 2),
               mapper_ms=round(state.get("InrLastRenderTime"), 2), frames=state.get("InrAccumulatedFrames"),
               width=state.get("InrLastImageWidth"), height=state.get("InrLastImageHeight"),
               interactive=state.get("InrLastRenderInteractive"), converged=state.get("InrConverged"))
    rows.append(row)
    return row


def refine(model, phase, step, state):
    """Still renders until converged (or --converge-seconds); wall seconds and the renders."""
    start = time.perf_counter()
    done = []
    while True:
        done.append(render("still", model, phase, step, state))
        if done[-1]["converged"] or time.perf_counter() - start > args.converge_seconds:
            return time.perf_counter() - start, done


def engine_seconds(model_path, t, tf_path, unit_distance, target):
    """inr render --converge with the view's camera: (seconds, frames) or None."""
    if not args.inr:
        return None
    cam = view.GetActiveCamera()
    camera = ",".join(f"{v:.9g}" for v in (*cam.GetPosition(), *cam.GetFocalPoint(), *cam.GetViewUp(),
                                           cam.GetViewAngle()))
    cmd = [args.inr, "render", model_path, "--time", repr(t), "--size", f"{args.size[0]}x{args.size[1]}",
           "--camera", camera, "--opacity-unit-distance", repr(unit_distance), "--converge", repr(target),
           "--frames", "2048", "--backend", args.backend, "--output", os.path.join(args.out, "engine.png")]
    if os.path.exists(tf_path):
        cmd += ["--tf", tf_path]
    out = subprocess.run(cmd, capture_output=True, text=True)
    m = re.search(r"convergence: \S+ after (\d+) frame\(s\) in ([0-9.]+) s", out.stdout)
    if not m:
        print("inr render failed:", out.stdout[-800:], out.stderr[-800:], flush=True)
        return None
    return float(m.group(2)), int(m.group(1))


for model_path in args.models:
    name = os.path.splitext(os.path.basename(model_path))[0]
    tf_path = os.path.splitext(model_path)[0] + ".tf.json"
    view.ViewSize = args.size
    open_start = time.perf_counter()
    reader, display, (t0, t1) = show_model(view, model_path, BACKENDS[args.backend])
    state = State(display)
    view.ViewTime = t0
    refine(name, "open", 0, state)
    open_s = time.perf_counter() - open_start
    target = display.InrConvergenceTarget
    print(f"{name}: {state.get('InrBackendInUse')}; open to converged {open_s:.2f} s", flush=True)
    m = summary["models"][name] = {"backend_in_use": state.get("InrBackendInUse"), "open_s": round(open_s, 3),
                                   "target_db": target, "time_changes": []}

    # 1. Time change -> converged, and the engine's own time for the same image.
    for k in range(args.time_changes):
        t = t0 + (t1 - t0) * (k + 1) / (args.time_changes + 1)
        view.ViewTime = t
        seconds, renders = refine(name, "time-change", k, state)
        per = [r["view_ms"] for r in renders]
        engine = engine_seconds(model_path, t, tf_path, display.ScalarOpacityUnitDistance, target)
        entry = dict(time=t, seconds=round(seconds, 3), renders=len(renders), frames=renders[-1]["frames"],
                     converged=renders[-1]["converged"], render_ms_median=round(statistics.median(per), 2),
                     render_ms_max=round(max(per), 2),
                     engine_seconds=engine[0] if engine else None, engine_frames=engine[1] if engine else None)
        m["time_changes"].append(entry)
        simple.SaveScreenshot(os.path.join(args.out, f"{name}_t{k}.png"), view, ImageResolution=args.size)
        print(f"  time {t:.3f}: converged={entry['converged']} in {seconds:.2f} s, {len(renders)} renders "
              f"(median {entry['render_ms_median']:.1f} ms, max {entry['render_ms_max']:.1f} ms), "
              f"{entry['frames']} frames; engine {engine}", flush=True)

    # 2. Camera drag at the drag size.
    view.ViewSize = args.drag_size
    view.SMProxy.StillRender()
    camera = view.GetActiveCamera()
    drag = []
    for i in range(args.drag_steps):
        camera.Azimuth(5.0)
        drag.append(render("drag", name, "drag", i, state, still=False))
    dm = [r["view_ms"] for r in drag[2:]]
    m["drag_ms_median"] = round(statistics.median(dm), 2)
    m["drag_ms_max"] = round(max(dm), 2)
    m["drag_image"] = f"{drag[-1]['width']}x{drag[-1]['height']}"
    print(f"  drag at {args.drag_size[0]}x{args.drag_size[1]}: median {m['drag_ms_median']:.1f} ms, "
          f"max {m['drag_ms_max']:.1f} ms, image {m['drag_image']}", flush=True)
    for i in range(args.drag_steps):
        camera.Azimuth(-5.0)

    # 3. Animation: one still render per time step, then the shown frames against converged ones.
    view.ViewSize = args.size
    view.SMProxy.StillRender()
    steps = [t0 + (t1 - t0) * i / max(1, args.animation_steps - 1) for i in range(args.animation_steps)]
    check_every = max(1, args.animation_steps // max(1, args.animation_checks))
    # Twice, as Play in a loop does: the first pass builds each time's macrocell slices as it
    # first visits them, the second finds them built.
    pass_s = []
    for p in range(2):
        shown = {}
        elapsed = 0.0
        for i, t in enumerate(steps):
            start = time.perf_counter()
            view.ViewTime = t
            render("still", name, f"animation-{p + 1}", i, state)
            elapsed += time.perf_counter() - start
            if i % check_every == 0:
                shown[i] = grab()  # the image as Play showed it (its read-back is not timed)
        pass_s.append(elapsed)
    anim_s = pass_s[1]
    m["animation_first_pass_steps_per_s"] = round(len(steps) / pass_s[0], 2)
    psnrs = []
    for i, image in shown.items():
        view.ViewTime = steps[i]
        refine(name, "animation-reference", i, state)
        reference = grab()
        psnrs.append(round(psnr_over(image, reference, volume_pixels(reference)), 2))
    m["animation_steps_per_s"] = round(len(steps) / anim_s, 2)
    m["animation_psnr_db"] = psnrs
    print(f"  animation: {len(steps)} steps in {anim_s:.2f} s = {m['animation_steps_per_s']:.1f} steps/s "
          f"(first pass, slices built on the way: {m['animation_first_pass_steps_per_s']:.1f}); "
          f"shown vs converged {psnrs} dB", flush=True)

    # 5 (before 4, which changes the size). Renders of exactly one frame each (no time budget, no
    # stop): the render's fixed cost beside the frame, i.e. what the image's way to the screen
    # costs (compare runs with INR_CUDA_GL_INTEROP=0).
    view.ViewSize = args.size
    saved = (display.InrRefinementTimeBudget, display.InrConvergenceTarget, display.InrMaximumFrames)
    display.InrRefinementTimeBudget = 0
    display.InrConvergenceTarget = 0
    display.InrMaximumFrames = 65536
    view.ViewTime = steps[1]
    view.SMProxy.StillRender()
    single = [render("still", name, "single-frame", i, state) for i in range(args.single_frames)]
    m["single_frame_view_ms_median"] = round(statistics.median(r["view_ms"] for r in single[2:]), 2)
    m["single_frame_mapper_ms_median"] = round(statistics.median(r["mapper_ms"] for r in single[2:]), 2)
    print(f"  one-frame renders at {args.size[0]}x{args.size[1]}: view {m['single_frame_view_ms_median']:.2f} ms, "
          f"mapper {m['single_frame_mapper_ms_median']:.2f} ms (median of {len(single) - 2})", flush=True)
    (display.InrRefinementTimeBudget, display.InrConvergenceTarget, display.InrMaximumFrames) = saved

    # 4. The CUDA image against the CPU image of the same scene.
    if args.cpu_compare_size > 0 and args.backend != "cpu":
        view.ViewSize = [args.cpu_compare_size, args.cpu_compare_size]
        view.ViewTime = steps[len(steps) // 2]
        saved_target = display.InrConvergenceTarget
        display.InrConvergenceTarget = 44
        images = {}
        for backend in ("cuda", "cpu"):
            display.InrBackend = BACKENDS[backend]
            refine(name, f"compare-{backend}", 0, state)
            images[backend] = grab()
            simple.SaveScreenshot(os.path.join(args.out, f"{name}_{backend}.png"), view,
                                  ImageResolution=view.ViewSize)
        mask = volume_pixels(images["cpu"]) | volume_pixels(images["cuda"])
        m["cuda_vs_cpu_psnr_db"] = round(psnr_over(images["cuda"], images["cpu"], mask), 2)
        m["cuda_vs_cpu_pixels"] = int(mask.sum())
        print(f"  CUDA vs CPU at {args.cpu_compare_size}^2, both to 44 dB: {m['cuda_vs_cpu_psnr_db']:.2f} dB "
              f"over {m['cuda_vs_cpu_pixels']} pixels", flush=True)
        display.InrConvergenceTarget = saved_target
        display.InrBackend = BACKENDS[args.backend]
    simple.Delete(display)
    simple.Delete(reader)

with open(os.path.join(args.out, "gpu_session.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
    w.writeheader()
    w.writerows(rows)
with open(os.path.join(args.out, "gpu_session.json"), "w") as f:
    json.dump(summary, f, indent=1)

print()
print(f"INR Volume in pvpython, backend {args.backend}, {args.size[0]}x{args.size[1]} "
      f"(drag {args.drag_size[0]}x{args.drag_size[1]})")
print(f"{'model':26s} {'to converged s':>14s} {'engine s':>9s} {'ratio':>6s} {'render ms med/max':>18s} "
      f"{'drag ms':>8s} {'anim steps/s':>12s} {'anim dB (min)':>13s} {'cuda-cpu dB':>11s} {'1-frame ms':>10s}")
for name, m in summary["models"].items():
    for tc in m["time_changes"]:
        ratio = tc["seconds"] / tc["engine_seconds"] if tc["engine_seconds"] else float("nan")
        print(f"{name:26s} {tc['seconds']:14.2f} {tc['engine_seconds'] or float('nan'):9.2f} {ratio:6.2f} "
              f"{tc['render_ms_median']:8.1f}/{tc['render_ms_max']:<9.1f} {m['drag_ms_median']:8.1f} "
              f"{m['animation_steps_per_s']:12.1f} {min(m['animation_psnr_db'] or [float('nan')]):13.1f} "
              f"{m.get('cuda_vs_cpu_psnr_db', float('nan')):11.2f} {m['single_frame_view_ms_median']:10.2f}")
print(f"CSV: {os.path.join(args.out, 'gpu_session.csv')}")
sys.stdout.flush()
