#!/usr/bin/env python3
"""Fails when a code comment carries a measured figure.

Measured figures belong in Benchmarks/results/ (raw output) and Benchmarks/RESULTS.md, where they
can be re-measured and dated; a figure in a comment goes stale silently. This check reads the
comments of the project's C++, CUDA, Python, CMake and shell files and reports each line that
states a measurement: the word "measured" followed by a number, or a number with a unit (dB, ms,
GB, G q/s, ...) beside the machine it was measured on (H100, a 2-core machine, GCC 13, ...).

Comments may still name numbers that are specifications or bounds (a test's threshold, a timer's
period, a format's limit): those carry no "measured" and no machine. A line that must name both
for another reason may end with the marker `figure-ok`.

Usage: figures_in_comments.py [ROOT]   (default: the repository root above this file)
Exit status 1 when something is found, with one line per hit: path:line: the comment.
"""
import os
import re
import sys

SOURCE_SUFFIXES = {".h", ".hpp", ".cpp", ".cxx", ".cu", ".cuh", ".py", ".cmake", ".sh"}
SKIP_DIRS = {".git", "build", "results", "__pycache__", "shared", ".optix", ".gl", ".whl", ".data",
             "example-output"}
UNIT = r"(?:dB|ms|µs|us|ns|s|min|GB|MB|KB|GiB|MiB|KiB|G ?q/s|M ?q/s|TFLOP/s|GB/s|fps|x|×)"
NUMBER = r"(?<![\w.])\d+(?:\.\d+)?"
FIGURE_WITH_UNIT = re.compile(NUMBER + r"\s?" + UNIT + r"(?![\w/])")
MEASURED_NUMBER = re.compile(r"\bmeasured\b[^.;]*?(?<![\w.])\d", re.IGNORECASE)
MACHINE = re.compile(r"\b(?:H100|H200|A100|RTX ?\d+|\d+-core|GCC \d+|clang \d+)\b")
MARKER = "figure-ok"


def comment_text(line, suffix):
    """The comment part of one line, or None (a simple scan: quotes are not tracked)."""
    if suffix in {".py", ".cmake", ".sh"}:
        i = line.find("#")
        if i < 0 or line[:i].count('"') % 2 == 1 or line[:i].count("'") % 2 == 1:
            return None
        return line[i + 1:]
    i = line.find("//")
    if i >= 0 and line[:i].count('"') % 2 == 0:
        return line[i + 2:]
    stripped = line.lstrip()
    if stripped.startswith("*") or stripped.startswith("/*"):
        return stripped.lstrip("/*")
    return None


def hits(root):
    for base, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and not d.startswith("build")]
        for name in files:
            suffix = os.path.splitext(name)[1]
            if name == "CMakeLists.txt":
                suffix = ".cmake"
            if suffix not in SOURCE_SUFFIXES:
                continue
            path = os.path.join(base, name)
            try:
                with open(path, encoding="utf-8") as f:
                    lines = f.readlines()
            except (UnicodeDecodeError, OSError):
                continue
            for number, line in enumerate(lines, 1):
                text = comment_text(line, suffix)
                if not text or MARKER in text:
                    continue
                if MEASURED_NUMBER.search(text) or (MACHINE.search(text) and FIGURE_WITH_UNIT.search(text)):
                    yield os.path.relpath(path, root), number, text.strip()


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    found = list(hits(os.path.abspath(root)))
    for path, number, text in found:
        print(f"{path}:{number}: {text}")
    if found:
        print(f"figures_in_comments: {len(found)} comment(s) state a measured figure: move the figure to "
              "Benchmarks/RESULTS.md with its raw file in Benchmarks/results/ and cite the section, or end "
              f"the line with '{MARKER}' if the number is a specification or bound, not a measurement")
        return 1
    print("figures_in_comments: no measured figures in comments")
    return 0


if __name__ == "__main__":
    sys.exit(main())
