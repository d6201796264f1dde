#!/usr/bin/env python3
"""Pure-numpy float64 reference evaluator for INR Volume files (Docs/FORMAT.md).

Slow but simple: it is the executable reading of the format spec that the Python tools and
tests use to cross-check the exporter and the C++ evaluators.

Library::

    from inr_reference import ReferenceModel
    m = ReferenceModel.load("model.inr")
    values = m.evaluate(xyz, t)        # xyz: (N, 3) world coordinates, t: world time

Command line (same contract as ``inr eval``)::

    inr_reference.py MODEL --time T [--points FILE]   # points "x y z" per line (stdin if none)
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from inr_format import FormatError, read_inr  # noqa: E402
import inr_hashgrid  # noqa: E402

_LAYER_FIELDS = {
    "fourier": {"B", "frequency_scale", "include_input"},
    "hashgrid": {"table", "include_input"} | set(inr_hashgrid.HashGridSpec.FIELDS),
    "linear": {"weight", "bias"},
    "sine": {"w0"},
    "silu": set(), "relu": set(), "sigmoid": set(), "tanh": set(), "identity": set(),
    "scale": {"factor"},
    "residual": {"body", "shortcut", "scale"},
}
_DOMAIN_FIELDS = {"bounds", "input_range", "centering", "resolution", "time_range",
                  "time_input_range", "input_order", "time_steps"}


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))


class ReferenceModel(object):
    def __init__(self, inr):
        self.inr = inr
        self.where = inr.path
        self._used = set()
        arch = inr.architecture
        if set(arch) - {"input_dim", "layers"}:
            raise FormatError("%s: architecture: unknown keys %s"
                              % (self.where, sorted(set(arch) - {"input_dim", "layers"})))
        self.input_dim = int(arch["input_dim"])
        self.layers, out = self._check_layers(arch["layers"], self.input_dim, "layers")
        if out != 1:
            raise FormatError("%s: final width is %d, must be 1" % (self.where, out))
        unused = set(inr.tensors) - self._used
        if unused:
            raise FormatError("%s: tensors not referenced by the architecture: %s"
                              % (self.where, sorted(unused)))
        self._setup_domain(inr.domain)
        self._setup_output(inr.output)

    @classmethod
    def load(cls, path):
        return cls(read_inr(path))

    # ----------------------------------------------------------------- architecture
    def _tensor(self, name, what):
        if name not in self.inr.tensors:
            raise FormatError("%s: %s: tensor %r does not exist" % (self.where, what, name))
        if name in self._used:
            raise FormatError("%s: %s: tensor %r referenced twice" % (self.where, what, name))
        self._used.add(name)
        return self.inr.tensors[name].astype(np.float64)

    def _check_layers(self, layers, width, path):
        out = []
        for i, L in enumerate(layers):
            what = "%s[%d]" % (path, i)
            kind = L.get("type")
            if kind not in _LAYER_FIELDS:
                raise FormatError("%s: %s: unknown layer type %r" % (self.where, what, kind))
            extra = set(L) - _LAYER_FIELDS[kind] - {"type"}
            if extra:
                raise FormatError("%s: %s: unknown keys %s" % (self.where, what, sorted(extra)))
            R = {"type": kind}
            if kind == "linear":
                W = self._tensor(L["weight"], what)
                if W.ndim != 2 or W.shape[1] != width:
                    raise FormatError("%s: %s: weight %r has shape %s, expected [out, %d]"
                                      % (self.where, what, L["weight"], W.shape, width))
                R["W"] = W
                b = L.get("bias")
                R["b"] = None
                if b is not None:
                    R["b"] = self._tensor(b, what)
                    if R["b"].shape != (W.shape[0],):
                        raise FormatError("%s: %s: bias %r has shape %s, expected [%d]"
                                          % (self.where, what, b, R["b"].shape, W.shape[0]))
                width = W.shape[0]
            elif kind == "fourier":
                B = self._tensor(L["B"], what)
                if B.ndim != 2 or B.shape[1] != width:
                    raise FormatError("%s: %s: B %r has shape %s, expected [m, %d]"
                                      % (self.where, what, L["B"], B.shape, width))
                R["B"] = B
                R["s"] = float(L.get("frequency_scale", 2.0 * np.pi))
                R["inc"] = L.get("include_input", "none")
                if R["inc"] not in ("none", "first", "last"):
                    raise FormatError("%s: %s: bad include_input" % (self.where, what))
                width = 2 * B.shape[0] + (width if R["inc"] != "none" else 0)
            elif kind == "hashgrid":
                try:
                    R["spec"] = inr_hashgrid.HashGridSpec.from_json(width, L, what)
                except ValueError as e:
                    raise FormatError("%s: %s" % (self.where, e))
                R["table"] = self._tensor(L["table"], what)
                if R["table"].shape != R["spec"].table_shape:
                    raise FormatError("%s: %s: table %r has shape %s, expected %s"
                                      % (self.where, what, L["table"], R["table"].shape,
                                         R["spec"].table_shape))
                R["inc"] = L.get("include_input", "none")
                if R["inc"] not in ("none", "first", "last"):
                    raise FormatError("%s: %s: bad include_input" % (self.where, what))
                width = R["spec"].n_output_dims + (width if R["inc"] != "none" else 0)
            elif kind == "sine":
                R["w0"] = float(L.get("w0", 30.0))
            elif kind == "scale":
                R["factor"] = float(L["factor"])
            elif kind == "residual":
                R["body"], wb = self._check_layers(L["body"], width, what + ".body")
                R["shortcut"], ws = self._check_layers(L.get("shortcut") or [], width,
                                                       what + ".shortcut")
                if wb != ws:
                    raise FormatError("%s: %s: body ends at width %d, shortcut at %d"
                                      % (self.where, what, wb, ws))
                R["scale"] = float(L.get("scale", 1.0))
                width = wb
            out.append(R)
        return out, width

    @staticmethod
    def _run(layers, x):
        for R in layers:
            k = R["type"]
            if k == "linear":
                x = x @ R["W"].T
                if R["b"] is not None:
                    x = x + R["b"]
            elif k == "fourier":
                p = R["s"] * (x @ R["B"].T)
                f = [np.sin(p), np.cos(p)]
                if R["inc"] == "first":
                    f = [x] + f
                elif R["inc"] == "last":
                    f = f + [x]
                x = np.concatenate(f, axis=1)
            elif k == "hashgrid":
                f = [inr_hashgrid.encode(R["spec"], R["table"], x)]
                if R["inc"] == "first":
                    f = [x] + f
                elif R["inc"] == "last":
                    f = f + [x]
                x = np.concatenate(f, axis=1)
            elif k == "sine":
                x = np.sin(R["w0"] * x)
            elif k == "silu":
                x = x * _sigmoid(x)
            elif k == "relu":
                x = np.maximum(x, 0.0)
            elif k == "sigmoid":
                x = _sigmoid(x)
            elif k == "tanh":
                x = np.tanh(x)
            elif k == "scale":
                x = R["factor"] * x
            elif k == "residual":
                x = R["scale"] * (ReferenceModel._run(R["body"], x)
                                  + ReferenceModel._run(R["shortcut"], x))
        return x

    # ----------------------------------------------------------------- domain
    def _setup_domain(self, d):
        extra = set(d) - _DOMAIN_FIELDS
        if extra:
            raise FormatError("%s: domain: unknown keys %s" % (self.where, sorted(extra)))
        b = [float(v) for v in d["bounds"]]
        if len(b) != 6 or not (b[0] < b[1] and b[2] < b[3] and b[4] < b[5]):
            raise FormatError("%s: domain.bounds must be 6 numbers with min < max" % self.where)
        self.bounds = b
        ir = d.get("input_range", [-1, 1])
        if len(ir) == 2 and not isinstance(ir[0], list):
            ir = [ir, ir, ir]
        centering = d.get("centering", "node")
        res = d.get("resolution")
        self.axis_maps = []  # (scale, offset) network = scale * world + offset
        for a in range(3):
            lo, hi = float(ir[a][0]), float(ir[a][1])
            mn, mx = b[2 * a], b[2 * a + 1]
            if centering == "node":
                w0, w1 = mn, mx
            elif centering == "cell":
                if res is None or int(res[a]) < 2:
                    raise FormatError("%s: cell centering needs resolution >= 2" % self.where)
                h = (mx - mn) / int(res[a])
                w0, w1 = mn + h / 2, mx - h / 2
            else:
                raise FormatError("%s: bad centering %r" % (self.where, centering))
            s = (hi - lo) / (w1 - w0)
            self.axis_maps.append((s, lo - s * w0))
        t0, t1 = (float(v) for v in d["time_range"])
        if not t0 < t1:
            raise FormatError("%s: domain.time_range must have t0 < t1" % self.where)
        self.time_range = (t0, t1)
        tlo, thi = (float(v) for v in d.get("time_input_range", [-1, 1]))
        s = (thi - tlo) / (t1 - t0)
        self.axis_maps.append((s, tlo - s * t0))
        # Default as the C++ loader: x, y, z (and t for 4 inputs).
        order = d.get("input_order", ["x", "y", "z", "t"][:self.input_dim])
        if len(order) != self.input_dim or sorted(set(order) - {"t"}) != ["x", "y", "z"] \
                or len(set(order)) != len(order):
            raise FormatError("%s: domain.input_order %s does not fit input_dim %d"
                              % (self.where, order, self.input_dim))
        self.input_order = ["xyzt".index(c) for c in order]

    def _setup_output(self, o):
        self.per_time = None
        self.out_scale, self.out_offset = 1.0, 0.0
        if o is None:
            return
        if "per_time" in o:
            if set(o) != {"per_time"}:
                raise FormatError("%s: output.per_time excludes scale/offset" % self.where)
            p = o["per_time"]
            extra = set(p) - {"times", "min", "max", "network_range"}
            if extra:
                raise FormatError("%s: output.per_time: unknown keys %s"
                                  % (self.where, sorted(extra)))
            times = np.asarray(p["times"], float)
            if len(times) < 1 or np.any(np.diff(times) <= 0) or \
                    len(p["min"]) != len(times) or len(p["max"]) != len(times):
                raise FormatError("%s: output.per_time: bad table" % self.where)
            self.per_time = (times, np.asarray(p["min"], float), np.asarray(p["max"], float),
                             [float(v) for v in p.get("network_range", [-1, 1])])
        else:
            extra = set(o) - {"scale", "offset"}
            if extra:
                raise FormatError("%s: output: unknown keys %s" % (self.where, sorted(extra)))
            self.out_scale = float(o.get("scale", 1.0))
            self.out_offset = float(o.get("offset", 0.0))

    # ----------------------------------------------------------------- evaluation
    def network_inputs(self, xyz, t):
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        world = np.concatenate([xyz, np.full((xyz.shape[0], 1), float(t))], axis=1)
        cols = []
        for c in self.input_order:
            s, o = self.axis_maps[c]
            cols.append(s * world[:, c] + o)
        return np.stack(cols, axis=1)

    def network(self, inputs):
        return self._run(self.layers, np.asarray(inputs, np.float64))[:, 0]

    def output_map(self, net, t):
        if self.per_time is None:
            return self.out_scale * net + self.out_offset
        times, mn, mx, (nlo, nhi) = self.per_time
        lo = np.interp(t, times, mn)
        hi = np.interp(t, times, mx)
        return lo + (net - nlo) / (nhi - nlo) * (hi - lo)

    def evaluate(self, xyz, t):
        return self.output_map(self.network(self.network_inputs(xyz, t)), float(t))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model")
    ap.add_argument("--time", type=float, required=True)
    ap.add_argument("--points", help="file with 'x y z' per line (default: stdin)")
    a = ap.parse_args(argv)
    try:
        m = ReferenceModel.load(a.model)
        src = open(a.points) if a.points else sys.stdin
        pts = [list(map(float, ln.split())) for ln in src if ln.strip()]
        if any(len(p) != 3 for p in pts):
            raise FormatError("points must be 'x y z' per line")
        vals = m.evaluate(np.asarray(pts).reshape(-1, 3), a.time) if pts else []
    except (FormatError, OSError, KeyError, ValueError, TypeError) as e:
        sys.stderr.write("inr_reference: error: %s\n" % e)
        return 1
    sys.stdout.write("".join("%.9g\n" % v for v in vals))
    return 0


if __name__ == "__main__":
    sys.exit(main())
