#!/usr/bin/env python3
"""Plots gpu_render_benchmark's CSV: frames/s per model (with and without shadows), the 4b
ratio against the evaluator bound, the 4c speed-ups over the baselines.
usage: plot_render_benchmark.py render.csv OUT_PREFIX   (writes OUT_PREFIX.png)"""
import csv
import sys


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    rows = list(csv.DictReader(open(sys.argv[1])))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not available: no plot")
        return 0
    b = [r for r in rows if r["group"] == "4b"]
    c = [r for r in rows if r["group"] == "4c"]
    models = list(dict.fromkeys(r["model"] for r in b))
    fig, ax = plt.subplots(1, 3, figsize=(16, 5))
    x = range(len(models))
    for k, (variant, off) in enumerate((("wavefront", -0.2), ("wavefront+shadows", 0.2))):
        fps = [next((float(r["fps"]) for r in b if r["model"] == m and r["variant"] == variant), 0) for m in models]
        ax[0].bar([i + off for i in x], fps, 0.4, label=variant)
        ratio = [next((float(r["ratio"]) for r in b if r["model"] == m and r["variant"] == variant), 0) for m in models]
        ax[1].bar([i + off for i in x], ratio, 0.4, label=variant)
    ax[0].set_title("frames/s (4b)")
    ax[1].axhline(1.5, color="k", ls="--", lw=1)
    ax[1].set_title("frame time / (queries / evaluator throughput)")
    variants = list(dict.fromkeys(r["variant"] for r in c))
    for k, v in enumerate(variants):
        sp = [next((float(r["ratio"]) for r in c if r["model"] == m and r["variant"] == v), 0) for m in models]
        w = 0.8 / max(1, len(variants))
        ax[2].bar([i - 0.4 + w * (k + 0.5) for i in x], sp, w, label=v)
    ax[2].set_yscale("log")
    ax[2].axhline(100, color="k", ls="--", lw=1)
    ax[2].axhline(150, color="gray", ls=":", lw=1)
    ax[2].set_title("speed-up of the wavefront pipeline (4c)")
    for a in ax:
        a.set_xticks(list(x))
        a.set_xticklabels(models, rotation=30, ha="right", fontsize=7)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(sys.argv[2] + ".png", dpi=120)
    print("wrote", sys.argv[2] + ".png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
