#!/usr/bin/env python3
"""Is the convergence estimate honest? From query_reduction_benchmark's curves.csv and
summary.csv (one output folder): per model, configuration and frame count, the PSNR over the
volume's pixels measured against the reference, the same with the reference's own estimated error
taken off (an image with error e shows e + the reference's error against it), and the renderer's
estimate (what `inr render --converge` and the plugin stop on). Prints a table; --csv writes it.

    Benchmarks/estimate_honesty.py OUT_DIR [--frames 4,8,16,32,64,128] [--csv FILE]

Where the reference's error is within ~3 dB of the measured one, the correction is dominated by
the reference's own noise and is marked unreliable ("~")."""
import argparse
import csv
import math
import os
import sys


def corrected(measured, reference):
    """The error behind `measured` (dB, against a reference whose own error is `reference` dB)."""
    x = 10 ** (-measured / 10) - 10 ** (-reference / 10)
    return -10 * math.log10(x) if x > 0 else float("inf")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--frames", default="4,8,16,32,64,128")
    ap.add_argument("--csv")
    a = ap.parse_args()
    frames = {int(f) for f in a.frames.split(",")}
    try:
        summary = list(csv.DictReader(open(os.path.join(a.out_dir, "summary.csv"))))
        curves = csv.DictReader(open(os.path.join(a.out_dir, "curves.csv")))
    except OSError as e:
        sys.exit("estimate_honesty: %s (expected query_reduction_benchmark's --out folder)" % e)
    reference = {}
    for r in summary:
        if "reference_estimated_psnr_volume" not in r or not r["reference_estimated_psnr_volume"]:
            sys.exit("estimate_honesty: %s has no reference_estimated_psnr_volume column (an older benchmark)"
                     % os.path.join(a.out_dir, "summary.csv"))
        reference[r["model"]] = float(r["reference_estimated_psnr_volume"])
    rows = []
    for r in curves:
        if int(r["frame"]) not in frames or not r.get("estimated_psnr_volume") or not r["psnr_volume"]:
            continue
        ref = reference.get(r["model"])
        if ref is None:
            continue
        measured, estimate = float(r["psnr_volume"]), float(r["estimated_psnr_volume"])
        truth = corrected(measured, ref)
        rows.append([r["model"], r["config"], int(r["frame"]), measured, ref, truth, estimate, estimate - truth,
                     ref - measured < 3.0])
    print("%-32s %-30s %6s %9s %9s %9s %9s %7s" % ("model", "config", "frames", "measured", "ref.est", "corrected",
                                                   "estimate", "est-cor"))
    for m, c, f, meas, ref, truth, est, diff, shaky in rows:
        print("%-32s %-30s %6d %9.2f %9.2f %9.2f %9.2f %6.2f%s" % (m, c, f, meas, ref, truth, est, diff,
                                                                   " ~" if shaky else ""))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["model", "config", "frame", "psnr_volume", "reference_estimated", "corrected", "estimated",
                        "estimated_minus_corrected", "reference_dominates"])
            for row in rows:
                w.writerow(row[:3] + ["%.3f" % v for v in row[3:8]] + [int(row[8])])


if __name__ == "__main__":
    main()
