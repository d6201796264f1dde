#!/usr/bin/env python3
"""tiny-cuda-nn's own files through ``inr_export.py tcnn`` (Docs/FORMAT.md "hashgrid"):

1. every shipped config in Testing/Data/tcnn/ (tiny-cuda-nn's ``data/config*.json``, verbatim)
   whose encoding is a hash grid exports, over 3 and 4 inputs, from the parameter layouts
   tiny-cuda-nn's PyTorch bindings save (a ``tcnn.NetworkWithInputEncoding`` state_dict, the bare
   tensor, a .npy vector, a tcnn.Encoding + tcnn.Network pair, training checkpoints with
   optimiser state, DataParallel's ``module.`` and EMA copies), and the files evaluate with the
   C++ ``inr eval`` to the network computed by an independent PyTorch implementation
   (Tools/python/inr_hashgrid_torch.py and the matrices below), within 1e-5 of the value range;
   the shipped configs that use other encodings are refused naming the encoding;
2. what tiny-cuda-nn reads the same way gives the same file (its defaults, network otype
   aliases, the field spellings of its own hyperparams() output, any letter case);
3. what changes the network and has no counterpart here is refused by name.

Usage: test_tcnn_configs.py --inr PATH_TO_inr|reference --data Testing/Data/tcnn
"""

import argparse
import collections
import contextlib
import glob
import io
import json
import os
import sys
import tempfile

import numpy as np

from inr_test_util import require_torch, run_eval  # (sets sys.path)

import inr_export  # noqa: E402
import inr_hashgrid  # noqa: E402

# Both sides evaluate in fp32 from the same fp16 parameters; they differ only in the order of
# fp32 sums and in the hash grid's position arithmetic (a fused multiply-add or two roundings),
# which moves a value by a few fp32 ulps of the terms summed. A wrong weight, padding column,
# hash index or activation moves it by a sizeable fraction of the value range.
REL_TOL = 2e-6
N_POINTS = 2000

failures = []


def check(ok, message):
    print("%s %s" % ("ok  " if ok else "FAIL", message))
    if not ok:
        failures.append(message)


def uses_hash_grid(encoding):
    """Whether tiny-cuda-nn builds a hash grid from this encoding object: its Grid family by
    otype (names compared without regard to case), of type Hash, the type's default for all but
    DenseGrid and TiledGrid."""
    otype = str(encoding.get("otype", "OneBlob")).lower()
    if otype not in ("grid", "hashgrid", "densegrid", "tiledgrid"):
        return False
    default = {"densegrid": "dense", "tiledgrid": "tiled"}.get(otype, "hash")
    return str(encoding.get("type", default)).lower() == "hash"


