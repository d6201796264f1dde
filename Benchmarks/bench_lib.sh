# Sourced by Benchmarks/bench.sh (the benchmark door) and, through it, by every suite in
# Benchmarks/suites/. Works from the repository root. What a suite sees:
#   OUT           the suite's output folder (raw logs, CSV, tables; summary.md/json written after)
#   BUILD         this tree's build folder; BEFORE_BUILD the BEFORE commit's (when BEFORE is set)
#   BEFORE        a commit whose tree is built beside this one (bench.sh --before COMMIT)
#   DRY_RUN       1 in a dry run: x prints each command instead of running it
#   x [timeout N] [env NAME=VALUE...] PROGRAM ARGS...   runs one command of the suite (a step): recorded in
#                 $OUT/steps.tsv (exit status, seconds, step, command); in a dry run printed and
#                 checked: a program in a build folder must be a CMake target of this tree, a
#                 script or a repository path among its arguments must exist
#   stamp MESSAGE a step's heading with the seconds since the run began (also names the steps)
#   bench_gpu_name  the GPU's name and driver (nvidia-smi; "none" without one)
#   TIME_TO_IMAGE_ARGS, TIME_TO_IMAGE_MODELS  the time-to-image protocol (issue 26): 1024^2,
#                 1.5 s of summed frame times (at least 8 frames) per configuration against a
#                 4096-frame delta-tracking reference, no orbit or heatmaps, the GPU ray marcher
#                 at four steps; on the shipped full-size real models
set -uo pipefail
BENCH_ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$BENCH_ROOT"
DRY_RUN=${DRY_RUN:-0}
BENCH_STEP=${BENCH_STEP:-setup}
bench_start=${bench_start:-$(date +%s)}

TIME_TO_IMAGE_ARGS=(--backend cuda --size 1024 --seconds 1.5 --min-frames 8 --reference-frames 4096 --orbit-steps 0
                    --heatmap-frames 0 --march-steps 64,128,256,512)
TIME_TO_IMAGE_MODELS="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr Testing/Data/real/coordnet_cylinder_u.inr"

stamp() {
  BENCH_STEP=$1
  echo "== $1 ($(($(date +%s) - bench_start)) s)"
  [ "$DRY_RUN" = 1 ] && echo "== $1" >&3
  return 0
}

# Every executable target of this tree's CMake files (add_executable, inr_add_benchmark,
# inr_add_gtest NAME), one per line: what a build folder's programs may be.
bench_targets() {
  if [ -z "${bench_target_list:-}" ]; then
    bench_target_list=$(grep -rhoE --include=CMakeLists.txt \
      "(add_executable|inr_add_benchmark|add_custom_target)\(\s*[A-Za-z0-9_]+|inr_add_gtest\(NAME\s+[A-Za-z0-9_]+|^\s+NAME\s+[A-Za-z0-9_]+_tests" \
      Kernels Tools Benchmarks Testing Plugin 2>/dev/null | sed -E 's/.*[( ]//' | sort -u)
  fi
  echo "$bench_target_list"
}
bench_is_target() {
  [ -n "${bench_target_list:-}" ] || bench_target_list=$(bench_targets)
  [[ $'\n'"$bench_target_list"$'\n' == *$'\n'"$1"$'\n'* ]]
}

# A command as a shell would read it back, in bench_quoted: words quoted only where they need it.
bench_quote() {
  local w q out=()
  for w in "$@"; do
    if [[ "$w" =~ ^[A-Za-z0-9_./:=,+@%^-]+$ ]]; then out+=("$w"); else printf -v q %q "$w"; out+=("$q"); fi
  done
  bench_quoted="${out[*]}"
}

