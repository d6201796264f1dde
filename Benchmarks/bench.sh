#!/usr/bin/env bash
# The benchmark door: one command for every benchmark suite of this repository.
#
#   Benchmarks/bench.sh --list                      the suites: what each runs, its cost, its needs
#   Benchmarks/bench.sh SUITE --help                one suite's settings
#   Benchmarks/bench.sh SUITE [options] [NAME=VALUE ...] [-- ARGS...]
#
# Options:
#   --out DIR        where the results go (default bench-results/SUITE in the repository): the
#                    raw logs, CSV and tables the suite writes, steps.tsv (every command with its
#                    exit status and seconds) and summary.md / summary.json (one shape for every
#                    suite)
#   --before COMMIT  also builds COMMIT's tree beside this one (git archive, built in
#                    $BEFORE_BUILD, default /tmp/bench-before-build, during this tree's build) and
#                    measures it in the same run: the suite's own before steps where it has them,
#                    else the whole suite again with the before build, into DIR/before/
#                    (--before none: no before build, for a suite that has a default one)
#   --build DIR      this tree's build folder (default build-bench, or build-bench-cpu for a CPU
#                    run); kept between runs, so a second suite on a warm machine builds little.
#                    BENCH_JOBS (default every core) and BENCH_BUILD_SECONDS (default 500) in the
#                    environment bound the build
#   --no-build       use the build folder as it is; --build-only: build and stop
#   --dry-run        print every command the suite would run (nothing runs, nothing is built) and
#                    check that each resolves: its programs are CMake targets of this tree, its
#                    scripts and data files exist; exit status 1 where one does not
#   NAME=VALUE       a suite's setting (bench.sh SUITE --help lists them)
#   -- ARGS          passed to the suite (models, or extra arguments of its benchmark program);
#                    the suites run from the repository root, so paths in ARGS are the root's
#
# On the GPU machine of a device call (the working tree in the current folder, $OUT returned):
#   bash Benchmarks/bench.sh evaluator --out "$OUT/evaluator" --before HEAD~1
set -uo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
CALLER_DIR=$PWD  # relative --out and --build are the caller's; the suites run from the repository root
invocation="bench.sh $*"
SUITES_DIR=${BENCH_SUITES_DIR:-$HERE/suites}  # (another folder: the door's own test)

