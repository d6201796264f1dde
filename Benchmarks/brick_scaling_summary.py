#!/usr/bin/env python3
"""Table of the scaling suite (Benchmarks/bench.sh scaling): per image size and model, the single-GPU run against each split
(pixels, samples, bricks) on N GPUs.

  brick_scaling_summary.py OUT [OUT...] MODEL.inr... [--csv FILE] [--plot FILE] [--target DB]

Each OUT is one image size's output folder of the scaling suite (OUT/SIZE). Columns:
  ms/frame     median frame time of one GPU (the slowest part's)
  ms/picture   time per frame of the whole picture: a pixel or brick split's parts render one
               picture frame together, N sample shares N of them at once (ms/frame / N)
  frames       frames of the whole picture until the estimate reaches TARGET (40 dB): for sample
               shares N times the frames each share took
  t->40 s      render time (frame times summed) until the estimated PSNR over the volume's pixels
               first reaches TARGET: the single run's own estimate; for pixel or brick parts the
               slowest part's own; for sample shares the estimate of their mean, from each share's
               own (independent errors: the mean's MSE is the sum of the shares' MSEs over N^2),
               at the first local frame all shares reach together, timed by the slowest share
  speed-up     t->40 of one GPU / t->40 of N; efficiency = speed-up / N
  queries/GPU  each part's share of all the parts' queries (primary + shadow), and the largest
               deviation from 1/N
  vs 1 GPU     PSNR of the composite against the 1-GPU image over the volume's pixels
               (composite_bricks.py); for sample shares at equal frames
Writes FILE (default OUT/brick_scaling.csv for a single OUT) and, with matplotlib, the plot.
"""
import argparse
import csv
import glob
import json
import math
import os
import re
import statistics


def load(path):
    with open(path) as f:
        return json.load(f)


def frame_ms(frames):
    return [f["ms"]["total"] for f in frames]


def estimates(frames):
    return [f.get("estimated_psnr_db") if f.get("estimated_psnr_db") is not None else -math.inf for f in frames]


def time_to(frames, target):
    """(seconds, frames) until a run's own estimate first reaches target; nan when it never does."""
    t = 0.0
    for k, (ms, db) in enumerate(zip(frame_ms(frames), estimates(frames))):
        t += ms
        if db >= target:
            return t / 1000.0, k + 1
    return math.nan, math.nan


def sample_shares_time_to(parts, target):
    """(seconds, picture frames) until the estimate of the sample shares' mean first reaches
    target: at local frame f every share holds f + 1 frames (equal weights), the mean's MSE is
    sum(MSE_r) / N^2, and the time is the slowest share's."""
    n = len(parts)
    elapsed = [0.0] * n
    for f in range(min(len(p) for p in parts)):
        mse = 0.0
        for r, p in enumerate(parts):
            elapsed[r] += p[f]["ms"]["total"]
            db = estimates([p[f]])[0]
            mse += math.inf if db == -math.inf else 10.0 ** (-db / 10.0) / n ** 2
        if mse == 0.0 or -10.0 * math.log10(mse) >= target:
            return max(elapsed) / 1000.0, n * (f + 1)
    return math.nan, math.nan


def composite_psnr(path):
    try:
        m = re.search(r"PSNR ([0-9.]+|inf) dB", open(path).read())
        return float(m.group(1)) if m else math.nan
    except OSError:
        return math.nan


def queries(frames):
    return sum(f["queries"] + f["shadow_queries"] for f in frames)


