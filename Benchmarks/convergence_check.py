#!/usr/bin/env python3
"""Is "converged" honest? For each model: render a reference with many frames (another seed),
then render with `inr render --converge DB` and measure the PSNR of the converged image against
the reference over the pixels the volume covers (reference pixels that differ from the black
background), next to the renderer's own estimate. Prints a table and writes CSV.

    convergence_check.py --inr build/bin/inr --size 1024 --target 41 --reference-frames 1024 \
        --csv out.csv MODEL.inr [MODEL.inr ...]

Each model's suggested transfer function (MODEL.tf.json beside it) is used when present.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np


def read_pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"PF"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, 3)


def render(inr, model, out, size, extra):
    cmd = [inr, "render", model, "-o", out, "--size", f"{size}x{size}", "--quiet"] + extra
    tf = model[:-4] + ".tf.json"
    if os.path.exists(tf):
        cmd += ["--tf", tf]
    t = subprocess.run(cmd, capture_output=True, text=True)
    if t.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{t.stderr}")
    return t.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inr", required=True)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--target", type=float, default=41.0)
    ap.add_argument("--reference-frames", type=int, default=1024)
    ap.add_argument("--max-frames", type=int, default=1024)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--csv")
    ap.add_argument("models", nargs="+")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for model in a.models:
            name = os.path.basename(model)[:-4]
            ref, img, stats, refstats = (os.path.join(tmp, f"{name}_{k}")
                                         for k in ("ref.pfm", "img.pfm", "stats.json", "refstats.json"))
            common = ["--backend", a.backend]
            render(a.inr, model, ref, a.size,
                   common + ["--frames", str(a.reference_frames), "--seed", "977", "--stats-json", refstats])
            render(a.inr, model, img, a.size,
                   common + ["--frames", str(a.max_frames), "--converge", str(a.target), "--stats-json", stats])
            r, x = read_pfm(ref), read_pfm(img)
            covered = np.any(r > 0, axis=2)
            mse_volume = float(np.mean((x[covered] - r[covered]) ** 2)) if covered.any() else 0.0
            mse_all = float(np.mean((x - r) ** 2))
            psnr = lambda m: float("inf") if m == 0 else -10 * np.log10(m)
            conv = json.load(open(stats))["convergence"]
            # The reference is noisy too: its own estimated MSE adds to the measured one.
            ref_mse = 10 ** (-json.load(open(refstats))["convergence"]["estimate"] / 10)
            rows.append(dict(model=name, size=a.size, frames=conv["frames"], seconds=conv["seconds"],
                             estimated_db=conv["estimate"], measured_volume_db=psnr(mse_volume),
                             measured_image_db=psnr(mse_all), reference_estimated_db=psnr(ref_mse),
                             measured_volume_minus_reference_noise_db=psnr(max(mse_volume - ref_mse, 1e-30)),
                             covered_fraction=float(covered.mean()),
                             converged=conv["converged"]))
            row = rows[-1]
            print(f"{name:34s} {row['frames']:5d} frames {row['seconds']:8.3f} s  estimated {row['estimated_db']:6.2f} dB"
                  f"  measured over the volume {row['measured_volume_db']:6.2f} dB"
                  f" ({row['measured_volume_minus_reference_noise_db']:6.2f} without the reference's noise; whole image"
                  f" {row['measured_image_db']:6.2f} dB, volume covers {100 * row['covered_fraction']:.0f}%)",
                  flush=True)
    if a.csv:
        with open(a.csv, "w") as f:
            f.write(",".join(rows[0].keys()) + "\n")
            for row in rows:
                f.write(",".join(str(v) for v in row.values()) + "\n")


if __name__ == "__main__":
    main()
