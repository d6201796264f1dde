#!/usr/bin/env python3
"""Dynamic-CT-style time series from a real MR head volume: smooth elastic compression and
torsion with exact mass conservation.

    /usr/bin/python3 Tools/data/make_mri_deform.py [--out .data] [--frames 30]
                     [--res 64 64 44] [--dtype float16]

Source: ``Testing/Data/real/sources/HeadMRVolume.{mhd,raw}`` -- a real MR scan of a head,
48 x 62 x 42 voxels of 4 mm, unsigned 8 bit, from the VTK test data (VTKData, BSD licence,
``Testing/Data/real/sources/VTKData-Copyright.txt``; obtained via the pyvista/vtk-data
repository, see Docs/DATA.md). Axial slices: x = left-right, y = anterior-posterior,
z = inferior-superior.

The motion mimics an in-situ dynamic CT experiment (a specimen squeezed and twisted in a load
frame). The forward map of a material point X (relative to the vertical axis through the
volume centre, z measured from the fixed base z0, zeta = (Z - z0) / H in [0, 1]) is

    z - z0 = lambda(t) * (Z - z0)                 axial compression, lambda = 1 - eps s(t)
    x_lat  = R(alpha) * mu(zeta, t) * X_lat       lateral bulge mu = 1 + nu eps s(t) b(zeta)
                                                   and torsion alpha = alpha_max r(t) zeta

with s(t) = sin^2(pi t / t_end) (load and unload), r(t) = smoothstep(t / t_end) (twist
accumulates), b(zeta) = 0.5 + 2 zeta (1 - zeta) (largest bulge at mid height), Poisson-like
ratio nu. It is invertible in closed form (zeta depends on z only). The field is a density
advected by the motion, so mass is conserved exactly:

    rho(x, t) = rho_0(X(x, t)) * det(dX/dx) = rho_0(X) / (lambda * mu^2)

(the Jacobian is block-triangular; rotation has unit determinant). rho_0 is the MR intensity
scaled to [0, 1], trilinearly interpolated (zero outside the scan). The script prints the total
mass of every frame relative to frame 0 (it stays 1 up to discretisation).

Writes ``mri_head_deform.npy`` [T, Z, Y, X] and ``mri_head_deform.json`` (dataset_io.py).
Needs numpy and scipy (python3-scipy).
"""

import argparse
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import dataset_io  # noqa: E402

SRC = os.path.join(REPO, "Testing", "Data", "real", "sources")


