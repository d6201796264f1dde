#!/usr/bin/env python3
"""Train the small test INRs shipped in Testing/Data/models/ (CPU PyTorch, fixed seeds).

    /usr/bin/python3 Tools/python/train_test_models.py [--out DIR] [--steps-scale F]

Each model family (SIREN in both official layouts, Reed et al.'s Fourier-feature network,
CoordNet, neurcomp) is trained on the same analytic time-varying field -- two Gaussian blobs
that move towards each other and merge, plus a travelling wave -- in the world box
x in [0,2], y in [-1,1], z in [0,1] over world time [0,10]. The networks are built in the
official state_dict layouts (inr_torch_layouts.py), saved as .pth and converted with
inr_export.py, so the shipped .inr files are what the exporter produces. For every model it
writes:

  <name>.inr      the model
  <name>.ref.txt  PyTorch float64 reference outputs at fixed random points and times
                  (lines "t x y z value", world coordinates, %.9g; '#' lines are comments)

and README.md describing all of them (architecture, sizes, settings, PSNR, ranges).
"""

import argparse
import collections
import math
import os
import sys
import tempfile
import time

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import inr_export  # noqa: E402
import inr_torch_layouts as L  # noqa: E402
from inr_format import read_inr  # noqa: E402
from inr_reference import ReferenceModel  # noqa: E402

REPO = os.path.dirname(os.path.dirname(HERE))
BOUNDS = [0.0, 2.0, -1.0, 1.0, 0.0, 1.0]
TIME_RANGE = [0.0, 10.0]
REF_TIMES = [0.0, 1.7, 5.0, 8.25, 10.0]


# ------------------------------------------------------------------ the analytic field
def field(x, y, z, t, xp=np):
    """Two merging Gaussian blobs plus a travelling wave; values in [0, 1]."""
    s = t / 10.0
    zs = 0.15 * xp.sin(math.pi * s)
    sig2 = 2.0 * (0.16 + 0.04 * s) ** 2
    b1 = xp.exp(-((x - (0.45 + 0.5 * s)) ** 2 + (y - (-0.45 + 0.45 * s)) ** 2
                  + (z - (0.5 + zs)) ** 2) / sig2)
    b2 = xp.exp(-((x - (1.55 - 0.5 * s)) ** 2 + (y - (0.45 - 0.45 * s)) ** 2
                  + (z - (0.5 - zs)) ** 2) / sig2)
    blobs = 1.0 - (1.0 - b1) * (1.0 - b2)
    wave = 0.5 + 0.5 * xp.sin(2.0 * math.pi * (0.8 * x - 0.12 * t) + 1.5 * y)
    return 0.8 * blobs + 0.2 * wave * xp.exp(-((z - 0.5) / 0.4) ** 2)


def sample_world(n, gen):
    u = torch.rand((n, 4), generator=gen, dtype=torch.float64)
    lo = torch.tensor([BOUNDS[0], BOUNDS[2], BOUNDS[4], TIME_RANGE[0]], dtype=torch.float64)
    hi = torch.tensor([BOUNDS[1], BOUNDS[3], BOUNDS[5], TIME_RANGE[1]], dtype=torch.float64)
    return lo + u * (hi - lo)


# ------------------------------------------------------------------ world -> network maps
def node_map(w, lo, hi, nlo=-1.0, nhi=1.0):
    return nlo + (w - lo) / (hi - lo) * (nhi - nlo)


def cell_map(w, lo, hi, n, nlo, nhi):
    h = (hi - lo) / n
    return nlo + (w - lo - h / 2) / (hi - lo - h) * (nhi - nlo)


def time_map(t):
    return node_map(t, TIME_RANGE[0], TIME_RANGE[1])


