#!/usr/bin/env python3
"""Test of figures_in_comments.py: it finds a figure planted in a comment (the control), passes
the same tree without it, and passes the repository itself."""
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
CHECK = os.path.join(HERE, "figures_in_comments.py")
REPO = os.path.abspath(os.path.join(HERE, "..", ".."))


def run(root):
    return subprocess.run([sys.executable, CHECK, root], capture_output=True, text=True)


def main():
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        planted = {
            "a.cpp": "int x = 1;  // measured 12.5 ms on the test machine\n",
            "b.py": "x = 2  # 0.48 ms per frame (H100)\n",
            "c.cu": "/*\n * the kernel took 3 s on a 2-core machine\n */\n",
        }
        clean = {
            "a.cpp": "int x = 1;  // a bound: at most 12.5 ms per frame\n",
            "b.py": "x = 2  # see Benchmarks/RESULTS.md\n",
            "c.cu": "/*\n * the kernel's budget is 3 s\n */\n",
        }
        for name, text in planted.items():
            with open(os.path.join(tmp, name), "w") as f:
                f.write(text)
        r = run(tmp)
        for name in planted:
            if r.returncode != 1 or name + ":" not in r.stdout:
                failures.append(f"planted figure in {name} not found (exit {r.returncode}): {r.stdout}")
        for name, text in clean.items():
            with open(os.path.join(tmp, name), "w") as f:
                f.write(text)
        r = run(tmp)
        if r.returncode != 0:
            failures.append(f"clean tree flagged (exit {r.returncode}): {r.stdout}")
    r = run(REPO)
    if r.returncode != 0:
        failures.append("the repository has figures in comments:\n" + r.stdout)
    for f in failures:
        print("FAIL:", f)
    print("figures_in_comments_test:", "FAILED" if failures else "ok")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
