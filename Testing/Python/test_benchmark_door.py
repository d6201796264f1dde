#!/usr/bin/python3
"""The benchmark door cannot rot silently (ctest benchmarks.door).

    test_benchmark_door.py --source SOURCE_DIR

Checks, without a GPU and without building anything:
  1. `Benchmarks/bench.sh --list` names every suite of Benchmarks/suites/, with its cost and needs;
  2. every suite's `--dry-run` (and its variants: a before build for the suites with before steps
     of their own and for one that reruns itself, the CPU backend where a suite has one, every
     step of the ParaView suites) prints commands and finds
     each one resolving: programs of a build folder are CMake targets of this tree, scripts and
     data files exist;
  3. the checker itself catches what it is for: a suite naming a program no CMake file builds and
     a model file that does not exist fails its dry run and names both;
  4. `Benchmarks/current_figures.py --check`: RESULTS.md's table is what the cited raw files give,
     every row cites at least one file and every cited file exists;
  5. every link into RESULTS.md or RESULTS-archive.md from Benchmarks/, Docs/ and the README names
     a heading that exists.
"""
import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL:", message)
    return condition


def door(source, *args, env=None):
    run_env = dict(os.environ)
    if env:
        run_env.update(env)
    p = subprocess.run(["bash", os.path.join(source, "Benchmarks", "bench.sh"), *args], cwd=source,
                       capture_output=True, text=True, env=run_env, timeout=300)
    return p.returncode, p.stdout, p.stderr


def suite_names(source):
    return sorted(os.path.basename(f)[:-3] for f in glob.glob(os.path.join(source, "Benchmarks", "suites", "*.sh")))


def suite_before(source, name):
    with open(os.path.join(source, "Benchmarks", "suites", name + ".sh"), encoding="utf-8") as f:
        m = re.search(r"^SUITE_BEFORE=(\S+)", f.read(), re.M)
    return m.group(1).strip("\"'") if m else "none"


def is_git_checkout(source):
    return subprocess.run(["git", "rev-parse", "--verify", "--quiet", "HEAD^{commit}"], cwd=source,
                          capture_output=True).returncode == 0