def export(args):
    """inr_export's exit status and stderr, in this process."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rc = inr_export.main(args)
    return rc, err.getvalue()


class Network(object):
    """A tiny-cuda-nn hash-grid MLP with its own weights: the reference forward pass in PyTorch
    and the parameter vectors tiny-cuda-nn lays out for it."""

    def __init__(self, torch, dims, encoding, network, seed):
        from inr_hashgrid_torch import HashGridEncoding
        self.torch = torch
        fields = {k: encoding[k] for k in inr_hashgrid.HashGridSpec.FIELDS if k in encoding}
        torch.manual_seed(seed)
        self.encoding = HashGridEncoding(dims, exact_position=True, **fields)
        with torch.no_grad():  # fp16, as tiny-cuda-nn trains the table
            self.encoding.embeddings.uniform_(-1, 1)
            self.encoding.embeddings.copy_(self.encoding.embeddings.half().float())
        width = network.get("n_neurons", 128)
        hidden = network.get("n_hidden_layers", 5)
        fan_ins = [self.encoding.spec.n_output_dims] + [width] * hidden
        fan_outs = [width] * hidden + [1]
        g = torch.Generator().manual_seed(seed + 1)
        # fp16 weights, as the bindings hold them: [out, in]
        self.weights = [((torch.rand(o, i, generator=g) * 2 - 1) * (3.0 / i) ** 0.5).half().float()
                        for i, o in zip(fan_ins, fan_outs)]
        self.bias = None  # first-layer bias (a tcnn.Network's padded inputs are ones)
        self.activation = str(network.get("activation", "ReLU")).lower()

    def forward(self, x):
        torch = self.torch
        with torch.no_grad():
            h = self.encoding(torch.from_numpy(np.asarray(x, np.float32)))
            for i, W in enumerate(self.weights):
                h = h @ W.T
                if i == 0 and self.bias is not None:
                    h = h + self.bias
                if i + 1 < len(self.weights):
                    h = torch.relu(h) if self.activation == "relu" else h
            return h[:, 0].double().numpy()

    def mlp_params(self, ones_padding=False, alignment=16):
        """The MLP's parameters as tiny-cuda-nn lays them out: each matrix [out, in] row-major,
        the first one's inputs and the last one's outputs padded to the alignment. With
        ``ones_padding`` (a tcnn.Network: its padded inputs are ones) the padded columns get
        weights, whose sum the reference adds as a bias."""
        torch = self.torch
        pad = lambda n: (n + alignment - 1) // alignment * alignment  # noqa: E731
        parts, g = [], torch.Generator().manual_seed(99)
        for i, W in enumerate(self.weights):
            rows = pad(W.shape[0]) if i + 1 == len(self.weights) else W.shape[0]
            cols = pad(W.shape[1]) if i == 0 else W.shape[1]
            P = torch.zeros(rows, cols)
            P[:W.shape[0], :W.shape[1]] = W
            if i == 0 and ones_padding and cols > W.shape[1]:
                P[:W.shape[0], W.shape[1]:] = (torch.rand(W.shape[0], cols - W.shape[1],
                                                          generator=g) - 0.5).half().float()
                self.bias = P[:W.shape[0], W.shape[1]:].sum(dim=1)
            if i + 1 == len(self.weights):  # padded outputs: tiny-cuda-nn computes and drops them
                P[W.shape[0]:, :] = 0.25
            parts.append(P.reshape(-1))
        return torch.cat(parts).half()

    def table(self, dtype):
        return self.encoding.embeddings.detach().reshape(-1).to(dtype)


def sample_inputs(dims):
    """World points in the box [0, 1]^3 (the network's inputs) and the network inputs at t."""
    pts = np.random.default_rng(7 + dims).uniform(0.0, 1.0, size=(N_POINTS, 3))
    t = 0.37  # world time range [0, 1] = the network's time input
    x = np.concatenate([pts, np.full((N_POINTS, 1), t)], axis=1) if dims == 4 else pts
    return pts, t, x


def evaluate(inr, path, dims, tmp, net, label):
    pts, t, x = sample_inputs(dims)
    want = net.forward(x)
    got = np.array(run_eval(inr, path, t, pts.tolist(), tmp))
    value_range = float(want.max() - want.min())
    err = float(np.abs(got - want).max())
    check(value_range > 0 and err <= REL_TOL * value_range,
          "%s: inr eval vs PyTorch max |error| %.3g = %.2g of the value range %.3g (bound %g)"
          % (label, err, err / value_range if value_range else float("inf"), value_range, REL_TOL))
    return got


def shipped_configs(torch, inr, data, tmp):
    files = sorted(glob.glob(os.path.join(data, "config*.json")))
    check(len(files) >= 1, "%d shipped tiny-cuda-nn configs in %s" % (len(files), data))
    hash_configs = 0
    for cfg_path in files:
        name = os.path.basename(cfg_path)
        with open(cfg_path) as f:
            cfg = json.load(f)
        if not uses_hash_grid(cfg["encoding"]):
            params = os.path.join(tmp, "any.npy")
            np.save(params, np.zeros(1000, np.float16))
            rc, err = export(["tcnn", params, os.path.join(tmp, "x.inr"), "--tcnn-config", cfg_path])
            otype = cfg["encoding"].get("otype")
            check(rc == 1 and name in err and "encoding otype %r" % otype in err,
                  "%s (%s encoding) refused naming it: %s" % (name, otype, err.strip()))
            continue
        hash_configs += 1
        for dims in (3, 4):
            shipped_config_layouts(torch, inr, cfg_path, cfg, dims, tmp)
    check(hash_configs >= 1, "%d shipped configs use a hash grid (config_hash.json does)"
          % hash_configs)


def shipped_config_layouts(torch, inr, cfg_path, cfg, dims, tmp):
    """One shipped config over ``dims`` inputs, saved every way the bindings' users save it."""
    name = os.path.basename(cfg_path)
    net = Network(torch, dims, cfg["encoding"], cfg["network"], seed=dims)
    flat = torch.cat([net.mlp_params(), net.table(torch.float16)])  # NetworkWithInputEncoding
    ema = Network(torch, dims, cfg["encoding"], cfg["network"], seed=dims + 50)
    ema_flat = torch.cat([ema.mlp_params(), ema.table(torch.float16)])
    optimizer = {"state": {0: {"step": torch.tensor(10.0), "exp_avg": torch.zeros_like(flat),
                               "exp_avg_sq": torch.zeros_like(flat)}},
                 "param_groups": [{"lr": 1e-2, "betas": (0.9, 0.99), "params": [0]}]}
    files = collections.OrderedDict()

    def save(label, obj, ext=".pth"):
        p = os.path.join(tmp, "%s_%dd_%s%s" % (os.path.splitext(name)[0], dims, label, ext))
        torch.save(obj, p)
        files[label] = (p, [])

    save("state_dict", collections.OrderedDict(params=flat))  # tcnn.NetworkWithInputEncoding
    save("bare_tensor", flat, ".pt")
    npy = os.path.join(tmp, "%s_%dd.npy" % (os.path.splitext(name)[0], dims))
    np.save(npy, flat.numpy())
    files["npy"] = (npy, [])
    save("fp32_params", {"params": flat.float()})
    # a user's module holding the tcnn module, under DataParallel, in a training checkpoint
    save("checkpoint", {"epoch": 3, "global_step": 3000, "optimizer": optimizer,
                        "state_dict": {"module.model.params": flat}})
    save("ema_entry", {"model": {"params": flat}, "ema": {"params": ema_flat},
                       "optimizer": optimizer})
    save("ema_keys", {"params": flat, "ema.params": ema_flat})
    for label, (path, extra) in files.items():
        out = os.path.join(tmp, "%s_%dd_%s.inr" % (os.path.splitext(name)[0], dims, label))
        rc, err = export(["tcnn", path, out, "--tcnn-config", cfg_path, "--bounds", "0", "1", "0",
                          "1", "0", "1", "--time-range", "0", "1"] + extra)
        check(rc == 0, "%s %dD %s: exported (%s)" % (name, dims, label, err.strip().splitlines()[-1]))
        if rc != 0:
            continue
        if label == "checkpoint":
            check("'state_dict'" in err and "'optimizer'" in err,
                  "%dD checkpoint: the note names the entry used and the optimizer beside it" % dims)
        if label == "ema_entry":
            check("'model'" in err and "'ema'" in err and "--checkpoint-key" in err,
                  "%dD ema_entry: the note names 'model', 'ema' and --checkpoint-key" % dims)
        if label == "ema_keys":
            check("'ema.'" in err, "%dD ema_keys: the note names the copy under 'ema.'" % dims)
        evaluate(inr, out, dims, tmp, net, "%s %dD %s" % (name, dims, label))
    # --checkpoint-key picks the EMA copy: its values, not the model's
    out = os.path.join(tmp, "ema_%dd.inr" % dims)
    rc, err = export(["tcnn", files["ema_entry"][0], out, "--tcnn-config", cfg_path,
                      "--checkpoint-key", "ema", "--bounds", "0", "1", "0", "1", "0", "1",
                      "--time-range", "0", "1"])
    check(rc == 0, "%s %dD --checkpoint-key ema: exported" % (name, dims))
    if rc == 0:
        got = evaluate(inr, out, dims, tmp, ema, "%s %dD --checkpoint-key ema" % (name, dims))
        other = net.forward(sample_inputs(dims)[2])
        check(np.abs(got - other).max() > 0.01 * (other.max() - other.min()),
              "%dD: the EMA export differs from the model's (the test can tell them apart)" % dims)


def encoding_network_pair(torch, inr, data, tmp):
    """A tcnn.Encoding + tcnn.Network pair (keys '<name>.params'), with an encoding width (5 levels
    x 4 features = 20) that the network pads to 32 with ones: the padded columns' weights are a
    bias. Saved as attributes of a module and as nn.Sequential(encoding, network)."""
    with open(os.path.join(data, "config_hash.json")) as f:
        cfg = json.load(f)
    cfg["encoding"].update(n_levels=5, n_features_per_level=4, log2_hashmap_size=14)
    cfg["network"].update(n_neurons=32, n_hidden_layers=1)
    cfg_path = os.path.join(tmp, "pair.json")
    with open(cfg_path, "w") as f:
        json.dump(cfg, f)
    for dims in (3, 4):
        net = Network(torch, dims, cfg["encoding"], cfg["network"], seed=20 + dims)
        mlp = net.mlp_params(ones_padding=True)
        check(net.bias is not None and float(net.bias.abs().max()) > 0.1,
              "%dD pair: the padded inputs carry a bias (max %.3g)" % (dims, float(net.bias.abs().max())))
        for label, sd in (("attributes", {"encoder.params": net.table(torch.float32),
                                          "decoder.params": mlp}),
                          ("sequential", {"0.params": net.table(torch.float16), "1.params": mlp})):
            p = os.path.join(tmp, "pair_%dd_%s.pth" % (dims, label))
            torch.save(sd, p)
            out = p[:-4] + ".inr"
            rc, err = export(["tcnn", p, out, "--tcnn-config", cfg_path, "--bounds", "0", "1", "0",
                              "1", "0", "1", "--time-range", "0", "1", "--quiet"])
            check(rc == 0, "%dD encoding + network (%s): exported %s" % (dims, label, err.strip()))
            if rc == 0:
                evaluate(inr, out, dims, tmp, net, "%dD encoding + network (%s)" % (dims, label))
        # the same MLP vector read as a NetworkWithInputEncoding (zero padding) is another network
        with torch.no_grad():
            bias, net.bias = net.bias, None
            p = os.path.join(tmp, "pair_%dd_flat.npy" % dims)
            np.save(p, torch.cat([mlp, net.table(torch.float16)]).numpy())
            rc, _ = export(["tcnn", p, p[:-4] + ".inr", "--tcnn-config", cfg_path, "--bounds", "0",
                            "1", "0", "1", "0", "1", "--time-range", "0", "1", "--quiet"])
            check(rc == 0, "%dD the pair's vectors as one NetworkWithInputEncoding vector: "
                  "exported" % dims)
            if rc == 0:  # that module's grid pads with zeros: no bias
                evaluate(inr, p[:-4] + ".inr", dims, tmp, net, "%dD one vector: no bias" % dims)
            net.bias = bias


def same_conversion(torch, data):
    """Spellings tiny-cuda-nn reads alike must give the same file."""
    with open(os.path.join(data, "config_hash.json")) as f:
        base = json.load(f)
    dims = 3
    net = Network(torch, dims, base["encoding"], base["network"], seed=5)
    flat = torch.cat([net.mlp_params(), net.table(torch.float16)]).numpy()

    class Opts(object):
        final_activation = None
        input_order = None

    def convert(cfg):
        o = Opts()
        o.tcnn_config = json.dumps(cfg)
        tensors, arch, _ = inr_export.convert({"params": flat}, "tcnn", o)
        return arch, tensors

    want_arch, want_tensors = convert(base)

    def same(label, cfg):
        try:
            arch, tensors = convert(cfg)
        except inr_export.ExportError as e:
            check(False, "%s: refused: %s" % (label, e))
            return
        equal = arch == want_arch and list(tensors) == list(want_tensors) and all(
            np.array_equal(tensors[k], want_tensors[k]) for k in tensors)
        check(equal, "%s: the same file as config_hash.json" % label)

    enc, network = base["encoding"], base["network"]
    for otype in (None, "MLP", "CutlassMLP", "MegakernelMLP", "fullyfusedmlp"):
        n = {k: v for k, v in network.items() if k != "otype"}
        if otype:
            n["otype"] = otype
        same("network otype %s" % (otype or "absent (tiny-cuda-nn: MLP)"), dict(base, network=n))
    e = {k: v for k, v in enc.items() if k != "fixed_point_pos"}
    same("fixed_point_pos absent", dict(base, encoding=e))
    same("stochastic_interpolation true (training only)",
         dict(base, encoding=dict(enc, stochastic_interpolation=True)))
    # the form tiny-cuda-nn's hyperparams() writes (a bindings module's extra_repr shows it)
    same("hyperparams() spelling", {"otype": "NetworkWithInputEncoding", "encoding": {
        "otype": "Grid", "type": "Hash", "n_levels": 16, "n_features_per_level": 2,
        "base_resolution": 16, "per_level_scale": 1.5, "interpolation": "Linear",
        "hash": "CoherentPrime", "log2_hashmap_size": 15}, "network": {
        "otype": "FullyFusedMLP", "activation": "ReLU", "output_activation": "None",
        "n_neurons": 64, "n_hidden_layers": 2}})
    same("n_features instead of n_levels",
         dict(base, encoding=dict({k: v for k, v in enc.items() if k != "n_levels"}, n_features=32)))
    same("letter case", dict(base, encoding=dict(enc, otype="hashgrid", interpolation="LINEAR",
                                                 hash="coherentprime"),
                             network=dict(network, activation="relu", output_activation="none")))
    same("n_dims_to_encode 3", dict(base, encoding=dict(enc, n_dims_to_encode=3)))
    same("n_input_dims 3", dict(base, n_input_dims=3))
    same("network defaults spelled out", dict(base, network=dict(network, n_input_dims=32,
                                                                  n_output_dims=1)))
    # tiny-cuda-nn's defaults when the fields are absent
    spec = inr_export._tcnn_hashgrid({"otype": "HashGrid"}, 3, "defaults")
    check((spec.n_levels, spec.n_features_per_level, spec.log2_hashmap_size, spec.base_resolution,
           spec.per_level_scale, spec.interpolation) == (16, 2, 19, 16, 2.0, "linear"),
          "HashGrid defaults are tiny-cuda-nn's (16 levels, 2 features, 2^19, base 16, x2, linear)")
    _, norm = inr_export._tcnn_config({"encoding": enc, "network": {}}, "defaults")
    check((norm["otype"], norm["n_neurons"], norm["n_hidden_layers"], norm["activation"],
           norm["output_activation"]) == ("CutlassMLP", 128, 5, [{"type": "relu"}], []),
          "network defaults are tiny-cuda-nn's (MLP = CutlassMLP, 128 x 5, ReLU, None)")


def refusals(torch, data, tmp):
    """What changes the network and is not supported is refused, naming it."""
    with open(os.path.join(data, "config_hash.json")) as f:
        base = json.load(f)
    enc, network = base["encoding"], base["network"]
    params = os.path.join(tmp, "refuse.npy")
    np.save(params, np.zeros(1000, np.float16))
    cases = [
        ({"encoding": dict(enc, fixed_point_pos=True)}, ["fixed_point_pos true"]),
        ({"encoding": dict(enc, fixed_point_pos="no")}, ["fixed_point_pos", "'no'"]),
        ({"encoding": dict(enc, hash="Prime")}, ["encoding hash 'Prime'"]),
        ({"encoding": dict(enc, hash="ReversedPrime")}, ["encoding hash 'ReversedPrime'"]),
        ({"encoding": dict(enc, hash="Rng")}, ["encoding hash 'Rng'"]),
        ({"encoding": dict(enc, hash="BaseConvert")}, ["encoding hash 'BaseConvert'"]),
        ({"encoding": dict(enc, type="Dense")}, ["type 'Dense'"]),
        ({"encoding": dict(enc, otype="Grid", type="Tiled")}, ["type 'Tiled'"]),
        ({"encoding": dict(enc, otype="DenseGrid")}, ["encoding otype 'DenseGrid'"]),
        ({"encoding": dict(enc, otype="TiledGrid")}, ["encoding otype 'TiledGrid'"]),
        ({"encoding": {k: v for k, v in enc.items() if k != "otype"}}, ["OneBlob"]),
        ({"encoding": dict(enc, interpolation="Nearest")}, ["interpolation Nearest"]),
        ({"encoding": dict(enc, n_features=32)}, ["n_features and n_levels"]),
        ({"encoding": dict(enc, n_bins=8)}, ["unknown or unsupported fields ['n_bins']"]),
        ({"encoding": dict(enc, n_levels=2.5)}, ["n_levels is 2.5"]),
        ({"network": dict(network, otype="ResNet")}, ["network otype 'ResNet'"]),
        ({"network": dict(network, activation="LeakyReLU")}, ["network activation 'LeakyReLU'"]),
        ({"network": dict(network, activation="Softplus")}, ["network activation 'Softplus'"]),
        ({"network": dict(network, output_activation="Exponential")},
         ["network output_activation 'Exponential'"]),
        ({"network": dict(network, output_activation="Squareplus")},
         ["network output_activation 'Squareplus'"]),
        ({"network": dict(network, n_output_dims=4)}, ["network n_output_dims is 4"]),
        ({"network": dict(network, dropout=0.1)}, ["unknown or unsupported fields ['dropout']"]),
        ({}, ["1000 parameters ('params') fit neither 3 nor 4 inputs"]),
        ({"n_input_dims": 4}, ["1000 parameters ('params') do not fit 4 inputs", "over 4 inputs"]),
        ({"n_input_dims": "three"}, ["n_input_dims is 'three'"]),
        ({"n_input_dims": 3, "encoding": dict(enc, n_dims_to_encode=2)}, ["n_dims_to_encode 2"]),
    ]
    for patch, needles in cases:
        cfg = dict(base, **patch)
        rc, err = export(["tcnn", params, os.path.join(tmp, "refused.inr"), "--tcnn-config",
                          json.dumps(cfg)])
        check(rc == 1 and all(n in err for n in needles),
              "refused naming %s: %s" % (needles, err.strip().splitlines()[-1] if err else "(none)"))
    # parameter vectors the exporter cannot choose between: named
    cfg = os.path.join(data, "config_hash.json")
    net = Network(torch, 3, enc, network, seed=1)
    flat = torch.cat([net.mlp_params(), net.table(torch.float16)])
    for label, obj, needles in (
            ("three vectors", {"a.params": flat, "b.params": flat, "c.params": flat},
             ["'a.params'", "'b.params'", "'c.params'", "--prefix"]),
            ("a second network's vector", {"model.params": flat, "renderer.params": flat[:100]},
             ["'renderer.params'"]),
            ("two state_dicts, neither the usual name", {"student": {"params": flat},
                                                         "teacher": {"params": flat}},
             ["'student'", "'teacher'", "--checkpoint-key"]),
            ("no parameters", {"weights": torch.zeros(4)}, ["'params'", "'weights'"])):
        p = os.path.join(tmp, "refuse_%s.pth" % label.replace(" ", "_").replace("'", ""))
        torch.save(obj, p)
        rc, err = export(["tcnn", p, os.path.join(tmp, "refused.inr"), "--tcnn-config", cfg])
        check(rc == 1 and all(n in err for n in needles) and os.path.basename(p) in err,
              "%s: refused naming %s: %s" % (label, needles, err.strip().splitlines()[-1]))
    check(not os.path.exists(os.path.join(tmp, "refused.inr")), "no file left by a refusal")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--inr", required=True, help="path to the inr CLI, or 'reference'")
    ap.add_argument("--data", required=True, help="Testing/Data/tcnn")
    a = ap.parse_args()
    torch = require_torch()
    with tempfile.TemporaryDirectory() as tmp:
        shipped_configs(torch, a.inr, a.data, tmp)
        encoding_network_pair(torch, a.inr, a.data, tmp)
        same_conversion(torch, a.data)
        refusals(torch, a.data, tmp)
    if failures:
        print("FAILED: %d check(s)" % len(failures))
        return 1
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
