"""The INR Volume panel as the plugin's XML declares it, without ParaView: every property of the
InrVolumeRepresentation proxy is exposed in exactly one of the panel's groups (Rendering,
Macrocells, Shadows, Query reduction, Refinement, in that order), every group names only real
properties, and every property has a tooltip (<Documentation>). Exit status 0 = pass.

  python3 panel_groups.py ServerManagerXML/InrVolumeRepresentation.xml
"""
import sys
import xml.etree.ElementTree as ET

GROUPS = ["Rendering", "Macrocells", "Shadows", "Query reduction", "Refinement"]
# The options behind the advanced (gear) toggle that this check pins: the macrocell fine-tuning.
ADVANCED = {"InrSkipBlock", "InrBoundsPadding", "InrGhostPasses", "InrRefineMacrocells"}
# The one switch a user looks for first stays visible.
DEFAULT_VISIBLE = {"InrBackend", "InrMacrocellResolution", "InrShadows", "InrProgressiveRefinement",
                   "RayBudget"}

failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what, flush=True)
    if not ok:
        failures.append(what)


root = ET.parse(sys.argv[1]).getroot()
proxy = next(e for e in root.iter("RepresentationProxy") if e.get("name") == "InrVolumeRepresentation")
properties = {e.get("name"): e for e in proxy if e.tag.endswith("Property")}
check(len(properties) > 20, f"{len(properties)} properties declared on InrVolumeRepresentation")

extension = next(e for e in root.iter("Extension") if e.get("name") == "UniformGridRepresentation")
exposed = extension.find("SubProxy/ExposedProperties")
groups = [(g.get("label"), [p.get("name") for p in g.iter("Property")]) for g in exposed.iter("PropertyGroup")]
check([label for label, _ in groups] == GROUPS, f"panel groups {[label for label, _ in groups]} (want {GROUPS})")
ungrouped = [p.get("name") for p in exposed.findall("Property")]
check(not ungrouped, f"no property exposed outside a group ({ungrouped})")

membership = {}
for label, names in groups:
    check(bool(names), f"group {label!r} is not empty")
    for n in names:
        check(n in properties, f"group {label!r}: {n} is a property of InrVolumeRepresentation")
        membership.setdefault(n, []).append(label)
for n in properties:
    where = membership.get(n, [])
    check(len(where) == 1, f"{n} is in exactly one group ({where})")

for n, e in properties.items():
    doc = e.find("Documentation")
    text = " ".join((doc.text or "").split()) if doc is not None else ""
    check(len(text) >= 30, f"{n} has a tooltip ({len(text)} characters)")
    visibility = e.get("panel_visibility", "default")
    if n in ADVANCED:
        check(visibility == "advanced", f"{n} is behind the advanced toggle ({visibility})")
    if n in DEFAULT_VISIBLE:
        check(visibility == "default", f"{n} is visible by default ({visibility})")

print("RESULT:", "PASS" if not failures else "FAIL " + "; ".join(failures), flush=True)
sys.exit(1 if failures else 0)
