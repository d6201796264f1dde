#!/usr/bin/env python3
"""Joins what the evaluator suite (Benchmarks/bench.sh evaluator) measured in one run into Markdown tables (stdout)
and summary.csv in the same folder:
  - per network: ours autotuned at 2^21 (ours.csv) and the configuration it chose (ours.txt's
    launch report), PyTorch fp16 eager (torch.csv) and torch.compile (torch_compile.csv) at the
    same batch, and the ratios;
  - per network: ours at every swept batch (batches.csv), a launch alone and launches queued
    back to back, with its share of the 2^21 rate, and PyTorch eager at 8192 (torch_8k.csv);
  - with a BEFORE build's sweep (before_batches.csv): before and now at 2^21 and 8192;
  - per profiled launch (ncu/NAME_BATCH.csv, `ncu --page raw --csv`): time, the speed-of-light
    throughputs, the tensor pipe, the busiest pipes and the largest warp stall reasons.

usage: evaluator_summary.py LOG_DIR
"""
import csv
import glob
import os
import re
import sys


def read_rates(path, want_path=None, column="median_qps"):
    """{(model, path, batch): median q/s} from a benchmark or PyTorch CSV (missing file or column,
    empty value: no entry). column "stream_median_qps": a --batches sweep's launches queued back
    to back."""
    out = {}
    if not os.path.exists(path):
        return out
    for r in csv.DictReader(open(path)):
        if want_path and r["path"] != want_path:
            continue
        if r.get(column):
            out[(r["model"], r["path"], int(r["batch"]))] = float(r[column])
    return out


def choices(path):
    """{model: the configuration the autotuner chose} from a benchmark's printed launch reports."""
    out, model = {}, None
    if not os.path.exists(path):
        return out
    for line in open(path):
        m = re.match(r"^(\S+\.inr)\s+fused-fp16\s", line)
        if m:
            model = m.group(1)
        m = re.search(r"fused launch autotuning: .*? -> (.*)$", line)
        if m and model:
            out[model] = m.group(1).strip()
            model = None
        elif model and "fused launch autotuning:" in line:
            out[model] = line.split("fused launch autotuning:", 1)[1].strip()
            model = None
    return out


def gq(v):
    return "–" if v is None else "%.3f" % (v / 1e9)


def ratio(a, b):
    return "–" if not a or not b else "%.2f×" % (a / b)


def ncu_rows(log):
    """One dict of metric -> value per profiled launch (first kernel row of each raw CSV)."""
    rows = []
    for path in sorted(glob.glob(os.path.join(log, "ncu", "*.csv"))):
        lines = [l for l in open(path) if l.startswith('"')]
        if len(lines) < 3:  # header, units, one kernel
            continue
        header = next(csv.reader([lines[0]]))
        units = next(csv.reader([lines[1]]))
        values = next(csv.reader([lines[2]]))
        d = dict(zip(header, values))
        d["_units"] = dict(zip(header, units))
        rows.append((os.path.basename(path)[:-4], d))
    return rows


def num(d, key):
    try:
        return float(d.get(key, "").replace(",", ""))
    except ValueError:
        return None


