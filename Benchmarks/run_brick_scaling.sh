#!/usr/bin/env bash
# Sub-domain rendering over several GPUs without MPI (issue 16, item 6): for each model, one
# `inr render --pixel-share 0/1` (or --brick 0/1) on GPU 0 (the single-GPU image and timing), then N parts at once,
# one process per GPU (CUDA_VISIBLE_DEVICES), composited front to back by composite_bricks.py
# and compared with the single-GPU image. Each run stops at an estimated PSNR of TARGET dB over
# the volume (or MAX_FRAMES); the table (brick_scaling_summary.py) gives frame times and the
# render time to 40 dB read from the per-frame estimates.
# SPLIT=pixels (default: the plugin's image-space split, `inr render --pixel-share I/N`) or
# SPLIT=bricks (`--brick I/N`).
# BACKEND=cpu INR_BIN=build/bin/inr: CPU processes instead (no build, no GPU): the single run
# uses every core, each of the N parallel ones nproc/N threads (CPU "ranks" on one machine).
# PYTHON: the interpreter with numpy for the compositing (default python3).
#   OUT=dir [N=2] [SPLIT=pixels] [TARGET=46] [MAX_FRAMES=3000] [SIZE=1024] bash Benchmarks/run_brick_scaling.sh MODEL.inr...
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
N=${N:-2}
SPLIT=${SPLIT:-pixels}
case "$SPLIT" in
  pixels) SPLIT_OPTION=--pixel-share ;;
  bricks) SPLIT_OPTION=--brick ;;
  *) echo "run_brick_scaling.sh: SPLIT must be pixels or bricks, got '$SPLIT'" >&2; exit 2 ;;
esac
TARGET=${TARGET:-46}
MAX_FRAMES=${MAX_FRAMES:-3000}
SIZE=${SIZE:-1024}
SCRATCH=$(mktemp -d)  # the float images stay out of $OUT (16 MB each at 1024^2)
trap 'rm -rf "$SCRATCH"' EXIT
BACKEND=${BACKEND:-cuda}
if [ "$BACKEND" = cpu ]; then
  INR=${INR_BIN:?BACKEND=cpu needs INR_BIN=path/to/inr}
  per=$(( $(nproc) / N )); [ "$per" -ge 1 ] || per=1
  whole_args=(--threads "$(nproc)")
  part_args=(--threads "$per")
  nproc | sed 's/^/cpu cores: /' | tee "$OUT/gpus.txt"
else
  gpu_configure -DCMAKE_BUILD_TYPE=Release
  cmake --build "$BUILD" -j"$(nproc)" --target inr > "$OUT/build.log" 2>&1 || { tail -30 "$OUT/build.log"; exit 1; }
  INR=$BUILD/bin/inr
  whole_args=()
  part_args=()
  nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$OUT/gpus.txt"
fi
for model in "$@"; do
  name=$(basename "$model" .inr)
  tf="${model%.inr}.tf.json"
  common=(--time 2 --size "${SIZE}x${SIZE}" --macrocells 64 --backend "$BACKEND" --converge "$TARGET"
          --frames "$MAX_FRAMES" --quiet)
  [ -f "$tf" ] && common+=(--tf "$tf")
  echo "== $name: 1 GPU"
  t0=$(date +%s%N)
  CUDA_VISIBLE_DEVICES=0 "$INR" render "$model" "${common[@]}" "${whole_args[@]}" "$SPLIT_OPTION" 0/1 -o "$SCRATCH/$name.whole.npy" \
    --stats-json "$OUT/$name.whole.stats.json" | tail -2
  echo "wall $(( ($(date +%s%N) - t0) / 1000000 )) ms" | tee "$OUT/$name.whole.wall"
  echo "== $name: $N parts ($SPLIT) on $N GPUs"
  t0=$(date +%s%N)
  pids=()
  for ((i = 0; i < N; i++)); do
    CUDA_VISIBLE_DEVICES=$i "$INR" render "$model" "${common[@]}" "${part_args[@]}" "$SPLIT_OPTION" "$i/$N" -o "$SCRATCH/$name.b$i.npy" \
      --stats-json "$OUT/$name.b$i.stats.json" > "$OUT/$name.b$i.log" 2>&1 &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || echo "brick process $p failed"; done
  echo "wall $(( ($(date +%s%N) - t0) / 1000000 )) ms" | tee "$OUT/$name.bricks.wall"
  cp "$SCRATCH/$name.whole.brick.json" "$OUT/"
  for ((i = 0; i < N; i++)); do cp "$SCRATCH/$name.b$i.brick.json" "$OUT/"; done
  "${PYTHON:-python3}" Benchmarks/composite_bricks.py "$SCRATCH/$name".b*.npy --reference "$SCRATCH/$name.whole.npy" \
    --min-psnr 40 -o "$OUT/$name.composite.png" --csv "$OUT/$name.bricks.csv" | tee "$OUT/$name.composite.txt"
done
"${PYTHON:-python3}" Benchmarks/brick_scaling_summary.py "$OUT" "$@" | tee "$OUT/brick_scaling.txt"
