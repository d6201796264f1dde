#!/usr/bin/env python3
"""Joins the GPU evaluator CSV and the PyTorch baseline CSV (same models, same batch) into one
table of throughputs and ratios, written as CSV and, when matplotlib is present, a PNG bar chart.

usage: compare_evaluators.py OURS.csv TORCH.csv OUT_PREFIX
"""
import csv
import sys


def main():
    ours_csv, torch_csv, prefix = sys.argv[1:4]
    ours = {}
    for r in csv.DictReader(open(ours_csv)):
        ours.setdefault(r["model"], {})[r["path"]] = float(r["median_qps"])
    torch_rows = {}
    for r in csv.DictReader(open(torch_csv)):
        torch_rows.setdefault(r["model"], {})[r["path"]] = float(r["median_qps"])
    rows = []
    print("%-28s %12s %12s %12s %10s" % ("model", "fused Gq/s", "generic", "torch fp16", "fused/torch"))
    for model, paths in ours.items():
        t = torch_rows.get(model, {}).get("torch-fp16-eager")
        f = paths.get("fused-fp16")
        g = paths.get("generic-fp32")
        ratio = f / t if (f and t) else float("nan")
        rows.append((model, f or 0, g or 0, t or 0, ratio))
        print("%-28s %12.4f %12.4f %12.4f %10.2f" % (model, (f or 0) / 1e9, (g or 0) / 1e9, (t or 0) / 1e9, ratio))
    with open(prefix + ".csv", "w") as out:
        out.write("model,fused_qps,generic_qps,torch_fp16_qps,fused_over_torch\n")
        for r in rows:
            out.write("%s,%.6g,%.6g,%.6g,%.4f\n" % r)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(9, 4))
        xs = range(len(rows))
        w = 0.27
        ax.bar([x - w for x in xs], [r[1] / 1e9 for r in rows], w, label="ours fused fp16")
        ax.bar(list(xs), [r[2] / 1e9 for r in rows], w, label="ours generic fp32")
        ax.bar([x + w for x in xs], [r[3] / 1e9 for r in rows], w, label="PyTorch fp16 eager")
        ax.set_xticks(list(xs))
        ax.set_xticklabels([r[0].replace(".inr", "") for r in rows], rotation=30, ha="right")
        ax.set_ylabel("G queries / s")
        ax.legend()
        fig.tight_layout()
        fig.savefig(prefix + ".png", dpi=120)
    except ImportError:
        pass


if __name__ == "__main__":
    main()
