#!/usr/bin/env python3
"""Where a kernel's warps spend their time, from ncu's source page with warp-state sampling:
  ncu --profile-from-start off --launch-count 1 -k regex:MlpKernel --section SourceCounters \\
      --section WarpStateStats -o REPORT gpu_evaluator_benchmark --only paper_siren --batch 2097152 --reps 3
  ncu --import REPORT.ncu-rep --page source --csv --print-source sass > SOURCE.csv
  ncu_source_breakdown.py SOURCE.csv [--blocks N]

Prints, for instructions that whole warps execute and for those one lane executes apart (by ncu's
average threads executed: in the Hopper kernel the second holds the producer, and also the
consumers' single-lane code such as a barrier arrive or an output write; a kernel without a
producer has only that): the stall reasons' shares of the sampled time, the executed
instructions by opcode with their share of the samples, and the N code blocks (straight runs of
instructions with one execution count) with the most samples, each with its opcodes and largest
stalls. Samples are proportional to the time warps spend at an instruction, so a block's share is
the share of the warps' time spent there.
"""
import argparse
import collections
import csv
import re


def number(s):
    try:
        return float(s.replace(",", ""))
    except ValueError:
        return 0.0


def load(path):
    rows = list(csv.reader(open(path)))
    kernel = rows[0][1] if rows and len(rows[0]) > 1 else "?"
    at = next(i for i, r in enumerate(rows) if r and r[0] == "Address")
    header = rows[at]
    col = {n: i for i, n in enumerate(header)}
    stalls = [n for n in header if n.startswith("stall_") and "Not Issued" not in n]
    instrs = []
    for r in rows[at + 1:]:
        if len(r) < len(header):
            continue
        source = r[col["Source"]].strip()
        m = re.match(r"(@!?U?P\w+\s+)?([A-Z0-9_]+)", source)
        instrs.append({
            "source": source,
            "op": m.group(2) if m else "?",
            "executed": number(r[col["Instructions Executed"]]),
            "threads": number(r[col["Avg. Threads Executed"]]),
            "samples": number(r[col["Warp Stall Sampling (All Samples)"]]),
            "stalls": {n[len("stall_"):]: number(r[col[n]]) for n in stalls},
        })
    return kernel, instrs


def blocks_of(instrs):
    """Straight runs with one execution count, cut after a jump, barrier or wgmma wait."""
    out, cur, cut = [], None, True
    for i, ins in enumerate(instrs):
        if cur is None or cut or ins["executed"] != cur["executed"]:
            cur = {"start": i, "executed": ins["executed"], "threads": ins["threads"], "instrs": []}
            out.append(cur)
        cur["instrs"].append(ins)
        head = ins["source"].split()
        op = head[1] if head and head[0].startswith("@") and len(head) > 1 else (head[0] if head else "")
        cut = op.startswith(("BRA", "BRX", "JMP", "JMX", "CALL", "EXIT", "BAR", "WARPGROUP.DEPBAR", "RET"))
    return out


def report(title, instrs, nblocks):
    total = sum(i["samples"] for i in instrs)
    executed = sum(i["executed"] for i in instrs)
    if not total:
        return
    print("\n## %s: %.0f warp instructions executed, %.0f samples" % (title, executed, total))
    stalls = collections.Counter()
    for i in instrs:
        stalls.update(i["stalls"])
    print("stalls: " + ", ".join("%s %.0f%%" % (k, 100 * v / total) for k, v in stalls.most_common(8)))
    ops, op_samples = collections.Counter(), collections.Counter()
    for i in instrs:
        ops[i["op"]] += i["executed"]
        op_samples[i["op"]] += i["samples"]
    print("\n| opcode | share of executed | share of samples |\n| --- | --- | --- |")
    for op, n in ops.most_common(16):
        print("| %s | %.1f%% | %.1f%% |" % (op, 100 * n / executed, 100 * op_samples[op] / total))
    blocks = sorted(blocks_of(instrs), key=lambda b: -sum(i["samples"] for i in b["instrs"]))
    print("\n| share of samples | instructions | executed | first instruction | opcodes | largest stalls |")
    print("| --- | --- | --- | --- | --- | --- |")
    for b in blocks[:nblocks]:
        s = sum(i["samples"] for i in b["instrs"])
        if not s:
            break
        bops = collections.Counter(i["op"] for i in b["instrs"])
        bst = collections.Counter()
        for i in b["instrs"]:
            bst.update(i["stalls"])
        print("| %.1f%% | %d | %.0f | `%s` | %s | %s |" % (
            100 * s / total, len(b["instrs"]), b["executed"], b["instrs"][0]["source"][:48],
            " ".join("%s×%d" % kv for kv in bops.most_common(5)),
            ", ".join("%s %.0f%%" % (k, 100 * v / s) for k, v in bst.most_common(3))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source_csv")
    ap.add_argument("--blocks", type=int, default=12)
    a = ap.parse_args()
    kernel, instrs = load(a.source_csv)
    print("# %s" % kernel)
    ran = [i for i in instrs if i["executed"] > 0 or i["samples"] > 0]
    report("code whole warps run", [i for i in ran if i["threads"] >= 2 or (i["executed"] == 0 and i["samples"] > 0)],
           a.blocks)
    report("code one lane runs (the Hopper producer; single-lane parts of the others)",
           [i for i in ran if 0 < i["threads"] < 2], min(a.blocks, 4))


if __name__ == "__main__":
    main()
