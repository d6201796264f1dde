#!/usr/bin/env python3
"""Exporter round trip: build a network in an official PyTorch layout with random weights,
save its state_dict (.pth), convert it with Tools/python/inr_export.py, evaluate the file with
the C++ CLI (``inr eval``) and compare with a PyTorch float64 forward pass at random world
points: |c - r| <= 1e-5 * max(1, |r|).

The world -> network mapping and the output mapping are written out here independently of
the exporter (from Docs/FORMAT.md), so a wrong mapping in either is caught.

    test_export_roundtrip.py --layout LAYOUT --inr PATH/TO/inr     (or --inr reference)
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import inr_test_util as U

torch = U.require_torch()
import numpy as np  # noqa: E402  (python3-numpy comes with python3-torch)
import inr_torch_layouts as L  # noqa: E402


def node(w, lo, hi, nlo=-1.0, nhi=1.0):
    return nlo + (w - lo) / (hi - lo) * (nhi - nlo)


def cell(w, lo, hi, n, nlo=-1.0, nhi=1.0):
    h = (hi - lo) / n
    return nlo + (w - lo - h / 2) / (hi - lo - h) * (nhi - nlo)


class GenericNet(torch.nn.Module):
    """A made-up network for the generic path: Fourier features (B stored [in, m], input
    included first), a residual block with a linear shortcut, SiLU/tanh, bias-free output."""

    def __init__(self):
        super().__init__()
        self.register_buffer("enc_B", torch.randn(4, 6) * 0.8)
        self.fc0 = torch.nn.Linear(4 + 12, 20)
        self.blk_a = torch.nn.Linear(20, 24)
        self.blk_b = torch.nn.Linear(24, 24)
        self.blk_sc = torch.nn.Linear(20, 24)
        self.out = torch.nn.Linear(24, 1, bias=False)

    def forward_points(self, x):
        p = 3.0 * (x @ self.enc_B)
        h = torch.cat([x, torch.sin(p), torch.cos(p)], dim=1)
        h = torch.nn.functional.silu(self.fc0(h))
        body = torch.sin(25.0 * self.blk_b(torch.tanh(self.blk_a(h))))
        h = 0.75 * (body + self.blk_sc(h))
        return self.out(torch.relu(h))[:, 0]


GENERIC_SPEC = {
    "layers": [
        {"type": "fourier", "B": "enc_B", "B_transpose": True, "frequency_scale": 3.0,
         "include_input": "first"},
        {"type": "linear", "weight": "fc0.weight", "bias": "fc0.bias"},
        {"type": "silu"},
        {"type": "residual", "scale": 0.75,
         "body": [{"type": "linear", "weight": "blk_a.weight", "bias": "blk_a.bias"},
                  {"type": "tanh"},
                  {"type": "linear", "weight": "blk_b.weight", "bias": "blk_b.bias"},
                  {"type": "sine", "w0": 25}],
         "shortcut": [{"type": "linear", "weight": "blk_sc.weight", "bias": "blk_sc.bias"}]},
        {"type": "relu"},
        {"type": "linear", "weight": "out.weight", "bias": None}],
    "name": "generic round trip",
}


def cases():
    """layout -> (build, export args, world(N,4) -> network inputs, (net, t) -> value)."""
    C = {}
    b1 = [0.0, 2.0, -1.0, 1.0, 0.0, 1.0]
    C["siren-notebook"] = dict(
        layout="siren-notebook",
        build=lambda: L.SirenNotebook(4, 32, 2, first_omega_0=20.0, hidden_omega_0=25.0),
        args=["--bounds"] + [str(v) for v in b1] + ["--time-range", "0", "10",
                                                     "--first-w0", "20", "--w0", "25"],
        bounds=b1, trange=(0.0, 10.0),
        inputs=lambda w: np.stack([node(w[:, 0], 0, 2), node(w[:, 1], -1, 1),
                                   node(w[:, 2], 0, 1), node(w[:, 3], 0, 10)], 1),
        out=lambda y, t: y)
    C["siren-notebook-sine-output"] = dict(
        layout="siren-notebook",
        build=lambda: L.SirenNotebook(4, 24, 1, outermost_linear=False),
        args=["--bounds"] + [str(v) for v in b1] + ["--time-range", "0", "10",
                                                     "--input-order", "t,x,y,z"],
        bounds=b1, trange=(0.0, 10.0),
        inputs=lambda w: np.stack([node(w[:, 3], 0, 10), node(w[:, 0], 0, 2),
                                   node(w[:, 1], -1, 1), node(w[:, 2], 0, 1)], 1),
        out=lambda y, t: y)
    b2 = [-3.0, -1.0, 0.0, 4.0, 10.0, 12.0]
    C["siren-modules"] = dict(
        layout="siren-modules", build=lambda: L.SirenModules(4, 32, 2),
        args=["--bounds"] + [str(v) for v in b2] + [
            "--time-range", "2", "7", "--centering", "cell", "--resolution", "16", "8", "4",
            "--output-scale", "0.5", "--output-offset", "0.5"],
        bounds=b2, trange=(2.0, 7.0),
        inputs=lambda w: np.stack([cell(w[:, 0], -3, -1, 16), cell(w[:, 1], 0, 4, 8),
                                   cell(w[:, 2], 10, 12, 4), node(w[:, 3], 2, 7)], 1),
        out=lambda y, t: 0.5 * y + 0.5)
    b3 = [0.0, 127.0, 0.0, 63.0, 0.0, 31.0]
    table = {"times": [1.0, 20.0, 45.0, 90.0], "min": [-2.0, -1.5, 0.5, 1.0],
             "max": [3.0, 8.0, 4.0, 12.0]}

    def per_time(y, t):
        lo = np.interp(t, table["times"], table["min"])
        hi = np.interp(t, table["times"], table["max"])
        return lo + (y + 1.0) / 2.0 * (hi - lo)
    cn_inputs = lambda w: np.stack([node(w[:, 3], 1, 90), node(w[:, 2], 0, 31),  # noqa: E731
                                    node(w[:, 1], 0, 63), node(w[:, 0], 0, 127)], 1)
    C["coordnet"] = dict(
        layout="coordnet", build=lambda: L.CoordNet(4, 1, init_features=8, num_res=2),
        args=["--bounds"] + [str(v) for v in b3] + ["--time-range", "1", "90",
                                                     "--per-time-table", "@TABLE"],
        table=table, bounds=b3, trange=(1.0, 90.0), inputs=cn_inputs, out=per_time)
    C["coordnet-relu"] = dict(
        layout="coordnet", build=lambda: L.CoordNetReLU(4, 1, init_features=8, num_res=1),
        args=["--bounds"] + [str(v) for v in b3] + ["--time-range", "1", "90",
                                                     "--per-time-table", "@TABLE"],
        table=table, bounds=b3, trange=(1.0, 90.0), inputs=cn_inputs, out=per_time)
    # neurcomp as published: static 3D, aspect-scaled inputs of a 65x33x17 volume.
    b4 = [0.0, 64.0, 0.0, 32.0, 0.0, 16.0]
    C["neurcomp"] = dict(
        layout="neurcomp", build=lambda: L.NeurcompFieldNet(3, [24] * 5),
        args=["--neurcomp-volume-shape", "65", "33", "17", "--output-range", "-5", "20"],
        bounds=b4, trange=(0.0, 1.0),
        inputs=lambda w: np.stack([node(w[:, 0], 0, 64), node(w[:, 1], 0, 32, -0.5, 0.5),
                                   node(w[:, 2], 0, 16, -0.25, 0.25)], 1),
        out=lambda y, t: 12.5 * y + 7.5)
    C["neurcomp-4d"] = dict(
        layout="neurcomp", build=lambda: L.NeurcompFieldNet(4, [20] * 3),
        args=["--bounds"] + [str(v) for v in b1] + ["--time-range", "0", "10"],
        bounds=b1, trange=(0.0, 10.0),
        inputs=lambda w: np.stack([node(w[:, 0], 0, 2), node(w[:, 1], -1, 1),
                                   node(w[:, 2], 0, 1), node(w[:, 3], 0, 10)], 1),
        out=lambda y, t: y)
    # Reed et al. as published: 3 channels, B regenerated from seed 0 / sigma 1.5;
    # bounds are the voxel box, cell centres at +-(1 - 1/n) = node mapping of the faces.
    b5 = [0.0, 80.0, 0.0, 80.0, 0.0, 80.0]
    C["reed-ffn"] = dict(
        layout="reed-ffn", build=lambda: L.ReedFFN(3, nf=16, sigma=1.5, seed=0),
        args=["--reed-sigma", "1.5", "--bounds"] + [str(v) for v in b5],
        bounds=b5, trange=(0.0, 1.0),
        inputs=lambda w: np.stack([node(w[:, a], 0, 80) for a in range(3)], 1),
        out=lambda y, t: y)
    C["reed-ffn-Bfile"] = dict(
        layout="reed-ffn", build=lambda: L.ReedFFN(4, nf=12, sigma=2.0, seed=7,
                                                   hidden_convs=2),
        args=["--fourier-B", "@BFILE", "--bounds"] + [str(v) for v in b1] + [
            "--time-range", "0", "10"],
        bounds=b1, trange=(0.0, 10.0),
        inputs=lambda w: np.stack([node(w[:, 0], 0, 2), node(w[:, 1], -1, 1),
                                   node(w[:, 2], 0, 1), node(w[:, 3], 0, 10)], 1),
        out=lambda y, t: y)
    C["generic"] = dict(
        layout="generic", build=GenericNet,
        args=["--layers", "@SPEC", "--bounds"] + [str(v) for v in b2] + [
            "--time-range", "-5", "5", "--time-input-range", "0", "1",
            "--input-range", "-2", "2", "0", "1", "-1", "1"],
        bounds=b2, trange=(-5.0, 5.0),
        inputs=lambda w: np.stack([node(w[:, 0], -3, -1, -2, 2), node(w[:, 1], 0, 4, 0, 1),
                                   node(w[:, 2], 10, 12), node(w[:, 3], -5, 5, 0, 1)], 1),
        out=lambda y, t: y)
    return C


def main():
    C = cases()
    ap = argparse.ArgumentParser()
    ap.add_argument("--layout", required=True, choices=sorted(C))
    ap.add_argument("--inr", required=True, help="the inr CLI, or 'reference'")
    ap.add_argument("--points", type=int, default=200)
    a = ap.parse_args()
    case = C[a.layout]
    torch.manual_seed(sum(map(ord, a.layout)))
    model = case["build"]()  # official initialisation (random weights and biases)
    with tempfile.TemporaryDirectory() as tmp:
        pth = os.path.join(tmp, "model.pth")
        torch.save(model.state_dict(), pth)
        args = []
        for x in case["args"]:
            if x == "@TABLE":
                x = os.path.join(tmp, "table.json")
                with open(x, "w") as f:
                    json.dump(case["table"], f)
            elif x == "@BFILE":
                x = os.path.join(tmp, "B.npy")
                np.save(x, model.B.numpy())
            elif x == "@SPEC":
                x = os.path.join(tmp, "spec.json")
                with open(x, "w") as f:
                    json.dump(GENERIC_SPEC, f)
            args.append(x)
        out = os.path.join(tmp, "model.inr")
        cmd = [sys.executable, os.path.join(U.TOOLS, "inr_export.py"), case["layout"], pth,
               out] + args
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           universal_newlines=True)
        print(r.stderr.strip())
        if r.returncode != 0:
            print("FAIL: export failed: %s" % " ".join(cmd))
            return 1

        m64 = case["build"]()
        m64.load_state_dict(model.state_dict())
        if isinstance(model, L.ReedFFN):  # B is not in the state_dict
            m64.B = model.B.clone()
        m64 = m64.double()
        rs = np.random.RandomState(7)
        b = case["bounds"]
        lo, hi = np.array(b[0::2]), np.array(b[1::2])
        t0, t1 = case["trange"]
        ok_all = True
        for t in (t0, t0 + 0.37 * (t1 - t0), t1):
            pts = lo + rs.uniform(size=(a.points, 3)) * (hi - lo)
            pts[:8] = [[x, y, z] for x in b[0:2] for y in b[2:4] for z in b[4:6]]
            w = np.concatenate([pts, np.full((len(pts), 1), t)], axis=1)
            with torch.no_grad():
                y = m64.forward_points(torch.from_numpy(case["inputs"](w))).numpy()
            want = case["out"](y, t)
            got = U.run_eval(a.inr, out, t, pts, tmp)
            ok, _, msg = U.compare("%s t=%g" % (a.layout, t), got, list(want))
            print(("ok   " if ok else "FAIL ") + msg)
            ok_all &= ok
            if float(np.std(want)) < 1e-6:
                print("FAIL %s: reference outputs are constant; the test would prove nothing"
                      % a.layout)
                ok_all = False
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
