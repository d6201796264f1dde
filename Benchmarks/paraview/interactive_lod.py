"""Interactive frame times of the INR Volume representation in ParaView, level of detail on/off.

    pvpython Benchmarks/paraview/interactive_lod.py --plugin BUILD/lib/paraview-plugins/InrVolume/InrVolume.so
        [--models A.inr B.inr ...] [--size 1280 768] [--backend cpu] [--orbit-steps 24]
        [--scrub-steps 16] [--converge-seconds 120] [--frame-time 100]
        [--interactive-macrocells 8] [--interactive-macrocells-ahead 1] [--csv lod.csv]

Per model (default: the shipped paper-size models in Testing/Data/real, each with its suggested
MODEL.tf.json colour map), in one render view of --size (needs X; run under Xvfb):
  1. a still render at the first time: "open" is the wall time from Show to its end (engine,
     first fine macrocell slices, with --interactive-macrocells-ahead every coarse interactive
     slice, and the renders ParaView does while the view is set up), one per model;
  2. time scrub, first visits: the view time steps through --scrub-steps times over the range,
     one still render each (ParaView renders time changes as still renders; with level of detail
     the mapper draws them as interactive frames); macrocell slices are built as they are first
     needed, so these are "first visit" figures. Twice: "scrub-first-visit" with the
     representation's coarse interactive macrocells (--interactive-macrocells cells per axis:
     only coarse slices are built, or none when they were built ahead), then "scrub-first-visit-fine" with them off (0), the fine
     32^3 slices built by the time-change frame itself (what every time change did before the
     coarse grid existed); after it the fine slices of every scrub time are built;
  3. for level of detail on (LOD "on": with the CPU backend's drag stand-in, InrInteractiveStandIn;
     "net": without it, the drag draws the network) and off: a camera orbit of --orbit-steps
     interactive renders (vtkSMViewProxy::InteractiveRender, the path of a mouse drag; 5 degrees
     azimuth each) and a time scrub over the now built slices;
  4. with level of detail on: still renders after the orbit until the image converges (the
     representation's convergence target) or --converge-seconds pass: the still image's time to
     converge (the still path is the same with level of detail off).
Frame times are the wall time of the view's render call seen from Python (the whole render:
pipeline update, geometry, volume, compositing), plus the mapper's own time and image size.
Prints a table (median, p90, max per model/phase/mode) and writes every frame to --csv.
"""
import argparse
import csv
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "..", "Testing", "Data", "real"))
PAPER_MODELS = ["siren_cylinder_vorticity.inr", "ffn_mri_head.inr", "coordnet_cylinder_u.inr"]

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--plugin", default="", help="InrVolume.so (unless PV_PLUGIN_PATH autoloads it)")
ap.add_argument("--models", nargs="*", default=[os.path.join(DATA, m) for m in PAPER_MODELS])
ap.add_argument("--size", type=int, nargs=2, default=[1280, 768])
ap.add_argument("--backend", choices=["auto", "cpu", "cuda"], default="cpu")
ap.add_argument("--orbit-steps", type=int, default=24)
ap.add_argument("--pictures", default="",
                help="directory: the window after the last orbit frame of each mode, as drawn "
                     "(MODEL_orbit_LOD.png), and the still image after the orbits (MODEL_still.png)")
ap.add_argument("--orbit-only", action="store_true",
                help="only the open and the orbits (no scrubs, no convergence): the drag figures")
ap.add_argument("--scrub-steps", type=int, default=16)
ap.add_argument("--converge-seconds", type=float, default=120.0)
ap.add_argument("--frame-time", type=float, default=100.0, help="InrInteractiveFrameTime (ms)")
ap.add_argument("--interactive-macrocells", type=int, default=8,
                help="InrInteractiveMacrocellResolution for the first-visit scrub and the built-slice phases")
ap.add_argument("--interactive-macrocells-ahead", type=int, choices=[0, 1], default=1,
                help="InrInteractiveMacrocellsAhead: coarse slices built ahead in the first still render (1) "
                     "or by the time-change frames that need them (0)")
ap.add_argument("--csv", default="interactive_lod.csv")
args = ap.parse_args()

