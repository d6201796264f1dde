#!/usr/bin/env python3
"""Train INRs in the layouts of their official implementations on the real time-varying
volumes made by Tools/data/, and export them as INR Volume files.

    /usr/bin/python3 Tools/training/train.py --config small|paper [--device auto|cpu|cuda]
        [--minutes M | --steps N] [--data .data] [--out DIR] [--only NAME ...] [--list]

Models (``--list`` prints them). ``paper`` = the paper's sizes (<= 3 MB each), ``small`` =
siblings of tens of KB for the CPU tests:

  siren_cylinder_vorticity      SIREN, vsitzmann/siren notebook layout, on Gerris cylinder |w|
  siren_sphere_plate_vorticity  SIREN, same layout, on Gerris sphere+plate |w|
  ffn_mri_head                  Fourier-feature network, awreed/DynamicCTReconstruction INR_3D
                                layout (4-channel B, SiLU, sigmoid), on the deforming MR head
  coordnet_cylinder_u           CoordNet, stevenhan1991/TVCG23-CoordNet layout, on Gerris
                                cylinder streamwise velocity (per-time-step normalisation)
  hashgrid_mri_head             hash grid (tiny-cuda-nn HashGrid over x, y, z, t) + ReLU MLP,
                                Tools/python/inr_hashgrid_torch.py, on the deforming MR head

Every model is trained with Adam on MSE at the grid samples (fixed seeds; learning rate on a
cosine schedule over the budget), its reconstruction PSNR against the training data is
measured on the grid, the state_dict is converted by Tools/python/inr_export.py with the
dataset's domain (world bounds, cell centring at the grid resolution, time range and snapshot
times, input order) and output mapping, the written file is re-read and checked against
PyTorch with the numpy reference evaluator, and ``NAME.json`` (settings, PSNR, sizes) and
``NAME.tf.json`` (suggested ParaView colour map / opacity) are written next to ``NAME.inr``.
``summary.json`` lists all models.

Budget: ``--minutes`` per model (time-based schedule, the step count reached is recorded), or
``--steps`` for bit-reproducible runs on one device. Works with PyTorch 1.13 and 2.x; on CUDA
TF32 matrix products are enabled for training (evaluation and export are fp32).
"""

import argparse
import collections
import hashlib
import json
import math
import os
import sys
import tempfile
import time

import numpy as np
import torch
import torch.nn.functional as F

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "Tools", "python"))
sys.path.insert(0, os.path.join(REPO, "Tools", "data"))
import dataset_io  # noqa: E402
import inr_export  # noqa: E402
import inr_hashgrid_torch as HG  # noqa: E402
import inr_torch_layouts as L  # noqa: E402

SEED = 20240607


# ---------------------------------------------------------------------------- model specs
class Spec(object):
    def __init__(self, **kw):
        self.__dict__.update(kw)


def _siren(width, hidden_layers):
    return lambda: L.SirenNotebook(4, width, hidden_layers, 1, outermost_linear=True,
                                   first_omega_0=30.0, hidden_omega_0=30.0)