def read_mhd(path):
    hdr = {}
    with open(path) as f:
        for line in f:
            if "=" in line:
                k, v = line.split("=", 1)
                hdr[k.strip()] = v.strip()
    dims = [int(v) for v in hdr["DimSize"].split()]
    spacing = [float(v) for v in hdr["ElementSpacing"].split()]
    if hdr.get("ElementType") != "MET_UCHAR":
        raise SystemExit("%s: expected MET_UCHAR" % path)
    raw = os.path.join(os.path.dirname(path), hdr["ElementDataFile"])
    vol = np.fromfile(raw, dtype=np.uint8)
    if vol.size != dims[0] * dims[1] * dims[2]:
        raise SystemExit("%s: %d bytes, expected %d" % (raw, vol.size, np.prod(dims)))
    return vol.reshape(dims[2], dims[1], dims[0]), spacing  # [Z, Y, X]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(REPO, ".data"))
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--t-end", type=float, default=2.9, help="time of the last frame [2.9 s]")
    ap.add_argument("--res", type=int, nargs=3, default=[64, 64, 44], metavar=("X", "Y", "Z"))
    ap.add_argument("--eps", type=float, default=0.25, help="peak axial compression [0.25]")
    ap.add_argument("--nu", type=float, default=0.3, help="lateral bulge ratio [0.3]")
    ap.add_argument("--twist", type=float, default=30.0, help="top twist, degrees [30]")
    ap.add_argument("--dtype", default="float16", choices=("float16", "float32"))
    a = ap.parse_args(argv)
    from scipy.ndimage import map_coordinates

    t0 = time.time()
    vol, sp = read_mhd(os.path.join(SRC, "HeadMRVolume.mhd"))
    rho0 = vol.astype(np.float64) / 255.0
    nz, ny, nx = vol.shape
    # Voxel (i, j, k) sits at (i, j, k) * spacing (MetaImage, no Offset given).
    ext = [(n - 1) * s for n, s in zip((nx, ny, nz), sp)]
    cx, cy, cz = ext[0] / 2.0, ext[1] / 2.0, ext[2] / 2.0
    z0 = -0.5 * sp[2]                  # fixed base: the lower face of the first slice
    H = ext[2] + sp[2]                 # specimen height
    h = 4.0                            # output spacing (mm), the scan's
    RX, RY, RZ = a.res
    bounds = [cx - RX * h / 2, cx + RX * h / 2, cy - RY * h / 2, cy + RY * h / 2,
              cz - RZ * h / 2, cz + RZ * h / 2]
    xs = dataset_io.cell_centres(bounds[0], bounds[1], RX)
    ys = dataset_io.cell_centres(bounds[2], bounds[3], RY)
    zs = dataset_io.cell_centres(bounds[4], bounds[5], RZ)
    Z, Y, X = np.meshgrid(zs, ys, xs, indexing="ij")
    times = [round(a.t_end * k / (a.frames - 1), 9) for k in range(a.frames)]
    out = np.zeros((a.frames, RZ, RY, RX), dtype=np.float32)
    mass0 = None
    cell = h ** 3
    src_mass = rho0.sum() * sp[0] * sp[1] * sp[2]
    for k, t in enumerate(times):
        u = t / a.t_end
        s = math.sin(math.pi * u) ** 2
        r = u * u * (3.0 - 2.0 * u)
        lam = 1.0 - a.eps * s
        Zr = z0 + (Z - z0) / lam
        zeta = np.clip((Zr - z0) / H, 0.0, 1.0)
        mu = 1.0 + a.nu * a.eps * s * (0.5 + 2.0 * zeta * (1.0 - zeta))
        alpha = math.radians(a.twist) * r * zeta
        ca, sa = np.cos(alpha), np.sin(alpha)
        dx, dy = X - cx, Y - cy
        Xr = cx + (ca * dx + sa * dy) / mu     # R(-alpha) x_lat / mu
        Yr = cy + (-sa * dx + ca * dy) / mu
        coords = np.stack([Zr / sp[2], Yr / sp[1], Xr / sp[0]])
        rho = map_coordinates(rho0, coords, order=1, mode="constant", cval=0.0)
        rho = rho / (lam * mu * mu)
        out[k] = rho
        mass = rho.sum() * cell
        if mass0 is None:
            mass0 = mass
        print("frame %2d t=%.3f  compression %.3f  twist %5.1f deg  mass/mass0 %.4f  max %.3f"
              % (k, t, 1 - lam, math.degrees(math.radians(a.twist) * r), mass / mass0,
                 rho.max()), flush=True)
    meta = {
        "quantity": "density (MR intensity as a mass density, advected by an elastic "
                    "compression + torsion, mass conserving)",
        "units": "normalised (source MR intensity / 255)",
        "length_units": "mm", "time_units": "s (nominal)",
        "bounds": bounds, "centering": "cell", "times": times,
        "source": "VTKData HeadMRVolume (real MR head scan, 48x62x42 x 4 mm, uint8), via "
                  "pyvista/vtk-data Data/HeadMRVolume.{mhd,raw}; committed as "
                  "Testing/Data/real/sources/HeadMRVolume.*",
        "licence": "source: VTK data licence (BSD-3-Clause style, "
                   "Testing/Data/real/sources/VTKData-Copyright.txt); derived data: ours",
        "generator": "Tools/data/make_mri_deform.py " + " ".join(argv if argv is not None
                                                                 else sys.argv[1:]),
        "parameters": {"eps": a.eps, "nu": a.nu, "twist_deg": a.twist, "t_end": a.t_end,
                       "frames": a.frames, "spacing_mm": h,
                       "source_mass_over_frame0_mass": float(src_mass / mass0)},
    }
    p = dataset_io.save(a.out, "mri_head_deform", out.astype(a.dtype), meta)
    print("wrote %s (%.1f MB) in %.0f s" % (p, os.path.getsize(p) / 1e6, time.time() - t0))


if __name__ == "__main__":
    main()
