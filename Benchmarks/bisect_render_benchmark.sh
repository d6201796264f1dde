#!/usr/bin/env bash
# Builds gpu_render_benchmark at each commit given (from a git bundle of the repository at
# build-xfer/main.bundle: `git bundle create build-xfer/main.bundle main`) in parallel and runs
# the benchmark scenes twice per build, alternating; results in $OUT. How the traversal
# regression of e7b64c6 was found (Benchmarks/RESULTS.md).
#   OUT=dir bash Benchmarks/bisect_render_benchmark.sh COMMIT...
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-bisect-results}; mkdir -p "$OUT"
ROOT=$PWD; W=$(mktemp -d)
git clone -q build-xfer/main.bundle $W/repo -b main || exit 1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
build() {
  c=$1; d=$W/src-$c
  git -C $W/repo worktree add -q $d $c
  cmake -S $d -B $d/b -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DINR_BUILD_TESTS=OFF -DCMAKE_CUDA_ARCHITECTURES=90 -DCMAKE_BUILD_TYPE=Release > $W/cfg-$c.log 2>&1
  ninja -C $d/b -j4 gpu_render_benchmark > $W/build-$c.log 2>&1 || { echo "build $c failed"; tail -20 $W/build-$c.log; }
}
COMMITS="$*"
for c in $COMMITS; do build $c & done; wait
R=$ROOT/Testing/Data/real
for r in 1 2; do for c in $COMMITS; do
  B=$(find $W/src-$c/b -name gpu_render_benchmark -type f | head -1)
  echo "== $c run $r"; $B --no-paper --no-baselines --frames 30 $R/siren_cylinder_vorticity.inr $R/ffn_mri_head.inr 2>&1 | tee $OUT/bench_${c}_$r.txt | grep "^4b"
done; done