from paraview import simple  # noqa: E402

sys.path.insert(0, HERE)
from pv_bench_common import RepresentationState, save_window, show_model  # noqa: E402

if args.plugin:
    simple.LoadPlugin(args.plugin, remote=False, ns=globals())

BACKENDS = {"auto": 0, "cpu": 1, "cuda": 2}
LOAD_AT_START = os.getloadavg()


def percentile(values, q):
    s = sorted(values)
    if not s:
        return float("nan")
    k = min(len(s) - 1, max(0, int(round(q * (len(s) - 1)))))
    return s[k]


rows = []


def picture(view, name):
    """The window as last drawn into --pictures/NAME."""
    os.makedirs(args.pictures, exist_ok=True)
    save_window(view, os.path.join(args.pictures, name))


def timed(model, phase, lod, step, render, state):
    t0 = time.perf_counter()
    render()
    ms = 1000.0 * (time.perf_counter() - t0)
    w, h = state.get("InrLastImageWidth"), state.get("InrLastImageHeight")
    row = dict(model=model, phase=phase, lod=lod, step=step, view_ms=round(ms, 2),
               mapper_ms=round(state.get("InrLastRenderTime"), 2),
               update_ms=round(state.get("InrLastUpdateTime"), 2), width=w, height=h,
               interactive=state.get("InrLastRenderInteractive"),
               frames=state.get("InrAccumulatedFrames"))
    rows.append(row)
    return row


view = simple.GetActiveViewOrCreate("RenderView")
view.ViewSize = args.size
view.OrientationAxesVisibility = 0
for model_path in args.models:
    name = os.path.splitext(os.path.basename(model_path))[0]
    open_start = time.perf_counter()

    def before_colouring(display):
        # Before anything renders (the camera set-up renders once): the first still render
        # builds the coarse interactive slices ahead or not.
        display.InrInteractiveLevelOfDetail = 2
        display.InrInteractiveMacrocellResolution = args.interactive_macrocells
        display.InrInteractiveMacrocellsAhead = args.interactive_macrocells_ahead
        display.InrFramesPerRender = 1

    reader, display, (t0, t1) = show_model(view, model_path, BACKENDS[args.backend], before_colouring)
    display.InrInteractiveFrameTime = args.frame_time
    proxy = view.SMProxy
    mapper = RepresentationState(display)
    times = [t0 + (t1 - t0) * i / max(1, args.scrub_steps - 1) for i in range(args.scrub_steps)]

    def set_time(t):
        view.ViewTime = t

    set_time(times[0])
    warm = timed(name, "first-still", "on", 0, proxy.StillRender, mapper)
    # From Show to the first still image: engine, first fine slices, coarse slices ahead, frames.
    rows.append(dict(warm, phase="open", view_ms=round(1000.0 * (time.perf_counter() - open_start), 2)))
    print(f"{name}: open to first still image {rows[-1]['view_ms']:.0f} ms, last still render "
          f"{warm['view_ms']:.0f} ms ({mapper.get('InrBackendInUse')})", flush=True)
    for i, t in enumerate(times[1:] if not args.orbit_only else [], 1):
        set_time(t)
        timed(name, "scrub-first-visit", "on", i, proxy.StillRender, mapper)
    # The same first visits for the fine grid (coarse interactive macrocells off): each
    # time-change frame waits for its fine slices; afterwards every scrub time's fine slices exist.
    display.InrInteractiveMacrocellResolution = 0
    set_time(times[0])
    proxy.StillRender()
    for i, t in enumerate(times[1:] if not args.orbit_only else [], 1):
        set_time(t)
        timed(name, "scrub-first-visit-fine", "on", i, proxy.StillRender, mapper)
    display.InrInteractiveMacrocellResolution = args.interactive_macrocells
    set_time(times[0])
    timed(name, "settle", "on", 0, proxy.StillRender, mapper)
    for lod, mode, stand_in in (("on", 2, 1), ("net", 2, 0), ("off", 0, 1)):
        display.InrInteractiveLevelOfDetail = mode
        display.InrInteractiveStandIn = stand_in
        proxy.StillRender()
        camera = view.GetActiveCamera()
        for i in range(args.orbit_steps):
            camera.Azimuth(5.0)
            timed(name, "orbit", lod, i, proxy.InteractiveRender, mapper)
        if args.pictures:
            picture(view, f"{name}_orbit_{lod}.png")
            camera.Azimuth(-5.0 * args.orbit_steps)  # every mode's orbit ends at the same camera
        display.InrInteractiveStandIn = 1
        for i, t in enumerate(times[1:] if not args.orbit_only else [], 1):
            set_time(t)
            timed(name, "scrub-built", lod, i, proxy.StillRender, mapper)
        set_time(times[0])
        proxy.StillRender()
    if args.pictures:
        # The still image at the orbits' last camera, refined for a while: what the drag frames
        # stand for.
        display.InrInteractiveLevelOfDetail = 2
        view.GetActiveCamera().Azimuth(5.0 * args.orbit_steps)
        for _ in range(40):
            proxy.StillRender()
        picture(view, f"{name}_still.png")
        view.GetActiveCamera().Azimuth(-5.0 * args.orbit_steps)
    if args.orbit_only:
        continue
    # The still image after an orbit step: time to converge (same with LOD on or off).
    display.InrInteractiveLevelOfDetail = 2
    view.GetActiveCamera().Azimuth(5.0)
    proxy.InteractiveRender()
    start = time.perf_counter()
    step = 0
    while True:
        row = timed(name, "still-refine", "on", step, proxy.StillRender, mapper)
        step += 1
        elapsed = time.perf_counter() - start
        converged = mapper.get("InrConverged")
        if converged or elapsed > args.converge_seconds:
            break
    print(f"{name}: still image {'converged' if converged else 'NOT converged'} after "
          f"{elapsed:.1f} s, {row['frames']} frames, estimate {mapper.get('InrConvergenceEstimate'):.1f} dB",
          flush=True)
    rows.append(dict(model=name, phase="converge", lod="on", step=step, view_ms=round(1000 * elapsed, 1),
                     mapper_ms="", update_ms="", width=row["width"], height=row["height"],
                     interactive=0, frames=row["frames"]))
    simple.Delete(display)
    simple.Delete(reader)

