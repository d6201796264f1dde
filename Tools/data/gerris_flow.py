#!/usr/bin/env python3
"""3D incompressible flow past obstacles with the Gerris Flow Solver, resampled to a regular
grid: vorticity magnitude and the streamwise velocity component, many snapshots.

    /usr/bin/python3 Tools/data/gerris_flow.py CASE [--out .data] [--level 5]
                     [--t-start T0] [--t-end T1] [--dt 0.15] [--work DIR] [--keep]
    CASE: cylinder | sphere_plate

Needs Debian's ``gerris`` with ``libgfs-dev pkg-config`` (gerris3D compiles the solid and
initial-condition expressions at run time) and numpy. Run it in the background, nice'd; with
the defaults (30 snapshots each) a case needs ~5-8 min of CPU, 20-40 min on the shared
2-core development machine.

Set-up (Gerris units; U = 1 inflow, lengths in box units):

* domain: 3 unit boxes along x, x in [-0.5, 2.5], y, z in [-0.5, 0.5]; inflow U = 1 on the
  left (Dirichlet), outflow on the right, slip walls elsewhere (Gerris' default boundary).
* ``cylinder``: a finite circular cylinder, axis along z, radius 0.125 (D = 0.25), length
  0.6 (z in [-0.3, 0.3]), centred at (0, 0.02), impulsively started: the starting vortex
  loop (spanwise rollers joined by the tip vortices) forms, separates and is swept
  downstream. Re = U D / nu = 250. Snapshots t = 0.15 ... 4.5. (At this resolution the wake
  of this short cylinder becomes steady after t ~ 5, hence the start-up window.)
* ``sphere_plate``: a sphere (radius 0.14 at (0, 0.16, 0.1)) beside a thin flat plate normal
  to the flow (0.05 x 0.28 x 0.44 at (0.05, -0.17, -0.06)); their wakes interact and the
  plate sheds vortices continuously. Re(sphere) = 280. Snapshots t = 3.5 ... 7.85.
* viscosity nu = 0.001; initial U = 1 plus a small non-divergence-free V perturbation (the
  projection removes its divergent part) so that shedding starts early.
* mesh: adaptive octree, uniform ``--level - 1`` everywhere, ``--level`` (default 5, i.e.
  32 cells per unit) on the obstacles and wherever the vorticity criterion asks.

Snapshots (``OutputSimulation``) from ``--t-start`` to ``--t-end`` every ``--dt`` are sampled
with ``gfs2oogl3D -p`` (Gerris' own interpolation) at the centres of a regular grid of
2^level cells per unit (96 x 32 x 32 at level 5). Samples inside the obstacles are set to 0
(velocity of the wall). The vorticity is computed on that grid by second-order central
differences (numpy.gradient). Writes, in ``--out``:

    gerris_CASE_vorticity.npy/.json   |curl u|, 1/time units
    gerris_CASE_u.npy/.json           streamwise velocity u_x, units of the inflow velocity

as float16 [T, Z, Y, X] with the sidecar of dataset_io.py (cell-centred, bounds = the domain).
"""

import argparse
import glob
import math
import os
import shutil
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import dataset_io  # noqa: E402

BOUNDS = [-0.5, 2.5, -0.5, 0.5, -0.5, 0.5]
NU = 0.001


# ------------------------------------------------------------------ obstacles
# Each obstacle is an implicit function f (C expression for Gerris, numpy for masking) that is
# positive in the fluid and negative in the solid (Gerris' convention for Solid).
def _cyl(cx, cy, r, zh):
    c = ("fmax(sqrt((x-(%r))*(x-(%r)) + (y-(%r))*(y-(%r))) - %r, fabs(z) - %r)"
         % (cx, cx, cy, cy, r, zh))

    def f(x, y, z):
        return np.maximum(np.sqrt((x - cx) ** 2 + (y - cy) ** 2) - r, np.abs(z) - zh)
    return c, f


def _sphere(cx, cy, cz, r):
    c = ("sqrt((x-(%r))*(x-(%r)) + (y-(%r))*(y-(%r)) + (z-(%r))*(z-(%r))) - %r"
         % (cx, cx, cy, cy, cz, cz, r))

    def f(x, y, z):
        return np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) - r
    return c, f


def _box(cx, cy, cz, hx, hy, hz):
    c = ("fmax(fmax(fabs(x-(%r)) - %r, fabs(y-(%r)) - %r), fabs(z-(%r)) - %r)"
         % (cx, hx, cy, hy, cz, hz))

    def f(x, y, z):
        return np.maximum(np.maximum(np.abs(x - cx) - hx, np.abs(y - cy) - hy),
                          np.abs(z - cz) - hz)
    return c, f


