"""Out of GPU memory in ParaView (issue 52, item 2), on a GPU: for N = 1, 2, ... a pvpython child
runs with INR_TEST_DEVICE_ALLOCATION_FAULT=N (the N-th device allocation fails as if the GPU were
full): it opens the model, shows it as INR Volume (Backend Auto), renders, enlarges the view (a
new image size) and renders again. Each child must
  - stay alive (exit 0, "SURVIVED");
  - show the volume in its last screenshot (the view is not left empty or stuck);
  - where an allocation failed, print "out of GPU memory" with what to lower (Backend In Use, which
    says "cpu: ... out of memory" where the fine session fell back to the CPU, is printed).
N runs over 1..24, then every 5th (each child is a ParaView start-up); the sweep ends at the first
N whose child meets no failure (the fault lies past every allocation).
Exit 77 (skipped) without a usable GPU (Backend In Use of a fault-free run is not cuda).
  pvpython pv_gpu_oom.py --pvpython PVPYTHON --model MODEL.inr --out DIR [--max-faults 300]"""
import argparse
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--pvpython", default="pvpython")
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--max-faults", type=int, default=300)
ap.add_argument("--child", action="store_true")
args = ap.parse_args()
out_dir = os.path.abspath(args.out)

if args.child:
    from paraview import simple
    reader = simple.OpenDataFile(args.model)
    view = C.setup_view([96, 72])
    display = C.show_inr(reader, view, seed=7, maximum_frames=8, frames_per_render=8)
    for _ in range(2):
        simple.Render(view)
    view.ViewSize = [320, 240]  # a new image size: the session's image buffers are reallocated
    for _ in range(3):
        simple.Render(view)
    print("BACKEND_IN_USE=%s" % C.info(display, "InrBackendInUse"), flush=True)
    png = os.path.join(out_dir, "gpu_oom_%s.png" % os.environ.get("INR_TEST_DEVICE_ALLOCATION_FAULT", "none"))
    simple.SaveScreenshot(png, view, ImageResolution=[320, 240])
    print("PNG=%s" % png, flush=True)
    print("SURVIVED", flush=True)
    sys.stdout.flush()
    os._exit(0)


def child(fault):
    env = dict(os.environ)
    env.pop("INR_TEST_DEVICE_ALLOCATION_FAULT", None)
    if fault:
        env["INR_TEST_DEVICE_ALLOCATION_FAULT"] = str(fault)
    p = subprocess.run([args.pvpython, "--force-offscreen-rendering", os.path.abspath(__file__), "--child",
                        "--model", args.model, "--out", args.out],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, timeout=300)
    lines = p.stdout.splitlines()
    value = lambda key: next((l[len(key) + 1:] for l in lines if l.startswith(key + "=")), "")  # noqa: E731
    return p.returncode, p.stdout, value("BACKEND_IN_USE"), value("PNG")


def covered(png):
    import numpy as np
    img = C.read_png(png)
    bg = np.array(C.BACKGROUND) * 255.0
    return int(np.count_nonzero(np.any(np.abs(img - bg) > 8, axis=2)))


os.makedirs(out_dir, exist_ok=True)
rc, out, backend, png = child(0)
if rc != 0 or not backend.startswith("cuda"):
    print(out[-3000:])
    print("SKIPPED: no GPU session here (Backend In Use: %r, exit %d)" % (backend, rc))
    sys.exit(77)
check = C.Checks()
reference = covered(png)
check(reference > 0, "without a fault the volume covers %d pixels" % reference)
tried = survived = 0
positions = list(range(1, 25)) + list(range(25, args.max_faults + 1, 5))
for n in positions:
    rc, out, backend, png = child(n)
    faulted = "out of GPU memory" in out
    ok = rc == 0 and "SURVIVED" in out
    cover = covered(png) if ok and png and os.path.exists(png) else 0
    advice = not faulted or any(w in out for w in ("; lower", "; turn", "free GPU memory"))
    tried += 1
    good = ok and cover > 0 and advice
    survived += good
    check(good, "fault at allocation %d: exit %d, %s, volume on %d pixels; Backend In Use %r"
          % (n, rc, "an allocation failed" if faulted else "no allocation failed", cover, backend[:200]))
    if not good:
        print(out[-3000:])
    if not faulted and ok:
        break
else:
    check(False, "still meeting faults at allocation %d" % args.max_faults)
print("cases tried %d, survived %d" % (tried, survived))
sys.exit(check.report())
