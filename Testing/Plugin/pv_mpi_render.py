"""One INR Volume render through ParaView, run under `mpirun -np N pvbatch` (or pvpython): the
converged image without and with shadows, and what every rank reported (Ranks In Use), written
to OUT/shadows0.png, OUT/shadows1.png and OUT/ranks.json for run_mpi_split.py to compare across
rank counts.

  mpirun -np N pvbatch pv_mpi_render.py --model M.inr --out DIR [--frames 64] [--size 200 200]
      [--split samples|pixels] [--no-refine]
"""
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--frames", type=int, default=64)
ap.add_argument("--size", type=int, nargs=2, default=[200, 200])
ap.add_argument("--time", type=float, default=2.5)
ap.add_argument("--split", choices=["samples", "pixels"], default="samples", help="Rank Split")
ap.add_argument("--no-refine", action="store_true",
                help="Refine Macrocells off: sample shares then draw exactly one renderer's numbers")
args = ap.parse_args()

from paraview import simple  # noqa: E402

C.load_plugin(args.plugin, remote=False)
check = C.Checks()
os.makedirs(args.out, exist_ok=True)
reader = simple.OpenDataFile(args.model)
view = C.setup_view(args.size)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
display = simple.Show(reader, view)
C.apply_colormap(display, view)
display.Representation = "INR Volume"
C.refine_in_one_render(display, args.frames)
display.InrRankSplit = 0 if args.split == "samples" else 1
if args.no_refine:
    display.InrRefineMacrocells = 0
scene.AnimationTime = args.time

report = {"frames": args.frames, "renders": []}
for shadows in (1, 0):  # each render after the first restarts the accumulation: all do the work
    display.InrShadows = shadows
    png = os.path.join(args.out, f"shadows{shadows}.png")
    simple.SaveScreenshot(png, view, ImageResolution=list(args.size))
    ranks_text = C.info(display, "InrRanksInUse")
    frames = C.info(display, "InrAccumulatedFrames")
    converged = C.info(display, "InrConverged")
    print(f"shadows {shadows}: {frames} frames, converged {converged}; ranks in use:\n{ranks_text}")
    # The reduced state: the fewest frames of all ranks (pixel shares) or all ranks' frames
    # together (sample shares), converged only when every rank is.
    check(frames == args.frames, f"shadows {shadows}: every rank accumulated {frames} frames (asked {args.frames})")
    check(converged == 1, f"shadows {shadows}: converged on every rank")
    ranks = []
    for line in ranks_text.splitlines():
        m = re.match(r"rank (\d+) of (\d+): (\d+) queries in the last render, (\d+) frames, (\w+); (.*)", line)
        check(m is not None, f"a rank line reads as expected: {line!r}")
        if m:
            ranks.append({"rank": int(m.group(1)), "of": int(m.group(2)), "queries": int(m.group(3)),
                          "frames": int(m.group(4)), "state": m.group(5), "backend": m.group(6)})
    report["renders"].append({"shadows": shadows, "png": png, "ranks": ranks})

# A camera move with reprojection (the default): the ranks together keep one renderer's history
# (the engine's reprojectHistory, 32 frames: QueryReductionSettings), so one render after the
# move stands between it and Maximum Frames, not at it, and the view refines on to Maximum Frames
# (sample shares kept the whole history on every rank, and the view reported Maximum Frames,
# converged, after one render). Pixel shares restart instead (no reprojection across shares).
if args.split == "samples" and args.frames > 40:
    n_ranks = len(C.info(display, "InrRanksInUse").splitlines())
    display.InrFramesPerRender = 1
    display.InrRefinementTimeBudget = 0  # one new frame per rank and render, whatever the machine's speed
    view.GetActiveCamera().Azimuth(10)
    simple.Render(view)
    after_move = C.info(display, "InrAccumulatedFrames")
    display.InrFramesPerRender = args.frames  # then the rest in one render
    renders = 1
    while not C.info(display, "InrConverged") and renders < 10:
        simple.Render(view)
        renders += 1
    refined = C.info(display, "InrAccumulatedFrames")
    print(f"camera move: {after_move} frames after one render, {refined} after {renders} renders")
    check(32 < after_move <= 32 + n_ranks,
          f"one render after a camera move: {after_move} frames, the 32 reprojected and one new frame of each of "
          f"{n_ranks} ranks")
    check(refined == args.frames and C.info(display, "InrConverged") == 1,
          f"after the move the view refines to Maximum Frames again ({refined} of {args.frames}, {renders} renders)")
    report["camera_move"] = {"frames_after_one_render": after_move, "frames": refined, "renders": renders}

with open(os.path.join(args.out, "ranks.json"), "w") as f:
    json.dump(report, f, indent=1)
status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