def specs_for(config, ffn_sigma=None):
    paper = config == "paper"
    s = []
    w, hl = (256, 4) if paper else (64, 2)
    for case in ("cylinder", "sphere_plate"):
        s.append(Spec(
            name="siren_%s_vorticity" % case, dataset="gerris_%s_vorticity" % case,
            family="SIREN", layout="siren-notebook",
            official="vsitzmann/siren explore_siren.ipynb `Siren` (outermost_linear=True, "
                     "first/hidden omega_0 = 30)",
            arch="4 -> %s -> 1 (sine w0=30, linear output)" % " -> ".join([str(w)] * (hl + 1)),
            build=_siren(w, hl), inputs="xyzt", target="minmax",
            lr=1e-4 if paper else 5e-4, batch=65536 if paper else 2048))
    nf, hc, sigma = (128, 5, 1.0) if paper else (32, 2, 0.5)
    sigma = ffn_sigma or sigma
    s.append(Spec(
        name="ffn_mri_head", dataset="mri_head_deform", family="FFN", layout="reed-ffn",
        official="awreed/DynamicCTReconstruction nn_models.py `INR_3D` (1x1x1 Conv3d, Swish, "
                 "Sigmoid) + `FourierFeatures` (4 input channels x,y,z,t)",
        arch="fourier(B %dx4 ~ N(0, %g^2), 2 pi) -> %d | %s -> 1 sigmoid"
             % (nf, sigma, 2 * nf, " -> ".join(["%d silu" % (2 * nf)] * hc)),
        build=lambda: L.ReedFFN(num_input_channels=4, nf=nf, sigma=sigma, seed=SEED % 1000,
                                hidden_convs=hc),
        inputs="xyzt", target="sigmoid", sigma=sigma,
        lr=1e-3 if paper else 2e-3, batch=65536 if paper else 2048))
    # Hash grid (tiny-cuda-nn's HashGrid over x, y, z, t; instant-vnr style) + ReLU MLP.
    hg = ({"n_levels": 16, "n_features_per_level": 2, "log2_hashmap_size": 17, "base_resolution": 4,
           "per_level_scale": 1.4} if paper else
          {"n_levels": 8, "n_features_per_level": 2, "log2_hashmap_size": 11, "base_resolution": 4,
           "per_level_scale": 1.6})
    hw = 64 if paper else 32
    s.append(Spec(
        name="hashgrid_mri_head", dataset="mri_head_deform", family="HashGrid",
        layout="hashgrid-torch",
        official="Tools/python/inr_hashgrid_torch.py `HashGridNetwork` (tiny-cuda-nn HashGrid "
                 "conventions, plain PyTorch)",
        arch="hashgrid(4D, %d levels x %d, 2^%d, base %d, x%g) -> %d relu -> %d relu -> 1"
             % (hg["n_levels"], hg["n_features_per_level"], hg["log2_hashmap_size"],
                hg["base_resolution"], hg["per_level_scale"], hw, hw),
        build=lambda: HG.HashGridNetwork(4, hg, width=hw, hidden_layers=2),
        hashgrid_config=dict(hg, n_input_dims=4),
        inputs="xyzt", target="minmax", lr=1e-2, batch=65536 if paper else 4096))
    f0, nres = (48, 6) if paper else (12, 1)
    s.append(Spec(
        name="coordnet_cylinder_u", dataset="gerris_cylinder_u", family="CoordNet",
        layout="coordnet",
        official="stevenhan1991/TVCG23-CoordNet Code/model.py `CoordNet` (init_features=%d, "
                 "num_res=%d)" % (f0, nres),
        arch="res(4->%d) res(->%d) res(->%d) %d x res(%d) res(->1); 0.5*(sine-sine body + "
             "[sine transform | identity]), w0=30" % (f0, 2 * f0, 4 * f0, nres, 4 * f0),
        build=lambda: L.CoordNet(4, 1, init_features=f0, num_res=nres),
        inputs="tzyx", target="per_time",
        lr=1e-4 if paper else 5e-4, batch=32768 if paper else 2048))
    for sp in s:
        if not paper:
            sp.name += "_small"
    return s


