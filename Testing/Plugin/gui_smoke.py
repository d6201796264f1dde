# Runs inside the ParaView GUI (paraview --script=gui_smoke.py): opens the model, shows it as
# INR Volume with FramesPerRender 1, saves a screenshot, and logs the accumulated frame count
# after every render of the view to INR_GUI_OUT/gui_frames.txt, so the driver can check that the
# GUI kept refining by itself while the test pauses (gui_pause.xml).
import os
import time
from paraview import simple

out = os.environ["INR_GUI_OUT"]
model = os.environ["INR_GUI_MODEL"]
reader = simple.OpenDataFile(model)
view = simple.GetActiveViewOrCreate("RenderView")
try:
    simple.GetLayout(view).SetSize(240, 240)  # small view: CPU frames stay cheap on CI
except Exception as e:  # noqa: BLE001
    print("layout size not set:", e)
display = simple.Show(reader, view)
display.InrMaximumFrames = 48
display.InrFramesPerRender = 1
display.InrConvergenceTarget = 0.0
# INR_GUI_REFINEMENT=0: Progressive Refinement off, the view must stay at one frame per render.
display.InrProgressiveRefinement = int(os.environ.get("INR_GUI_REFINEMENT", "1"))
# INR_GUI_TIME_BUDGET=MS: another Refinement Time Budget (for measuring what it does).
if os.environ.get("INR_GUI_TIME_BUDGET"):
    display.InrRefinementTimeBudget = float(os.environ["INR_GUI_TIME_BUDGET"])
simple.ResetCamera(view)
simple.Render(view)
proxy = display.SMProxy
prop = proxy.GetProperty("InrAccumulatedFrames")
log = open(os.path.join(out, "gui_frames.txt"), "w")


def on_end(obj, event):
    proxy.UpdatePropertyInformation(prop)
    log.write(f"{prop.GetElement(0)} {display.Representation} "
              f"{display.ColorArrayName[1] if display.ColorArrayName else ''} t={time.time():.4f}\n")
    log.flush()


view.GetRenderWindow().AddObserver("EndEvent", on_end)
simple.SaveScreenshot(os.path.join(out, "gui_smoke.png"), view, ImageResolution=[240, 240])
log.write(f"representation {display.Representation}\n")
log.flush()
