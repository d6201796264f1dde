"""What Apply costs the GUI's event loop: INR Volume against ParaView's own Volume of a grid.

    pvpython Benchmarks/paraview/apply_stall.py --plugin-dir .../paraview-plugins/InrVolume
        [--model Testing/Data/real/siren_cylinder_vorticity.inr] [--grid 64] [--repeat 3]
        [--settle-ms 6000] [--out DIR] [--csv FILE]

Plays the same recorded session in `paraview` (under Xvfb: DISPLAY must be set; with
Testing/Plugin/gui_session_setup.py, which logs the view's renders) for each case: File > Open, Apply, choose the representation in the toolbar, a pause, exit. Cases:
  - inr:     the model (.inr), INR Volume (the plugin's own first image and refinement);
  - grid:    the model resampled to a GRID^3 .vti (written first by this script through the
             plugin's reader), ParaView's Volume;
  - outline: the same .vti left as ParaView shows it by default (Outline): Apply alone.
The plugin's event-loop watch (INR_VOLUME_EVENT_LOOP_LOG: the loop's stalls over 40 ms, logged by
a 5 ms timer) is on in every case, so the figures are the same instrument's. Per run: the longest
stall after Apply was clicked and the sum of the stalls over 250 ms (what a user feels as a
freeze). Prints a table of medians over the repeats and writes the runs as CSV.

The grid and outline cases are what ParaView itself costs for a volume of the same size, with no
plugin code on the path (the plugin is loaded, but its representation is not used): the part of
INR Volume's stall that the plugin cannot remove.
"""
import argparse
import csv
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
TOOLBAR = "pqClientMainWindow/representationToolbar/displayRepresentation/comboBox"
STALL_BOUND_MS = 250.0
QUIET_GAP_S = 2.5
# Logs every render of the view (start, time held) and sets the view's size: the GUI tests' own,
# whose log readers (inr_pv_common) this script shares.
SETUP = os.path.join(ROOT, "Testing", "Plugin", "gui_session_setup.py")
sys.path.insert(0, os.path.dirname(SETUP))
import inr_pv_common as C  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--plugin-dir", required=True, help="the folder of InrVolume.so (PV_PLUGIN_PATH)")
ap.add_argument("--paraview", default="paraview")
ap.add_argument("--model", default=os.path.join(ROOT, "Testing", "Data", "real", "siren_cylinder_vorticity.inr"))
ap.add_argument("--grid", type=int, default=64, help="resample size per axis for the grid cases")
ap.add_argument("--repeat", type=int, default=3)
ap.add_argument("--settle-ms", type=int, default=6000, help="pause after choosing the representation")
ap.add_argument("--view-size", default="960x600", help="the view's size (the setup script sets it)")
ap.add_argument("--out", default="", help="folder for the logs (a temporary one if empty)")
ap.add_argument("--csv", default="", help="CSV of every run")
ap.add_argument("--cases", nargs="+", default=["inr", "grid", "outline"], choices=["inr", "grid", "outline"])
args = ap.parse_args()
if not os.environ.get("DISPLAY"):
    sys.exit("apply_stall.py: no X display (DISPLAY unset; Tools/xvfb.sh starts Xvfb)")
if args.grid < 2:
    sys.exit(f"apply_stall.py: --grid {args.grid}: must be at least 2")
if not os.path.exists(os.path.join(args.plugin_dir, "InrVolume.so")):
    sys.exit(f"apply_stall.py: --plugin-dir {args.plugin_dir}: no InrVolume.so there")
if "grid" in args.cases and not shutil.which("xdotool"):
    sys.exit("apply_stall.py: the grid case needs xdotool (to answer ParaView's volume-rendering "
             "prompt): apt install xdotool, or leave it out with --cases inr outline")
out = args.out or tempfile.mkdtemp(prefix="apply_stall_")
os.makedirs(out, exist_ok=True)
env = dict(os.environ, PV_PLUGIN_PATH=os.path.abspath(args.plugin_dir))

