#!/usr/bin/env python3
"""Hash-grid models (Docs/FORMAT.md "hashgrid") across implementations, with fixed seeds:

1. the numpy encoding (Tools/python/inr_hashgrid.py) against the plain PyTorch module
   (Tools/python/inr_hashgrid_torch.py), 3D and 4D, linear and smoothstep;
2. a HashGridNetwork exported with ``inr_export.py hashgrid-torch``, and the same network as
   tiny-cuda-nn's flat parameter vector + JSON config exported with ``inr_export.py tcnn``:
   the evaluator (the C++ CLI ``inr eval``, or ``--inr reference``) against PyTorch, within
   1e-3 of the value range (the table is stored in fp16, so PyTorch runs on the fp16 table);
3. the exporter's errors for unsupported tiny-cuda-nn options name the option.

Usage: test_hashgrid.py --inr PATH_TO_inr|reference
"""

import argparse
import json
import os
import sys
import tempfile

import numpy as np

from inr_test_util import SKIP, require_torch, run_eval  # noqa: F401  (sets sys.path)

import inr_export  # noqa: E402
import inr_hashgrid  # noqa: E402

CONFIGS = [  # (dims, encoding fields)
    (3, {"n_levels": 8, "n_features_per_level": 2, "log2_hashmap_size": 12, "base_resolution": 4,
         "per_level_scale": 1.7}),
    (4, {"n_levels": 6, "n_features_per_level": 4, "log2_hashmap_size": 11, "base_resolution": 3,
         "per_level_scale": 1.5, "interpolation": "Smoothstep"}),
]


def check(ok, message):
    if not ok:
        raise AssertionError(message)


def encoding_parity(torch):
    from inr_hashgrid_torch import HashGridEncoding
    for dims, cfg in CONFIGS:
        torch.manual_seed(dims)
        enc = HashGridEncoding(dims, **cfg)
        with torch.no_grad():
            enc.embeddings.uniform_(-1, 1)
        x = np.random.default_rng(dims).uniform(-0.02, 1.02, size=(4000, dims)).astype(np.float32)
        want = enc(torch.from_numpy(x)).detach().numpy().astype(np.float64)
        got = inr_hashgrid.encode(enc.spec, enc.embeddings.detach().numpy(), x)
        err = np.abs(got - want).max()
        print("encoding %dD %s: numpy vs PyTorch max abs %.3g" % (dims, cfg.get("interpolation", "Linear"), err))
        # fp32 (PyTorch) against float64 (numpy); a wrong index or weight would differ by O(1)
        check(err < 1e-4, "numpy and PyTorch hash-grid encodings differ by %g" % err)


def tcnn_flat_params(model, alignment=16):
    """The network as tiny-cuda-nn lays out NetworkWithInputEncoding's parameters: the MLP's
    matrices [out, in] row-major (inputs padded with zero columns, the output padded with zero
    rows, to the alignment; no biases), then the hash table."""
    pad = lambda n: (n + alignment - 1) // alignment * alignment  # noqa: E731
    mats = [m.weight.detach().numpy().astype(np.float64) for m in model.network
            if hasattr(m, "weight")]
    parts = []
    for i, W in enumerate(mats):
        rows = pad(W.shape[0]) if i + 1 == len(mats) else W.shape[0]
        cols = pad(W.shape[1]) if i == 0 else W.shape[1]
        P = np.zeros((rows, cols))
        P[:W.shape[0], :W.shape[1]] = W
        parts.append(P.ravel())
    parts.append(model.encoding.embeddings.detach().numpy().astype(np.float64).ravel())
    return np.concatenate(parts)


