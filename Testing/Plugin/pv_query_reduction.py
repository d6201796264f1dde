"""The "Query reduction" properties of the INR Volume representation through paraview.simple:
each one set by its documented Python name reaches the renderer (read back from the engine through
the information property InrQueryReductionInUse), the panel group and tooltips are there, pruning
changes restart the accumulation, an invalid value is refused and the previous setting kept, and
renders still work. Exit status 0 = pass.

  pvpython pv_query_reduction.py --model M.inr --out DIR [--plugin InrVolume.so]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import inr_pv_common as C  # noqa: E402

ap = C.argument_parser()
args = ap.parse_args()

from paraview import simple  # noqa: E402

C.load_plugin(args.plugin, remote=False)
check = C.Checks()


def in_use(display):
    """InrQueryReductionInUse ("budget=stbn rho=0.5 ...") as a dict of strings."""
    text = C.info(display, "InrQueryReductionInUse")
    return dict(item.split("=", 1) for item in text.split())


def expect_in_use(display, want, what):
    got = in_use(display)
    bad = {k: (got.get(k), v) for k, v in want.items()
           if not (got.get(k) == v if k == "budget" else got.get(k) is not None and float(got[k]) == float(v))}
    check(not bad, f"{what}: engine holds {got}" + (f", mismatches (got, want): {bad}" if bad else ""))


SIZE = [96, 80]
reader = simple.OpenDataFile(args.model)
view = C.setup_view(SIZE)
display = C.show_inr(reader, view, seed=3, maximum_frames=64, frames_per_render=1, macrocells=8)

# The panel: one "Query reduction" group with the seven settings and the read-back, tooltips
# naming the paper's symbols, the finer knobs under the advanced toggle.
names = ["InrRayBudget", "InrBudgetFraction", "InrBudgetMaxSkip", "InrBudgetAlpha", "InrReproject", "InrPruneEpsilon",
         "InrPruneFalloff", "InrQueryReductionInUse"]
proxy = display.SMProxy
groups = [proxy.GetPropertyGroup(i) for i in range(proxy.GetNumberOfPropertyGroups())]
group = next((g for g in groups if g.GetXMLLabel() == "Query reduction"), None)
check(group is not None, "the representation has a 'Query reduction' property group")
if group is not None:
    members = [group.GetProperty(i) for i in range(group.GetNumberOfProperties())]
    for n in names:
        check(proxy.GetProperty(n) in members, f"{n} is in the 'Query reduction' group")
symbols = {"InrRayBudget": "ρ", "InrBudgetFraction": "ρ", "InrBudgetMaxSkip": "K", "InrBudgetAlpha": "α",
           "InrReproject": "reproject", "InrPruneEpsilon": "ε", "InrPruneFalloff": "δ"}
for n, symbol in symbols.items():
    doc = proxy.GetProperty(n).GetDocumentation()
    text = doc.GetDescription() if doc else ""
    check(symbol in text, f"{n}'s tooltip names {symbol!r}")
for n in names[:-1]:
    want = "advanced" if n in ("InrBudgetMaxSkip", "InrBudgetAlpha", "InrPruneFalloff") else "default"
    got = proxy.GetProperty(n).GetPanelVisibility()
    check(got == want, f"{n} panel visibility {got!r} (want {want!r})")
check(list(display.GetProperty("InrRayBudget").Available) == ["none", "histogram", "stbn", "weighted-stbn"],
      f"InrRayBudget choices {list(display.GetProperty('InrRayBudget').Available)}")

# Defaults (the XML's, equal to inr::QueryReductionSettings' by cli.query_reduction_xml_defaults)
# are what the engine holds after the first render.
defaults = {"budget": display.InrRayBudget, "rho": display.InrBudgetFraction, "K": display.InrBudgetMaxSkip,
            "alpha": display.InrBudgetAlpha, "reproject": display.InrReproject, "epsilon": display.InrPruneEpsilon,
            "delta": display.InrPruneFalloff}
simple.Render(view)
expect_in_use(display, defaults, "defaults reach the engine")

# Every property, set by the name Docs/paraview.md documents, reaches the engine.
display.InrRayBudget = "stbn"
display.InrBudgetFraction = 0.5
display.InrBudgetMaxSkip = 5
display.InrBudgetAlpha = 0.25
display.InrReproject = 1
simple.Render(view)
expect_in_use(display, {"budget": "stbn", "rho": 0.5, "K": 5, "alpha": 0.25, "reproject": 1},
              "budget settings and reprojection reach the engine")
simple.Render(view)
frames = C.info(display, "InrAccumulatedFrames")
check(frames >= 2, f"accumulating with the budget on ({frames} frames after 3 renders)")

# Pruning thresholds change the estimator: the engine restarts the accumulation (one frame per
# render from here: no time budget, so the restarted image holds exactly the render's one frame).
display.InrRefinementTimeBudget = 0.0
display.InrPruneEpsilon = 0.02
display.InrPruneFalloff = 0.01
simple.Render(view)
expect_in_use(display, {"epsilon": 0.02, "delta": 0.01}, "pruning thresholds reach the engine")
after = C.info(display, "InrAccumulatedFrames")
check(after == 1, f"a pruning change restarts the accumulation ({frames} -> {after} frames)")

for scheme in ("histogram", "weighted-stbn"):
    display.InrRayBudget = scheme
    simple.Render(view)
    expect_in_use(display, {"budget": scheme}, f"InrRayBudget = {scheme!r} reaches the engine")

# An invalid value is refused with an error naming it; the engine keeps the previous settings.
display.InrBudgetFraction = 0.0
simple.Render(view)
expect_in_use(display, {"rho": 0.5}, "InrBudgetFraction = 0 is refused, rho stays 0.5")
display.InrBudgetFraction = 0.5

# The old names (before the Inr prefix) still set the engine, for older scripts.
display.RayBudget = "stbn"
display.BudgetFraction = 0.25
simple.Render(view)
expect_in_use(display, {"budget": "stbn", "rho": 0.25}, "the old names RayBudget / BudgetFraction still reach the engine")
display.InrRayBudget = "histogram"
display.InrBudgetFraction = 0.4
simple.Render(view)
expect_in_use(display, {"budget": "histogram", "rho": 0.4}, "the new names win when set after the old ones")
display.InrBudgetFraction = 0.5

# Everything off: exact images again.
display.InrRayBudget = "none"
display.InrReproject = 0
display.InrPruneEpsilon = 0.0
display.InrPruneFalloff = 0.0
display.InrMaximumFrames = 4
display.InrFramesPerRender = 4
out = os.path.join(args.out, "query_reduction_off.png")
simple.SaveScreenshot(out, view, ImageResolution=SIZE)
expect_in_use(display, {"budget": "none", "reproject": 0, "epsilon": 0, "delta": 0},
              "everything off reaches the engine")
check(C.info(display, "InrAccumulatedFrames") == 4, "4 frames after switching everything off")

# The render still shows the volume: the image is not just the background.
img = C.read_png(out)
bg = [255.0 * c for c in C.BACKGROUND]
diff = abs(img - bg).max(axis=2)
covered = float((diff > 8).mean())
check(covered > 0.05, f"the volume covers {100 * covered:.1f}% of the screenshot")

status = check.report()
sys.stdout.flush()
if status:
    sys.exit(status)