# The grid: the plugin's reader resamples the network (its preview output at --grid per axis),
# saved with the point array only (the reader's field arrays, the model's bytes among them, are
# no part of a plain grid's Apply).
model_name = os.path.splitext(os.path.basename(args.model))[0]
grid_path = os.path.join(out, f"{model_name}_resampled_{args.grid}.vti")
pvpython = os.path.join(os.path.dirname(shutil.which(args.paraview) or args.paraview), "pvpython")
if not os.path.exists(pvpython):
    pvpython = shutil.which("pvpython") or "pvpython"
if not os.path.exists(grid_path):
    script = f"""
from paraview import simple, servermanager
from vtkmodules.vtkIOXML import vtkXMLImageDataWriter
r = simple.OpenDataFile({os.path.abspath(args.model)!r})
r.PreviewResolution = {args.grid}
r.UpdatePipeline()
image = servermanager.Fetch(r)
image.GetFieldData().Initialize()
w = vtkXMLImageDataWriter()
w.SetFileName({grid_path!r})
w.SetInputData(image)
w.Write()
"""
    p = subprocess.run([pvpython, "-c", script], env=env, capture_output=True, text=True)
    if p.returncode != 0 or not os.path.exists(grid_path):
        sys.exit(f"apply_stall.py: resampling {args.model} to {grid_path} failed:\n{p.stdout}{p.stderr}")

CASES = [("inr", os.path.abspath(args.model), "INR Volume"),
         ("grid", grid_path, "Volume"),
         ("outline", grid_path, None)]


def session_xml(path, representation):
    events = ['<pqevent object="pqClientMainWindow" command="process_events" arguments="1500" />',
              '<pqevent object="pqClientMainWindow/menubar/menu_File" command="activate" arguments="actionFileOpen" />',
              f'<pqevent object="pqClientMainWindow/FileOpenDialog" command="filesSelected" arguments="{path}" />',
              # Apply's mark in the watch's log: a quiet gap longer than any other before it.
              f'<pqevent object="pqClientMainWindow" command="process_events" arguments="{int(QUIET_GAP_S * 1200)}" />',
              '<pqevent object="pqClientMainWindow/propertiesDock/propertiesPanel/Accept" command="activate" arguments="" />']
    if representation:
        events.append(f'<pqevent object="{TOOLBAR}" command="activated" arguments="{representation}" />')
    events.append(f'<pqevent object="pqClientMainWindow" command="process_events" arguments="{args.settle_ms}" />')
    return '<?xml version="1.0" ?>\n<pqevents>\n  ' + "\n  ".join(events) + "\n</pqevents>\n"