# bench_check WORD...: in a dry run, says what in a command does not resolve (appended to
# $bench_missing, printed after the command).
bench_check() {
  local prog=$1 a base
  shift
  local problems=()
  case "$prog" in
    "$BUILD"/* | "${BEFORE_BUILD:-/nonexistent}"/* | */build*/bin/* | */Benchmarks/*_benchmark)
      base=$(basename "$prog")
      bench_is_target "$base" || problems+=("$base is no CMake target of this tree") ;;
    python3 | /usr/bin/python3 | pvpython | pvbatch | bash | "${PYTHON:-python3}")
      for a in "$@"; do
        case "$a" in -*) ;; *) [ -e "$a" ] || problems+=("$a does not exist"); break ;; esac
      done ;;
    */*) [ -e "$prog" ] || problems+=("$prog does not exist") ;;
    cmake)
      local want=0
      for a in "$@"; do
        if [ "$want" = 1 ]; then bench_is_target "$a" || problems+=("cmake target $a is no CMake target of this tree"); continue; fi
        [ "$a" = --target ] && want=1
      done ;;
    ninja)
      local skip=0
      for a in "$@"; do
        if [ "$skip" = 1 ]; then skip=0; continue; fi
        case "$a" in -C | -j | -l | -k) skip=1 ;; -*) ;;
          *) bench_is_target "$a" || problems+=("ninja target $a is no CMake target of this tree") ;; esac
      done ;;
  esac
  for a in "$@"; do
    a=${a#*=}
    case "$a" in
      Testing/* | Benchmarks/* | Tools/*) [ -e "$a" ] || problems+=("$a does not exist") ;;
    esac
  done
  for a in "${problems[@]}"; do
    echo "   MISSING: $a" >&3
    echo "$a" >> "$bench_missing"
  done
}

# x [timeout N] [env NAME=VALUE...] PROGRAM ARGS...: one recorded command (see the header).
x() {
  local words=("$@") i=0
  [ "${words[0]}" = timeout ] && i=2
  if [ "${words[$i]}" = env ]; then
    i=$((i + 1))
    while [[ "${words[$i]}" == *=* ]]; do i=$((i + 1)); done
  fi
  if [ "$DRY_RUN" = 1 ]; then
    bench_quote "$@"
    echo "+ ${bench_quoted//$BENCH_DRY_ROOT/\$OUT}" >&3
    bench_check "${words[@]:$i}"
    return 0
  fi
  local t0 rc
  t0=$(date +%s%N)
  "$@"
  rc=$?
  bench_quote "$@"
  printf '%s\t%s\t%s\t%s\n' "$rc" "$(( ($(date +%s%N) - t0) / 1000000 ))" "$BENCH_STEP" "$bench_quoted" \
    >> "$OUT/steps.tsv"
  return $rc
}

bench_gpu_name() {
  if [ "$DRY_RUN" = 1 ]; then echo "(dry run)"; return; fi
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2> /dev/null | head -1 | grep . || echo none
}

# The GPU's compute capability without the dot (90 where nvidia-smi says nothing).
bench_cuda_arch() {
  local arch=
  [ "$DRY_RUN" = 1 ] || arch=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2> /dev/null | head -1 | tr -d .)
  echo "${arch:-90}"
}

# bench_configure SRC BUILD [extra CMake args]: a Release build without ParaView; with CUDA for
# this machine's GPU (sm_90 where none answers) unless BENCH_GPU=0. OptiX where
# $OptiX_INSTALL_DIR is set.
bench_configure() {
  local src=$1 build=$2
  shift 2
  local cuda=(-DINR_ENABLE_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES="$(bench_cuda_arch)")
  [ "${BENCH_GPU:-1}" = 0 ] && cuda=(-DINR_ENABLE_CUDA=OFF)
  x cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DINR_ENABLE_PARAVIEW=OFF "${cuda[@]}" \
    ${OptiX_INSTALL_DIR:+-DOptiX_INSTALL_DIR="$OptiX_INSTALL_DIR"} "$@"
}

# bench_source_of COMMIT DIR: that commit's tree in DIR (git archive).
bench_source_of() {
  if [ "$DRY_RUN" = 1 ]; then echo "+ git archive $1 | tar -x -C $2" >&3; return 0; fi
  rm -rf "$2" && mkdir -p "$2" && git archive "$1" | tar -x -C "$2"
}

# bench_spills BUILD_LOG: the Hopper kernels' spills and any wgmma serialisation warning (ptxas
# C75xx) in a build's log, and every spill line counted.
bench_spills() {
  [ "$DRY_RUN" = 1 ] && return 0
  grep -E "spill|C75[0-9][0-9]" "$1" | grep -iE "hopper|C75" | sed 's/.*function //' | cut -c1-200
  grep -iE "spill" "$1" | sed 's/.*function//' | sort | uniq -c | head -20
}

# bench_build TARGETS... [-- BEFORE_TARGETS...]: TARGETS built in $BUILD ($BENCH_JOBS jobs,
# default every core) and, when BEFORE names a commit, BEFORE_TARGETS (default the same) of its tree in
# $BEFORE_BUILD beside it (4 jobs, in the background, during this build). Logs in $OUT/logs.
# Each build is cut at $BENCH_BUILD_SECONDS (default 500). Returns 1 where a build fails.
bench_build() {
  local targets=() before_targets=() seen_dash=0 log="$OUT/logs" limit=${BENCH_BUILD_SECONDS:-500}
  for a in "$@"; do
    if [ "$a" = -- ]; then seen_dash=1; continue; fi
    if [ "$seen_dash" = 1 ]; then before_targets+=("$a"); else targets+=("$a"); fi
  done
  [ "${#before_targets[@]}" -gt 0 ] || before_targets=("${targets[@]}")
  mkdir -p "$log"
  stamp "configure and build (this tree${BEFORE:+, and $BEFORE beside it})"
  bench_configure . "$BUILD" > "$log/configure.log" 2>&1 || { tail -30 "$log/configure.log"; return 1; }
  local before_pid=
  if [ -n "${BEFORE:-}" ]; then
    bench_source_of "$BEFORE" "$BEFORE_SRC"
    bench_configure "$BEFORE_SRC" "$BEFORE_BUILD" > "$log/configure_before.log" 2>&1 \
      || { tail -30 "$log/configure_before.log"; return 1; }
    x timeout "$limit" ninja -C "$BEFORE_BUILD" -j4 "${before_targets[@]}" > "$log/build_before.log" 2>&1 &
    before_pid=$!
  fi
  x timeout "$limit" ninja -C "$BUILD" -j"${BENCH_JOBS:-$(nproc)}" "${targets[@]}" > "$log/build.log" 2>&1 \
    || { grep -E "error|FAILED" "$log/build.log" | head -30; [ -n "$before_pid" ] && kill "$before_pid"; return 1; }
  if [ -n "$before_pid" ] && ! wait "$before_pid"; then
    echo "(the build of BEFORE=$BEFORE failed)"; grep -E "error|FAILED" "$log/build_before.log" | head; return 1
  fi
  bench_spills "$log/build.log"
  return 0
}
