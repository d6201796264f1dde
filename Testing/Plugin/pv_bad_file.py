"""Malformed models: the reader reports the loader's message (vtkErrorMacro -> ParaView's output
window, stderr in pvpython) and nothing crashes.
  pvpython pv_bad_file.py --plugin InrVolume.so --pvpython PVPYTHON BAD.inr [BAD2.inr ...]
Runs itself as a child per file and checks the child's output and exit status."""
import argparse
import os
import subprocess
import sys

ap = argparse.ArgumentParser()
ap.add_argument("--plugin", default="")
ap.add_argument("--pvpython", default="pvpython")
ap.add_argument("--child", action="store_true")
ap.add_argument("files", nargs="+")
args = ap.parse_args()

if args.child:
    from paraview import simple
    if args.plugin:
        simple.LoadPlugin(args.plugin, remote=False, ns=globals())
    r = simple.OpenDataFile(args.files[0])
    print("reader:", r.GetXMLName() if r else None, flush=True)
    try:
        r.UpdatePipeline()
    except Exception as e:  # ParaView may raise on a failed update
        print("python exception:", e, flush=True)
    view = simple.GetActiveViewOrCreate("RenderView")
    simple.Show(r, view)
    simple.Render(view)
    print("SURVIVED", flush=True)
    sys.stdout.flush()
    os._exit(0)

failures = 0
for f in args.files:
    cmd = [args.pvpython, "--force-offscreen-rendering", os.path.abspath(__file__), "--child"]
    if args.plugin:  # (an empty argument upsets pvpython's command-line decoding)
        cmd += ["--plugin", args.plugin]
    p = subprocess.run(cmd + [f],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    out = p.stdout
    name = os.path.basename(f)
    ok = p.returncode == 0 and "SURVIVED" in out and any(name in l and "ERR" in l for l in out.splitlines())
    print(f"{'ok' if ok else 'FAIL'}: {name}: exit {p.returncode}")
    for line in out.splitlines():
        if name in line and "ERR" in line:
            print("   ", line.strip()[:300])
    if not ok:
        print(out)
        failures += 1
sys.exit(1 if failures else 0)