# ------------------------------------------------------------------ the models
class Spec(object):
    """One shipped model: how to build, feed, train and export it."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def _inputs_xyzt(world, maps):
    cols = [maps[a](world[:, a]) for a in range(3)] + [time_map(world[:, 3])]
    return torch.stack(cols, dim=1)


def make_specs():
    specs = []

    # 1. SIREN, notebook layout, node-centred [-1,1] inputs, identity output.
    node = [lambda w, a=a: node_map(w, BOUNDS[2 * a], BOUNDS[2 * a + 1]) for a in range(3)]
    specs.append(Spec(
        name="siren_blobs", layout="siren-notebook", family="SIREN (vsitzmann/siren notebook "
        "`Siren`, outermost_linear)",
        build=lambda: L.SirenNotebook(4, 48, 2, 1, outermost_linear=True,
                                      first_omega_0=30.0, hidden_omega_0=30.0),
        arch="4 -> 48 sine(30) -> 48 sine(30) -> 48 sine(30) -> 1",
        inputs=lambda w: _inputs_xyzt(w, node),
        target=lambda v, w: v, untarget=lambda y, t: y,
        lr=1e-3, steps=800,
        export=["--bounds"] + [str(v) for v in BOUNDS] + ["--time-range", "0", "10",
                                                          "--value-range", "0", "1"],
        mapping="node-centred, input_range [-1,1], inputs (x,y,z,t), output identity"))

    # 2. SIREN, modules.py SingleBVPNet layout, cell-centred, output scale 0.5 offset 0.5
    #    (like the official video/volume scripts that train on (v - 0.5) / 0.5).
    res = [64, 64, 32]
    cell = [lambda w, a=a: cell_map(w, BOUNDS[2 * a], BOUNDS[2 * a + 1], res[a], -1.0, 1.0)
            for a in range(3)]
    specs.append(Spec(
        name="siren_modules_cell", layout="siren-modules",
        family="SIREN (vsitzmann/siren modules.py `SingleBVPNet`, type 'sine')",
        build=lambda: L.SirenModules(4, 40, 2, 1, nonlinearity="sine"),
        arch="4 -> 40 sine(30) -> 40 sine(30) -> 40 sine(30) -> 1",
        inputs=lambda w: _inputs_xyzt(w, cell),
        target=lambda v, w: (v - 0.5) / 0.5, untarget=lambda y, t: 0.5 * y + 0.5,
        lr=1e-3, steps=800,
        export=["--bounds"] + [str(v) for v in BOUNDS] + [
            "--time-range", "0", "10", "--centering", "cell",
            "--resolution"] + [str(r) for r in res] + [
            "--output-scale", "0.5", "--output-offset", "0.5", "--value-range", "0", "1"],
        mapping="cell-centred on a 64x64x32 grid, input_range [-1,1], inputs (x,y,z,t), "
                "output 0.5*net+0.5"))

    # 3. Reed et al. Fourier-feature network (INR_3D layout, 1x1x1 Conv3d, Swish, Sigmoid),
    #    with a 4-channel B (x,y,z,t) regenerated from seed 0 / sigma 1.0. Cell-centred with
    #    the official convention: cell centres at +-(1 - 1/n).
    rres = [40, 40, 20]
    rir = [(-1.0 + 1.0 / n, 1.0 - 1.0 / n) for n in rres]
    rcell = [lambda w, a=a: cell_map(w, BOUNDS[2 * a], BOUNDS[2 * a + 1], rres[a],
                                     rir[a][0], rir[a][1]) for a in range(3)]
    specs.append(Spec(
        name="ffn_blobs", layout="reed-ffn",
        family="Fourier-feature network (awreed/DynamicCTReconstruction `INR_3D` + "
               "`FourierFeatures`, 4 input channels)",
        build=lambda: L.ReedFFN(num_input_channels=4, nf=32, sigma=1.0, seed=0,
                                hidden_convs=3),
        arch="fourier(B 32x4, 2*pi) -> 64 | 64 silu -> 64 silu -> 64 silu -> 1 sigmoid",
        inputs=lambda w: _inputs_xyzt(w, rcell),
        target=lambda v, w: v, untarget=lambda y, t: y,
        lr=5e-3, steps=800,
        export=["--reed-sigma", "1.0", "--reed-seed", "0", "--reed-input-channels", "4",
                "--bounds"] + [str(v) for v in BOUNDS] + [
            "--time-range", "0", "10", "--centering", "cell", "--resolution"] + [
            str(r) for r in rres] + ["--input-range"] + [
            repr(v) for p in rir for v in p] + ["--value-range", "0", "1"],
        mapping="cell-centred on a 40x40x20 grid with centres at +-(1-1/n) (the official "
                "convention), inputs (x,y,z,t), sigmoid output"))

    # 4. CoordNet: (t,z,y,x) inputs, 0.5-weighted residual sine blocks, per-time-step target
    #    normalisation to [-1,1] (min/max of each snapshot on a 33x33x17 node grid).
    snap_times = np.linspace(0.0, 10.0, 21)
    specs.append(Spec(
        name="coordnet_blobs", layout="coordnet",
        family="CoordNet (stevenhan1991/TVCG23-CoordNet `CoordNet`, init_features=8, "
               "num_res=1)",
        build=lambda: L.CoordNet(4, 1, init_features=8, num_res=1),
        arch="res(4->8) res(8->16) res(16->32) res(32->32) res(32->1); each "
             "0.5*(sine-sine body + [sine transform | identity])",
        inputs=lambda w: torch.stack([time_map(w[:, 3])] + [
            node_map(w[:, a], BOUNDS[2 * a], BOUNDS[2 * a + 1]) for a in (2, 1, 0)], dim=1),
        snap_times=snap_times, lr=1e-3, steps=800,
        export=["--bounds"] + [str(v) for v in BOUNDS] + [
            "--time-range", "0", "10", "--time-steps"] + ["%g" % t for t in snap_times],
        mapping="node-centred, input_range [-1,1], inputs (t,z,y,x), output per_time "
                "min/max table (21 snapshots)"))

    # 5. neurcomp: residual sine layers, aspect-scaled inputs of a 65x65x33 volume
    #    (input ranges x,y: [-1,1], z: [-0.5,0.5]) and the global [-1,1] value scaling.
    nshape = [65, 65, 33]
    m = float(max(n - 1 for n in nshape))
    nsc = [(n - 1) / m for n in nshape]
    nmap = [lambda w, a=a: node_map(w, BOUNDS[2 * a], BOUNDS[2 * a + 1], -nsc[a], nsc[a])
            for a in range(3)]
    specs.append(Spec(
        name="neurcomp_blobs", layout="neurcomp",
        family="neurcomp (matthewberger/neurcomp `FieldNet`, is_residual, d_in=4)",
        build=lambda: L.NeurcompFieldNet(4, [36] * 4, 1, is_residual=True),
        arch="4 -> 36 sine(30) -> 3 residual sine layers (36) -> 1",
        inputs=lambda w: _inputs_xyzt(w, nmap), lr=1e-3, steps=800,
        neurcomp_shape=nshape,
        export=["--neurcomp-volume-shape"] + [str(n) for n in nshape] + [
            "--bounds"] + [str(v) for v in BOUNDS] + ["--time-range", "0", "10"],
        mapping="node-centred, aspect-scaled input ranges [-1,1],[-1,1],[-0.5,0.5] "
                "(neurcomp's), inputs (x,y,z,t), output (max-min)/2*net+(max+min)/2"))
    return specs


def grid_points(n=(33, 33, 17)):
    axes = [np.linspace(BOUNDS[2 * a], BOUNDS[2 * a + 1], n[a]) for a in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


def train(spec, log):
    torch.manual_seed(1234)
    model = spec.build()
    gen = torch.Generator().manual_seed(4321)
    grid = grid_points()
    if spec.layout == "coordnet":
        mins, maxs = [], []
        for t in spec.snap_times:
            v = field(grid[:, 0], grid[:, 1], grid[:, 2], t)
            mins.append(float(v.min()))
            maxs.append(float(v.max()))
        spec.table = (list(spec.snap_times), mins, maxs)
        st = torch.tensor(spec.snap_times)
        mn_t, mx_t = torch.tensor(mins), torch.tensor(maxs)

        def draw(n):
            w = sample_world(n, gen)
            k = torch.randint(0, len(st), (n,), generator=gen)
            w[:, 3] = st[k]
            v = field(w[:, 0], w[:, 1], w[:, 2], w[:, 3], torch)
            return w, 2.0 * (v - mn_t[k]) / (mx_t[k] - mn_t[k]) - 1.0
        spec.untarget = lambda y, t: np.interp(t, spec.snap_times, mins) + (y + 1.0) / 2.0 * (
            np.interp(t, spec.snap_times, maxs) - np.interp(t, spec.snap_times, mins))
    else:
        if spec.layout == "neurcomp":
            vals = np.concatenate([field(grid[:, 0], grid[:, 1], grid[:, 2], t)
                                   for t in np.linspace(0, 10, 11)])
            vmin, vmax = float(vals.min()), float(vals.max())
            spec.vrange = (vmin, vmax)
            spec.target = lambda v, w: 2.0 * ((v - vmin) / (vmax - vmin) - 0.5)
            spec.untarget = lambda y, t: (vmax - vmin) / 2.0 * y + (vmax + vmin) / 2.0
            spec.export = spec.export + ["--output-range", repr(vmin), repr(vmax),
                                         "--value-range", "0", "1"]

        def draw(n):
            w = sample_world(n, gen)
            v = field(w[:, 0], w[:, 1], w[:, 2], w[:, 3], torch)
            return w, spec.target(v, w)

    opt = torch.optim.Adam(model.parameters(), lr=spec.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, spec.steps, eta_min=spec.lr * 0.05)
    t0, c0 = time.time(), time.process_time()
    batch = 2048
    for step in range(spec.steps):
        w, y = draw(batch)
        pred = model.forward_points(spec.inputs(w).float())
        loss = torch.mean((pred - y.float()) ** 2)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if step % 400 == 0 or step == spec.steps - 1:
            log("  %s step %4d loss %.3e" % (spec.name, step, loss.item()))
    spec.train_seconds = time.time() - t0
    spec.train_cpu_seconds = time.process_time() - c0
    spec.batch = batch
    return model


def eval64(model, spec, world):
    m64 = spec.build()
    m64.load_state_dict(model.state_dict())
    if hasattr(model, "B"):
        m64.B = model.B.clone()
    m64 = m64.double()
    with torch.no_grad():
        return m64.forward_points(spec.inputs(torch.from_numpy(world))).numpy()


def psnr(model, spec):
    grid = grid_points((41, 41, 21))
    se, gts = [], []
    for t in np.linspace(0.0, 10.0, 11):
        w = np.concatenate([grid, np.full((len(grid), 1), t)], axis=1)
        y = eval64(model, spec, w)
        pred = spec.untarget(y, t)
        gt = field(grid[:, 0], grid[:, 1], grid[:, 2], t)
        se.append((pred - gt) ** 2)
        gts.append(gt)
    gts = np.concatenate(gts)
    mse = float(np.mean(np.concatenate(se)))
    peak = float(gts.max() - gts.min())
    return 10.0 * math.log10(peak * peak / mse), peak


def ref_points():
    rs = np.random.RandomState(20240607)
    lo = np.array(BOUNDS[0::2])
    hi = np.array(BOUNDS[1::2])
    pts = lo + rs.uniform(size=(44, 3)) * (hi - lo)
    corners = np.array([[x, y, z] for x in BOUNDS[0:2] for y in BOUNDS[2:4] for z in BOUNDS[4:6]])
    return np.concatenate([corners[:4], pts])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(REPO, "Testing", "Data", "models"))
    ap.add_argument("--steps-scale", type=float, default=1.0,
                    help="multiply every model's training steps (for quick trials)")
    ap.add_argument("--only", nargs="*", help="train only these model names")
    a = ap.parse_args(argv)
    torch.set_num_threads(max(1, min(2, os.cpu_count() or 1)))
    os.makedirs(a.out, exist_ok=True)
    log = lambda s: print(s, flush=True)  # noqa: E731
    results = []
    t_all = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for spec in make_specs():
            if a.only and spec.name not in a.only:
                continue
            spec.steps = max(1, int(spec.steps * a.steps_scale))
            log("training %s (%s)" % (spec.name, spec.layout))
            model = train(spec, log)
            pth = os.path.join(tmp, spec.name + ".pth")
            torch.save(model.state_dict(), pth)
            extra = []
            if spec.layout == "coordnet":
                table = os.path.join(tmp, spec.name + ".table.txt")
                with open(table, "w") as f:
                    for row in zip(*spec.table):
                        f.write("%r %r %r\n" % row)
                extra = ["--per-time-table", table]
            out = os.path.join(a.out, spec.name + ".inr")
            args = [spec.layout, pth, out, "--name", spec.name, "--quiet",
                    "--description", "test model: %s trained on merging Gaussian blobs + a "
                    "travelling wave (Tools/python/train_test_models.py)" % spec.family,
                    "--provenance", "Tools/python/train_test_models.py -> inr_export.py %s"
                    % spec.layout] + spec.export + extra
            if inr_export.main(args) != 0:
                raise SystemExit("export of %s failed" % spec.name)
            # Reference outputs, PyTorch float64 on the exported weights.
            pts = ref_points()
            ref = ReferenceModel.load(out)
            lines = ["# INR Volume reference outputs for %s.inr" % spec.name,
                     "# PyTorch float64 forward of the exported %s layout "
                     "(Tools/python/train_test_models.py)" % spec.layout,
                     "# columns: t x y z value  (world time, world x y z, field value after "
                     "the output mapping)"]
            worst = 0.0
            for t in REF_TIMES:
                w = np.concatenate([pts, np.full((len(pts), 1), t)], axis=1)
                vals = spec.untarget(eval64(model, spec, w), t)
                chk = ref.evaluate(pts, t)  # the numpy reading of the file must agree
                worst = max(worst, float(np.max(np.abs(chk - vals))))
                for p, v in zip(pts, vals):
                    lines.append("%.9g %.9g %.9g %.9g %.9g" % (t, p[0], p[1], p[2], v))
            if worst > 1e-9:
                raise SystemExit("%s: file and PyTorch disagree by %g" % (spec.name, worst))
            with open(os.path.join(a.out, spec.name + ".ref.txt"), "w") as f:
                f.write("\n".join(lines) + "\n")
            p, peak = psnr(model, spec)
            inr = read_inr(out)
            results.append(dict(spec=spec, psnr=p, bytes=os.path.getsize(out),
                                params=inr.parameter_count(), value_range=inr.value_range))
            log("  %s: %d params, %d bytes, PSNR %.2f dB, %.0f s"
                % (spec.name, inr.parameter_count(), os.path.getsize(out), p,
                   spec.train_seconds))
    if not a.only:
        write_readme(a.out, results, time.time() - t_all)
    log("done in %.0f s" % (time.time() - t_all))
    return 0


def write_readme(out, results, total):
    R = []
    R.append("# Test models\n")
    R.append("Small INRs of each architecture family, trained on CPU by\n"
             "`Tools/python/train_test_models.py` and converted by `Tools/python/inr_export.py`"
             "\n(the networks are built in the official state_dict layouts, saved as `.pth`, "
             "then exported).\nRegenerate them all (fixed seeds; this run took %.0f s wall "
             "clock on 2 cores; bit-identical\nresults need the same PyTorch build):\n"
             % total)
    R.append("```\n/usr/bin/python3 Tools/python/train_test_models.py\n```\n")
    R.append("## The field\n")
    R.append("World box x in [0,2], y in [-1,1], z in [0,1]; world time [0,10]. With "
             "s = t/10:\n\n"
             "- two Gaussian blobs, sigma = 0.16 + 0.04 s, centres "
             "(0.45+0.5s, -0.45+0.45s, 0.5+0.15 sin(pi s)) and\n"
             "  (1.55-0.5s, 0.45-0.45s, 0.5-0.15 sin(pi s)): they approach and merge near "
             "(1, 0, 0.5) at t = 10;\n"
             "  combined as blobs = 1 - (1-b1)(1-b2);\n"
             "- a travelling wave 0.5 + 0.5 sin(2 pi (0.8 x - 0.12 t) + 1.5 y), damped by "
             "exp(-((z-0.5)/0.4)^2);\n"
             "- value = 0.8 blobs + 0.2 wave, in [0, 1] (`field()` in the script).\n")
    R.append("## Models\n")
    R.append("| file | family / official layout | parameters | file size | PSNR |\n"
             "| --- | --- | ---: | ---: | ---: |")
    for r in results:
        s = r["spec"]
        R.append("| `%s.inr` | %s | %d | %d B | %.2f dB |"
                 % (s.name, s.family, r["params"], r["bytes"], r["psnr"]))
    R.append("\nPSNR: against the analytic field on a 41x41x21 node grid at 11 times "
             "(t = 0, 1, ..., 10), peak = range of the field there. All models: float32 "
             "weights, time_range [0, 10] mapped to network t in [-1, 1], value_range "
             "[0, 1].\n")
    for r in results:
        s = r["spec"]
        R.append("### %s\n" % s.name)
        R.append("- architecture: %s" % s.arch)
        R.append("- domain/output: %s" % s.mapping)
        R.append("- export: `inr_export.py %s MODEL.pth %s.inr %s`"
                 % (s.layout, s.name, " ".join(x for x in s.export)
                    + (" --per-time-table TABLE" if s.layout == "coordnet" else "")))
        R.append("- training: Adam lr %g with cosine decay to 5%%, %d steps of %d uniformly "
                 "random points in box x time%s, MSE in the network's own normalisation; "
                 "seed 1234 (weights) / 4321 (samples); %.0f s wall, %.0f s CPU"
                 % (s.lr, s.steps, s.batch,
                    " (CoordNet: at the 21 snapshot times t = 0, 0.5, ..., 10)"
                    if s.layout == "coordnet" else "", s.train_seconds,
                    s.train_cpu_seconds))
        R.append("- PSNR %.2f dB; value_range %s\n" % (r["psnr"], r["value_range"]))
    R.append("## Reference outputs (`*.ref.txt`)\n")
    R.append("PyTorch float64 forward passes of the exported weights (the same fp32 numbers "
             "as in the file, evaluated\nin double precision), at 48 fixed points (4 box "
             "corners + 44 random) and times %s.\nText: `#` lines are comments; every other "
             "line is `t x y z value` (world time, world coordinates,\nfield value after "
             "the output mapping), printed with `%%.9g`. `Testing/Python/test_shipped_models.py`"
             "\ncompares them with `inr eval` (|c - r| <= 1e-5 max(1, |r|)).\n"
             % ", ".join("%g" % t for t in REF_TIMES))
    R.append("## Suggested transfer function\n")
    R.append("Scalar range [0, 1]. Opacity 0 up to 0.2 (hides the faint wave, max 0.2), "
             "rising linearly to about 0.8 at 1.0;\nany sequential colour map (e.g. Viridis) "
             "over [0, 1]. To see the wave too, start the ramp at 0.05.\n")
    with open(os.path.join(out, "README.md"), "w") as f:
        f.write("\n".join(R))


if __name__ == "__main__":
    sys.exit(main())