# ---------------------------------------------------------------------------- data
class Volume(object):
    """A dataset on the device: flat values plus per-axis network coordinates."""

    def __init__(self, name, datadir, device):
        try:
            arr, meta = dataset_io.load(name, datadir)
        except (OSError, IOError) as e:
            raise SystemExit("dataset %s not found in %s (%s). Generate it with the scripts in "
                             "Tools/data/ (see Docs/DATA.md)." % (name, datadir, e))
        self.meta = meta
        self.path = os.path.join(datadir, name + ".npy")
        a = np.asarray(arr, dtype=np.float32)
        self.shape = a.shape  # T, Z, Y, X
        self.values_np = a
        self.values = torch.from_numpy(a.reshape(-1).copy()).to(device)
        T, Z, Y, X = a.shape
        # network coordinate of sample i along an axis of n samples: first/last centre at -1/+1
        ax = lambda n: torch.linspace(-1.0, 1.0, n, dtype=torch.float32, device=device)  # noqa
        self.ct, self.cz, self.cy, self.cx = ax(T), ax(Z), ax(Y), ax(X)
        self.vmin = float(a.min())
        self.vmax = float(a.max())
        self.tmin = torch.from_numpy(a.reshape(T, -1).min(axis=1)).to(device)
        self.tmax = torch.from_numpy(a.reshape(T, -1).max(axis=1)).to(device)

    def sha256(self):
        h = hashlib.sha256()
        with open(self.path, "rb") as f:
            for blk in iter(lambda: f.read(1 << 20), b""):
                h.update(blk)
        return h.hexdigest()

    def coords(self, idx, order):
        T, Z, Y, X = self.shape
        i = idx % X
        j = (idx // X) % Y
        k = (idx // (X * Y)) % Z
        t = idx // (X * Y * Z)
        c = {"x": self.cx[i], "y": self.cy[j], "z": self.cz[k], "t": self.ct[t]}
        return torch.stack([c[a] for a in order], dim=1), t


# ---------------------------------------------------------------------------- forward
def forward(model, spec, x):
    if spec.layout == "reed-ffn":
        # Same parameters and maths as ReedFFN.forward_points, with the 1x1x1 convolutions
        # applied as matrix products (much faster than cuDNN Conv3d on 1-voxel volumes).
        p = 2.0 * math.pi * (x @ model.B.to(device=x.device, dtype=x.dtype))
        h = torch.cat([torch.sin(p), torch.cos(p)], dim=1)
        for m in model.main:
            if isinstance(m, torch.nn.Conv3d):
                h = F.linear(h, m.weight.flatten(1), m.bias)
            else:
                h = m(h)
        return h[:, 0]
    return model.forward_points(x)


class Target(object):
    """Maps field values to the network's training target and back."""

    def __init__(self, spec, vol):
        self.kind = spec.target
        self.vol = vol
        if self.kind == "minmax":      # [-1, 1] over the whole series
            self.c = 0.5 * (vol.vmax + vol.vmin)
            self.s = 0.5 * (vol.vmax - vol.vmin)
        elif self.kind == "sigmoid":   # (0, 1) with headroom below and above
            self.s = 1.05 * vol.vmax
            if vol.vmin < 0:
                raise SystemExit("%s: sigmoid target needs non-negative data" % spec.dataset)

    def forward(self, v, t):
        if self.kind == "minmax":
            return (v - self.c) / self.s
        if self.kind == "sigmoid":
            return v / self.s
        lo, hi = self.vol.tmin[t], self.vol.tmax[t]
        return 2.0 * (v - lo) / torch.clamp(hi - lo, min=1e-12) - 1.0

    def inverse(self, y, t):
        if self.kind == "minmax":
            return y * self.s + self.c
        if self.kind == "sigmoid":
            return y * self.s
        lo, hi = self.vol.tmin[t], self.vol.tmax[t]
        return lo + (y + 1.0) * 0.5 * (hi - lo)

    def export_args(self, tmpdir, name):
        vol = self.vol
        if self.kind == "minmax":
            return ["--output-range", repr(vol.vmin), repr(vol.vmax)], \
                {"scale": self.s, "offset": self.c}
        if self.kind == "sigmoid":
            return ["--output-scale", repr(self.s), "--output-offset", "0"], \
                {"scale": self.s, "offset": 0.0}
        table = os.path.join(tmpdir, name + ".table.txt")
        times = vol.meta["times"]
        mn = vol.tmin.cpu().numpy().tolist()
        mx = vol.tmax.cpu().numpy().tolist()
        with open(table, "w") as f:
            for row in zip(times, mn, mx):
                f.write("%r %r %r\n" % row)
        return ["--per-time-table", table], {"per_time": "min/max of each snapshot -> [-1, 1]"}


# ---------------------------------------------------------------------------- training
def lr_at(lr0, p):
    return lr0 * (0.05 + 0.95 * 0.5 * (1.0 + math.cos(math.pi * min(1.0, p))))


def train_one(spec, vol, device, minutes, steps, log):
    torch.manual_seed(SEED)
    model = spec.build()   # ReedFFN seeds the global generator itself (official B recipe)
    torch.manual_seed(SEED + 1)
    model = model.to(device)
    if hasattr(model, "B"):
        model.B = model.B.to(device)
    target = Target(spec, vol)
    order = spec.inputs
    gen = torch.Generator(device=device)
    gen.manual_seed(SEED + 2)
    opt = torch.optim.Adam(model.parameters(), lr=spec.lr)
    N = vol.values.numel()
    budget = None if steps else minutes * 60.0
    t0 = time.time()
    step, next_log, loss_ema = 0, 0.0, None
    while True:
        el = time.time() - t0
        p = step / float(steps) if steps else el / budget
        if p >= 1.0:
            break
        for g in opt.param_groups:
            g["lr"] = lr_at(spec.lr, p)
        idx = torch.randint(0, N, (spec.batch,), device=device, generator=gen)
        x, t = vol.coords(idx, order)
        y = target.forward(vol.values[idx], t)
        pred = forward(model, spec, x)
        loss = torch.mean((pred - y) ** 2)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        step += 1
        if p >= next_log or step == 1:
            lv = loss.item()
            loss_ema = lv
            log("  %-32s step %6d  %5.1f%%  loss %.3e  lr %.1e  %.0f samples/s"
                % (spec.name, step, 100 * p, lv, lr_at(spec.lr, p),
                   step * spec.batch / max(1e-9, time.time() - t0)))
            next_log += 0.1
    spec.steps_done = step
    spec.train_seconds = time.time() - t0
    spec.final_loss = float(loss.item()) if step else loss_ema
    return model, target


def evaluate(model, spec, vol, target, device, max_points):
    """PSNR (peak = data max - min) and max abs error over the grid (or a strided subset)."""
    N = vol.values.numel()
    stride = max(1, int(math.ceil(N / float(max_points))))
    idx_all = torch.arange(0, N, stride, device=device)
    se, worst, n = 0.0, 0.0, 0
    tf32 = None
    if device.type == "cuda":
        tf32 = torch.backends.cuda.matmul.allow_tf32
        torch.backends.cuda.matmul.allow_tf32 = False
    with torch.no_grad():
        for c in torch.split(idx_all, 1 << 18):
            x, t = vol.coords(c, spec.inputs)
            v = target.inverse(forward(model, spec, x), t)
            d = (v - vol.values[c]).double()
            se += float((d * d).sum())
            worst = max(worst, float(d.abs().max()))
            n += c.numel()
    if tf32 is not None:
        torch.backends.cuda.matmul.allow_tf32 = tf32
    mse = se / n
    peak = vol.vmax - vol.vmin
    return 10.0 * math.log10(peak * peak / max(mse, 1e-30)), worst, n, stride


# ---------------------------------------------------------------------------- transfer functions
def transfer_function(spec, vol):
    """A suggested ParaView colour map + opacity (preset JSON: RGBPoints, Points)."""
    lo, hi = vol.vmin, vol.vmax
    q = lambda f: lo + f * (hi - lo)  # noqa: E731
    v = vol.values_np
    if spec.dataset.endswith("_vorticity"):
        p99 = float(np.percentile(v[v > 0], 99.5)) if np.any(v > 0) else hi
        a = lambda f: f * p99  # noqa: E731
        rgb = [a(0.0), 0.0, 0.0, 0.02, a(0.15), 0.25, 0.05, 0.45, a(0.35), 0.75, 0.15, 0.45,
               a(0.6), 0.98, 0.45, 0.1, a(1.0), 1.0, 0.95, 0.6, hi, 1.0, 1.0, 1.0]
        pts = [a(0.0), 0.0, 0.5, 0.0, a(0.12), 0.0, 0.5, 0.0, a(0.35), 0.25, 0.5, 0.0,
               a(1.0), 0.8, 0.5, 0.0, hi, 1.0, 0.5, 0.0]
        note = "magma-like on |w|; transparent below 12% of the 99.5th percentile"
    elif spec.dataset.startswith("mri"):
        rgb = [q(0.0), 0.0, 0.0, 0.0, q(0.12), 0.35, 0.15, 0.1, q(0.3), 0.8, 0.5, 0.35,
               q(0.6), 0.95, 0.85, 0.7, q(1.0), 1.0, 1.0, 1.0]
        pts = [q(0.0), 0.0, 0.5, 0.0, q(0.15), 0.0, 0.5, 0.0, q(0.3), 0.04, 0.5, 0.0,
               q(0.6), 0.3, 0.5, 0.0, q(1.0), 0.8, 0.5, 0.0]
        note = "skin/tissue ramp; air, background and faint tissue nearly transparent"
    else:  # velocity component: diverging, recirculation (u < 0) and the fast stream visible
        rgb = [lo, 0.23, 0.30, 0.75, 0.0, 0.55, 0.65, 0.95, 1.0, 0.87, 0.87, 0.87,
               max(1.0, q(0.85)), 0.95, 0.55, 0.4, hi, 0.7, 0.02, 0.15]
        rgb = _sorted_points(rgb, 4)
        pts = _sorted_points([lo, 0.9, 0.5, 0.0, 0.0, 0.35, 0.5, 0.0, 0.6, 0.0, 0.5, 0.0,
                              1.0, 0.0, 0.5, 0.0, max(1.0, q(0.85)), 0.2, 0.5, 0.0,
                              hi, 0.8, 0.5, 0.0], 4)
        note = "cool-warm around u = 1 (free stream, transparent); wake deficit/recirculation " \
               "(u < 0.6) blue, over-speed red"
    return [{"Name": spec.name, "ColorSpace": "RGB", "RGBPoints": rgb, "Points": pts,
             "Annotation": note, "ValueRange": [lo, hi]}]


def _sorted_points(flat, k):
    rows = [flat[i:i + k] for i in range(0, len(flat), k)]
    rows.sort(key=lambda r: r[0])
    out, last = [], None
    for r in rows:
        if last is not None and r[0] <= last:
            continue
        out += r
        last = r[0]
    return out


# ---------------------------------------------------------------------------- export
def export(model, spec, vol, target, outdir, log):
    from inr_reference import ReferenceModel
    meta = vol.meta
    T, Z, Y, X = vol.shape
    with tempfile.TemporaryDirectory() as tmp:
        sd = collections.OrderedDict((k, v.detach().cpu()) for k, v in model.state_dict().items())
        pth = os.path.join(tmp, spec.name + ".pth")
        torch.save(sd, pth)
        out_args, mapping = target.export_args(tmp, spec.name)
        extra = []
        if spec.layout == "reed-ffn":
            bfile = os.path.join(tmp, "B.npy")
            np.save(bfile, model.B.detach().cpu().numpy().astype(np.float64))
            extra = ["--fourier-B", bfile]
        if spec.layout == "hashgrid-torch":
            extra = ["--hashgrid-config", json.dumps(spec.hashgrid_config)]
        out = os.path.join(outdir, spec.name + ".inr")
        args = [spec.layout, pth, out, "--quiet", "--name", spec.name,
                "--bounds"] + [repr(float(b)) for b in meta["bounds"]] + [
            "--centering", "cell", "--resolution", str(X), str(Y), str(Z),
            "--time-range", repr(meta["times"][0]), repr(meta["times"][-1]),
            "--time-steps"] + [repr(float(t)) for t in meta["times"]] + [
            "--value-range", repr(vol.vmin), repr(vol.vmax),
            "--description", "%s trained on %s (%s, %s)" % (spec.family, spec.dataset,
                                                             meta.get("quantity"),
                                                             meta.get("units")),
            "--provenance", "Tools/training/train.py (%s) on %s; data: %s"
            % (spec.layout, spec.dataset, meta.get("source"))] + out_args + extra
        if inr_export.main(args) != 0:
            raise SystemExit("export of %s failed" % spec.name)
    # The file must evaluate like the PyTorch model (numpy float64 reference reader).
    ref = ReferenceModel.load(out)
    rs = np.random.RandomState(7)
    b = meta["bounds"]
    pts = np.stack([rs.uniform(b[0], b[1], 500), rs.uniform(b[2], b[3], 500),
                    rs.uniform(b[4], b[5], 500)], axis=1)
    worst = 0.0
    times = meta["times"]
    for t in (times[0], times[len(times) // 3], times[-1]):
        fv = ref.evaluate(pts, t)
        tv = torch_eval_world(model, spec, vol, target, pts, t)
        worst = max(worst, float(np.max(np.abs(fv - tv))))
    tol = 1e-3 * max(1.0, abs(vol.vmax), abs(vol.vmin))
    if not worst < tol:
        raise SystemExit("%s: exported file and PyTorch disagree by %g" % (out, worst))
    log("  %s: exported %s (%d bytes); file vs PyTorch max |diff| %.2e"
        % (spec.name, out, os.path.getsize(out), worst))
    return out, worst, mapping


def torch_eval_world(model, spec, vol, target, pts, t):
    """PyTorch value at world points (cell-centred map) and world time t (interpolated
    per-time table, like the file's output mapping)."""
    meta = vol.meta
    T, Z, Y, X = vol.shape
    b = meta["bounds"]
    res = {"x": X, "y": Y, "z": Z}
    col = {"x": 0, "y": 1, "z": 2}
    dev = vol.values.device
    cols = []
    times = meta["times"]
    tn = -1.0 + 2.0 * (t - times[0]) / (times[-1] - times[0])
    for a in spec.inputs:
        if a == "t":
            cols.append(np.full(len(pts), tn))
        else:
            lo, hi, n = b[2 * col[a]], b[2 * col[a] + 1], res[a]
            h = (hi - lo) / n
            cols.append(-1.0 + 2.0 * (pts[:, col[a]] - lo - h / 2) / (hi - lo - h))
    x = torch.from_numpy(np.stack(cols, axis=1).astype(np.float32)).to(dev)
    tf32 = None
    if dev.type == "cuda":
        tf32 = torch.backends.cuda.matmul.allow_tf32
        torch.backends.cuda.matmul.allow_tf32 = False
    with torch.no_grad():
        y = forward(model, spec, x).double().cpu().numpy()
    if tf32 is not None:
        torch.backends.cuda.matmul.allow_tf32 = tf32
    if target.kind == "per_time":
        mn = np.interp(t, times, vol.tmin.cpu().numpy())
        mx = np.interp(t, times, vol.tmax.cpu().numpy())
        return mn + (y + 1.0) * 0.5 * (mx - mn)
    return y * target.s + (target.c if target.kind == "minmax" else 0.0)


# ---------------------------------------------------------------------------- main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--config", choices=("paper", "small"), default="small")
    ap.add_argument("--device", default="auto", help="auto | cpu | cuda | cuda:N [auto]")
    ap.add_argument("--minutes", type=float, default=None,
                    help="training time per model [paper 1.6, small 4]")
    ap.add_argument("--steps", type=int, default=None, help="fixed step count per model")
    ap.add_argument("--data", default=os.path.join(REPO, ".data"))
    ap.add_argument("--out", default=None, help="[Testing/Data/real for small]")
    ap.add_argument("--only", nargs="*", help="train only these models")
    ap.add_argument("--eval-max", type=int, default=None,
                    help="max grid points for the PSNR [all on CUDA, 1M on CPU]")
    ap.add_argument("--threads", type=int, default=None, help="CPU threads [all cores]")
    ap.add_argument("--batch", type=int, default=None, help="override every model's batch size")
    ap.add_argument("--ffn-sigma", type=float, default=None,
                    help="std of the Fourier matrix B [paper 1.0, small 0.5]")
    ap.add_argument("--lr-scale", type=float, default=1.0, help="multiply every learning rate")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args(argv)
    specs = specs_for(a.config, a.ffn_sigma)
    if a.list:
        for s in specs:
            print("%-34s %-9s %-15s on %-28s %s" % (s.name, s.family, s.layout, s.dataset,
                                                    s.arch))
        return 0
    if a.only:
        unknown = set(a.only) - {s.name for s in specs}
        if unknown:
            raise SystemExit("unknown model(s) %s (see --list)" % ", ".join(sorted(unknown)))
        specs = [s for s in specs if s.name in a.only]
    for s in specs:
        if a.batch:
            s.batch = a.batch
        s.lr *= a.lr_scale
    if a.device == "auto":
        device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    else:
        device = torch.device(a.device)
    if a.threads:
        torch.set_num_threads(a.threads)
    if device.type == "cuda":
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
    minutes = a.minutes if a.minutes is not None else (1.6 if a.config == "paper" else 4.0)
    eval_max = a.eval_max or (1 << 30 if device.type == "cuda" else 1 << 20)
    out = a.out or os.path.join(REPO, "Testing", "Data", "real")
    os.makedirs(out, exist_ok=True)
    log = lambda s: print(s, flush=True)  # noqa: E731
    dev_name = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu (%d threads)" \
        % torch.get_num_threads()
    log("train.py: config %s, device %s, torch %s, %s per model"
        % (a.config, dev_name, torch.__version__,
           "%d steps" % a.steps if a.steps else "%.2f min" % minutes))
    t_all = time.time()
    summary = []
    vols = {}
    for spec in specs:
        if spec.dataset not in vols:
            vols[spec.dataset] = Volume(spec.dataset, a.data, device)
        vol = vols[spec.dataset]
        log("%s: %s %s on %s %s" % (spec.name, spec.family, spec.arch, spec.dataset,
                                     "x".join(map(str, vol.shape))))
        model, target = train_one(spec, vol, device, minutes, a.steps, log)
        psnr, maxerr, npts, stride = evaluate(model, spec, vol, target, device, eval_max)
        path, filediff, mapping = export(model, spec, vol, target, out, log)
        nparams = sum(int(p.numel()) for p in model.parameters()) + (
            int(model.B.numel()) if hasattr(model, "B") else 0)
        m = vol.meta
        rec = collections.OrderedDict([
            ("name", spec.name), ("file", os.path.basename(path)),
            ("file_bytes", os.path.getsize(path)), ("parameters", nparams),
            ("family", spec.family), ("layout", spec.layout), ("official", spec.official),
            ("architecture", spec.arch), ("config", a.config),
            ("dataset", spec.dataset), ("dataset_sha256", vol.sha256()),
            ("dataset_shape_TZYX", list(vol.shape)),
            ("quantity", m.get("quantity")), ("units", m.get("units")),
            ("source", m.get("source")), ("licence", m.get("licence")),
            ("bounds", m["bounds"]), ("length_units", m.get("length_units")),
            ("time_range", [m["times"][0], m["times"][-1]]), ("time_units", m.get("time_units")),
            ("snapshots", len(m["times"])), ("value_range", [vol.vmin, vol.vmax]),
            ("input_order", list(spec.inputs)),
            ("input_mapping", "cell-centred: first/last sample centre -> %s on every axis "
                              "(x, y, z); first/last snapshot time -> %s"
                              % (("0/1", "0/1") if spec.layout == "hashgrid-torch" else ("-1/+1", "-1/+1"))),
            ("output_mapping", mapping), ("target", spec.target),
            ("device", dev_name), ("torch", torch.__version__),
            ("seed", SEED), ("optimizer", "Adam"), ("lr", spec.lr),
            ("lr_schedule", "cosine to 5% over the budget"), ("batch", spec.batch),
            ("budget_minutes", None if a.steps else minutes), ("steps", spec.steps_done),
            ("train_seconds", round(spec.train_seconds, 1)),
            ("samples_seen", spec.steps_done * spec.batch),
            ("final_batch_mse_normalised", spec.final_loss),
            ("psnr_db", round(psnr, 3)), ("psnr_peak", "data max - min"),
            ("psnr_points", npts), ("psnr_grid_stride", stride),
            ("max_abs_error", maxerr), ("file_vs_torch_max_abs_diff", filediff),
            ("command", "Tools/training/train.py " + " ".join(argv if argv is not None
                                                              else sys.argv[1:]))])
        with open(os.path.join(out, spec.name + ".json"), "w") as f:
            json.dump(rec, f, indent=1)
            f.write("\n")
        with open(os.path.join(out, spec.name + ".tf.json"), "w") as f:
            json.dump(transfer_function(spec, vol), f, indent=1)
            f.write("\n")
        summary.append(rec)
        log("  %s: PSNR %.2f dB (max |err| %.3g) after %d steps in %.0f s; %d params, %d bytes"
            % (spec.name, psnr, maxerr, spec.steps_done, spec.train_seconds, nparams,
               os.path.getsize(path)))
        del model
        if device.type == "cuda":
            torch.cuda.empty_cache()
    with open(os.path.join(out, "summary%s.json" % ("" if a.config == "paper" else "_small")),
              "w") as f:
        json.dump(summary, f, indent=1)
        f.write("\n")
    log("done: %d models in %.0f s -> %s" % (len(summary), time.time() - t_all, out))
    for r in summary:
        log("  %-34s %8d bytes  PSNR %6.2f dB  %s" % (r["name"], r["file_bytes"], r["psnr_db"],
                                                     r["dataset"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