def _union(*parts):
    c = parts[0][0]
    for p in parts[1:]:
        c = "fmin(%s, %s)" % (c, p[0])

    def f(x, y, z):
        v = parts[0][1](x, y, z)
        for p in parts[1:]:
            v = np.minimum(v, p[1](x, y, z))
        return v
    return c, f


CASES = {
    "cylinder": dict(
        solid=lambda: _cyl(0.0, 0.02, 0.125, 0.3),
        description="finite circular cylinder (D = 0.25, length 0.6, axis z) in an "
                    "impulsively started uniform stream, Re = 250",
        length=0.25, t_start=0.15, t_end=4.5),
    "sphere_plate": dict(
        solid=lambda: _union(_sphere(0.0, 0.16, 0.1, 0.14),
                             _box(0.05, -0.17, -0.06, 0.025, 0.14, 0.22)),
        description="sphere (D = 0.28) beside a flat plate (0.05 x 0.28 x 0.44) normal to a "
                    "uniform stream, Re(sphere) = 280",
        length=0.28, t_start=3.5, t_end=7.85),
}


def gfs_text(case, level, t_end, t_start, dt):
    solid, _ = CASES[case]["solid"]()
    return """# Generated by Tools/data/gerris_flow.py (case %(case)s)
3 2 GfsSimulation GfsBox GfsGEdge {} {
  Time { end = %(t_end)r }
  Refine %(base)d
  Solid ({ return %(solid)s; })
  RefineSolid %(level)d
  Init {} {
    U = 1
    V = 0.1*exp(-((x-0.6)*(x-0.6) + y*y)/0.02)*sin(3.14159265*z)
  }
  AdaptVorticity { istep = 1 } { maxlevel = %(level)d minlevel = %(base)d cmax = 0.01 }
  SourceViscosity %(nu)r
  OutputTime { istep = 20 } stderr
  OutputSimulation { start = %(t_start)r step = %(dt)r } snap-%%g.gfs
}
GfsBox { left = Boundary { BcDirichlet U 1 } }
GfsBox {}
GfsBox { right = BoundaryOutflow }
1 2 right
2 3 right
""" % dict(case=case, t_end=float(t_end), base=level - 1, level=level, solid=solid,
           nu=NU, t_start=float(t_start), dt=float(dt))


def grid(level):
    n = 2 ** level
    res = [3 * n, n, n]
    axes = [dataset_io.cell_centres(BOUNDS[2 * a], BOUNDS[2 * a + 1], res[a]) for a in range(3)]
    Z, Y, X = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return res, X, Y, Z


