#!/usr/bin/env python3
"""Table of run_brick_scaling.sh: per model, the single-GPU run against N bricks on N GPUs —
frame time (median ms per frame; for bricks the slowest brick's, as the composite waits for it),
render time to an estimated 40 dB (sum of frame times until the estimate first reaches 40; for
bricks the slowest brick's), frames, queries per brick and the composite's PSNR against the
single-GPU image. Writes OUT/brick_scaling.csv.
  brick_scaling_summary.py OUT MODEL.inr...
"""
import csv
import json
import os
import re
import statistics
import sys


def frames_of(path):
    with open(path) as f:
        j = json.load(f)
    return j["frames"]


def time_to(frames, target):
    t = 0.0
    for f in frames:
        t += f["ms"]["total"]
        if (f.get("estimated_psnr_db") or 0.0) >= target:
            return t / 1000.0
    return float("nan")


def main():
    out, models = sys.argv[1], sys.argv[2:]
    rows = []
    print(f"{'model':<30} {'GPUs':>4} {'ms/frame':>9} {'frames':>7} {'t->40 s':>8} {'speed-up':>8} "
          f"{'queries/brick (share)':>32} {'PSNR vs 1 GPU':>13}")
    for model in models:
        name = os.path.basename(model)[:-4]
        whole = frames_of(os.path.join(out, f"{name}.whole.stats.json"))
        bricks = []
        i = 0
        while os.path.exists(os.path.join(out, f"{name}.b{i}.stats.json")):
            bricks.append(frames_of(os.path.join(out, f"{name}.b{i}.stats.json")))
            i += 1
        if not bricks:
            continue
        ms1 = statistics.median(f["ms"]["total"] for f in whole)
        t1 = time_to(whole, 40.0)
        msn = max(statistics.median(f["ms"]["total"] for f in b) for b in bricks)
        tn = max(time_to(b, 40.0) for b in bricks)
        q = [sum(f["queries"] + f["shadow_queries"] for f in b) / len(b) for b in bricks]
        share = " ".join(f"{v / sum(q):.2f}" for v in q)
        psnr = float("nan")
        try:
            m = re.search(r"PSNR ([0-9.]+) dB", open(os.path.join(out, f"{name}.composite.txt")).read())
            psnr = float(m.group(1)) if m else psnr
        except OSError:
            pass
        print(f"{name:<30} {1:>4} {ms1:>9.2f} {len(whole):>7} {t1:>8.3f} {'':>8} {'':>32} {'':>13}")
        qs = "/".join(f"{v / 1e6:.2f}M" for v in q) + f" ({share})"
        print(f"{name:<30} {len(bricks):>4} {msn:>9.2f} {max(len(b) for b in bricks):>7} {tn:>8.3f} "
              f"{t1 / tn if tn == tn and tn > 0 else float('nan'):>8.2f} {qs:>32} {psnr:>13.2f}")
        rows.append({"model": name, "gpus": len(bricks), "ms_per_frame_1": ms1, "ms_per_frame_n": msn,
                     "frames_1": len(whole), "frames_n": max(len(b) for b in bricks), "t40_1_s": t1,
                     "t40_n_s": tn, "queries_per_brick": " ".join(f"{v:.0f}" for v in q),
                     "psnr_composite_vs_1_db": psnr})
    if rows:
        with open(os.path.join(out, "brick_scaling.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
