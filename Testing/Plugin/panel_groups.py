"""The INR Volume panel as the plugin's XML declares it, without ParaView: every property of the
InrVolumeRepresentation proxy is exposed in exactly one of the panel's groups (Rendering,
Macrocells, Shadows, Query reduction, Refinement, in that order), every group names only real
properties, and every property has a tooltip (<Documentation>). With Docs/paraview.md: its table
of property names for pvpython lists every property once, in its group, with the XML's default
(read-only for information properties). Exit status 0 = pass.

  python3 panel_groups.py ServerManagerXML/InrVolumeRepresentation.xml [Docs/paraview.md]
"""
import re
import sys
import xml.etree.ElementTree as ET

GROUPS = ["Rendering", "Macrocells", "Shadows", "Gradient opacity", "Query reduction", "Refinement"]
# The options behind the advanced (gear) toggle that this check pins: the macrocell fine-tuning.
ADVANCED = {"InrSkipBlock", "InrBoundsPadding", "InrGhostPasses", "InrRefineMacrocells"}
# The one switch a user looks for first stays visible.
DEFAULT_VISIBLE = {"InrBackend", "InrMacrocellResolution", "InrShadows", "InrProgressiveRefinement",
                   "InrRayBudget"}

failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what, flush=True)
    if not ok:
        failures.append(what)


root = ET.parse(sys.argv[1]).getroot()
proxy = next(e for e in root.iter("InrVolumeRepresentationProxy") if e.get("name") == "InrVolumeRepresentation")
properties = {e.get("name"): e for e in proxy if e.tag.endswith("Property")}
check(len(properties) > 20, f"{len(properties)} properties declared on InrVolumeRepresentation")

extension = next(e for e in root.iter("Extension") if e.get("name") == "UniformGridRepresentation")
exposed = extension.find("SubProxy/ExposedProperties")
groups = [(g.get("label"), [p.get("name") for p in g.iter("Property")]) for g in exposed.iter("PropertyGroup")]
check([label for label, _ in groups] == GROUPS, f"panel groups {[label for label, _ in groups]} (want {GROUPS})")
ungrouped = [p.get("name") for p in exposed.findall("Property")]
# Outside the groups only the old names of renamed properties: hidden setters of the new property's
# command, not saved in state files, so that older scripts keep working.
renamed = {n: properties.get("Inr" + n) for n in ungrouped}
for n, new in renamed.items():
    old = properties.get(n)
    check(old is not None and new is not None and old.get("command") == new.get("command")
          and old.get("panel_visibility") == "never" and old.get("state_ignored") == "1"
          and old.get("default_values") == new.get("default_values"),
          f"{n}, exposed outside a group, is a hidden, state-ignored old name of Inr{n} (same command and default)")
# ParaView's own Volume properties that INR Volume redeclares (override="1", never shown: the
# panel shows ParaView's row, shared with INR Volume).
paraview_own = {n for n, e in properties.items() if e.get("override") == "1"}
check(paraview_own <= {"SliceFunction"}, f"ParaView's properties redeclared: {sorted(paraview_own)}")
for n in paraview_own:
    check(properties[n].get("panel_visibility") == "never", f"{n} (ParaView's, redeclared) is never shown")
uninrd = [n for n in properties if not n.startswith("Inr") and n not in renamed and n not in paraview_own]
check(not uninrd, f"every property name carries the Inr prefix, old names aside ({uninrd})")

membership = {}
for label, names in groups:
    check(bool(names), f"group {label!r} is not empty")
    for n in names:
        check(n in properties, f"group {label!r}: {n} is a property of InrVolumeRepresentation")
        membership.setdefault(n, []).append(label)
for n, e in properties.items():
    where = membership.get(n, [])
    if e.get("panel_visibility") == "never":
        # Hidden read-back values (e.g. the last render's size and time, for scripts and tests):
        # never shown, so in no group.
        check(not where, f"{n} (never shown) is in no group ({where})")
        continue
    check(len(where) == 1, f"{n} is in exactly one group ({where})")

for n, e in properties.items():
    if n in renamed:
        continue
    doc = e.find("Documentation")
    text = " ".join((doc.text or "").split()) if doc is not None else ""
    check(len(text) >= 30, f"{n} has a tooltip ({len(text)} characters)")
    visibility = e.get("panel_visibility", "default")
    if n in ADVANCED:
        check(visibility == "advanced", f"{n} is behind the advanced toggle ({visibility})")
    if n in DEFAULT_VISIBLE:
        check(visibility == "default", f"{n} is visible by default ({visibility})")

if len(sys.argv) > 2:
    # Rows "| `Name` [⚙] | group | default | what it trades |" of the property table in Docs/paraview.md.
    rows = {}
    for line in open(sys.argv[2], encoding="utf-8"):
        m = re.match(r"\| `(\w+)`( ⚙)? \| ([^|]+) \| ([^|]+) \|", line)
        if m and m.group(1) in properties or (m and m.group(3).strip() in GROUPS):
            check(m.group(1) not in rows, f"table: {m.group(1)} listed once")
            rows[m.group(1)] = (m.group(3).strip(), m.group(4).strip(), bool(m.group(2)))
    shown = {n for n, e in properties.items() if e.get("panel_visibility") != "never"}
    check(set(rows) == shown,
          f"table: the table lists every panel property (missing {sorted(shown - set(rows))}, "
          f"unknown {sorted(set(rows) - shown)})")
    for n, (group, default, advanced) in rows.items():
        if n not in properties:
            continue
        e = properties[n]
        check(membership.get(n) == [group], f"table: {n} in group {group!r} ({membership.get(n)})")
        check(advanced == (e.get("panel_visibility") == "advanced"), f"table: {n} marked advanced as in the XML")
        if e.get("information_only") == "1":
            check(default == "read-only", f"table: {n} is read-only ({default!r})")
            continue
        value = re.search(r"\((-?[\d.]+)\)$", default)
        written = value.group(1) if value else default
        if written == "(empty)":  # a list property without default values
            written = ""
        want = [float(v) for v in e.get("default_values", "").split()]
        try:
            got = [float(v) for v in written.split()]
        except ValueError:
            got = None
        check(got == want, f"table: {n} default {default!r} (XML {e.get('default_values')!r})")

print("RESULT:", "PASS" if not failures else "FAIL " + "; ".join(failures), flush=True)
sys.exit(1 if failures else 0)
