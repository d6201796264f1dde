#!/usr/bin/env python3
# Compares two PFM images bit for bit: max |difference|, differing pixels, PSNR (peak 1).
#   compare_pfm.py A.pfm B.pfm LABEL
import sys, numpy as np
def pfm(p):
    with open(p,'rb') as f:
        assert f.readline().strip() in (b'PF', b'Pf')
        w,h = map(int, f.readline().split()); s = float(f.readline())
        a = np.fromfile(f, dtype='<f4' if s < 0 else '>f4')
    return a.reshape(h, w, -1)
a, b = pfm(sys.argv[1]), pfm(sys.argv[2])
d = np.abs(a.astype(np.float64) - b)
mse = float((d**2).mean())
psnr = float('inf') if mse == 0 else 10*np.log10(1.0/mse)
print(f"{sys.argv[3]}: {a.shape[1]}x{a.shape[0]} max|diff| {d.max():.3g}, differing pixels {int((d.max(axis=2)>0).sum())}, PSNR {psnr:.2f} dB, bit-identical {bool((a==b).all())}")
