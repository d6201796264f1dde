"""Where a time step's wall time goes in pvpython (what Play pays per step), per shipped model:
the reader's update at the new time, the view's update (representations, data delivery), and the
still render (the mapper's share read back from the representation).

    pvpython Benchmarks/paraview/time_step_cost.py [--plugin .../InrVolume.so] [--models A.inr ...]
        [--size 1024 1024] [--backend cuda] [--steps 24] [--preview 8 2] [--budget 50]

Per model and per reader PreviewResolution in --preview: --steps times over the range, each
visited twice (the second pass is timed: macrocell slices built), one still render per step
with the given Refinement Time Budget. Prints the medians (ms): reader update, view update,
render, the mapper's render time and scene update, and the rest of the render outside the mapper.
"""
import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "..", "Testing", "Data", "real"))
PAPER_MODELS = ["siren_cylinder_vorticity.inr", "ffn_mri_head.inr", "coordnet_cylinder_u.inr"]
BACKENDS = {"auto": 0, "cpu": 1, "cuda": 2}

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--plugin", default="")
ap.add_argument("--models", nargs="*", default=[os.path.join(DATA, m) for m in PAPER_MODELS])
ap.add_argument("--size", type=int, nargs=2, default=[1024, 1024])
ap.add_argument("--backend", choices=list(BACKENDS), default="cuda")
ap.add_argument("--steps", type=int, default=24)
ap.add_argument("--preview", type=int, nargs="+", default=[8, 2])
ap.add_argument("--budget", type=float, default=50.0, help="InrRefinementTimeBudget (ms)")
args = ap.parse_args()

from paraview import simple  # noqa: E402

sys.path.insert(0, HERE)
from pv_bench_common import RepresentationState, show_model  # noqa: E402

if args.plugin:
    simple.LoadPlugin(args.plugin, remote=False, ns=globals())
view = simple.GetActiveViewOrCreate("RenderView")
view.OrientationAxesVisibility = 0
view.ViewSize = args.size
print(f"{'model':26s} {'preview':>7s} {'reader':>7s} {'view upd':>8s} {'render':>7s} {'mapper':>7s} "
      f"{'scene upd':>9s} {'outside':>7s} {'frames':>6s}  (medians, ms)")
for model_path in args.models:
    name = os.path.splitext(os.path.basename(model_path))[0]
    reader, display, (t0, t1) = show_model(view, model_path, BACKENDS[args.backend])
    display.InrRefinementTimeBudget = args.budget
    state = RepresentationState(display)
    times = [t0 + (t1 - t0) * i / max(1, args.steps - 1) for i in range(args.steps)]
    for preview in args.preview:
        reader.PreviewResolution = preview
        rows = []
        for p in range(2):
            for t in times:
                a = time.perf_counter()
                reader.UpdatePipeline(t)
                b = time.perf_counter()
                view.ViewTime = t
                view.Update()
                c = time.perf_counter()
                view.SMProxy.StillRender()
                e = time.perf_counter()
                if p == 1:
                    mapper = state.get("InrLastRenderTime")
                    rows.append((1e3 * (b - a), 1e3 * (c - b), 1e3 * (e - c), mapper,
                                 state.get("InrLastUpdateTime"), 1e3 * (e - c) - mapper,
                                 state.get("InrAccumulatedFrames")))
        med = [statistics.median(r[i] for r in rows) for i in range(7)]
        print(f"{name:26s} {preview:7d} {med[0]:7.1f} {med[1]:8.1f} {med[2]:7.1f} {med[3]:7.1f} "
              f"{med[4]:9.1f} {med[5]:7.1f} {med[6]:6.0f}", flush=True)
    simple.Delete(display)
    simple.Delete(reader)
