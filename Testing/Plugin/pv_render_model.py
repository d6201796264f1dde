"""Renders an INR Volume model through ParaView (pvpython, pvbatch, or a client of pvserver) and
optionally compares the screenshot with a baseline. Exit status 0 = pass.

  pvpython pv_render_model.py --model M.inr --out out.png [--plugin InrVolume.so]
      [--time 2.5] [--frames 64] [--size 200 200] [--connect 127.0.0.1:PORT]
      [--baseline B.png --min-psnr 40 --max-abs 64] [--write-baseline]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--time", type=float, default=2.5)
ap.add_argument("--frames", type=int, default=64)
ap.add_argument("--size", type=int, nargs=2, default=[200, 200])
ap.add_argument("--connect", default="")
ap.add_argument("--baseline", default="")
ap.add_argument("--min-psnr", type=float, default=40.0)
ap.add_argument("--max-abs", type=int, default=64)
ap.add_argument("--write-baseline", action="store_true")
ap.add_argument("--ranks", type=int, default=0, help="ranks that render (checks the Ranks In Use lines)")
args = ap.parse_args()

from paraview import simple  # noqa: E402
from paraview import servermanager  # noqa: E402

if args.connect:
    host, port = args.connect.rsplit(":", 1)
    simple.Connect(host, int(port))
    print("connected to", args.connect, "remote:", servermanager.ActiveConnection.IsRemote())
C.load_plugin(args.plugin, remote=bool(args.connect))

check = C.Checks()


# File > Open / OpenDataFile find our reader through the ReaderFactory hint.
reader = simple.OpenDataFile(args.model)
check(reader is not None and reader.GetXMLName() == "InrVolumeReader",
      "OpenDataFile picks the INR Volume reader")
reader.UpdatePipelineInformation()
trange = list(reader.GetProperty("TimeRange"))
check(abs(trange[0] - 0.0) < 1e-9 and abs(trange[1] - 10.0) < 1e-9,
      f"continuous TimeRange {trange}")
check(len(reader.GetProperty("TimestepValues")) == 0, "no TIME_STEPS (continuous time)")
# The model's bytes travel as the field array "InrModel"; the reader stores their range in VTK's
# range cache (ParaView's data information would otherwise scan them on Apply): it must be the
# bytes' true range.
model_bytes = open(args.model, "rb").read()
reader.UpdatePipeline()
info = reader.GetDataInformation().GetFieldDataInformation().GetArrayInformation("InrModel")
check(info is not None and info.GetNumberOfTuples() == len(model_bytes),
      "the field array InrModel holds the model file's bytes")
if info is not None:
    got = info.GetComponentRange(0)
    check(tuple(got) == (float(min(model_bytes)), float(max(model_bytes))),
          f"InrModel's range in the data information is the bytes' range ({tuple(got)})")

view = C.setup_view(args.size)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.PlayMode = "Sequence"
display = simple.Show(reader, view)
check(display.Representation == "INR Volume", "the reader's hint shows it as 'INR Volume'")
check("INR Volume" in display.Representation.Available, "'INR Volume' is in the list")
C.apply_colormap(display, view)
C.refine_in_one_render(display, args.frames)
scene.AnimationTime = args.time
check(abs(view.ViewTime - args.time) < 1e-9, f"view time {view.ViewTime}")

target = args.baseline if args.write_baseline else args.out
simple.SaveScreenshot(target, view, ImageResolution=list(args.size))
# The panel's state, in client/server mode too: the information properties come from the
# representation that renders (vtkSMInrVolumeRepresentationProxy pulls them from the render server;
# the client's copy does not render).
frames = C.info(display, "InrAccumulatedFrames")
check(frames == args.frames, f"accumulated {frames} frames (asked {args.frames})")
check(C.info(display, "InrConverged") == 1, "converged flag after the frame limit")
state = C.info(display, "InrRefinementState") or ""
check(state.startswith("stopped at") or state.startswith("converged"), f"refinement state '{state}' after the frame limit")
ranks = (C.info(display, "InrRanksInUse") or "").strip().splitlines()
print("backend:", C.info(display, "InrBackendInUse"), "| state:", state, "| ranks:", " / ".join(ranks))
if args.ranks:
    check(len(ranks) == args.ranks, f"{len(ranks)} lines in Ranks In Use (expected one per rank, {args.ranks})")

if args.write_baseline:
    print("wrote baseline", args.baseline)
elif args.baseline:
    ok, msg = C.compare(args.out, args.baseline, args.min_psnr, args.max_abs)
    print("comparison with", os.path.basename(args.baseline) + ":", msg)
    check(ok, "screenshot matches the baseline")

status = check.report()
if args.connect:
    simple.Disconnect()
# Success: let the script end (a clean exit, also for pvbatch satellites under mpirun);
# failure: a non-zero status.
sys.stdout.flush()
if status:
    sys.exit(status)