def dry_run(source, name, *args):
    label = " ".join([name, *args])
    rc, out, err = door(source, name, "--dry-run", *args)
    commands = [line for line in out.splitlines() if line.startswith("+ ")]
    missing = [line for line in out.splitlines() if "MISSING" in line]
    check(rc == 0, f"bench.sh {label} --dry-run: exit status {rc}; {err.strip()[:300]} {' '.join(missing)[:300]}")
    check(commands, f"bench.sh {label} --dry-run printed no command")
    check(not missing, f"bench.sh {label} --dry-run: {missing}")
    return commands


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", required=True, help="the repository's root")
    source = os.path.abspath(ap.parse_args().source)
    names = suite_names(source)
    check(len(names) >= 10, f"Benchmarks/suites/ holds {len(names)} suites")

    # 1. --list
    rc, out, err = door(source, "--list")
    check(rc == 0, f"bench.sh --list: exit status {rc}: {err.strip()}")
    for name in names:
        check(re.search(r"^" + re.escape(name) + r"\s", out, re.M), f"bench.sh --list does not name {name}")
    check(out.count("cost:") == len(names), "bench.sh --list: a suite without its cost line")

    # 2. every suite's dry run, and its variants
    git = is_git_checkout(source)
    variants = {
        "bisect-frames": [["--", "HEAD"]] if git else [],
        "time-to-image": [[], ["BACKEND=cpu"]],
        "query-reduction": [[], ["BACKEND=cpu"]],
        "scaling": [[], ["BACKEND=cpu", "SIZES=64", "N=2", "SPLIT=pixels samples bricks"]],
        "paraview-gpu": [["STEPS=setup tests session session-host timesteps"]],
        "paraview-gui": [["STEPS=drags time-changes fresh-frames apply-stall"]],
        "shading": [["--before", "none"]],
    }
    for name in names:
        for args in variants.get(name, [[]]):
            dry_run(source, name, *args)
        # A before build: the suites with before steps of their own, and one that reruns itself
        # (the door's generic path, the same for every such suite).
        if git and (suite_before(source, name) not in ("none", "rerun") or name == "cpu-evaluator"):
            commands = dry_run(source, name, "--before", "HEAD")
            check(any("bench-before-build" in c for c in commands),
                  f"bench.sh {name} --before HEAD --dry-run runs nothing of the before build")
    if names:
        rc, _, err = door(source, names[0], "NO_SUCH_SETTING=1", "--dry-run")
        check(rc == 2 and "NO_SUCH_SETTING" in err, f"a misspelt setting is not refused (exit {rc}): {err.strip()}")

    # 3. the checker catches a program no CMake file builds and a missing data file
    with tempfile.TemporaryDirectory() as suites:
        with open(os.path.join(suites, "broken.sh"), "w", encoding="utf-8") as f:
            f.write('SUITE_ABOUT="a suite naming what does not exist"\nSUITE_COST="none"\nSUITE_NEEDS="CPU"\n'
                    "SUITE_HELP='(no settings)'\n"
                    'suite_build() { bench_build no_such_benchmark; }\n'
                    'suite_run() { x "$BUILD/Benchmarks/no_such_benchmark" Testing/Data/real/no_such_model.inr; }\n')
        rc, out, _ = door(source, "broken", "--dry-run", env={"BENCH_SUITES_DIR": suites})
        check(rc == 1, f"a dry run of a suite naming a missing program exits {rc}, not 1")
        check("no_such_benchmark is no CMake target" in out, "the dry run does not name the missing program")
        check("no_such_model.inr does not exist" in out, "the dry run does not name the missing data file")

    # 4. the current-figures table against its raw files
    p = subprocess.run([sys.executable, os.path.join(source, "Benchmarks", "current_figures.py"), "--check"],
                       capture_output=True, text=True, timeout=300)
    check(p.returncode == 0, f"current_figures.py --check: exit {p.returncode}: {p.stderr.strip()[:600]}")
    with open(os.path.join(source, "Benchmarks", "RESULTS.md"), encoding="utf-8") as f:
        results = f.read()
    table = results[results.find("<!-- current-figures: generated"):results.find("<!-- current-figures: end")]
    figures = table.split("Figures without a raw file")[0]
    rows = [line for line in figures.splitlines()
            if line.startswith("| ") and not line.startswith("| claim") and not line.startswith("| ---")]
    check(len(rows) >= 10, f"RESULTS.md's current-figures table has {len(rows)} rows")
    for line in rows:
        cited = re.findall(r"\]\((results/[^)]+)\)", line)
        check(cited, f"a current-figures row cites no raw file: {line[:120]}")
        for rel in cited:
            check(os.path.isfile(os.path.join(source, "Benchmarks", rel)), f"RESULTS.md cites {rel}, which does not exist")

    # 5. links into RESULTS*.md name headings that exist
    def slug(heading):
        return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")

    anchors = {}
    for page in ("RESULTS.md", "RESULTS-archive.md"):
        with open(os.path.join(source, "Benchmarks", page), encoding="utf-8") as f:
            anchors[page] = {slug(h) for h in re.findall(r"^#+ (.*)$", f.read(), re.M)}
    docs = glob.glob(os.path.join(source, "Docs", "*.md")) + glob.glob(os.path.join(source, "Benchmarks", "*.md")) \
        + [os.path.join(source, "README.md")]
    for doc in docs:
        with open(doc, encoding="utf-8") as f:
            text = f.read()
        for page, anchor in re.findall(r"(RESULTS(?:-archive)?\.md)#([\w\-]+)", text):
            check(anchor in anchors[page], f"{os.path.relpath(doc, source)} links to {page}#{anchor}, no such heading")

    print(f"{len(names)} suites; {len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
