"""Shared helpers for the Python-side tests (exporter round trips, shipped models).

Evaluators: ``--inr PATH`` runs the C++ CLI (``inr eval FILE --time T --points PTS``);
``--inr reference`` uses Tools/python/inr_reference.py instead (for development before the
CLI exists; ctest always passes the CLI).
"""

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
TOOLS = os.path.join(REPO, "Tools", "python")
sys.path.insert(0, TOOLS)

SKIP = 77  # ctest SKIP_RETURN_CODE
TOL = 1e-5


def require_torch():
    """Import torch, or print SKIP and exit with the ctest skip code."""
    try:
        import torch  # noqa: F401
        return torch
    except ImportError as e:
        print("SKIP: PyTorch is not importable by %s (%s); install python3-torch"
              % (sys.executable, e))
        sys.exit(SKIP)


def run_eval(inr, model, t, points, tmpdir):
    """Evaluate ``model`` at world ``points`` (list of (x, y, z)) and time ``t``."""
    pts = os.path.join(tmpdir, "points.txt")
    with open(pts, "w") as f:
        for p in points:
            f.write("%.17g %.17g %.17g\n" % tuple(p))
    if inr == "reference":
        cmd = [sys.executable, os.path.join(TOOLS, "inr_reference.py")]
    else:
        cmd = [inr]
    cmd += ["eval", model, "--time", "%.17g" % t, "--points", pts] if inr != "reference" \
        else [model, "--time", "%.17g" % t, "--points", pts]
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       universal_newlines=True)
    if r.returncode != 0:
        raise AssertionError("%s failed (exit %d): %s" % (" ".join(cmd), r.returncode,
                                                          r.stderr.strip()))
    vals = [float(v) for v in r.stdout.split()]
    if len(vals) != len(points):
        raise AssertionError("%s printed %d values for %d points"
                             % (" ".join(cmd), len(vals), len(points)))
    return vals


def compare(label, got, want, tol=TOL):
    """Return (ok, worst relative error, message) for |c - r| <= tol * max(1, |r|)."""
    worst, worst_i = 0.0, -1
    for i, (c, r) in enumerate(zip(got, want)):
        if c != c:  # NaN
            return False, float("inf"), "%s: point %d: got NaN, want %.9g" % (label, i, r)
        e = abs(c - r) / max(1.0, abs(r))
        if e > worst:
            worst, worst_i = e, i
    ok = worst <= tol
    msg = "%s: %d values, worst |c-r|/max(1,|r|) = %.3g%s" % (
        label, len(got), worst,
        "" if ok else " at point %d (got %.9g, want %.9g) > %g"
        % (worst_i, got[worst_i], want[worst_i], tol))
    return ok, worst, msg
