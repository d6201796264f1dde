"""Opaque geometry that lives on ONE rank in front of the INR volume, run under
`mpirun -np N pvbatch` (or plain pvbatch): writes OUT/both.png (sphere and volume), and with
--layers also OUT/sphere.png (sphere alone) and OUT/volume.png (volume alone), for
run_mpi_depth.py to compare the composited N-rank image with the single-process one.

The sphere comes from a programmable source that produces it only on the last piece (rank N-1
of N; with one process, piece 0 of 1): with ParaView's distributed rendering each rank draws
only its own geometry into its own depth buffer and IceT composites afterwards, so a rank whose
rays stop at its own depth buffer alone would trace the volume behind another rank's sphere.

  mpirun -np N pvbatch pv_mpi_depth.py --model M.inr --out DIR [--frames 16] [--layers]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
ap.add_argument("--frames", type=int, default=16)
ap.add_argument("--size", type=int, nargs=2, default=[200, 200])
ap.add_argument("--time", type=float, default=2.5)
ap.add_argument("--owner", choices=["first", "last"], default="last",
                help="the rank that owns the sphere: 0 or N-1")
ap.add_argument("--center", type=float, nargs=3, default=[1.9, -1.5, 1.0])
ap.add_argument("--radius", type=float, default=0.45)
ap.add_argument("--layers", action="store_true", help="also the sphere alone and the volume alone")
args = ap.parse_args()

from paraview import simple  # noqa: E402

C.load_plugin(args.plugin, remote=False)
os.makedirs(args.out, exist_ok=True)

# Between the camera (C.CAMERA) and the volume, covering part of it (not all: the volume around
# it must match too). Printed by the rank that makes it, so the runner can check the ownership.
SPHERE_SCRIPT = """
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as S
from vtkmodules.vtkFiltersSources import vtkSphereSource
info = self.GetOutputInformation(0)
piece = info.Get(S.UPDATE_PIECE_NUMBER())
pieces = info.Get(S.UPDATE_NUMBER_OF_PIECES())
if piece == OWNER:
    s = vtkSphereSource()
    s.SetCenter(CENTER)
    s.SetRadius(RADIUS)
    s.SetThetaResolution(64)
    s.SetPhiResolution(64)
    s.Update()
    self.GetOutput().ShallowCopy(s.GetOutput())
print("sphere piece %d of %d: %d points" % (piece, pieces, self.GetOutput().GetNumberOfPoints()), flush=True)
"""
# Without this the executive asks only piece 0 for data (the sphere would always be rank 0's).
SPHERE_INFO = """
from vtkmodules.vtkCommonExecutionModel import vtkAlgorithm
self.GetOutputInformation(0).Set(vtkAlgorithm.CAN_HANDLE_PIECE_REQUEST(), 1)
"""

reader = simple.OpenDataFile(args.model)
view = C.setup_view(args.size)
scene = simple.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
volume = simple.Show(reader, view)
C.apply_colormap(volume, view)
volume.Representation = "INR Volume"
C.refine_in_one_render(volume, args.frames)
scene.AnimationTime = args.time

sphere = simple.ProgrammableSource()
sphere.OutputDataSetType = "vtkPolyData"
sphere.ScriptRequestInformation = SPHERE_INFO
sphere.Script = (SPHERE_SCRIPT.replace("OWNER", "0" if args.owner == "first" else "pieces - 1")
                 .replace("CENTER", ", ".join(map(repr, args.center))).replace("RADIUS", repr(args.radius)))
surface = simple.Show(sphere, view)
surface.ColorArrayName = ["POINTS", ""]
surface.AmbientColor = surface.DiffuseColor = [0.9, 0.8, 0.2]
surface.Specular = 0.0
surface.Opacity = 1.0

simple.SaveScreenshot(os.path.join(args.out, "both.png"), view, ImageResolution=list(args.size))
if args.layers:
    simple.Hide(reader, view)
    simple.SaveScreenshot(os.path.join(args.out, "sphere.png"), view, ImageResolution=list(args.size))
    simple.Show(reader, view)
    simple.Hide(sphere, view)
    simple.SaveScreenshot(os.path.join(args.out, "volume.png"), view, ImageResolution=list(args.size))
print("RESULT: PASS (images written)", flush=True)