def run_case(name, path, representation, k):
    xml_path = os.path.join(out, f"{name}_{k}.xml")
    log_path = os.path.join(out, f"{name}_{k}_event_loop.txt")
    with open(xml_path, "w") as f:
        f.write(session_xml(path, representation))
    gui_out = os.path.join(out, f"{name}_{k}")
    os.makedirs(gui_out, exist_ok=True)
    run_env = dict(env, INR_VOLUME_EVENT_LOOP_LOG=log_path, INR_GUI_OUT=gui_out, INR_GUI_VIEW_SIZE=args.view_size)
    proc = subprocess.Popen([args.paraview, "--dr", f"--script={SETUP}", f"--test-script={xml_path}", "--exit"],
                            env=run_env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    # ParaView asks before volume rendering a grid of this size ("Are you sure?", a modal dialog
    # the recorded test cannot answer): answered Yes as a user would, as soon as it shows.
    answered = []

    def answer_prompts():
        while proc.poll() is None:
            found = subprocess.run(["xdotool", "search", "--onlyvisible", "--name", "Are you sure"],
                                   capture_output=True, text=True).stdout.split()
            for w in found:
                # Focus and a real key press (XTEST): Qt ignores events sent to a window.
                subprocess.run(["xdotool", "windowfocus", "--sync", w], capture_output=True)
                subprocess.run(["xdotool", "key", "Return"], capture_output=True)
                answered.append(w)
            time.sleep(0.2)

    threading.Thread(target=answer_prompts, daemon=True).start()
    try:
        stdout, _ = proc.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
        sys.exit(f"apply_stall.py: paraview ran past 300 s on case {name}; logs in {out}")
    with open(os.path.join(out, f"{name}_{k}_paraview.log"), "w") as f:
        f.write(stdout)
    if proc.returncode != 0:
        sys.exit(f"apply_stall.py: paraview failed on case {name} (exit {proc.returncode}); log in {out}")
    # The setup script's log: each render, and what its own observer cost (screenshots and state
    # reads, in the INR case only), taken out of the stalls.
    renders_log = os.path.join(gui_out, "gui_session_renders.txt")
    if not os.path.exists(renders_log):
        sys.exit(f"apply_stall.py: case {name}: no render log {renders_log} (did {SETUP} run?)")
    renders, observer = C.read_render_log(renders_log)
    renders = [(float(r["start"]), float(r["block_ms"])) for r in renders if "start" in r]
    stalls = C.read_event_loop_stalls(log_path, observer)  # (begin, end, ms)
    # Apply's stalls: those after the first quiet gap of >= 2.5 s (the pause between File > Open
    # and Apply; the one before File > Open is 1.5 s), up to the next such gap (the settle pause
    # of a case whose view does not refine by itself) and no later than the settle pause's end
    # (ParaView's exit). A prompt's time on screen (the answer comes within 0.2 s) is not a
    # stall: its dialog runs the event loop.
    gaps = [i for i in range(1, len(stalls)) if stalls[i][0] - stalls[i - 1][1] >= QUIET_GAP_S]
    if not gaps:
        sys.exit(f"apply_stall.py: case {name}: no quiet pause before Apply in {log_path}")
    last = stalls[gaps[0]][0] + args.settle_ms / 1000.0
    end = gaps[1] if len(gaps) > 1 else len(stalls)
    window = [st for st in stalls[gaps[0]:end] if st[0] <= last]
    after = [ms for _, _, ms in window]
    # The view's renders inside Apply's longest stall: the part of it that is drawing, the rest is
    # ParaView's Apply.
    longest = max(window, key=lambda st: st[2], default=(0.0, 0.0, 0.0))
    in_longest = [ms for t, ms in renders if longest[0] <= t <= longest[1]]
    return dict(case=name, run=k, longest_ms=max(after, default=0.0),
                freeze_ms=sum(ms for ms in after if ms > STALL_BOUND_MS), stalls=len(after),
                renders_in_longest=len(in_longest), render_ms_in_longest=sum(in_longest),
                prompts=len(answered))


CASES = [c for c in CASES if c[0] in args.cases]
rows = []
for k in range(args.repeat):
    for name, path, representation in CASES:
        t = time.time()
        row = run_case(name, path, representation, k)
        rows.append(row)
        if name == "grid" and row["prompts"] == 0:
            print(f"warning: run {k} grid: ParaView's volume-rendering prompt was not seen and answered; "
                  "the case may not have rendered a Volume")
        print(f"run {k} {name}: longest stall {row['longest_ms']:.0f} ms ({row['renders_in_longest']} "
              f"render(s) in it, {row['render_ms_in_longest']:.0f} ms), stalls over "
              f"{STALL_BOUND_MS:.0f} ms sum {row['freeze_ms']:.0f} ms ({time.time() - t:.0f} s)", flush=True)

print(f"\nApply's event-loop stalls, median of {args.repeat} ({os.path.basename(args.model)}, "
      f"grid {args.grid}^3, load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
print(f"{'case':<10} {'representation':<15} {'longest stall ms':>17} {'renders in it ms':>17} "
      f"{'stalls>250ms sum':>17}")
for name, _, representation in CASES:
    mine = [r for r in rows if r["case"] == name]
    print(f"{name:<10} {representation or 'Outline':<15} "
          f"{statistics.median(r['longest_ms'] for r in mine):>17.0f} "
          f"{statistics.median(r['render_ms_in_longest'] for r in mine):>17.0f} "
          f"{statistics.median(r['freeze_ms'] for r in mine):>17.0f}")
if args.csv:
    with open(args.csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("wrote", args.csv)