def sample(snap, ptsfile, X, Y, Z, h):
    """Run gfs2oogl3D -p on one snapshot; returns {column name: array shaped like X}.

    gfs2oogl3D prints one line per location it finds in the fluid ('X Y Z P Pmac U V W ...',
    columns named in a '#' header) and skips locations inside the solid, so lines are put back
    on the grid by their coordinates; skipped locations stay NaN."""
    with open(snap, "rb") as fin:
        r = subprocess.run(["gfs2oogl3D", "-p", ptsfile], stdin=fin, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, check=True)
    lines = r.stdout.decode().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    if not head:
        raise SystemExit("%s: gfs2oogl3D printed no column header" % snap)
    cols = [c.split(":", 1)[1] for c in head[0][1:].split()]
    vals = np.loadtxt([ln for ln in lines if ln and not ln.startswith("#")], ndmin=2)
    idx = [np.rint((vals[:, a] - BOUNDS[2 * a]) / h - 0.5).astype(int) for a in range(3)]
    shape = X.shape
    for a, n in enumerate((shape[2], shape[1], shape[0])):
        if idx[a].min() < 0 or idx[a].max() >= n:
            raise SystemExit("%s: sample coordinates outside the grid" % snap)
    off = np.abs(vals[:, 0] - X[idx[2], idx[1], idx[0]]).max()
    if off > 1e-4:
        raise SystemExit("%s: sample coordinates do not match the grid (%g)" % (snap, off))
    out = {}
    for c in cols[3:]:
        g = np.full(shape, np.nan)
        g[idx[2], idx[1], idx[0]] = vals[:, cols.index(c)]
        out[c] = g
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", choices=sorted(CASES))
    ap.add_argument("--out", default=os.path.join(REPO, ".data"))
    ap.add_argument("--work", help="work directory [OUT/work/gerris_CASE]")
    ap.add_argument("--level", type=int, default=5)
    ap.add_argument("--t-start", type=float, default=None,
                    help="first snapshot [cylinder 0.15, sphere_plate 3.5]")
    ap.add_argument("--t-end", type=float, default=None,
                    help="end of the run = last snapshot [cylinder 4.5, sphere_plate 7.85]")
    ap.add_argument("--dt", type=float, default=0.15)
    ap.add_argument("--keep", action="store_true", help="keep the Gerris snapshots")
    ap.add_argument("--sample-only", action="store_true",
                    help="do not run Gerris, only resample existing snapshots in --work")
    a = ap.parse_args(argv)
    if a.t_start is None:
        a.t_start = CASES[a.case]["t_start"]
    if a.t_end is None:
        a.t_end = CASES[a.case]["t_end"]
    for tool in ("gerris3D", "gfs2oogl3D"):
        if shutil.which(tool) is None:
            raise SystemExit("%s not found: apt-get install gerris libgfs-dev pkg-config" % tool)
    work = a.work or os.path.join(a.out, "work", "gerris_" + a.case)
    os.makedirs(work, exist_ok=True)
    t0 = time.time()
    if not a.sample_only:
        for old in glob.glob(os.path.join(work, "snap-*.gfs")):
            os.remove(old)
        with open(os.path.join(work, "sim.gfs"), "w") as f:
            f.write(gfs_text(a.case, a.level, a.t_end, a.t_start, a.dt))
        print("running gerris3D in %s (log: gerris.log)" % work, flush=True)
        with open(os.path.join(work, "gerris.log"), "w") as log:
            subprocess.run(["gerris3D", "sim.gfs"], cwd=work, stdout=log,
                           stderr=subprocess.STDOUT, check=True)
        print("gerris3D done in %.0f s" % (time.time() - t0), flush=True)
    snaps = sorted(glob.glob(os.path.join(work, "snap-*.gfs")),
                   key=lambda p: float(os.path.basename(p)[5:-4]))
    times = [float(os.path.basename(p)[5:-4]) for p in snaps]
    if len(snaps) < 2:
        raise SystemExit("no snapshots in %s" % work)
    res, X, Y, Z = grid(a.level)
    ptsfile = os.path.join(work, "points.txt")
    np.savetxt(ptsfile, np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1), fmt="%.7g")
    _, fsolid = CASES[a.case]["solid"]()
    solid = fsolid(X, Y, Z) < 0.0
    h = (BOUNDS[1] - BOUNDS[0]) / res[0]
    T = len(snaps)
    vort = np.zeros((T,) + X.shape, dtype=np.float32)
    ux = np.zeros((T,) + X.shape, dtype=np.float32)
    for k, snap in enumerate(snaps):
        f = sample(snap, ptsfile, X, Y, Z, h)
        U, V, W = f["U"], f["V"], f["W"]
        for F in (U, V, W):
            F[solid | ~np.isfinite(F)] = 0.0
        # arrays are [z, y, x]: gradient axes 0 = z, 1 = y, 2 = x
        dU = np.gradient(U, h)
        dV = np.gradient(V, h)
        dW = np.gradient(W, h)
        wx = dW[1] - dV[0]
        wy = dU[0] - dW[2]
        wz = dV[2] - dU[1]
        vort[k] = np.sqrt(wx * wx + wy * wy + wz * wz)
        ux[k] = U
        print("  t=%6.2f  |w| max %.2f mean %.3f  u in [%.2f, %.2f]"
              % (times[k], vort[k].max(), vort[k].mean(), U.min(), U.max()), flush=True)
    common = {
        "length_units": "Gerris box units (domain 3 x 1 x 1)",
        "time_units": "Gerris time units (inflow speed 1)",
        "bounds": BOUNDS, "centering": "cell", "times": times,
        "source": "Gerris Flow Solver (Debian gerris) simulation: %s; adaptive octree level "
                  "%d, nu = %g; resampled with gfs2oogl3D -p"
                  % (CASES[a.case]["description"], a.level, NU),
        "licence": "simulation output generated by this project (ours); Gerris is GPL-2+ "
                   "software, its outputs are not covered by its licence",
        "generator": "Tools/data/gerris_flow.py " + " ".join(argv if argv is not None
                                                              else sys.argv[1:]),
        "solid_mask": "samples inside the obstacle are 0",
    }
    dataset_io.save(a.out, "gerris_%s_vorticity" % a.case, vort.astype(np.float16),
                    dict(common, quantity="vorticity magnitude |curl u|",
                         units="1 / Gerris time unit"))
    dataset_io.save(a.out, "gerris_%s_u" % a.case, ux.astype(np.float16),
                    dict(common, quantity="streamwise velocity u_x", units="inflow velocity"))
    if not a.keep:
        for s in snaps:
            os.remove(s)
    print("done: %d snapshots on %s in %.0f s" % (T, "x".join(map(str, res)), time.time() - t0))


if __name__ == "__main__":
    main()
