#!/usr/bin/python3
"""One summary shape for every benchmark suite: OUT/summary.json and OUT/summary.md.

    bench_summary.py OUT --suite NAME --status N --started ISO --seconds S --device TEXT
                     [--before COMMIT] [--tables "FILE ..."] [--command TEXT]

Reads OUT/steps.tsv (written by bench_lib.sh's x: exit status, milliseconds, step, command per
line; a before run's in OUT/before/steps.tsv) and lists every file the suite wrote. The
suite's own tables (--tables, paths relative to OUT; and the same under OUT/before/) are copied
into summary.md as they are.
summary.json:
    {"suite", "command", "commit", "before", "device", "started", "seconds", "status",
     "steps": [{"step", "command", "status", "seconds", "run"}],   run: "this" or "before"
     "tables": [FILE...], "files": [FILE...]}
"""
import argparse
import json
import os
import subprocess
import sys


def read_steps(path, run):
    steps = []
    if not os.path.exists(path):
        return steps
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            parts = line.rstrip("\n").split("\t", 3)
            if len(parts) != 4:
                sys.exit(f"bench_summary.py: {path} line {n}: expected 4 tab-separated fields, got {len(parts)}")
            status, ms, step, command = parts
            steps.append({"step": step, "command": command.strip(), "status": int(status),
                          "seconds": round(int(ms) / 1000.0, 3), "run": run})
    return steps


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--suite", required=True)
    ap.add_argument("--status", type=int, required=True)
    ap.add_argument("--started", required=True)
    ap.add_argument("--seconds", type=int, required=True)
    ap.add_argument("--device", default="")
    ap.add_argument("--before", default="")
    ap.add_argument("--tables", default="")
    ap.add_argument("--command", default="")
    a = ap.parse_args()
    if not os.path.isdir(a.out):
        sys.exit(f"bench_summary.py: {a.out} is not a folder")
    try:
        commit = subprocess.run(["git", "log", "-1", "--format=%H %s"], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "(no git)"
    steps = read_steps(os.path.join(a.out, "steps.tsv"), "this")
    steps += read_steps(os.path.join(a.out, "before", "steps.tsv"), "before")
    skip = {"summary.md", "summary.json"}
    files = sorted(os.path.relpath(os.path.join(d, f), a.out)
                   for d, _, fs in os.walk(a.out) for f in fs if f not in skip)
    # The suite's tables, and the same tables of a before run (OUT/before/) where it wrote them.
    tables = [t for name in a.tables.split() for t in (name, os.path.join("before", name))
              if os.path.exists(os.path.join(a.out, t))]
    summary = {"suite": a.suite, "command": a.command.strip(), "commit": commit, "before": a.before or None,
               "device": a.device, "started": a.started, "seconds": a.seconds, "status": a.status,
               "steps": steps, "tables": tables, "files": files}
    with open(os.path.join(a.out, "summary.json"), "w", encoding="utf-8") as f:
        json.dump(summary, f, indent=1)
        f.write("\n")

    md = [f"# {a.suite}: {'passed' if a.status == 0 else 'status ' + str(a.status)}", "",
          f"- command: `{summary['command']}`", f"- commit: {commit}",
          f"- before: {a.before or '(none)'}", f"- device: {a.device}",
          f"- started: {a.started}, {a.seconds} s in all", "", "## Steps", "",
          "| run | step | status | seconds | command |", "| --- | --- | --- | --- | --- |"]
    for s in steps:
        command = s["command"].replace("|", "\\|")
        if len(command) > 160:
            command = command[:157] + "..."
        md.append(f"| {s['run']} | {s['step']} | {s['status']} | {s['seconds']:.1f} | `{command}` |")
    for t in tables:
        md += ["", f"## {t}", "", "```"]
        with open(os.path.join(a.out, t), encoding="utf-8", errors="replace") as f:
            md.append(f.read().rstrip("\n"))
        md.append("```")
    md += ["", "## Files", ""] + [f"- `{f}`" for f in files]
    with open(os.path.join(a.out, "summary.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(md) + "\n")


if __name__ == "__main__":
    main()
