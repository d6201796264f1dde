#!/usr/bin/env python3
"""Check that models load and evaluate with the C++ CLI like the numpy reference evaluator.

    python3 Tools/training/check_cli.py INR_BINARY [MODEL.inr | DIR ...]

For each model: ``inr info`` must succeed, and ``inr eval`` at 256 random world points and
three times must agree with Tools/python/inr_reference.py (float64) to 1e-4 of the model's
value range. Prints one line per model; exit status 1 if any model fails. numpy only.
"""

import glob
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "python"))
from inr_format import read_inr  # noqa: E402
from inr_reference import ReferenceModel  # noqa: E402


def check(inr, path):
    r = subprocess.run([inr, "info", path], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        return False, "inr info failed: %s" % r.stdout.decode().strip()[-300:]
    ref = ReferenceModel.load(path)
    m = read_inr(path)
    b = m.domain["bounds"]
    t0, t1 = m.domain["time_range"]
    vr = m.value_range or [0.0, 1.0]
    span = max(1e-12, vr[1] - vr[0])
    rs = np.random.RandomState(11)
    pts = np.stack([rs.uniform(b[0], b[1], 256), rs.uniform(b[2], b[3], 256),
                    rs.uniform(b[4], b[5], 256)], axis=1)
    worst = 0.0
    for t in (t0, 0.37 * t0 + 0.63 * t1, t1):
        text = "\n".join("%.9g %.9g %.9g" % tuple(p) for p in pts) + "\n"
        r = subprocess.run([inr, "eval", path, "--time", repr(float(t))], input=text.encode(),
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        if r.returncode != 0:
            return False, "inr eval failed: %s" % r.stderr.decode().strip()[-300:]
        got = np.array([float(v) for v in r.stdout.decode().split()])
        if got.size != len(pts):
            return False, "inr eval printed %d values for %d points" % (got.size, len(pts))
        want = ref.evaluate(pts, t)
        worst = max(worst, float(np.max(np.abs(got - want))) / span)
    ok = worst < 1e-4
    return ok, "max |cli - reference| = %.2e of the value range" % worst


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    inr = sys.argv[1]
    paths = []
    for a in sys.argv[2:]:
        paths += sorted(glob.glob(os.path.join(a, "*.inr"))) if os.path.isdir(a) else [a]
    bad = 0
    for p in paths:
        ok, msg = check(inr, p)
        bad += not ok
        print("%-4s %-45s %s (%d bytes)" % ("ok" if ok else "FAIL", os.path.basename(p), msg,
                                            os.path.getsize(p)))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