def export_and_compare(torch, inr, tmp):
    from inr_hashgrid_torch import HashGridNetwork
    for dims, cfg in CONFIGS:
        torch.manual_seed(10 + dims)
        # Width 24 with 5 x 4 = 20 encoded features (3D: 16): the first matrix's input is padded.
        model = HashGridNetwork(dims, cfg, width=32, hidden_layers=2)
        with torch.no_grad():
            model.encoding.embeddings.uniform_(-1, 1)
            # The file stores the table in fp16 (as tiny-cuda-nn trains it): compare on those values.
            model.encoding.embeddings.copy_(model.encoding.embeddings.half().float())
            for m in model.network:
                if hasattr(m, "bias"):
                    m.bias.zero_()  # tiny-cuda-nn's MLPs have no biases (the same model both ways)
        order = "x,y,z,t" if dims == 4 else "x,y,z"
        bounds = ["--bounds", "-1", "2", "0", "1", "0", "3", "--time-range", "0", "5", "--input-order", order]
        torch_file = os.path.join(tmp, "hg%d.pth" % dims)
        torch.save(model.state_dict(), torch_file)
        out_torch = os.path.join(tmp, "hg%d_torch.inr" % dims)
        check(inr_export.main(["hashgrid-torch", torch_file, out_torch, "--hashgrid-config", json.dumps(cfg),
                               "--quiet"] + bounds) == 0, "hashgrid-torch export failed")
        params = os.path.join(tmp, "hg%d_params.npy" % dims)
        np.save(params, tcnn_flat_params(model).astype(np.float16))
        tcnn_cfg = {"encoding": dict(cfg, otype="HashGrid"),
                    "network": {"otype": "FullyFusedMLP", "activation": "ReLU", "output_activation": "None",
                                "n_neurons": 32, "n_hidden_layers": 2}}
        out_tcnn = os.path.join(tmp, "hg%d_tcnn.inr" % dims)
        check(inr_export.main(["tcnn", params, out_tcnn, "--tcnn-config", json.dumps(tcnn_cfg), "--quiet"]
                              + bounds) == 0, "tcnn export failed")
        rng = np.random.default_rng(100 + dims)
        pts = np.stack([rng.uniform(-1, 2, 3000), rng.uniform(0, 1, 3000), rng.uniform(0, 3, 3000)], axis=1)
        t = 1.7
        net_in = np.stack([(pts[:, 0] + 1) / 3, pts[:, 1], pts[:, 2] / 3] + ([np.full(3000, t / 5)] if dims == 4 else []),
                          axis=1).astype(np.float32)
        with torch.no_grad():
            want = model(torch.from_numpy(net_in)).numpy()[:, 0].astype(np.float64)
        value_range = want.max() - want.min()
        # tiny-cuda-nn stores the MLP in fp16 too: its reference is the fp16-rounded weights.
        with torch.no_grad():
            for m in model.network:
                if hasattr(m, "weight"):
                    m.weight.copy_(m.weight.half().float())
            want_tcnn = model(torch.from_numpy(net_in)).numpy()[:, 0].astype(np.float64)
        for label, path, ref in (("hashgrid-torch", out_torch, want), ("tcnn", out_tcnn, want_tcnn)):
            got = np.array(run_eval(inr, path, t, pts.tolist(), tmp))
            err = np.abs(got - ref).max()
            print("%dD %-15s %s vs PyTorch: max abs %.3g (value range %.3g)" % (dims, label, inr if inr == "reference" else "inr eval", err, value_range))
            check(err <= 1e-3 * value_range, "%s %dD: error %g exceeds 1e-3 of the value range %g" % (label, dims, err, value_range))


def export_errors(tmp):
    params = os.path.join(tmp, "p.npy")
    np.save(params, np.zeros(100, np.float32))
    base = {"encoding": {"otype": "HashGrid", "n_levels": 2, "log2_hashmap_size": 4, "base_resolution": 2},
            "network": {"otype": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 1}}
    cases = [
        ({"encoding": dict(base["encoding"], otype="DenseGrid")}, "encoding otype 'DenseGrid'"),
        ({"encoding": dict(base["encoding"], hash="ReversedPrime")}, "encoding hash 'ReversedPrime'"),
        ({"encoding": dict(base["encoding"], interpolation="Nearest")}, "interpolation Nearest"),
        ({"network": dict(base["network"], activation="LeakyReLU")}, "network activation 'LeakyReLU'"),
        ({"network": dict(base["network"], otype="CutlassMLPX")}, "network otype 'CutlassMLPX'"),
        ({}, "100 parameters ('params') fit neither 3 nor 4 inputs"),
        # base 8: every level hashed in 3D and 4D alike; 16 x 16 + 16 x 16 network + 2 x 16 x 2 table
        ({"encoding": dict(base["encoding"], base_resolution=8), "n_params": 576},
         "fit 3 and 4 inputs alike"),
    ]
    for patch, expect in cases:
        patch = dict(patch)
        np.save(params, np.zeros(patch.pop("n_params", 100), np.float32))
        cfg = dict(base, **patch)
        import io
        import contextlib
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            rc = inr_export.main(["tcnn", params, os.path.join(tmp, "e.inr"), "--tcnn-config", json.dumps(cfg)])
        check(rc == 1 and expect in err.getvalue(), "expected an error naming %r, got (exit %d): %s"
              % (expect, rc, err.getvalue().strip()))
        print("error names %r: ok" % expect)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--inr", required=True, help="path to the inr CLI, or 'reference'")
    a = ap.parse_args()
    torch = require_torch()
    with tempfile.TemporaryDirectory() as tmp:
        encoding_parity(torch)
        export_and_compare(torch, a.inr, tmp)
        export_errors(tmp)
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
