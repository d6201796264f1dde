"""A model file that changes while ParaView shows it (issue 52, item 3), through pvpython:

  (a) rewritten with new weights (the same size, as a training script's next checkpoint): after
      ReloadFiles (File > Reload Files) the preview values are the new model's and the INR Volume
      image changes, its accumulation restarted; rewritten again and only UpdatePipeline called
      (no Reload Files), the change is noticed too;
  (b) truncated (a save caught half-way): a warning names the file and the problem, the previous
      model stays (preview values and image unchanged, accumulation not restarted);
  (c) deleted: a warning says the file is gone, once however often it is reloaded; the previous
      model stays;
  then the file put back (an atomic save: a new file renamed over the path) is read again.
The process must stay alive through all of it (a child pvpython; its exit status and output are
checked here).
  pvpython pv_model_reload.py --pvpython PVPYTHON --model MODEL.inr --out DIR
The model must have a tensor named "l1.weight" (the plugin test model, Testing/Data/Plugin): its
sign is flipped to make the "retrained" model, whose values are 1 - the original's (output
0.5 * net + 0.5)."""
import argparse
import json
import os
import struct
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--pvpython", default="pvpython")
ap.add_argument("--model", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--child", action="store_true")
args = ap.parse_args()

out_dir = os.path.abspath(args.out)
model = os.path.join(out_dir, "reload_model.inr")
FRAMES = 32
# One render accumulates at least this many frames, then each render more up to FRAMES: the
# first render after a change holds fewer than FRAMES after a restart, FRAMES when none.
FRAMES_PER_RENDER = 8
SIZE = [96, 72]
# Two renders of one model that differ only in their sampling noise (a session made again), and
# two models: the PSNR between them (over the volume's pixels) is above SAME_DB and below
# OTHER_DB respectively.
SAME_DB = 30.0
OTHER_DB = 20.0


def retrained(data):
    """The model's bytes with the tensor l1.weight negated: the same size, other values."""
    import numpy as np
    n = struct.unpack("<Q", data[:8])[0]
    header = json.loads(data[8:8 + n])
    begin, end = header["l1.weight"]["data_offsets"]
    assert header["l1.weight"]["dtype"] == "F32"
    w = np.frombuffer(data, np.float32, (end - begin) // 4, 8 + n + begin)
    return data[:8 + n + begin] + (-w).astype(np.float32).tobytes() + data[8 + n + end:]


def write_in_place(path, data):
    """As torch.save does: the same file truncated and written (same inode)."""
    with open(path, "r+b" if os.path.exists(path) else "wb") as f:
        f.truncate(0)
        f.write(data)


if args.child:
    import numpy as np
    from paraview import servermanager, simple
    from vtkmodules.util.numpy_support import vtk_to_numpy

    with open(args.model, "rb") as f:
        original = f.read()
    reader = simple.OpenDataFile(model)
    view = C.setup_view(SIZE)
    display = C.show_inr(reader, view, seed=7, maximum_frames=FRAMES,
                         frames_per_render=FRAMES_PER_RENDER)
    step = [0]

    def state(name, reload, time_change=False):
        """Reloads (or moves the time away and back), renders until FRAMES are accumulated,
        prints the phase marker, returns (preview values, image, frames accumulated after the
        first render: fewer than FRAMES after a restart, FRAMES when the image was kept)."""
        print("PHASE %s" % name, flush=True)
        if reload:
            simple.ReloadFiles(reader)
        if time_change:
            view.ViewTime = 5.0
            simple.Render(view)
            view.ViewTime = 0.0
        simple.Render(view)
        frames = C.info(display, "InrAccumulatedFrames")
        for _ in range(4 * FRAMES):
            if C.info(display, "InrAccumulatedFrames") >= FRAMES:
                break
            simple.Render(view)
        step[0] += 1
        png = os.path.join(out_dir, "reload_%d_%s.png" % (step[0], name))
        simple.SaveScreenshot(png, view, ImageResolution=SIZE)
        values = vtk_to_numpy(servermanager.Fetch(reader).GetPointData().GetArray("value")).copy()
        print("STATE %s frames after the first render %d, at the end %d, values[:3]=%s"
              % (name, frames, C.info(display, "InrAccumulatedFrames"), values[:3]), flush=True)
        return values, C.read_png(png), frames

    v0, img0, f0 = state("first", False)
    write_in_place(model, retrained(original))
    v1, img1, f1 = state("retrained_reload", True)
    write_in_place(model, original)
    v2, img2, f2 = state("original_time_change", False, time_change=True)
    write_in_place(model, retrained(original))
    v3, img3, f3 = state("retrained_again", True)
    write_in_place(model, retrained(original)[: len(original) // 2])
    v4, img4, f4 = state("truncated", True)
    v4b, img4b, f4b = state("truncated_again", True)
    os.remove(model)
    v5, img5, f5 = state("deleted", True)
    v5b, img5b, f5b = state("deleted_again", True)
    tmp = model + ".tmp"
    write_in_place(tmp, original)
    os.replace(tmp, model)  # an atomic save: another inode under the same name
    v6, img6, f6 = state("restored", True)

    def report(ok, what):
        print("CHECK %s %s" % ("ok" if ok else "FAIL", what), flush=True)

    report(FRAMES_PER_RENDER <= f0 < FRAMES, "first render: %d frames accumulated (%d asked, "
           "at most %d)" % (f0, FRAMES_PER_RENDER, FRAMES))
    report(np.allclose(v1, 1.0 - v0, atol=1e-5) and not np.allclose(v1, v0, atol=1e-3),
           "(a) after ReloadFiles the preview is the rewritten model's (1 - the original's)")
    report(C.psnr_over_volume(img0, img1) < OTHER_DB and f1 < FRAMES,
           "(a) the image changed with the model: PSNR %.1f dB against the first (< %g), "
           "accumulation restarted (%d frames)" % (C.psnr_over_volume(img0, img1), OTHER_DB, f1))
    # (The images of one model are compared among those rendered after a model change: the
    # view's very first render differs from them in its noise.)
    report(np.allclose(v2, v0, atol=1e-6) and C.psnr_over_volume(img2, img6) >= SAME_DB and
           C.psnr_over_volume(img2, img1) < OTHER_DB and f2 < FRAMES,
           "(a) rewritten back, no Reload Files, the time moved and back: the original's preview "
           "and image again (PSNR %.1f dB against the original read again at the end, >= %g; "
           "%.1f against the rewritten model's, < %g; %.1f against the view's first)"
           % (C.psnr_over_volume(img2, img6), SAME_DB, C.psnr_over_volume(img2, img1), OTHER_DB,
              C.psnr_over_volume(img2, img0)))
    report(np.allclose(v3, v1, atol=1e-6) and C.psnr_over_volume(img3, img1) >= SAME_DB and
           f3 < FRAMES, "(a) the rewritten model again: its preview and image (PSNR %.1f dB, "
           ">= %g), accumulation restarted (%d frames)" % (C.psnr_over_volume(img3, img1),
                                                         SAME_DB, f3))
    report(np.array_equal(v4, v3) and np.array_equal(img4, img3) and f4 == FRAMES and
           np.array_equal(v4b, v3) and np.array_equal(img4b, img3) and f4b == FRAMES,
           "(b) truncated: the previous model's preview and image stay, the accumulation is not "
           "restarted (%d, %d frames after the first render)" % (f4, f4b))
    report(np.array_equal(v5, v3) and np.array_equal(img5, img3) and f5 == FRAMES and
           np.array_equal(v5b, v3) and np.array_equal(img5b, img3) and f5b == FRAMES,
           "(c) deleted: the previous model's preview and image stay, the accumulation is not "
           "restarted (%d, %d frames)" % (f5, f5b))
    report(np.allclose(v6, v0, atol=1e-6) and C.psnr_over_volume(img6, img3) < OTHER_DB and
           f6 < FRAMES, "put back by rename: the original's preview again, the image no longer "
           "the rewritten model's (PSNR %.1f dB, < %g)" % (C.psnr_over_volume(img6, img3), OTHER_DB))
    print("SURVIVED", flush=True)
    sys.stdout.flush()
    os._exit(0)

os.makedirs(out_dir, exist_ok=True)
with open(args.model, "rb") as f:
    write_in_place(model, f.read())
p = subprocess.run([args.pvpython, "--force-offscreen-rendering", os.path.abspath(__file__),
                    "--child", "--model", args.model, "--out", args.out],
                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=500)
out = p.stdout
check = C.Checks()
check(p.returncode == 0 and "SURVIVED" in out, "the pvpython process survived (exit %d)" % p.returncode)
for line in out.splitlines():
    if line.startswith("CHECK "):
        check(line.startswith("CHECK ok "), line.split(" ", 2)[2])
check(sum(l.startswith("CHECK ") for l in out.splitlines()) == 8, "every check of the child ran")

# The warnings, by phase (the child prints a marker before each step, flushed, and ParaView writes
# its warnings to stderr, merged here in order).
phases = {}
name = None
for line in out.splitlines():
    if line.startswith("PHASE "):
        name = line.split()[1]
        phases[name] = []
    elif name is not None and model in line:
        phases[name].append(line.strip())


def warned(phase, *words):
    return [l for l in phases.get(phase, []) if all(w in l for w in words)]


quiet = [p_ for p_ in ("first", "retrained_reload", "original_time_change", "retrained_again",
                       "restored", "truncated_again", "deleted_again") if phases.get(p_)]
check(not quiet, "no message when a good model is read, none repeated for the same fault: %s"
      % {p_: phases[p_][:1] for p_ in quiet})
trunc = warned("truncated", "WARN", "changed on disk", "model read before is still shown")
check(len(trunc) == 1, "(b) one warning names the truncated file, the loader's problem and the "
      "model kept: %s" % (trunc[0][:300] if trunc else phases.get("truncated")))
gone = warned("deleted", "WARN", "is gone", "still shown")
check(len(gone) == 1, "(c) one warning says the file is gone and the model stays: %s"
      % (gone[0][:300] if gone else phases.get("deleted")))
if check.failures:
    print(out)
sys.exit(check.report())