with open(args.csv, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
    w.writeheader()
    w.writerows(rows)

print()
print(f"INR Volume interactive frames, {args.size[0]}x{args.size[1]} view, backend {args.backend}, "
      f"budget {args.frame_time:g} ms, interactive macrocells {args.interactive_macrocells} "
      f"(built ahead: {'yes' if args.interactive_macrocells_ahead else 'no'}) (view render wall time, ms)")
print(f"load average at start {LOAD_AT_START[0]:.2f} / {LOAD_AT_START[1]:.2f}, at end "
      f"{os.getloadavg()[0]:.2f} / {os.getloadavg()[1]:.2f} (1 / 5 min) on {os.cpu_count()} CPUs")
header = (f"{'model':28s} {'phase':22s} {'LOD':3s} {'n':>3s} {'median':>8s} {'p90':>8s} {'max':>8s} "
          f"{'update med':>10s} {'image (median)':>15s}")
print(header)
print("-" * len(header))
groups = {}
for r in rows:
    if r["phase"] in ("open", "orbit", "scrub-built", "scrub-first-visit", "scrub-first-visit-fine"):
        groups.setdefault((r["model"], r["phase"], r["lod"]), []).append(r)
for (model, phase, lod), rs in groups.items():
    v = [r["view_ms"] for r in rs]
    sizes = sorted(rs, key=lambda r: r["width"])[len(rs) // 2]
    update = statistics.median([r["update_ms"] for r in rs])
    print(f"{model:28s} {phase:22s} {lod:3s} {len(v):3d} {statistics.median(v):8.1f} "
          f"{percentile(v, 0.9):8.1f} {max(v):8.1f} {update:10.1f} {sizes['width']:>7d}x{sizes['height']:<7d}")
for r in rows:
    if r["phase"] == "converge":
        print(f"{r['model']:28s} still image to converge: {r['view_ms'] / 1000:.1f} s, {r['frames']} frames")
print(f"CSV: {args.csv}")
sys.stdout.flush()
