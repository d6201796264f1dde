#!/usr/bin/env python3
"""Plots and tables from query_reduction_benchmark's CSVs (curves, summary, raymarch, orbit).

    plot_query_reduction.py RESULTS_DIR [--title "H100, 1024^2"]

Writes into RESULTS_DIR:
  psnr_vs_time_<model>.png  PSNR over the volume's pixels (top) and over the whole image (bottom)
                            against render time, one panel per scheme family (none and the compiled
                            defaults on every panel), fixed-step ray marching as markers
  pruning.png               frames/s and end PSNR against epsilon per model (epsilon 0 = none)
  orbit.png                 PSNR per orbit step after each step's first frame, with and without
                            reprojection
  tables.md                 the markdown tables for Benchmarks/RESULTS.md (also printed)
Needs only the standard library for the tables; the plots need matplotlib and are skipped with a
note when it is missing.
"""
import argparse
import csv
import math
import os
import sys
from collections import OrderedDict, defaultdict


def read(path):
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def num(v):
    try:
        return float(v) if v not in ("", None) else math.nan
    except ValueError:
        return math.nan


def cell(v, digits=2):
    return "—" if math.isnan(v) else f"{v:.{digits}f}"


FAMILIES = ["histogram", "stbn", "weighted-stbn", "prune", "combined"]
# The primary estimators (inr render --estimator) share one panel, "estimators".
ESTIMATORS = ("delta", "ratio", "march")


def panels(summary):
    """The families present in the summary, in FAMILIES order, then "estimators" if any is."""
    present = {r["family"] for r in summary}
    out = [f for f in FAMILIES if f in present]
    if present & set(ESTIMATORS):
        out.append("estimators")
    return out or ["none"]


def in_panel(family, panel):
    if panel == "estimators":
        return family in ESTIMATORS or family in ("none", "defaults")
    return family in (panel, "none", "defaults")


def tables(summary, raymarch, orbit):
    out = []
    models = list(OrderedDict.fromkeys(r["model"] for r in summary))
    for m in models:
        rows = [r for r in summary if r["model"] == m]
        first = rows[0]
        none = next((r for r in rows if r["config"] == "none"), None)
        t35_none = num(none["time_to_35"]) if none else math.nan
        out.append(f"\n**{m}** ({first['backend']}, {first['size']}², reference {first['reference_frames']} "
                   f"frames, volume covers {100 * num(first['covered_fraction']):.1f}% of the image)\n")
        out.append("| config | frames | fps | t→35 dB [s] | t→40 dB [s] | t35 / none | dB @400 | dB end (volume) "
                   "| dB end (image) | MAD % | rays/frame | pruned/frame | rays/px/frame | iterations/frame "
                   "| queries/frame |")
        out.append("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: "
                   "| ---: |")
        for r in rows:
            t35 = num(r["time_to_35"])
            ratio = t35 / t35_none if t35_none > 0 and not math.isnan(t35) else math.nan
            out.append(f"| {r['config']} | {r['frames']} | {num(r['fps']):.1f} | {cell(t35, 3)} | "
                       f"{cell(num(r['time_to_40']), 3)} | {cell(ratio)} | {cell(num(r['psnr_400_volume']))} | "
                       f"{cell(num(r['psnr_end_volume']))} | {cell(num(r['psnr_end_image']))} | "
                       f"{cell(100 * num(r['mad_end_volume']))} | {num(r['rays_per_frame']):.0f} | "
                       f"{num(r['pruned_per_frame']):.0f} | {cell(num(r['heatmap_mean']))} | "
                       f"{cell(num(r.get('iterations_per_frame', '')), 1)} | {cell(num(r['queries_per_frame']), 0)} |")
        march = [r for r in raymarch if r["model"] == m]
        if march:
            out.append("\n| ray marching (1 frame, pixel centres) | seconds | dB (volume) | dB (image) | queries |")
            out.append("| --- | ---: | ---: | ---: | ---: |")
            for r in march:
                out.append(f"| step = diagonal / {r['step_divisor']} | {num(r['seconds']):.4f} | "
                           f"{cell(num(r['psnr_volume']))} | {cell(num(r['psnr_image']))} | {r['queries']} |")
    if orbit:
        out.append("\n| model | orbit mode | steps | mean dB after 1st frame of a step | mean dB after last frame |")
        out.append("| --- | --- | ---: | ---: | ---: |")
        groups = defaultdict(list)
        for r in orbit:
            groups[(r["model"], r["mode"])].append(r)
        for (m, mode), rs in groups.items():
            last = max(int(r["frame_in_step"]) for r in rs)
            f1 = [num(r["psnr_volume"]) for r in rs if r["frame_in_step"] == "1"]
            fl = [num(r["psnr_volume"]) for r in rs if int(r["frame_in_step"]) == last]
            out.append(f"| {m} | {mode} | {len(f1)} | {cell(sum(f1) / len(f1))} | {cell(sum(fl) / len(fl))} |")
    return "\n".join(out) + "\n"