suite_names() { for f in "$SUITES_DIR"/*.sh; do basename "$f" .sh; done; }

# Reads a suite's description variables in a subshell (nothing of it runs).
suite_field() {
  (
    SUITE_ABOUT= SUITE_COST= SUITE_NEEDS= SUITE_HELP= SUITE_BEFORE=
    # shellcheck disable=SC1090
    source "$SUITES_DIR/$1.sh"
    eval "echo \"\${$2}\""
  )
}

usage() { sed -n '2,/^set -uo/p' "${BASH_SOURCE[0]}" | grep -v '^set -uo' | sed 's/^# \{0,1\}//'; }

list_suites() {
  echo "Suites (Benchmarks/bench.sh SUITE --help for one's settings; --dry-run for its commands):"
  echo
  local s
  for s in $(suite_names); do
    printf '%-22s %s\n' "$s" "$(suite_field "$s" SUITE_ABOUT)"
    printf '%-22s cost: %s; needs: %s; --before: %s\n' "" "$(suite_field "$s" SUITE_COST)" \
      "$(suite_field "$s" SUITE_NEEDS)" "$(suite_field "$s" SUITE_BEFORE)"
  done
}

case "${1:-}" in
  "" | -h | --help) usage; exit 0 ;;
  --list) list_suites; exit 0 ;;
esac
SUITE=$1
shift
if [ ! -f "$SUITES_DIR/$SUITE.sh" ]; then
  echo "bench.sh: no suite '$SUITE' (Benchmarks/suites/$SUITE.sh); the suites: $(suite_names | tr '\n' ' ')" >&2
  exit 2
fi

out= BEFORE= before_given=0 build= dry=0 no_build=0 build_only=0 suite_args=() settings=()
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out=${2:?bench.sh: --out needs a folder}; shift 2 ;;
    --before) BEFORE=${2:?bench.sh: --before needs a commit (or none)}; before_given=1; shift 2 ;;
    --build) build=${2:?bench.sh: --build needs a folder}; shift 2 ;;
    --dry-run) dry=1; shift ;;
    --no-build) no_build=1; shift ;;
    --build-only) build_only=1; shift ;;
    -h | --help)
      echo "$SUITE: $(suite_field "$SUITE" SUITE_ABOUT)"
      echo "cost: $(suite_field "$SUITE" SUITE_COST); needs: $(suite_field "$SUITE" SUITE_NEEDS)"
      echo "--before: $(suite_field "$SUITE" SUITE_BEFORE)"
      echo "settings (NAME=VALUE after the suite's name):"
      suite_field "$SUITE" SUITE_HELP | sed 's/^/  /'
      exit 0 ;;
    --) shift; suite_args=("$@"); break ;;
    [A-Z]*=*) settings+=("$1"); shift ;;
    *) echo "bench.sh: unknown option '$1' (bench.sh --help)" >&2; exit 2 ;;
  esac
done

# Settings: only the names the suite documents (a misspelt one would be ignored silently).
known=$(suite_field "$SUITE" SUITE_HELP | grep -oE '^[A-Z_][A-Z0-9_]*=' | tr -d =)
for s in "${settings[@]}"; do
  name=${s%%=*}
  if ! grep -qxF "$name" <<< "$known"; then
    echo "bench.sh: $SUITE has no setting $name (it has: $(echo $known))" >&2
    exit 2
  fi
  export "${s?}"
done

# From the caller's folder, where that is not the repository root (suites run from the root).
from_caller() {
  case "$1" in
    "" | /*) echo "$1" ;;
    *) if [ "$CALLER_DIR" = "$(cd "$HERE/.." && pwd)" ]; then echo "$1"; else echo "$CALLER_DIR/$1"; fi ;;
  esac
}
out=$(from_caller "$out")
build=$(from_caller "$build")

DRY_RUN=$dry
export DRY_RUN
# shellcheck source=Benchmarks/bench_lib.sh
source "$HERE/bench_lib.sh"
SUITE_BEFORE=none SUITE_DEFAULT_BEFORE= SUITE_DEFAULT_BUILD= SUITE_TABLES=
# shellcheck disable=SC1090
source "$SUITES_DIR/$SUITE.sh"
[ "$before_given" = 0 ] && BEFORE=$SUITE_DEFAULT_BEFORE
[ "$BEFORE" = none ] && BEFORE=
declare -F suite_needs_gpu > /dev/null || suite_needs_gpu() { [[ "$SUITE_NEEDS" != CPU* ]]; }
BENCH_GPU=1
suite_needs_gpu || BENCH_GPU=0
export BENCH_GPU

OUT_GIVEN=${out:-bench-results/$SUITE}
if [ "$dry" = 1 ]; then
  bench_target_list=$(bench_targets)  # (read once: the checks of every command use it)
  OUT=$(mktemp -d)
  BENCH_DRY_ROOT=$OUT
  bench_missing=$OUT/.missing
  : > "$bench_missing"
  exec 3>&1
else
  OUT=$OUT_GIVEN
  mkdir -p "$OUT" || { echo "bench.sh: cannot create the output folder $OUT" >&2; exit 2; }
  OUT=$(cd "$OUT" && pwd)
  rm -f "$OUT/steps.tsv" "$OUT/summary.md" "$OUT/summary.json"
fi
if [ -n "$build" ]; then BUILD=$build
elif [ -n "$SUITE_DEFAULT_BUILD" ]; then BUILD=$SUITE_DEFAULT_BUILD
elif [ "$BENCH_GPU" = 1 ]; then BUILD="build-bench"
else BUILD="build-bench-cpu"; fi
BEFORE_SRC=${BEFORE_SRC:-/tmp/bench-before-src}
BEFORE_BUILD=${BEFORE_BUILD:-/tmp/bench-before-build}
export OUT BUILD BEFORE BEFORE_SRC BEFORE_BUILD

if [ -n "$BEFORE" ]; then
  if [ "$SUITE_BEFORE" = none ]; then
    echo "bench.sh: $SUITE has no before measurement (--before is not for it)" >&2; exit 2
  fi
  if ! git rev-parse --verify --quiet "$BEFORE^{commit}" > /dev/null; then
    echo "bench.sh: --before $BEFORE names no commit of this checkout" >&2; exit 2
  fi
fi
if [ "$dry" = 0 ] && [ "$BENCH_GPU" = 1 ] && ! nvidia-smi -L > /dev/null 2>&1; then
  echo "bench.sh: $SUITE needs an NVIDIA GPU (nvidia-smi finds none); --dry-run shows its commands" >&2
  exit 2
fi

started=$(date -u +%Y-%m-%dT%H:%M:%SZ)
status=0
heading="bench.sh $SUITE at $(git log -1 --format='%h %s' 2> /dev/null | cut -c1-70)
device: $(bench_gpu_name); output: $OUT_GIVEN; build: $BUILD${BEFORE:+; before: $BEFORE in $BEFORE_BUILD}"
if [ "$dry" = 1 ]; then sed 's/^/# /' <<< "$heading" >&3; else sed 's/^/== /' <<< "$heading"; fi

# In a dry run the suites' display filters read logs no command wrote: they do nothing there
# (grep stays: suites choose their models with it).
bench_dry_filters() {
  for tool in sed cut head tail tee tar cat sort uniq nvidia-smi; do eval "$tool() { :; }"; done
}

run_suite_part() {
  if [ "$dry" = 1 ]; then
    ( bench_dry_filters; "$@" ) > /dev/null 2>&1
  else
    ( "$@" )
  fi
}

if [ "$no_build" = 0 ] && declare -F suite_build > /dev/null; then
  run_suite_part suite_build || status=1
fi
if [ "$build_only" = 0 ] && [ "$status" = 0 ]; then
  run_suite_part suite_run "${suite_args[@]}" || status=1
  if [ -n "$BEFORE" ] && [ "$SUITE_BEFORE" = rerun ]; then
    [ "$dry" = 1 ] && echo "# the same with $BEFORE's build, into \$OUT/before:" >&3
    mkdir -p "$OUT/before"
    OUT=$OUT/before BUILD=$BEFORE_BUILD run_suite_part suite_run "${suite_args[@]}" || status=1
  fi
fi

if [ "$dry" = 1 ]; then
  missing=$(sort -u "$bench_missing")
  rm -rf "$OUT"
  if [ -n "$missing" ]; then
    echo "# dry run: these do not resolve:" >&3
    sed 's/^/#   /' <<< "$missing" >&3
    exit 1
  fi
  echo "# dry run: every program, target and file resolves" >&3
  exit 0
fi

/usr/bin/python3 "$HERE/bench_summary.py" "$OUT" --suite "$SUITE" --status "$status" --started "$started" \
  --seconds "$(($(date +%s) - bench_start))" --device "$(bench_gpu_name)" --before "$BEFORE" \
  --tables "${SUITE_TABLES:-}" --command "$invocation" \
  || { echo "bench.sh: the summary failed" >&2; status=1; }
echo "== $SUITE: status $status; summary: $OUT_GIVEN/summary.md"
exit "$status"
