#!/usr/bin/env python3
"""Frame times of the isosurface and slice blend modes (issue 48) on the shipped `*_small` models.

usage: blend_cpu_benchmark.py INR_EXECUTABLE DATA_DIR OUT_DIR [--size N] [--frames F] [--backend B]
       [--models NAME ...] [--modes isosurface,slice] [--iso-args "ARGS"]

For each model in DATA_DIR/real/*_small.inr (or DATA_DIR/real/NAME.inr for each --models NAME: the
paper-size models on a GPU) with its shipped transfer function, renders
  - the isosurface at one isovalue: the highest value below which the TF's opacity falls under
    half its maximum (the edge of what the composite picture shows) when it lies in the inner 80 %
    of the model's sampled value range (`inr info`: a TF shared with a larger model may reach past
    what this one holds), else the value of that inner range where the TF is most opaque; lit
    (the CLI's default);
  - the slice through the box's centre, normal +z (ParaView's default Slice plane),
(--modes: either or both; --iso-args: more `inr render` options for the isosurface runs, e.g.
"--iso-refine-points 8") at N x N (default 512) for F frames (default 3: the first builds the candidate macrocells at the
time; later frames are jittered and cost what any frame of a new view costs), and prints a table:
the first frame's macrocell build (update) and the median frame time without it, queries per
frame, and a second table of where the time goes (the stages' medians). Each run's `inr` output and --stats-json land in OUT_DIR, with the table (table.md).
"""
import argparse
import glob
import json
import os
import shlex
import statistics
import subprocess
import sys


STAGES = ("init", "traverse", "evaluate", "shading", "finalize", "setup", "other")


def tf_points(path):
    d = json.load(open(path))
    d = d[0] if isinstance(d, list) else d
    pts = d["Points"]
    return [(pts[k], pts[k + 1]) for k in range(0, len(pts), 4)]


def edge_isovalue(points):
    """The highest x below which the piecewise-linear opacity falls under half its maximum."""
    half = 0.5 * max(a for _, a in points)
    for (x0, a0), (x1, a1) in reversed(list(zip(points, points[1:]))):
        if a0 < half <= a1:
            return x0 + (half - a0) / (a1 - a0) * (x1 - x0)
    return 0.5 * (points[0][0] + points[-1][0])


def opacity_at(points, x):
    if x <= points[0][0]:
        return points[0][1]
    for (x0, a0), (x1, a1) in zip(points, points[1:]):
        if x <= x1:
            return a0 + (a1 - a0) * (x - x0) / (x1 - x0) if x1 > x0 else a1
    return points[-1][1]


def choose_isovalue(points, lo, hi):
    inner = (lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
    edge = edge_isovalue(points)
    if inner[0] <= edge <= inner[1]:
        return edge
    xs = [inner[0] + (inner[1] - inner[0]) * k / 200 for k in range(201)]
    return max(xs, key=lambda x: opacity_at(points, x))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("inr")
    ap.add_argument("data")
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--models", nargs="*", default=None,
                    help="model names under DATA_DIR/real (default: every *_small model)")
    ap.add_argument("--modes", default="isosurface,slice", help="comma-separated: isosurface, slice")
    ap.add_argument("--iso-args", default="", help="more inr render options for the isosurface runs")
    a = ap.parse_args()
    modes = [m for m in a.modes.split(",") if m]
    if not modes or any(m not in ("isosurface", "slice") for m in modes):
        ap.error("--modes: isosurface and/or slice, comma-separated (got %r)" % a.modes)
    os.makedirs(a.out, exist_ok=True)
    env = dict(os.environ, OMP_WAIT_POLICY="passive")
    rows = []
    models = ([os.path.join(a.data, "real", m + ".inr") for m in a.models] if a.models
              else sorted(glob.glob(os.path.join(a.data, "real", "*_small.inr"))))
    for model in models:
        name = os.path.basename(model)[:-4]
        tf = model[:-4] + ".tf.json"
        info = json.loads(subprocess.run([a.inr, "info", model, "--json"], capture_output=True, text=True,
                                         check=True).stdout)["sampled_value_range"]
        lo, hi = info["min"], info["max"]
        iso = choose_isovalue(tf_points(tf), lo, hi)
        runs = (("isosurface", ["--iso", "%.6g" % iso, *shlex.split(a.iso_args)]), ("slice", []))
        for mode, extra in (r for r in runs if r[0] in modes):
            stem = os.path.join(a.out, "%s_%s" % (name, mode))
            cmd = [a.inr, "render", model, "--blend", mode, *extra, "--tf", tf, "--size", "%dx%d" % (a.size, a.size),
                   "--frames", str(a.frames), "--backend", a.backend, "--stats-json", stem + ".json", "-o",
                   stem + ".png"]
            p = subprocess.run(cmd, capture_output=True, text=True, env=env)
            open(stem + ".log", "w").write("$ " + " ".join(cmd) + "\n" + p.stdout + p.stderr)
            if p.returncode != 0:
                print("FAILED:", " ".join(cmd), p.stderr, file=sys.stderr)
                sys.exit(1)
            s = json.load(open(stem + ".json"))
            frames = s["frames"]
            update = frames[0]["ms"]["update"]
            render = [f["ms"]["total"] - f["ms"]["update"] for f in frames]
            rows.append({"model": name, "mode": mode, "iso": iso if mode == "isosurface" else None,
                         "update_ms": update, "frame_ms": statistics.median(render),
                         "first_frame_ms": frames[0]["ms"]["total"], "queries": frames[0]["queries"],
                         "gradient_queries": frames[0]["shading_queries"], "iterations": frames[0]["iterations"],
                         "rays": frames[0]["rays"], "threads": s["threads"],
                         "stages_ms": {k: statistics.median(f["ms"][k] for f in frames[1:] or frames)
                                       for k in STAGES}})
            print("%-34s %-10s frame %8.1f ms (first %8.1f, update %7.1f) %9d queries" %
                  (name, mode, rows[-1]["frame_ms"], rows[-1]["first_frame_ms"], update, rows[-1]["queries"]),
                  flush=True)
    lines = ["| model | mode | isovalue | frame ms (median) | first frame ms (incl. update) | macrocell update ms | "
             "queries / frame | gradient queries | iterations |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        lines.append("| %s | %s | %s | %.1f | %.1f | %.1f | %d | %d | %d |" %
                     (r["model"], r["mode"], "%.4g" % r["iso"] if r["iso"] is not None else "",
                      r["frame_ms"], r["first_frame_ms"], r["update_ms"], r["queries"], r["gradient_queries"],
                      r["iterations"]))
    lines += ["", "Where a frame's time goes (median of the frames after the first, ms; the GPU's isosurface "
              "stages are host times: launches, and the iteration's wait for the device in traverse):", "",
              "| model | mode | " + " | ".join(STAGES) + " |", "| --- | --- |" + " --- |" * len(STAGES)]
    for r in rows:
        lines.append("| %s | %s | " % (r["model"], r["mode"]) +
                     " | ".join("%.2f" % r["stages_ms"][k] for k in STAGES) + " |")
    table = "\n".join(lines) + "\n"
    open(os.path.join(a.out, "table.md"), "w").write(
        "%dx%d, %d frames, --backend %s, %d OpenMP threads\n\n" % (a.size, a.size, a.frames, a.backend,
                                                                  rows[0]["threads"]) + table)
    json.dump(rows, open(os.path.join(a.out, "results.json"), "w"), indent=1)
    print(table)


if __name__ == "__main__":
    main()