def plots(d, curves, summary, raymarch, orbit, title):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not available: tables only, no plots")
        return
    written = []

    def save(fig, name, heading):
        fig.suptitle(heading)
        fig.tight_layout()
        path = os.path.join(d, name)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    models = list(OrderedDict.fromkeys(r["model"] for r in summary))
    by = defaultdict(list)
    for r in curves:
        if r["psnr_volume"] != "":
            by[(r["model"], r["config"])].append(r)
    for m in models:
        configs = [r for r in summary if r["model"] == m]
        cols = panels(summary)
        fig, ax = plt.subplots(2, len(cols), figsize=(5 * len(cols), 8), sharex=True, squeeze=False)
        march = [r for r in raymarch if r["model"] == m]
        for col, fam in enumerate(cols):
            for row, key in enumerate(("psnr_volume", "psnr_image")):
                a = ax[row][col]
                for c in configs:
                    if not in_panel(c["family"], fam):
                        continue
                    pts = [(num(p["seconds"]), num(p[key])) for p in by[(m, c["config"])]]
                    pts = [(t, v) for t, v in pts if t > 0 and math.isfinite(v)]
                    if not pts:
                        continue
                    style = dict(color="k", lw=2) if c["family"] in ("none", "delta") else \
                        dict(color="gray", ls="--", lw=1.5) if c["family"] == "defaults" else dict(lw=1.2)
                    a.plot(*zip(*pts), label=c["config"], **style)
                # Ray marching in black, one marker shape per step, the same on every panel.
                for r, marker in zip(march, "osD^vP*X"):
                    t, v = num(r["seconds"]), num(r[key])
                    if t > 0 and math.isfinite(v):
                        a.plot([t], [v], marker=marker, ls="none", ms=7, mfc="none", mec="k", mew=1.5,
                               label=f"raymarch diag/{r['step_divisor']}")
                for y in (35, 40):
                    a.axhline(y, color="k", lw=0.5, ls=":")
                a.set_xscale("log")
                a.set_title(f"{fam} — {'volume pixels' if row == 0 else 'whole image'}", fontsize=9)
                if row == 1:
                    a.set_xlabel("render time [s]")
                if col == 0:
                    a.set_ylabel("PSNR vs reference [dB]")
                a.legend(fontsize=6)
        save(fig, f"psnr_vs_time_{m}.png", f"{m}: PSNR against render time {title}")
    prune = [r for r in summary if r["family"] in ("prune", "none")]
    if prune:
        fig, ax = plt.subplots(1, len(models), figsize=(5 * len(models), 4), squeeze=False)
        for k, m in enumerate(models):
            rs = sorted((r for r in prune if r["model"] == m), key=lambda r: num(r["epsilon"]))
            eps = [num(r["epsilon"]) for r in rs]
            a = ax[0][k]
            a.plot(eps, [num(r["fps"]) for r in rs], "o-", color="tab:red")
            a.set_ylabel("frames/s", color="tab:red")
            a.set_xlabel("epsilon (fraction of the value range)")
            b = a.twinx()
            b.plot(eps, [num(r["psnr_end_volume"]) for r in rs], "s-", color="tab:blue", label="end")
            b.plot(eps, [num(r["psnr_400_volume"]) for r in rs], "^--", color="tab:blue", label="frame 400")
            b.set_ylabel("PSNR over the volume [dB]", color="tab:blue")
            b.legend(fontsize=7)
            a.set_title(m, fontsize=9)
        save(fig, "pruning.png", f"homogeneity pruning {title}")
    if orbit:
        omodels = list(OrderedDict.fromkeys(r["model"] for r in orbit))
        fig, ax = plt.subplots(1, len(omodels), figsize=(5 * len(omodels), 4), squeeze=False)
        for k, m in enumerate(omodels):
            a = ax[0][k]
            modes = OrderedDict.fromkeys(r["mode"] for r in orbit if r["model"] == m)
            for mode, color in zip(modes, ("tab:gray", "tab:green", "tab:purple")):
                rs = [r for r in orbit if r["model"] == m and r["mode"] == mode]
                last = max(int(r["frame_in_step"]) for r in rs)
                for f, ls in ((1, "-"), (last, ":")):
                    pts = [(num(r["degrees"]), num(r["psnr_volume"])) for r in rs if int(r["frame_in_step"]) == f]
                    a.plot(*zip(*pts), ls=ls, color=color, label=f"{mode}, frame {f} of a step")
            a.set_xlabel("orbit angle [deg]")
            a.set_ylabel("PSNR over the volume [dB]")
            a.set_title(m, fontsize=9)
            a.legend(fontsize=7)
        save(fig, "orbit.png", f"camera orbit {title}")
    for p in written:
        print("wrote", p)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    summary = read(os.path.join(a.dir, "summary.csv"))
    if not summary:
        print(f"{a.dir}/summary.csv missing or empty")
        return 1
    curves = read(os.path.join(a.dir, "curves.csv"))
    raymarch = read(os.path.join(a.dir, "raymarch.csv"))
    orbit = read(os.path.join(a.dir, "orbit.csv"))
    md = tables(summary, raymarch, orbit)
    with open(os.path.join(a.dir, "tables.md"), "w") as f:
        f.write(md)
    print(md)
    plots(a.dir, curves, summary, raymarch, orbit, f"({a.title})" if a.title else "")
    return 0


if __name__ == "__main__":
    sys.exit(main())
