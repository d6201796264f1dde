#!/usr/bin/env python3
"""End-to-end checks of the `inr` CLI (standard library only).

usage: test_cli.py INR_EXECUTABLE DATA_DIR CHECK
CHECK is one of the functions named check_* below; exit 0 = pass.
"""
import json
import math
import os
import struct
import shutil
import subprocess
import sys
import tempfile

# Tools/run-sanitizers.sh sets INR_TEST_SMALL=1: instrumented code runs several times slower, so
# the checks that hold at any size render smaller images there (the same checks, fewer pixels).
SMALL = os.environ.get("INR_TEST_SMALL") == "1"


def run(inr, *args, stdin=None):
    p = subprocess.run([inr, *args], input=stdin, capture_output=True, text=True, timeout=300)
    if p.returncode < 0:
        raise AssertionError("inr %s crashed with signal %d\n%s" % (" ".join(args), -p.returncode, p.stderr))
    return p


def expect(cond, msg):
    if not cond:
        raise AssertionError(msg)


def read_control(data):
    """The tiny SIREN of the malformed corpus, read with the standard library."""
    raw = open(os.path.join(data, "malformed", "valid_control.inr"), "rb").read()
    n = struct.unpack("<Q", raw[:8])[0]
    header = json.loads(raw[8:8 + n])
    base = 8 + n
    t = {}
    for name, e in header.items():
        if name == "__metadata__":
            continue
        b, end = e["data_offsets"]
        t[name] = struct.unpack("<%df" % ((end - b) // 4), raw[base + b:base + end])
    return t


def control_value(t, x, y, z, time):
    # domain: box [0,1]^3 and time [0,1], node-centred onto [-1,1]
    inp = [2 * x - 1, 2 * y - 1, 2 * z - 1, 2 * time - 1]
    h = [math.sin(30 * (sum(t["l0.weight"][o * 4 + j] * inp[j] for j in range(4)) + t["l0.bias"][o]))
         for o in range(8)]
    return sum(t["l1.weight"][j] * h[j] for j in range(8)) + t["l1.bias"][0]


def check_eval_matches_reference(inr, data):
    t = read_control(data)
    pts = [(0.1, 0.2, 0.3), (0.9, 0.5, 0.0), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), (0.33, 0.66, 0.99)]
    text = "# comment line\n" + "\n".join("%r %r %r" % p for p in pts) + "\n\n"
    for time in (0.0, 0.25, 1.0):
        p = run(inr, "eval", os.path.join(data, "malformed", "valid_control.inr"), "--time", str(time), stdin=text)
        expect(p.returncode == 0, "eval failed: " + p.stderr)
        got = [float(v) for v in p.stdout.split()]
        expect(len(got) == len(pts), "expected %d values, got %d" % (len(pts), len(got)))
        for g, q in zip(got, pts):
            want = control_value(t, *q, time)
            expect(abs(g - want) <= 1e-5 * max(1.0, abs(want)), "eval %s t=%g: %r vs %r" % (q, time, g, want))


def check_eval_points_file_and_errors(inr, data):
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        pts = os.path.join(d, "pts.txt")
        open(pts, "w").write("0.5 0.5 0.5\n0.1 0.1 0.1\n")
        p = run(inr, "eval", model, "--time", "0.5", "--points", pts)
        expect(p.returncode == 0 and len(p.stdout.split()) == 2, "points file: " + p.stderr)
        open(pts, "w").write("0.5 0.5\n")
        p = run(inr, "eval", model, "--time", "0.5", "--points", pts)
        expect(p.returncode == 1 and "pts.txt:1" in p.stderr, "malformed point line not reported: " + p.stderr)
    p = run(inr, "eval", model, stdin="0 0 0\n")
    expect(p.returncode == 2 and "--time" in p.stderr, "missing --time not a usage error: " + p.stderr)
    p = run(inr, "eval", model, "--time", "abc", stdin="0 0 0\n")
    expect(p.returncode == 2 and "abc" in p.stderr, "bad --time not a usage error: " + p.stderr)
    p = run(inr, "eval", os.path.join(data, "no_such_model.inr"), "--time", "0", stdin="")
    expect(p.returncode == 1 and "cannot open" in p.stderr, "missing model: " + p.stderr)
    p = run(inr, "frobnicate")
    expect(p.returncode == 2, "unknown command must be a usage error")


def check_eval_malformed_input(inr, data):
    """Malformed point lines are errors naming the line (comments and blank lines count); an
    input without points gives no output and exit 0 (documented in `inr eval --help`)."""
    model = os.path.join(data, "malformed", "valid_control.inr")
    cases = [  # (stdin, line number, what the message must say)
        ("0.5 abc 0.5\n", 1, "'abc' is not a number"),
        ("# comment\n\n0.1 0.2 0.3\n0.5 0.5\n", 4, "got 2 field(s)"),
        ("0.5 0.5 0.5 0.5\n", 1, "got 4 field(s)"),
        ("0.5,0.5,0.5\n", 1, "got 1 field(s)"),
        ("0 0 0\nnan 0 0\n", 2, "'nan' is not finite"),
        ("0 inf 0\n", 1, "'inf' is not finite"),
        ("0 0 -Infinity\n", 1, "'-Infinity' is not finite"),
        ("1e39 0 0\n", 1, "'1e39' is outside the fp32 range"),
        ("0 1e999 0\n", 1, "'1e999' is outside the fp32 range"),
        ("0 0 0x\n", 1, "'0x' is not a number"),
    ]
    for text, line, needle in cases:
        p = run(inr, "eval", model, "--time", "0.5", stdin=text)
        expect(p.returncode == 1, "%r: exit %d, want 1: %s" % (text, p.returncode, p.stderr))
        expect("<stdin>:%d:" % line in p.stderr and needle in p.stderr,
               "%r: message lacks '<stdin>:%d:' or %r: %s" % (text, line, needle, p.stderr))
        expect(p.stdout == "", "%r: printed values despite the error: %r" % (text, p.stdout))
    for text in ("", "# only a comment\n\n   \n"):
        p = run(inr, "eval", model, "--time", "0.5", stdin=text)
        expect(p.returncode == 0 and p.stdout == "", "no points %r: exit %d, stdout %r, %s"
               % (text, p.returncode, p.stdout, p.stderr))
    # accepted: CRLF line ends, tabs, exponents, values that underflow to ~0
    p = run(inr, "eval", model, "--time", "0.5", stdin="0.5\t0.5 0.5\r\n1e-400 5e-1 +0.25\n")
    expect(p.returncode == 0 and len(p.stdout.split()) == 2, "valid variants: " + p.stderr)
    p = run(inr, "eval", "--help")
    expect(p.returncode == 0 and "no points" in p.stdout, "--help does not document empty input")


def check_info(inr, data):
    model = os.path.join(data, "malformed", "valid_control.inr")
    p = run(inr, "info", model)
    expect(p.returncode == 0, p.stderr)
    for s in ("linear(4->8) sine(30) linear(8->1)", "parameters:    49", "time range:    [0, 1]"):
        expect(s in p.stdout, "info lacks %r:\n%s" % (s, p.stdout))
    p = run(inr, "info", model, "--json")
    j = json.loads(p.stdout)
    expect(j["parameters"] == 49 and j["input_order"] == "xyzt" and j["time_dependent"], str(j))
    lo, hi = j["sampled_value_range"]["min"], j["sampled_value_range"]["max"]
    expect(lo < hi, "sampled range empty")


def check_malformed_files_fail_cleanly(inr, data):
    manifest = json.load(open(os.path.join(data, "malformed", "manifest.json")))
    for case in manifest:
        path = os.path.join(data, "malformed", case["file"])
        p = run(inr, "info", path)
        expect(p.returncode == 1, "%s: exit %d, want 1" % (case["file"], p.returncode))
        expect(path in p.stderr and case["expect"] in p.stderr,
               "%s: stderr lacks file name or %r: %s" % (case["file"], case["expect"], p.stderr))
        expect(p.stdout == "", "%s: printed to stdout on failure" % case["file"])


def check_slice_png(inr, data):
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "s.png")
        p = run(inr, "slice", model, "--time", "0.5", "--axis", "y", "--size", "40", "-o", out)
        expect(p.returncode == 0, p.stderr)
        raw = open(out, "rb").read()
        expect(raw[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG")
        w, h = struct.unpack(">II", raw[16:24])
        expect((w, h) == (40, 40), "PNG is %dx%d" % (w, h))
        p = run(inr, "slice", model, "--time", "0.5", "-o", os.path.join(d, "s.bmp"))
        expect(p.returncode == 1 and "extension" in p.stderr, "bad extension: " + p.stderr)


def shipped_models(data):
    out = []
    for sub in ("models", "real"):
        d = os.path.join(data, sub)
        if os.path.isdir(d):
            out += sorted(os.path.join(d, f) for f in os.listdir(d) if f.endswith(".inr"))
    return out


def check_every_shipped_model(inr, data):
    """info, eval and a small render work on every shipped model, values are finite and inside a
    sane envelope of the model's value range, and the render is not empty."""
    models = shipped_models(data)
    expect(len(models) >= 5, "expected the shipped test models, found %d" % len(models))
    with tempfile.TemporaryDirectory() as d:
        for m in models:
            p = run(inr, "info", m, "--json")
            expect(p.returncode == 0, "%s: info failed: %s" % (m, p.stderr))
            j = json.loads(p.stdout)
            b, (t0, t1) = j["bounds"], j["time_range"]
            pts = "\n".join("%r %r %r" % (b[0] + f * (b[1] - b[0]), b[2] + f * (b[3] - b[2]), b[4] + f * (b[5] - b[4]))
                            for f in (0.1, 0.5, 0.9)) + "\n"
            p = run(inr, "eval", m, "--time", repr((t0 + t1) / 2), stdin=pts)
            expect(p.returncode == 0, "%s: eval failed: %s" % (m, p.stderr))
            vals = [float(v) for v in p.stdout.split()]
            lo, hi = j["sampled_value_range"]["min"], j["sampled_value_range"]["max"]
            span = max(hi - lo, 1e-6)
            expect(len(vals) == 3 and all(math.isfinite(v) and lo - span <= v <= hi + span for v in vals),
                   "%s: eval values %s outside [%g, %g] +- span" % (m, vals, lo, hi))
            out = os.path.join(d, "r.pfm")
            p = run(inr, "render", m, "--time", repr(t0), "--size", "24x24", "--frames", "2", "--quiet", "-o", out)
            expect(p.returncode == 0, "%s: render failed: %s" % (m, p.stderr))
            raw = open(out, "rb").read()
            header_end = raw.index(b"\n", raw.index(b"\n", 3) + 1) + 1
            floats = struct.unpack("<%df" % ((len(raw) - header_end) // 4), raw[header_end:])
            expect(len(floats) == 24 * 24 * 3 and all(math.isfinite(v) for v in floats), "%s: bad PFM" % m)
            expect(max(floats) > 0.0, "%s: render is empty (all background)" % m)


QUERY_REDUCTION_FLAGS = ("--budget", "--budget-fraction", "--budget-max-skip", "--budget-alpha", "--reproject",
                         "--no-reproject", "--prune-epsilon", "--prune-falloff", "--converge")


def check_query_reduction_errors(inr, data):
    """Every query-reduction option is in --help, and a bad value is a usage error (exit 2) that
    names the option and its valid range, before any work is done."""
    model = os.path.join(data, "malformed", "valid_control.inr")
    p = run(inr, "render", "--help")
    expect(p.returncode == 0, "render --help failed: " + p.stderr)
    for flag in QUERY_REDUCTION_FLAGS:
        expect(flag + " " in p.stdout, "render --help does not list %s" % flag)
    for symbol in ("rho:", "K:", "alpha:", "epsilon:", "delta:"):
        expect(symbol in p.stdout, "render --help does not name the paper's symbol %r" % symbol)
    cases = [  # (arguments, what stderr must contain besides the option's name)
        (["--budget", "foo"], "weighted-stbn"),
        (["--budget-fraction", "0"], "(0, 1]"),
        (["--budget-fraction", "1.5"], "(0, 1]"),
        (["--budget-fraction", "abc"], "not a finite number"),
        (["--budget-max-skip", "-1"], "0..1024"),
        (["--budget-max-skip", "99999999999"], "0..1024"),
        (["--budget-max-skip", "2.5"], "not an integer"),
        (["--budget-alpha", "2"], "[0, 1]"),
        (["--prune-epsilon", "-0.1"], "[0, 1]"),
        (["--prune-falloff", "1.01"], "[0, 1]"),
    ]
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "r.png")
        for extra, needle in cases:
            p = run(inr, "render", model, "--size", "8x8", "--frames", "1", "-o", out, *extra)
            expect(p.returncode == 2, "%s: exit %d, want 2 (usage error): %s" % (extra, p.returncode, p.stderr))
            expect(extra[0] in p.stderr and needle in p.stderr,
                   "%s: message lacks %r or %r: %s" % (extra, extra[0], needle, p.stderr))
            expect(not os.path.exists(out), "%s: wrote an image despite the error" % extra)
        p = run(inr, "render", model, "--size", "8x8", "--method", "raymarch", "--budget", "stbn", "-o", out)
        expect(p.returncode == 2 and "--budget" in p.stderr and "delta tracking" in p.stderr,
               "--budget with --method raymarch must be refused: " + p.stderr)
        p = run(inr, "render", model, "--size", "8x8", "--reproject=1", "-o", out)
        expect(p.returncode == 2 and "--reproject" in p.stderr, "--reproject takes no value: " + p.stderr)


def render_stats(inr, model, d, size, frames, *extra):
    out, stats = os.path.join(d, "r.pfm"), os.path.join(d, "stats.json")
    p = run(inr, "render", model, "--size", "%dx%d" % size, "--frames", str(frames), "--quiet",
            "--backend", "cpu", "--stats-json", stats, "-o", out, *extra)
    expect(p.returncode == 0, "render %s failed: %s" % (" ".join(extra), p.stderr))
    return json.load(open(stats))


def check_query_reduction_stats(inr, data):
    """--stats-json carries the query-reduction settings the renderer ran with (read back from it)
    and per frame the rays cast, the pixels ray budgeting left out and the collisions pruning
    answered, as non-negative integers that fit the image; with everything off nothing is skipped
    or pruned."""
    model = os.path.join(data, "malformed", "valid_control.inr")
    w, h, frames = 20, 16, 4
    with tempfile.TemporaryDirectory() as d:
        runs = {
            "stbn": (["--budget", "stbn", "--budget-fraction", "0.5", "--budget-max-skip", "5", "--budget-alpha",
                      "0.25", "--reproject", "--prune-epsilon", "0.02", "--prune-falloff", "0.01"],
                     {"budget": "stbn", "budget_fraction": 0.5, "budget_max_skip": 5, "budget_alpha": 0.25,
                      "reproject": True, "prune_epsilon": 0.02, "prune_falloff": 0.01}),
            "histogram": (["--budget", "histogram"], {"budget": "histogram"}),
            "weighted-stbn": (["--budget", "weighted-stbn", "--budget-fraction", "0.3"],
                              {"budget": "weighted-stbn", "budget_fraction": 0.3}),
            "off": (["--budget", "none", "--prune-epsilon", "0", "--prune-falloff", "0", "--no-reproject"],
                    {"budget": "none", "prune_epsilon": 0.0, "prune_falloff": 0.0, "reproject": False}),
        }
        for name, (extra, want) in runs.items():
            j = render_stats(inr, model, d, (w, h), frames, *extra)
            q = j.get("query_reduction")
            expect(isinstance(q, dict), "%s: no query_reduction header in --stats-json: %s" % (name, list(j)))
            for k, v in want.items():
                expect(q.get(k) == v, "%s: header %s = %r, want %r" % (name, k, q.get(k), v))
            expect(len(j["frames"]) == frames, "%s: %d per-frame records, want %d" % (name, len(j["frames"]), frames))
            for f in j["frames"] + [j["total"]]:
                for k in ("rays", "budget_skipped", "pruned"):
                    expect(isinstance(f.get(k), int) and not isinstance(f.get(k), bool) and f[k] >= 0,
                           "%s: frame field %s = %r is not a non-negative integer" % (name, k, f.get(k)))
            for f in j["frames"]:
                expect(f["pixels"] == w * h, "%s: pixels %r" % (name, f["pixels"]))
                # A skipped pixel casts no ray.
                expect(f["rays"] + f["budget_skipped"] <= f["pixels"],
                       "%s frame %d: rays %d + skipped %d > pixels %d"
                       % (name, f["frame"], f["rays"], f["budget_skipped"], f["pixels"]))
            if name == "off":
                expect(all(f["budget_skipped"] == 0 and f["pruned"] == 0 for f in j["frames"]),
                       "off: something was skipped or pruned with query reduction off")
                expect(sum(f["rays"] for f in j["frames"]) > 0, "off: no ray entered the volume")
            expect(j["total"]["budget_skipped"] == sum(f["budget_skipped"] for f in j["frames"]),
                   "%s: total budget_skipped is not the sum over frames" % name)


def check_query_reduction_xml_defaults(inr, data):
    """The defaults live in one place, inr::QueryReductionSettings: the CLI runs with them when no
    option is given (read back from the renderer into --stats-json), and the ParaView plugin's XML
    must declare the same default for each property."""
    import xml.etree.ElementTree as ET
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        q = render_stats(inr, model, d, (8, 8), 1)["query_reduction"]
    xml = os.path.join(data, os.pardir, os.pardir, "ServerManagerXML", "InrVolumeRepresentation.xml")
    props = {e.get("name"): e for e in ET.parse(xml).getroot().iter() if e.get("default_values") is not None}
    budget = props["InrRayBudget"]
    entries = {e.get("value"): e.get("text") for e in budget.iter("Entry")}
    expect(entries == {"0": "none", "1": "histogram", "2": "stbn", "3": "weighted-stbn"},
           "InrRayBudget entries %r must be the CLI's scheme names" % entries)
    expect(entries[budget.get("default_values")] == q["budget"],
           "InrRayBudget default %r, struct default %r" % (entries[budget.get("default_values")], q["budget"]))
    for prop, key, cast in (("InrBudgetFraction", "budget_fraction", float), ("InrBudgetMaxSkip", "budget_max_skip", int),
                            ("InrBudgetAlpha", "budget_alpha", float), ("InrReproject", "reproject", lambda v: bool(int(v))),
                            ("InrPruneEpsilon", "prune_epsilon", float), ("InrPruneFalloff", "prune_falloff", float)):
        expect(prop in props, "the XML has no property %s" % prop)
        got = cast(props[prop].get("default_values"))
        expect(got == q[key], "%s: XML default %r, QueryReductionSettings default %r" % (prop, got, q[key]))


def check_estimator_xml_defaults(inr, data):
    """The estimator the CLI uses by default (inr::TrackingOptions::recommended(), read back into
    --stats-json) is the one the plugin's XML declares, entry names included; a bad value is
    refused naming the option."""
    import xml.etree.ElementTree as ET
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        e = render_stats(inr, model, d, (8, 8), 1)["estimator"]
    xml = os.path.join(data, os.pardir, os.pardir, "ServerManagerXML", "InrVolumeRepresentation.xml")
    props = {el.get("name"): el for el in ET.parse(xml).getroot().iter() if el.get("default_values") is not None}
    est = props["InrEstimator"]
    entries = {el.get("value"): el.get("text") for el in est.iter("Entry")}
    expect(entries == {"0": "delta", "1": "ratio", "2": "march", "3": "preintegrated", "4": "debiased"},
           "InrEstimator entries %r" % entries)
    expect(entries[est.get("default_values")] == e["name"],
           "InrEstimator default %r, CLI default %r" % (entries[est.get("default_values")], e["name"]))
    # Pinned by name (as ShippedDefaults.EstimatorIsTheDebiasedMarchWithRatioTrackingAtScale8WhereItFallsBack
    # pins TrackingOptions::recommended()): reverting the CLI and the XML together must fail too.
    expect((e["name"], e["majorant_scale"], e["points_per_iteration"], e["level_ratio"], e["max_level"],
            e["comb_minimum_steps"], e["jitter"], e["fallback_majorant_scale"]) ==
           ("debiased", 2.0, 32, 0.25, 5, 192.0, "stratified", 8.0),
           "the shipped default estimator is the debiased march (K 2, r 0.25, 5 levels, S 192, stratified "
           "jitter, 32 points per batch, ratio K 8 where it falls back); the CLI runs %r" % e)
    for prop, key, cast in (("InrResidualScale", "residual_scale", float),
                            ("InrPointsPerIteration", "points_per_iteration", int),
                            ("InrJitterControlFrames", "jitter_control_frames", int)):
        got = cast(props[prop].get("default_values"))
        expect(got == e[key], "%s: XML default %r, CLI default %r" % (prop, got, e[key]))
    # The density: the XML's 0 is the estimator's own, as the CLI takes it when only --estimator
    # is given (ratio tracking and the march at 8, not the debiased march's 2).
    got = float(props["InrMajorantScale"].get("default_values"))
    expect(got == 0.0, "InrMajorantScale: XML default %r, expected 0 (the estimator's own)" % got)
    with tempfile.TemporaryDirectory() as d:
        for name, scale in (("ratio", 8.0), ("march", 8.0), ("debiased", 2.0), ("preintegrated", 2.0)):
            own = render_stats(inr, model, d, (8, 8), 1, "--estimator", name)["estimator"]
            expect(own["majorant_scale"] == scale, "--estimator %s: majorant scale %r, expected %r" %
                   (name, own["majorant_scale"], scale))
        asked = render_stats(inr, model, d, (8, 8), 1, "--estimator", "ratio", "--majorant-scale", "3")["estimator"]
        expect(asked["majorant_scale"] == 3.0, "--majorant-scale 3 with --estimator ratio: %r" % asked)
    for args, what in ((["--estimator", "ratios"], "--estimator"), (["--majorant-scale", "0.5"], "majorant scale"),
                       (["--points-per-iteration", "65"], "points per iteration"),
                       (["--fallback-majorant-scale", "0.5"], "fallback majorant scale"),
                       (["--jitter-control", "-1"], "jitter control frames"),
                       (["--estimator", "delta", "--method", "raymarch"], "--estimator")):
        p = run(inr, "render", model, "--size", "8x8", *args, "-o", "/nonexistent/x.png")
        expect(p.returncode != 0 and what in p.stderr, "%s: %s" % (" ".join(args), p.stderr))


def check_panel_xml_defaults(inr, data):
    """The INR Volume panel's macrocell options start from the engine's defaults
    (inr::MacrocellOptions, inr::TrackingOptions): the CLI runs with them when no option is given
    (read back from the session into --stats-json) and the plugin's XML must declare the same."""
    import xml.etree.ElementTree as ET
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        m = render_stats(inr, model, d, (8, 8), 1)["macrocells"]
    xml = os.path.join(data, os.pardir, os.pardir, "ServerManagerXML", "InrVolumeRepresentation.xml")
    props = {e.get("name"): e.get("default_values") for e in ET.parse(xml).getroot().iter()
             if e.get("default_values") is not None}
    expect(m["dims"][0] == m["dims"][1] == m["dims"][2], "engine default dims %r are not a cube" % m["dims"])
    for prop, got_engine, cast in (("InrMacrocellResolution", m["dims"][0], int),
                                   ("InrTemporalSlices", m["temporal_slices"], int),
                                   ("InrSkipBlock", m["skip_block"], int),
                                   ("InrBoundsPadding", m["bounds_padding"], float),
                                   ("InrGhostPasses", m["ghost_passes"], int),
                                   ("InrRefineMacrocells", m["refine"], lambda v: bool(int(v)))):
        expect(prop in props, "the XML has no property %s" % prop)
        expect(cast(props[prop]) == got_engine,
               "%s: XML default %r, engine default %r" % (prop, props[prop], got_engine))


def check_brick_errors(inr, data):
    """--brick I/N is checked before anything renders: malformed indices, a non-.npy output and
    another method are refused with the option named."""
    model = os.path.join(data, "malformed", "valid_control.inr")
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "b.npy")
        for bad in ("2/2", "-1/2", "1/0", "x/2", "1"):
            p = run(inr, "render", model, "--size", "8x8", "--brick", bad, "-o", out)
            expect(p.returncode == 2 and "--brick" in p.stderr, "--brick %s must be refused: %s" % (bad, p.stderr))
        p = run(inr, "render", model, "--size", "8x8", "--brick", "0/2", "-o", os.path.join(d, "b.png"))
        expect(p.returncode == 2 and ".npy" in p.stderr, "--brick with a .png output must be refused: " + p.stderr)
        p = run(inr, "render", model, "--size", "8x8", "--brick", "0/2", "--method", "raymarch", "-o", out)
        expect(p.returncode == 2 and "--brick" in p.stderr, "--brick with raymarch must be refused: " + p.stderr)
        p = run(inr, "render", model, "--size", "8x8", "--macrocells", "1", "--brick", "0/2", "-o", out)
        expect(p.returncode == 2 and "macrocells" in p.stderr, "2 bricks of 1 macrocell must be refused: " + p.stderr)


def render_split_part(inr, model, args, option, spec, out_dir):
    """`inr render MODEL ARGS OPTION SPEC` (--brick, --pixel-share or --sample-share I/N) into
    OUT_DIR (made if missing); the .npy path."""
    os.makedirs(out_dir, exist_ok=True)
    out = os.path.join(out_dir, "%s%s.npy" % (option.strip("-")[0], spec.replace("/", "_")))
    p = run(inr, "render", model, *args, option, spec, "-o", out)
    expect(p.returncode == 0, "render %s %s failed: %s" % (option, spec, p.stderr))
    return out


def brick_composite(inr, data, n, shadows):
    """Sub-domain rendering without MPI: N bricks rendered one process each (`inr render --brick
    I/N`, premultiplied RGBA .npy) and composited front to back by Benchmarks/composite_bricks.py
    equal the whole box rendered at once (--brick 0/1) to >= 40 dB over the volume's pixels, seen
    obliquely so that bricks overlap in depth; with 4 bricks, composited in the reverse order they
    do not (the check can fail). Each render converges to 48 dB, which takes the same frames at any
    size: 24x24 under INR_TEST_SMALL."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    script = os.path.join(data, os.pardir, os.pardir, "Benchmarks", "composite_bricks.py")
    common = ["--size", "24x24" if SMALL else "40x40", "--camera", "4.5,-2.5,3,1,0,0.5,0,0,1,30", "--backend", "cpu",
              "--converge", "48", "--frames", "20000", "--quiet"] + (["--shadows"] if shadows else [])
    with tempfile.TemporaryDirectory() as d:
        def brick(spec):
            return render_split_part(inr, model, common, "--brick", spec, d)
        whole = brick("0/1")
        parts = [brick("%d/%d" % (i, n)) for i in range(n)]
        meta = [json.load(open(b[:-4] + ".brick.json")) for b in parts]
        expect(all(m["brick"]["count"] == n for m in meta), "brick descriptions: %r" % meta)
        p = subprocess.run([sys.executable, script, *parts, "--reference", whole, "--min-psnr", "40",
                            "-o", os.path.join(d, "c%d.png" % n)], capture_output=True, text=True, timeout=120)
        print(p.stdout)
        expect(p.returncode == 0, "%d bricks%s: composite differs from the whole render:\n%s%s"
               % (n, " with shadows" if shadows else "", p.stdout, p.stderr))
        expect(os.path.getsize(os.path.join(d, "c%d.png" % n)) > 0, "no composite PNG")
        if n == 4:
            # Back to front (the order reversed) must fail the composite's own 40 dB bound, by a
            # dB at least: the order matters in this view (RESULTS-archive, "Test bounds (the
            # debiased march as the default)").
            p = subprocess.run([sys.executable, "-c", REVERSED_ORDER, script, whole, *parts],
                               capture_output=True, text=True, timeout=120)
            expect(p.returncode == 0, "reverse-order check failed to run: " + p.stderr)
            print("reversed order: %s dB" % p.stdout.split()[-1])
            expect(float(p.stdout.split()[-1]) < 39.0, "4 bricks composited back to front still match: " + p.stdout)


# Four ctest tests (2 and 4 bricks, without and with shadows), so that each stays well inside its
# timeout under the sanitizers on a loaded machine and ctest -j can run them side by side.
def check_brick_composite_2(inr, data):
    brick_composite(inr, data, 2, shadows=False)


def check_brick_composite_4(inr, data):
    brick_composite(inr, data, 4, shadows=False)


def check_brick_composite_2_shadows(inr, data):
    brick_composite(inr, data, 2, shadows=True)


def check_brick_composite_4_shadows(inr, data):
    brick_composite(inr, data, 4, shadows=True)


# The fraction of the whole image's volume pixels (argv[1], alpha > 0) where the sum of the
# pixel shares (argv[2:]) differs by more than 1e-4 in a channel, then their count.
DIFFERING_PIXELS = (
    "import numpy as np, sys; w = np.load(sys.argv[1]); s = sum(np.load(f) for f in sys.argv[2:]); "
    "v = w[..., 3] > 0; d = (np.abs(w - s).max(axis=2) > 1e-4) & v; "
    "print(d.sum() / max(v.sum(), 1), '(%d of %d volume pixels differ)' % (d.sum(), v.sum()))")


def check_pixel_share_composite(inr, data):
    """The image-space split without MPI (`inr render --pixel-share I/N`, what the plugin does per
    rank): N = 2 and 3 shares rendered one process each add up to the whole image (same seed, each
    pixel's stream keyed by its place in the picture) to >= 60 dB over the volume's pixels, and
    with shadows at all but 1% of them; every share's queries are about 1/N of the whole's; a
    share's pixels of other shares are empty; bad specs fail naming the option."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    script = os.path.join(data, os.pardir, os.pardir, "Benchmarks", "composite_bricks.py")
    # Odd sizes, so that no share is a whole number of rows; 29x27 under INR_TEST_SMALL. Pixel
    # shares render without the sub-pixel jitter's control variate (a pixel's neighbours are
    # another share's), so the whole image they are compared with does too.
    common = ["--size", "29x27" if SMALL else "41x37", "--backend", "cpu", "--frames", "32", "--quiet",
              "--jitter-control", "0"]
    with tempfile.TemporaryDirectory() as d:
        for shadows in ([], ["--shadows"]):
            def share(spec):
                return render_split_part(inr, model, [*common, *shadows], "--pixel-share", spec, d)
            whole = share("0/1")
            whole_queries = json.load(open(whole[:-4] + ".brick.json"))["queries"]
            for n in (2, 3):
                parts = [share("%d/%d" % (i, n)) for i in range(n)]
                meta = [json.load(open(b[:-4] + ".brick.json")) for b in parts]
                expect(all(m["split"] == "pixels" and m["brick"]["count"] == n for m in meta), "descriptions: %r" % meta)
                for m in meta:
                    ratio = m["queries"] / (whole_queries / n)
                    expect(abs(ratio - 1) < 0.25, "share %d/%d: queries %s vs whole %s / %d" % (
                        m["brick"]["index"], n, m["queries"], whole_queries, n))
                if shadows:
                    # A share's rays meet the evaluator in other batches than the whole image's,
                    # which rounds a value's last bits differently now and then; with shadows a
                    # pixel's longer paths make that flip a tentative collision's decision in a
                    # pixel or two (RESULTS-archive, "Honest convergence estimate"). So here: all
                    # but 1% of the volume's pixels equal to 1e-4 (a wrong mapping of frames or
                    # streams changes nearly all of them).
                    p = subprocess.run([sys.executable, "-c", DIFFERING_PIXELS, whole, *parts],
                                       capture_output=True, text=True, timeout=120)
                    print("%d shares with shadows: %s" % (n, p.stdout.strip()))
                    expect(p.returncode == 0 and float(p.stdout.split()[0]) <= 0.01,
                           "%d shares with shadows: the sum differs from the whole render: %s%s"
                           % (n, p.stdout, p.stderr))
                    continue
                p = subprocess.run([sys.executable, script, *parts, "--reference", whole, "--min-psnr", "60"],
                                   capture_output=True, text=True, timeout=120)
                print(p.stdout)
                expect(p.returncode == 0, "%d shares: sum differs from the whole render:\n%s%s"
                       % (n, p.stdout, p.stderr))
        check = subprocess.run([sys.executable, "-c",
                                "import numpy as np, sys; a = np.load(sys.argv[1]); h, w, _ = a.shape; "
                                "print(int(sum(np.abs(a[y, x]).sum() > 0 for y in range(h) for x in range(w) if (x + y) % 3 != 1)))",
                                os.path.join(d, "p1_3.npy")], capture_output=True, text=True, timeout=60)
        expect(check.returncode == 0 and check.stdout.strip() == "0",
               "share 1/3 has non-empty pixels of other shares: " + check.stdout + check.stderr)
    for spec, what in (("3/3", "--pixel-share"), ("0/0", "--pixel-share"), ("x", "--pixel-share")):
        p = run(inr, "render", model, "--pixel-share", spec, "-o", "/nonexistent/x.npy")
        expect(p.returncode != 0 and what in p.stderr, "--pixel-share %s: %s" % (spec, p.stderr))
    p = run(inr, "render", model, "--pixel-share", "0/2", "--brick", "0/2", "-o", "/nonexistent/x.npy")
    expect(p.returncode != 0 and "give one" in p.stderr, "both splits: " + p.stderr)


def check_sample_share_composite(inr, data):
    """The sample-space split without MPI (`inr render --sample-share I/N`): every share renders
    every pixel of its own frames (share I's local frame f is frame f*N + I of one render), so the
    shares' frame-weighted mean (Benchmarks/composite_bricks.py) equals one render of all their
    frames, to float rounding without macrocell refinement (>= 90 dB over the volume's pixels;
    their queries add up exactly), for 2 shares of 12 frames and 4 uneven shares (3 + 3 + 2 + 2)
    of 10, with shadows; shares that all render the same frames do not (< 60 dB). With refinement
    on it stays close (>= 45 dB). The stats record the split; --converge prints the shares'
    expected mean; bad specs and a second split fail naming the option."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    script = os.path.join(data, os.pardir, os.pardir, "Benchmarks", "composite_bricks.py")
    common = ["--size", "29x27" if SMALL else "41x37", "--backend", "cpu", "--shadows", "--quiet"]
    with tempfile.TemporaryDirectory() as d:
        def part(spec, frames, *extra):
            out = render_split_part(inr, model, [*common, "--frames", str(frames), *extra], "--sample-share", spec, d)
            meta = json.load(open(out[:-4] + ".brick.json"))
            expect(meta["split"] == "samples" and meta["frames"] == frames, "description: %r" % meta)
            return out, meta

        def composite(parts, whole, min_psnr=None):
            p = subprocess.run([sys.executable, script, *parts, "--reference", whole] +
                               (["--min-psnr", str(min_psnr)] if min_psnr else []),
                               capture_output=True, text=True, timeout=120)
            print(p.stdout)
            expect(p.returncode == 0, "composite of %s:\n%s%s" % (parts, p.stdout, p.stderr))
            return float(p.stdout.split("composite vs ")[1].split("PSNR ")[1].split(" dB")[0])

        for total, n in ((12, 2), (10, 4)):
            whole, whole_meta = part("0/1", total, "--no-refine")
            parts = [part("%d/%d" % (i, n), (total - i + n - 1) // n, "--no-refine", "--stats-json",
                          os.path.join(d, "s%d.json" % i)) for i in range(n)]
            expect(sum(m["queries"] + m["shadow_queries"] for _, m in parts) ==
                   whole_meta["queries"] + whole_meta["shadow_queries"],
                   "the shares' queries must add up to the whole render's: %r vs %r" % ([m for _, m in parts], whole_meta))
            stats = json.load(open(os.path.join(d, "s1.json")))
            expect(stats["split"] == {"kind": "samples", "index": 1, "count": n}, "stats split: %r" % stats.get("split"))
            composite([p for p, _ in parts], whole, 90)
            # The control: shares that all rendered frames 0, 1, ... average to one render of those
            # frames, which is not the whole render.
            same = render_split_part(inr, model, [*common, "--frames", str(total // n), "--no-refine"],
                                     "--sample-share", "0/1", os.path.join(d, "same"))
            psnr = composite([same], whole)
            expect(psnr < 60, "shares without their own frames still match the whole render (%.1f dB)" % psnr)
        whole, _ = part("0/1", 12)
        composite([part("%d/2" % i, 6)[0] for i in range(2)], whole, 45)
        p = subprocess.run([inr, "render", model, "--size", "16x16", "--backend", "cpu", "--frames", "40", "--converge",
                            "20", "--sample-share", "1/4", "-o", os.path.join(d, "c.npy")],
                           capture_output=True, text=True, timeout=300)
        expect(p.returncode == 0 and "sample share 1/4: the average of all 4 shares" in p.stdout,
               "--converge with a sample share: " + p.stdout + p.stderr)
    for spec in ("4/4", "0/0", "x"):
        p = run(inr, "render", model, "--sample-share", spec, "-o", "/nonexistent/x.npy")
        expect(p.returncode == 2 and "--sample-share" in p.stderr, "--sample-share %s: %s" % (spec, p.stderr))
    p = run(inr, "render", model, "--sample-share", "0/2", "--pixel-share", "1/2", "-o", "/nonexistent/x.npy")
    expect(p.returncode == 2 and "give one" in p.stderr, "both splits: " + p.stderr)


def split_on_gpus(inr, data, option, count):
    """`count` parts (`option` I/N) of a paper-size model rendered at once, one process per GPU
    (CUDA_VISIBLE_DEVICES), composited, equal the one-GPU image to >= 40 dB over the volume's
    pixels, with shadows; pixel shares render all 512 frames, sample shares 512 / count each.
    Exits 77 (skipped, with the reason) where fewer than two GPUs are visible; uses at most the
    GPUs visible."""
    p = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True, text=True) \
        if shutil.which("nvidia-smi") else None
    gpus = [l for l in (p.stdout.splitlines() if p and p.returncode == 0 else []) if l.strip()]
    if len(gpus) < 2:
        print("SKIPPED: needs 2 GPUs, nvidia-smi lists %d" % len(gpus))
        sys.exit(77)
    count = min(count, len(gpus))
    print("GPUs:", gpus, "parts:", count)
    # The compositing script needs numpy, which the test's own interpreter may lack.
    python = next((py for py in (sys.executable, shutil.which("python3"), "/usr/bin/python3")
                   if py and subprocess.run([py, "-c", "import numpy"], capture_output=True).returncode == 0), None)
    expect(python is not None, "no Python with numpy for Benchmarks/composite_bricks.py (apt install python3-numpy)")
    model = os.path.join(data, "real", "siren_cylinder_vorticity.inr")
    script = os.path.join(data, os.pardir, os.pardir, "Benchmarks", "composite_bricks.py")
    common = ["--size", "512x512", "--backend", "cuda", "--shadows", "--time", "2", "--tf", model[:-4] + ".tf.json",
              "--quiet"]
    part_frames = 512 // count if option == "--sample-share" else 512
    with tempfile.TemporaryDirectory() as d:
        whole = os.path.join(d, "whole.npy")
        p = subprocess.run([inr, "render", model, *common, "--frames", "512", option, "0/1", "-o", whole],
                           env=dict(os.environ, CUDA_VISIBLE_DEVICES="0"), capture_output=True, text=True, timeout=300)
        expect(p.returncode == 0, "one GPU: " + p.stderr)
        procs = [subprocess.Popen([inr, "render", model, *common, "--frames", str(part_frames), option,
                                   "%d/%d" % (i, count), "-o", os.path.join(d, "p%d.npy" % i)],
                                  env=dict(os.environ, CUDA_VISIBLE_DEVICES=str(i)),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(count)]
        for i, q in enumerate(procs):
            out, err = q.communicate(timeout=300)
            expect(q.returncode == 0, "GPU %d: %s" % (i, err))
            meta = json.load(open(os.path.join(d, "p%d.brick.json" % i)))
            expect("cuda" in meta["backend"].lower(), "GPU %d ran on %s" % (i, meta["backend"]))
        p = subprocess.run([python, script, *[os.path.join(d, "p%d.npy" % i) for i in range(count)],
                            "--reference", whole, "--min-psnr", "40"], capture_output=True, text=True, timeout=120)
        print(p.stdout)
        expect(p.returncode == 0, "%d GPUs composited differ from one GPU:\n%s%s" % (count, p.stdout, p.stderr))


def check_pixel_share_two_gpus(inr, data):
    """Issue 16 on a 2-GPU machine: two pixel shares on two GPUs (split_on_gpus)."""
    split_on_gpus(inr, data, "--pixel-share", 2)


def check_sample_share_gpus(inr, data):
    """Issue 31: sample shares on up to 4 GPUs (split_on_gpus), 128 frames each for 4."""
    split_on_gpus(inr, data, "--sample-share", 4)


def check_raymarch_backend(inr, data):
    """--method raymarch marches on the session's backend: the CPU marcher with --backend cpu;
    with --backend cuda the GPU marcher, shadows and --shade included. The stats' "marcher"
    and the "ray marcher:" line say which. The CUDA half is skipped (said in the output) where
    --backend cuda cannot run."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    common = ["--method", "raymarch", "--size", "16x12", "--frames", "1"]
    with tempfile.TemporaryDirectory() as d:
        out, stats = os.path.join(d, "m.png"), os.path.join(d, "s.json")

        def marcher(*extra):
            p = run(inr, "render", model, "-o", out, "--stats-json", stats, *common, *extra)
            if p.returncode != 0:
                return p, None
            report = json.load(open(stats))
            expect("ray marcher: " + report["marcher"] in p.stdout, "no 'ray marcher:' line: " + p.stdout)
            return p, report["marcher"]

        p, m = marcher("--backend", "cpu")
        expect(m == "CPU ray marcher", "--backend cpu: %s %s" % (m, p.stderr))
        p, m = marcher("--backend", "cuda")
        if m is None:
            expect("unavailable" in p.stderr or "CUDA" in p.stderr, "--backend cuda failed: " + p.stderr)
            print("CUDA half skipped: " + p.stderr.strip())
            return
        expect(m == "GPU ray marcher", "--backend cuda runs %s" % m)
        p, m = marcher("--backend", "cuda", "--shadows")
        expect(m == "GPU ray marcher", "--backend cuda --shadows runs %s %s" % (m, p.stderr))
        p, m = marcher("--backend", "cuda", "--shade")
        expect(m == "GPU ray marcher", "--backend cuda --shade runs %s %s" % (m, p.stderr))


def read_pfm_rgb(path):
    """A PFM's pixels as rows (top row first) of (r, g, b)."""
    raw = open(path, "rb").read()
    lines = raw.split(b"\n", 3)
    w, h = (int(v) for v in lines[1].split())
    floats = struct.unpack("<%df" % (w * h * 3), lines[3][:w * h * 12])
    rows = [[floats[3 * (y * w + x):3 * (y * w + x) + 3] for x in range(w)] for y in range(h)]
    return rows[::-1]  # PFM stores rows bottom to top


BLEND_ERRORS = [  # (arguments, what stderr must name)
    (["--blend", "mip"], "--blend"),
    (["--blend", "isosurface"], "--iso"),
    (["--iso", "0.1"], "--iso needs --blend isosurface"),
    (["--blend", "isosurface", "--iso", "0.1,nan"], "--iso"),
    (["--blend", "isosurface", "--iso", "0.1", "--iso-step", "1.5"], "--iso-step"),
    (["--blend", "isosurface", "--iso", "0.1", "--iso-tolerance", "0"], "--iso-tolerance"),
    (["--blend", "slice", "--slice-normal", "0,0,0"], "--slice-normal"),
    (["--blend", "slice", "--slice-origin", "1,2"], "--slice-origin"),
    (["--slice-opaque"], "--slice-opaque needs --blend slice"),
    (["--crop", "0,1,0,1"], "--crop"),
    (["--crop", "0.5,0.2,0,1,0,1"], "--crop"),
    (["--crop", "2,3,2,3,2,3"], "--crop"),  # no overlap with the model's box (found once it loads)
    (["--crop", "0,1,0,1,0,1", "--method", "raymarch"], "--crop"),
    (["--blend", "slice", "--method", "raymarch"], "--method"),
    (["--blend", "slice", "--shadows"], "--shadows"),
    (["--blend", "isosurface", "--iso", "0.1", "--converge", "40"], "--converge"),
]


def check_blend_errors(inr, data):
    """--blend and its options are in --help, and a bad value or an option of another mode is a
    usage error (exit 2) naming the option, with no image written."""
    model = os.path.join(data, "malformed", "valid_control.inr")
    p = run(inr, "render", "--help")
    for flag in ("--blend", "--iso", "--iso-step", "--iso-tolerance", "--slice-origin", "--slice-normal",
                 "--slice-opaque", "--crop"):
        expect(flag + " " in p.stdout, "render --help does not list %s" % flag)
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "r.png")
        for extra, needle in BLEND_ERRORS:
            p = run(inr, "render", model, "--size", "8x8", "--backend", "cpu", "-o", out, *extra)
            expect(p.returncode == 2, "%s: exit %d, want 2 (usage error): %s" % (extra, p.returncode, p.stderr))
            expect(needle in p.stderr, "%s: message lacks %r: %s" % (extra, needle, p.stderr))
            expect(not os.path.exists(out), "%s: wrote an image despite the error" % extra)
        # Control: the same options where they apply render.
        for extra in (["--blend", "slice", "--slice-normal", "0,1,0", "--crop", "0,1,0,1,0,0.5"],
                      ["--blend", "isosurface", "--iso", "0.1,0.2"], ["--crop", "0,1,0,1,0,0.5", "--frames", "2"]):
            p = run(inr, "render", model, "--size", "8x8", "--backend", "cpu", "-o", out, *extra)
            expect(p.returncode == 0, "%s: %s" % (extra, p.stderr))


def check_blend_slice_values(inr, data):
    """--blend slice: with a grey ramp over the value range and --slice-opaque, each pixel of a
    parallel view down -z is the network's value where its ray meets the plane z = Z (the tiny
    SIREN's value computed here in Python); the plane at another Z is the control. One query per
    covered pixel. --crop clips the plane."""
    t = read_control(data)
    model = os.path.join(data, "malformed", "valid_control.inr")
    lo, hi = -3.0, 3.0
    n, z, time = 24, 0.37, 0.5
    with tempfile.TemporaryDirectory() as d:
        tf = os.path.join(d, "grey.json")
        json.dump([{"RGBPoints": [lo, 0, 0, 0, hi, 1, 1, 1], "Points": [lo, 1, 0.5, 0, hi, 1, 0.5, 0]}], open(tf, "w"))
        out, stats = os.path.join(d, "s.pfm"), os.path.join(d, "s.json")
        common = ["--blend", "slice", "--slice-opaque", "--slice-origin", "0.3,0.6,%r" % z, "--slice-normal", "0,0,1",
                  "--camera", "0.5,0.5,3,0.5,0.5,0.5,0,1,0,30", "--parallel-scale", "0.5", "--size", "%dx%d" % (n, n),
                  "--time", repr(time), "--tf", tf, "--backend", "cpu", "--stats-json", stats, "-o", out]
        p = run(inr, "render", model, *common)
        expect(p.returncode == 0, p.stderr)
        rows = read_pfm_rgb(out)
        report = json.load(open(stats))
        expect(report["blend"]["mode"] == "slice" and report["total"]["queries"] == n * n,
               "want one query per pixel: %s" % report["total"])

        def error_against(zz):
            worst = 0.0
            for py in range(n):
                for px in range(n):
                    x, y = (px + 0.5) / n, 1.0 - (py + 0.5) / n
                    v = control_value(t, x, y, zz, time)
                    want = min(1.0, max(0.0, (v - lo) / (hi - lo)))
                    worst = max(worst, abs(rows[py][px][0] - want))
            return worst

        err, control = error_against(z), error_against(z + 0.05)
        print("slice: max error %.3g, plane moved: %.3g" % (err, control))
        expect(err < 2e-3, "slice differs from the network's values by %g" % err)
        expect(control > 0.02, "control: the moved plane should differ (%g)" % control)
        p = run(inr, "render", model, *common, "--crop", "0,0.5,0,1,0,1")
        expect(p.returncode == 0, p.stderr)
        cropped = read_pfm_rgb(out)
        kept = sum(1 for py in range(n) for px in range(n) if cropped[py][px] == rows[py][px])
        empty = sum(1 for py in range(n) for px in range(n) if max(cropped[py][px]) == 0.0)
        expect(kept >= n * n // 2 - n and empty >= n * n // 2 - n,
               "--crop 0,0.5: want the left half kept, the right half empty: %d kept, %d empty" % (kept, empty))


def check_blend_isosurface(inr, data):
    """--blend isosurface renders a lit surface in one frame (its stats: the mode, isovalues, the
    step and tolerance, gradient queries for the lit hits); --crop removes part of it, and of the
    composite volume too."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    p = run(inr, "info", model, "--json")
    j = json.loads(p.stdout)
    lo, hi = j["sampled_value_range"]["min"], j["sampled_value_range"]["max"]
    iso = lo + 0.6 * (hi - lo)
    b = j["bounds"]
    with tempfile.TemporaryDirectory() as d:
        out, stats = os.path.join(d, "i.pfm"), os.path.join(d, "i.json")

        def render(*extra):
            p = run(inr, "render", model, "--blend", "isosurface", "--iso", repr(iso), "--size", "48x48",
                    "--backend", "cpu", "--stats-json", stats, "-o", out, *extra)
            expect(p.returncode == 0, p.stderr)
            rows = read_pfm_rgb(out)
            return json.load(open(stats)), sum(1 for r in rows for c in r if max(c) > 0.0)

        report, covered = render()
        expect(report["blend"]["mode"] == "isosurface" and report["blend"]["isovalues"] == [iso], report["blend"])
        expect(report["frames_requested"] == 1 and len(report["frames"]) == 1, "one frame by default")
        expect(report["total"]["shading_queries"] > 0, "the surface is lit from the gradient: %s" % report["total"])
        expect(report["blend"]["tolerance"] < report["blend"]["step"], report["blend"])
        expect(covered > 40, "the isosurface covers %d pixels" % covered)
        half = "%r,%r,%r,%r,%r,%r" % (b[0], (b[0] + b[1]) / 2, b[2], b[3], b[4], b[5])
        _, coveredCropped = render("--crop", half)
        print("isosurface: %d covered pixels, %d cropped" % (covered, coveredCropped))
        expect(coveredCropped < covered, "--crop to half the box should cover fewer pixels")

        # The composite's crop clips its camera rays: half the box shows less of the volume.
        def composite(*extra):
            p = run(inr, "render", model, "--size", "32x32", "--frames", "4", "--backend", "cpu", "--quiet", "-o", out,
                    *extra)
            expect(p.returncode == 0, p.stderr)
            return sum(sum(c) for r in read_pfm_rgb(out) for c in r)

        whole, cropped = composite(), composite("--crop", half)
        print("composite: brightness %.1f, cropped %.1f" % (whole, cropped))
        expect(0.0 < cropped < 0.9 * whole, "--crop with --blend composite should clip the volume")


def check_tf2d(inr, data):
    """--tf2d: a 2D transfer function opaque only at low gradient magnitudes and its mirror (opaque
    only at high ones) both show the model, differently, and ask for gradients; one transparent
    everywhere shows the background; a malformed file fails naming the file and the key."""
    model = os.path.join(data, "models", "siren_blobs.inr")
    j = json.loads(run(inr, "info", model, "--json").stdout)
    lo, hi = j["sampled_value_range"]["min"], j["sampled_value_range"]["max"]
    b = j["bounds"]
    # The median gradient magnitude (central differences of eval at a lattice of points) splits
    # the gradient axis.
    h = 1e-3 * (b[1] - b[0])
    pts, n = [], 6
    for i in range(n):
        for k in range(n):
            for m in range(n):
                c = [b[0] + (i + 0.5) / n * (b[1] - b[0]), b[2] + (k + 0.5) / n * (b[3] - b[2]),
                     b[4] + (m + 0.5) / n * (b[5] - b[4])]
                for a in range(3):
                    for sgn in (1, -1):
                        q = list(c)
                        q[a] += sgn * h
                        pts.append(q)
    p = run(inr, "eval", model, "--time", "0", stdin="\n".join("%r %r %r" % tuple(q) for q in pts) + "\n")
    expect(p.returncode == 0, p.stderr)
    v = [float(x) for x in p.stdout.split()]
    mags = sorted(math.sqrt(sum(((v[6 * e + 2 * a] - v[6 * e + 2 * a + 1]) / (2 * h)) ** 2 for a in range(3)))
                  for e in range(n ** 3))
    g_mid = mags[len(mags) // 2]
    with tempfile.TemporaryDirectory() as d:
        out, stats = os.path.join(d, "t.pfm"), os.path.join(d, "t.json")

        def render(rows, seed=1):
            """rows: opacity of row 0 (|grad f| = 0) and row 1 (2 x the median); colour by value."""
            tf = {"ScalarRange": [lo, hi], "GradientRange": [0.0, 2.0 * g_mid], "Width": 2, "Height": 2,
                  "RGBA": [0.2, 0.4, 1.0, rows[0], 1.0, 0.6, 0.2, rows[0], 0.2, 0.4, 1.0, rows[1], 1.0, 0.6, 0.2, rows[1]]}
            path = os.path.join(d, "tf2d.json")
            json.dump(tf, open(path, "w"))
            p = run(inr, "render", model, "--tf2d", path, "--size", "32x32", "--frames", "8", "--backend", "cpu",
                    "--quiet", "--seed", str(seed), "--stats-json", stats, "-o", out)
            expect(p.returncode == 0, p.stderr)
            return read_pfm_rgb(out), json.load(open(stats))

        def difference(a, b):
            return sum(abs(x - y) for ra, rb in zip(a, b) for ca, cb in zip(ra, rb) for x, y in zip(ca, cb))

        low, low_stats = render([0.05, 0.0])
        high, _ = render([0.0, 0.05])
        empty, _ = render([0.0, 0.0])
        bright = lambda img: sum(sum(c) for r in img for c in r)  # noqa: E731
        low_again, _ = render([0.05, 0.0], seed=2)
        diff, noise = difference(low, high), difference(low, low_again)  # (noise: another seed)
        print("tf2d: median |grad f| %.4g; brightness low-gradient %.2f, high-gradient %.2f, transparent %.2f, "
              "difference %.2f (another seed: %.2f); gradient queries %d" % (g_mid, bright(low), bright(high), bright(empty), diff, noise,
                                                         low_stats["total"]["gradient_opacity_queries"]))
        expect(bright(low) > 1.0 and bright(high) > 1.0, "both 2D transfer functions show the model")
        expect(diff > 3.0 * noise, "the gradient axis changes the picture beyond the noise")
        expect(bright(empty) == 0.0, "a transparent 2D transfer function shows the background")
        expect(low_stats["total"]["gradient_opacity_queries"] > 0, "the samples asked for gradients")
        bad = os.path.join(d, "bad.json")
        open(bad, "w").write('{"GradientRange": [0, 1], "Width": 1, "Height": 1, "RGBA": [0, 0, 0, 0]}')
        p = run(inr, "render", model, "--tf2d", bad, "--size", "8x8", "--backend", "cpu", "--quiet", "-o", out)
        expect(p.returncode != 0 and bad in p.stderr and "ScalarRange" in p.stderr,
               "a file without ScalarRange must fail naming it: %d %s" % (p.returncode, p.stderr))


# Composites the bricks in the reverse of their visibility order and prints the PSNR against the
# whole render: argv = script, whole, bricks...
REVERSED_ORDER = """
import importlib.util, sys, numpy as np
spec = importlib.util.spec_from_file_location("cb", sys.argv[1]); cb = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cb)
whole = np.load(sys.argv[2]).astype(float)
loaded = [cb.load_brick(p) for p in sys.argv[3:]]
order = cb.visibility_order([m["box"] for _, m in loaded], cb.eye_of(loaded[0][1]["camera"]))[::-1]
out = np.zeros_like(whole)
for k in order:
    out += (1.0 - out[..., 3:4]) * loaded[k][0]
print(cb.psnr_over_volume(out, whole)[0])
"""


if __name__ == "__main__":
    inr, data, check = sys.argv[1:4]
    globals()["check_" + check](inr, data)
    print("PASS", check)