def rows_of(out, models, target):
    rows = []
    for model in models:
        name = os.path.basename(model)[:-4]
        whole_path = os.path.join(out, f"{name}.whole.stats.json")
        if not os.path.exists(whole_path):
            continue
        whole = load(whole_path)
        size = f"{whole['width']}x{whole['height']}"
        t1, f1 = time_to(whole["frames"], target)
        ms1 = statistics.median(frame_ms(whole["frames"]))
        rows.append({"size": size, "model": name, "split": "-", "gpus": 1, "ms_per_frame": ms1, "ms_per_picture": ms1,
                     "frames_to_target": f1, "t_target_s": t1, "speedup": 1.0, "efficiency": 1.0,
                     "query_shares": "1.000", "query_share_max_deviation_pct": 0.0, "psnr_vs_1gpu_db": math.nan,
                     "frames_rendered": len(whole["frames"])})
        tags = {}
        for path in glob.glob(os.path.join(out, f"{name}.*.b*.stats.json")):
            m = re.fullmatch(re.escape(name) + r"\.(pixels|samples|bricks)(\d+)\.b(\d+)\.stats\.json",
                             os.path.basename(path))
            if m:
                tags.setdefault((m.group(1), int(m.group(2))), {})[int(m.group(3))] = path
        for (split, n), paths in sorted(tags.items()):
            if sorted(paths) != list(range(n)):
                print(f"{name} {split}{n}: parts {sorted(paths)} of {n} (a part failed?); skipped")
                continue
            parts = [load(paths[i])["frames"] for i in range(n)]
            ms = max(statistics.median(frame_ms(p)) for p in parts)
            if split == "samples":
                tn, fn = sample_shares_time_to(parts, target)
                per_picture = ms / n
            else:
                per_part = [time_to(p, target) for p in parts]
                tn = max(t for t, _ in per_part)
                fn = max(f for _, f in per_part)
                per_picture = ms
            q = [queries(p) for p in parts]
            shares = [v / sum(q) if sum(q) else math.nan for v in q]
            speedup = t1 / tn if tn == tn and tn > 0 else math.nan
            rows.append({"size": size, "model": name, "split": split, "gpus": n, "ms_per_frame": ms,
                         "ms_per_picture": per_picture, "frames_to_target": fn, "t_target_s": tn,
                         "speedup": speedup, "efficiency": speedup / n,
                         "query_shares": " ".join(f"{s:.3f}" for s in shares),
                         "query_share_max_deviation_pct": 100.0 * max(abs(s * n - 1.0) for s in shares),
                         "psnr_vs_1gpu_db": composite_psnr(os.path.join(out, f"{name}.{split}{n}.composite.txt")),
                         "frames_rendered": sum(len(p) for p in parts)})
    return rows


def plot(rows, path, target):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not available: no plot ({path})")
        return
    sizes = sorted({r["size"] for r in rows}, key=lambda s: int(s.split("x")[0]))
    fig, axes = plt.subplots(1, len(sizes), figsize=(6 * len(sizes), 4.5), squeeze=False)
    for ax, size in zip(axes[0], sizes):
        here = [r for r in rows if r["size"] == size]
        top = max(r["gpus"] for r in here)
        ax.plot([1, top], [1, top], color="0.7", lw=1, label="ideal")
        ax.plot([2, 4], [1.8, 3.2], "k*", ms=9, label="targets (2048²)")
        for k, model in enumerate(sorted({r["model"] for r in here})):
            for split, style in (("pixels", "--"), ("samples", "-"), ("bricks", ":")):
                pts = sorted([(1, 1.0)] + [(r["gpus"], r["speedup"]) for r in here
                                           if r["model"] == model and r["split"] == split])
                if len(pts) > 1:
                    ax.plot(*zip(*pts), style, marker="o", color=f"C{k}", label=f"{model} ({split})")
        ax.set_title(f"time to {target:g} dB, {size}")
        ax.set_xlabel("GPUs")
        ax.set_ylabel("speed-up over one GPU")
        ax.set_xticks(sorted({r["gpus"] for r in here}))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("paths", nargs="+", help="output folders, then MODEL.inr files")
    ap.add_argument("--csv")
    ap.add_argument("--plot")
    ap.add_argument("--target", type=float, default=40.0)
    a = ap.parse_args()
    outs = [p for p in a.paths if not p.endswith(".inr")]
    models = [p for p in a.paths if p.endswith(".inr")]
    rows = [r for out in outs for r in rows_of(out, models, a.target)]
    t = f"t->{a.target:g} s"
    print(f"{'size':>9} {'model':<30} {'split':>7} {'GPUs':>4} {'ms/frame':>8} {'ms/picture':>10} {'frames':>6} "
          f"{t:>8} {'speed-up':>8} {'effic.':>6} {'queries/GPU (max dev.)':>32} {'vs 1 GPU':>9}")
    for r in rows:
        qs = f"{r['query_shares']} ({r['query_share_max_deviation_pct']:.1f}%)" if r["gpus"] > 1 else ""
        vs = f"{r['psnr_vs_1gpu_db']:.2f}" if r["gpus"] > 1 else ""
        print(f"{r['size']:>9} {r['model']:<30} {r['split']:>7} {r['gpus']:>4} {r['ms_per_frame']:>8.2f} "
              f"{r['ms_per_picture']:>10.2f} {r['frames_to_target']:>6} {r['t_target_s']:>8.3f} {r['speedup']:>8.2f} "
              f"{r['efficiency']:>6.2f} {qs:>32} {vs:>9}")
    csv_path = a.csv or (os.path.join(outs[0], "brick_scaling.csv") if len(outs) == 1 else None)
    if rows and csv_path:
        with open(csv_path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
        print(f"csv: {csv_path}")
    if rows and a.plot:
        plot(rows, a.plot, a.target)


if __name__ == "__main__":
    main()
