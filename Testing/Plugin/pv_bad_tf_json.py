"""A broken MODEL.tf.json beside the model, through ParaView: the reader proxy's
InrTransferFunction (what the GUI applies as the model's colour map) is empty, so the default map
is used, ParaView's output (stderr in pvpython) carries a warning naming the file and the
problem, and the model still shows as INR Volume and renders. A valid preset written in its place
comes back verbatim.
  pvpython pv_bad_tf_json.py --pvpython PVPYTHON --model MODEL.inr --preset GOOD.tf.json --out DIR
Runs itself as a child (pvpython --child ...) and checks the child's output and exit status."""
import argparse
import os
import shutil
import subprocess
import sys

ap = argparse.ArgumentParser()
ap.add_argument("--pvpython", default="pvpython")
ap.add_argument("--model", required=True)
ap.add_argument("--preset", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--child", action="store_true")
args = ap.parse_args()

model = os.path.join(os.path.abspath(args.out), "tf_model.inr")
tf_path = model[:-len(".inr")] + ".tf.json"
# Python's json.dump writes a NaN opacity like this; JSON has no such literal.
BROKEN = '[{"Name": "broken", "RGBPoints": [0, 0, 0, 1, 1, 1, 0, 0], "Points": [0, NaN, 0.5, 0]}]'

if args.child:
    from paraview import simple
    reader = simple.OpenDataFile(model)
    prop = reader.GetProperty("InrTransferFunction")
    reader.SMProxy.UpdatePropertyInformation(prop.SMProperty)
    print("BROKEN_TF=%r" % reader.GetPropertyValue("InrTransferFunction"), flush=True)
    view = simple.GetActiveViewOrCreate("RenderView")
    view.ViewSize = [64, 48]
    display = simple.Show(reader, view)
    display.Representation = "INR Volume"
    simple.Render(view)
    print("RENDERED", flush=True)
    shutil.copyfile(args.preset, tf_path)
    reader.SMProxy.UpdatePropertyInformation(prop.SMProperty)
    print("GOOD_TF=%r" % reader.GetPropertyValue("InrTransferFunction"), flush=True)
    sys.stdout.flush()
    os._exit(0)

os.makedirs(args.out, exist_ok=True)
shutil.copyfile(args.model, model)
with open(tf_path, "w") as f:
    f.write(BROKEN)
p = subprocess.run([args.pvpython, "--force-offscreen-rendering", os.path.abspath(__file__),
                    "--child", "--model", args.model, "--preset", args.preset, "--out", args.out],
                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
out = p.stdout
lines = out.splitlines()
failures = 0


def check(ok, what):
    global failures
    print("%s %s" % ("ok  " if ok else "FAIL", what))
    failures += 0 if ok else 1


check(p.returncode == 0 and "RENDERED" in out, "pvpython exit %d, the model rendered as INR Volume"
      % p.returncode)
check("BROKEN_TF=''" in lines, "broken .tf.json: InrTransferFunction is empty (the default map)")
warnings = [l for l in lines if tf_path in l]
check(any("non-finite" in l and "default colour map" in l for l in warnings),
      "a warning names %s, the non-finite value and the default map: %s"
      % (os.path.basename(tf_path), warnings[0].strip()[:300] if warnings else "(none)"))
with open(args.preset) as f:
    preset = f.read()
check("GOOD_TF=%r" % preset in lines, "a valid preset in its place comes back verbatim")
if failures:
    print(out)
sys.exit(1 if failures else 0)
