#!/usr/bin/env python3
"""Writes the tiny model the ParaView plugin tests render (deterministic, numpy only).

    /usr/bin/python3 Testing/Data/Plugin/make_plugin_model.py [OUT.inr]

`clouds.inr`: a one-hidden-layer sine network, 4 -> 24 -> 1, value = 0.5 + 0.5 * net, i.e. a
low-frequency random Fourier series over the box x in [0, 2], y in [-1, 1], z in [0, 1] that
drifts over world time [0, 10]. With an opacity ramp over the upper part of its value range it
renders as a few soft clouds that move and merge. It is ~150 parameters, so CPU rendering in
the tests is fast; the value_range hint is the lattice-sampled range (41^3 points x 11 times).
"""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "Tools", "python"))
from inr_format import write_inr  # noqa: E402

BOUNDS = [0.0, 2.0, -1.0, 1.0, 0.0, 1.0]
TIME_RANGE = [0.0, 10.0]
HIDDEN = 24


def network():
    rng = np.random.default_rng(20240605)
    w1 = np.zeros((HIDDEN, 4), np.float32)
    w1[:, :3] = rng.normal(0.0, 2.2, size=(HIDDEN, 3))   # spatial frequencies (network coords)
    w1[:, 3] = rng.normal(0.0, 0.9, size=HIDDEN)         # slow drift in time
    b1 = rng.uniform(-np.pi, np.pi, size=HIDDEN).astype(np.float32)
    w2 = (rng.normal(0.0, 1.0, size=(1, HIDDEN)) / np.sqrt(HIDDEN) * 0.6).astype(np.float32)
    b2 = np.zeros(1, np.float32)
    return w1, b1, w2, b2


def evaluate(w1, b1, w2, b2, pts):
    """pts: (n, 4) world x y z t -> values (numpy reference of the file's semantics)."""
    lo = np.array([BOUNDS[0], BOUNDS[2], BOUNDS[4], TIME_RANGE[0]])
    hi = np.array([BOUNDS[1], BOUNDS[3], BOUNDS[5], TIME_RANGE[1]])
    net_in = -1.0 + 2.0 * (pts - lo) / (hi - lo)
    h = np.sin(net_in @ w1.T.astype(np.float64) + b1)
    return 0.5 + 0.5 * (h @ w2.T.astype(np.float64) + b2)[:, 0]


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "clouds.inr")
    w1, b1, w2, b2 = network()
    g = np.linspace(0.0, 1.0, 41)
    vals = []
    for t in np.linspace(*TIME_RANGE, 11):
        x, y, z = np.meshgrid(BOUNDS[0] + g * 2.0, BOUNDS[2] + g * 2.0, BOUNDS[4] + g, indexing="ij")
        pts = np.stack([x.ravel(), y.ravel(), z.ravel(), np.full(x.size, t)], axis=1)
        vals.append(evaluate(w1, b1, w2, b2, pts))
    vals = np.concatenate(vals)
    lo, hi = float(np.floor(vals.min() * 100) / 100), float(np.ceil(vals.max() * 100) / 100)
    write_inr(out,
              {"l0.weight": w1, "l0.bias": b1, "l1.weight": w2, "l1.bias": b2},
              architecture={"input_dim": 4, "layers": [
                  {"type": "linear", "weight": "l0.weight", "bias": "l0.bias"},
                  {"type": "sine", "w0": 1.0},
                  {"type": "linear", "weight": "l1.weight", "bias": "l1.bias"}]},
              domain={"bounds": BOUNDS, "time_range": TIME_RANGE},
              output={"scale": 0.5, "offset": 0.5},
              value_range=[lo, hi],
              name="clouds (plugin test model)")
    print(f"wrote {out}: value range [{lo}, {hi}]")


if __name__ == "__main__":
    main()
