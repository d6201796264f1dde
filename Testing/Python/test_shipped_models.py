#!/usr/bin/env python3
"""Shipped test models: evaluate every Testing/Data/models/<name>.inr with ``inr eval`` at the
points and times of <name>.ref.txt (PyTorch float64 reference outputs) and require
|c - r| <= 1e-5 * max(1, |r|). Needs neither PyTorch nor numpy.

    test_shipped_models.py --inr PATH/TO/inr [--models DIR] [--only NAME ...]
"""

import argparse
import collections
import glob
import os
import sys
import tempfile

import inr_test_util as U


def read_ref(path):
    by_t = collections.OrderedDict()
    with open(path) as f:
        for n, line in enumerate(f, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            v = s.split()
            if len(v) != 5:
                raise AssertionError("%s:%d: expected 't x y z value'" % (path, n))
            t, x, y, z, val = map(float, v)
            by_t.setdefault(t, []).append(((x, y, z), val))
    return by_t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--inr", required=True, help="the inr CLI, or 'reference'")
    ap.add_argument("--models", default=os.path.join(U.REPO, "Testing", "Data", "models"))
    ap.add_argument("--only", nargs="*")
    a = ap.parse_args()
    refs = sorted(glob.glob(os.path.join(a.models, "*.ref.txt")))
    if a.only:
        refs = [r for r in refs if os.path.basename(r)[:-len(".ref.txt")] in a.only]
    if not refs:
        print("FAIL: no *.ref.txt files in %s" % a.models)
        return 1
    ok_all = True
    with tempfile.TemporaryDirectory() as tmp:
        for ref in refs:
            model = ref[:-len(".ref.txt")] + ".inr"
            name = os.path.basename(model)
            if not os.path.exists(model):
                print("FAIL %s: %s is missing" % (os.path.basename(ref), name))
                ok_all = False
                continue
            by_t = read_ref(ref)
            n = 0
            for t, rows in by_t.items():
                try:
                    got = U.run_eval(a.inr, model, t, [p for p, _ in rows], tmp)
                except AssertionError as e:
                    print("FAIL %s: %s" % (name, e))
                    ok_all = False
                    break
                ok, _, msg = U.compare("%s t=%g" % (name, t), got, [v for _, v in rows])
                print(("ok   " if ok else "FAIL ") + msg)
                ok_all &= ok
                n += len(rows)
            if n < 100:
                print("FAIL %s: only %d reference values" % (name, n))
                ok_all = False
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