def main():
    log = sys.argv[1]
    ours = read_rates(os.path.join(log, "ours.csv"), "fused-fp16")
    mma = read_rates(os.path.join(log, "ours.csv"), "fused-mma.sync")
    eager = read_rates(os.path.join(log, "torch.csv"), "torch-fp16-eager")
    compiled = read_rates(os.path.join(log, "torch_compile.csv"), "torch-fp16-compile")
    batches = read_rates(os.path.join(log, "batches.csv"), "fused-fp16")
    queued = read_rates(os.path.join(log, "batches.csv"), "fused-fp16", "stream_median_qps")
    before = read_rates(os.path.join(log, "before_batches.csv"), "fused-fp16")
    before_queued = read_rates(os.path.join(log, "before_batches.csv"), "fused-fp16", "stream_median_qps")
    eager8k = read_rates(os.path.join(log, "torch_8k.csv"), "torch-fp16-eager")
    chosen = choices(os.path.join(log, "ours.txt"))
    gpu = open(os.path.join(log, "gpu.txt")).read().strip() if os.path.exists(os.path.join(log, "gpu.txt")) else "?"
    full = 1 << 21
    models = sorted({m for (m, _, b) in ours}, key=lambda m: (not m.startswith("paper_"), m))
    csv_rows = [("model", "batch", "ours_qps", "mma_sync_qps", "eager_qps", "compile_qps", "ours_queued_qps")]

    print("## Evaluator, batch 2^21, %s\n" % gpu)
    print("| network | ours (G q/s) | chosen configuration | mma.sync only | PyTorch fp16 eager | torch.compile | ours / eager | ours / compile |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for m in models:
        o, s = ours.get((m, "fused-fp16", full)), mma.get((m, "fused-mma.sync", full))
        e, c = eager.get((m, "torch-fp16-eager", full)), compiled.get((m, "torch-fp16-compile", full))
        print("| %s | %s | %s | %s | %s | %s | %s | %s |" % (m[:-4], gq(o), chosen.get(m, "?"), gq(s), gq(e), gq(c), ratio(o, e), ratio(o, c)))
        # (ours_queued_qps: the batch sweep's queued launches at 2^21; ours_qps is ours.csv's rate)
        csv_rows.append((m, full, o, s, e, c, queued.get((m, "fused-fp16", full))))

    sizes = sorted({b for (_, _, b) in batches})
    largest = sizes[-1] if sizes else full  # a share's denominator: 2^21 where it was swept, else the largest batch

    def share(rates, m, b):
        small, top = rates.get((m, "fused-fp16", b)), rates.get((m, "fused-fp16", largest))
        return "%.0f%%" % (100 * small / top) if small and top else "–"

    if sizes:
        print("\n## Evaluator at small batches (share of the same evaluator's %s rate), %s\n"
              % ("2^21" if largest == full else "%d-query" % largest, gpu))
        if queued:  # (sweeps before the queued timing have none)
            print("A launch alone (the host's launch latency included), and in brackets launches queued "
                  "back to back, as the wavefront queues its evaluator launches.\n")
        print("| network | " + " | ".join("%d" % b for b in sizes) + " | 8192 / largest |" +
              (" 8192 / largest, queued |" if queued else "") + " PyTorch eager at 8192 | ours / eager at 8192 |")
        print("| --- | " + " | ".join("---" for _ in sizes) + " | --- |" + (" --- |" if queued else "") + " --- | --- |")
        for m in models:
            cells = []
            for b in sizes:
                r, q = batches.get((m, "fused-fp16", b)), queued.get((m, "fused-fp16", b))
                cells.append(gq(r) + ("" if q is None else " (%s)" % gq(q)))
            small = batches.get((m, "fused-fp16", 8192))
            e8 = eager8k.get((m, "torch-fp16-eager", 8192))
            print("| %s | %s | %s |%s %s | %s |" % (m[:-4], " | ".join(cells), share(batches, m, 8192),
                                                    " %s |" % share(queued, m, 8192) if queued else "", gq(e8),
                                                    ratio(small, e8)))
            for b in sizes:
                if b != full:
                    csv_rows.append((m, b, batches.get((m, "fused-fp16", b)), None, e8 if b == 8192 else None, None,
                                     queued.get((m, "fused-fp16", b))))

    if before:
        commit = open(os.path.join(log, "before_commit.txt")).read().strip()[:10] \
            if os.path.exists(os.path.join(log, "before_commit.txt")) else "?"
        print("\n## Before (%s) and now, the same run, %s\n" % (commit, gpu))
        print("| network | 2^21 before → now | 8192 before → now | 8192 queued before → now | 8192 / largest queued, now |")
        print("| --- | --- | --- | --- | --- |")
        for m in models:
            def pair(a, b, n):
                x, y = a.get((m, "fused-fp16", n)), b.get((m, "fused-fp16", n))
                return "%s → %s%s" % (gq(x), gq(y), "" if not x or not y else " (%+.0f%%)" % (100 * (y / x - 1)))
            print("| %s | %s | %s | %s | %s |" % (m[:-4], pair(before, batches, full), pair(before, batches, 8192),
                                                  pair(before_queued, queued, 8192), share(queued, m, 8192)))

    rows = ncu_rows(log)
    if rows:
        print("\n## Profiles (ncu, the first timed launch), %s\n" % gpu)
        print("| launch | kernel | time (µs) | SM throughput | memory throughput | L2 | DRAM | tensor pipe | busiest pipes | largest stalls (cycles per issued instruction) |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for tag, d in rows:
            kernel = d.get("Kernel Name", "?").split("(")[0].replace("void ", "")
            t = num(d, "gpu__time_duration.sum")
            scale = {"ns": 1e-3, "nsecond": 1e-3, "us": 1.0, "usecond": 1.0, "ms": 1e3, "msecond": 1e3, "s": 1e6, "second": 1e6}
            unit = d["_units"].get("gpu__time_duration.sum", "")
            t_us = None if t is None or unit not in scale else t * scale[unit]
            pipes = sorted(((num(d, k) or 0, k) for k in d if k != "_units"
                            if re.match(r"sm__inst_executed_pipe_[a-z0-9_]+\.avg\.pct_of_peak_sustained_active$", k)), reverse=True)[:3]
            pipe_s = ", ".join("%s %.0f%%" % (k.split("pipe_")[1].split(".")[0], v) for v, k in pipes if v > 0)
            stalls = sorted(((num(d, k) or 0, k) for k in d
                             if re.match(r"smsp__average_warp_latency_issue_stalled_[a-z_]+\.ratio$", k)
                             or re.match(r"smsp__average_warps_issue_stalled_[a-z_]+_per_issue_active\.ratio$", k)), reverse=True)[:4]
            stall_s = ", ".join("%s %.1f" % (re.sub(r"_per_issue_active$", "", k.split("stalled_")[1].split(".")[0]), v) for v, k in stalls if v > 0)

            def pct(key):
                v = num(d, key)
                return "–" if v is None else "%.0f%%" % v

            print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                tag, kernel, "–" if t_us is None else "%.1f" % t_us,
                pct("sm__throughput.avg.pct_of_peak_sustained_elapsed"),
                pct("gpu__compute_memory_throughput.avg.pct_of_peak_sustained_elapsed"),
                pct("lts__throughput.avg.pct_of_peak_sustained_elapsed"),
                pct("gpu__dram_throughput.avg.pct_of_peak_sustained_elapsed"),
                pct("sm__pipe_tensor_op_hmma_cycles_active.avg.pct_of_peak_sustained_active"), pipe_s, stall_s))

    with open(os.path.join(log, "summary.csv"), "w") as f:
        w = csv.writer(f)
        for r in csv_rows:
            w.writerow(["" if v is None else v for v in r])


if __name__ == "__main__":
    main()
