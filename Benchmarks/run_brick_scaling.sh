#!/usr/bin/env bash
# Sub-domain rendering over several GPUs without MPI (issue 16, item 6): for each model, one
# `inr render --brick 0/1` on GPU 0 (the single-GPU image and timing), then N bricks at once,
# one process per GPU (CUDA_VISIBLE_DEVICES), composited front to back by composite_bricks.py
# and compared with the single-GPU image. Each run stops at an estimated PSNR of TARGET dB over
# the volume (or MAX_FRAMES); the table (brick_scaling_summary.py) gives frame times and the
# render time to 40 dB read from the per-frame estimates.
#   OUT=dir [N=2] [TARGET=46] [MAX_FRAMES=3000] [SIZE=1024] bash Benchmarks/run_brick_scaling.sh MODEL.inr...
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
N=${N:-2}
TARGET=${TARGET:-46}
MAX_FRAMES=${MAX_FRAMES:-3000}
SIZE=${SIZE:-1024}
SCRATCH=$(mktemp -d)  # the float images stay out of $OUT (16 MB each at 1024^2)
trap 'rm -rf "$SCRATCH"' EXIT
gpu_configure -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD" -j"$(nproc)" --target inr > "$OUT/build.log" 2>&1 || { tail -30 "$OUT/build.log"; exit 1; }
INR=$BUILD/bin/inr
nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$OUT/gpus.txt"
for model in "$@"; do
  name=$(basename "$model" .inr)
  tf="${model%.inr}.tf.json"
  common=(--time 2 --size "${SIZE}x${SIZE}" --macrocells 64 --backend cuda --converge "$TARGET"
          --frames "$MAX_FRAMES" --quiet)
  [ -f "$tf" ] && common+=(--tf "$tf")
  echo "== $name: 1 GPU"
  t0=$(date +%s.%N)
  CUDA_VISIBLE_DEVICES=0 "$INR" render "$model" "${common[@]}" --brick 0/1 -o "$SCRATCH/$name.whole.npy" \
    --stats-json "$OUT/$name.whole.stats.json" | tail -2
  echo "wall $(echo "$(date +%s.%N) - $t0" | bc) s" | tee "$OUT/$name.whole.wall"
  echo "== $name: $N bricks on $N GPUs"
  t0=$(date +%s.%N)
  pids=()
  for ((i = 0; i < N; i++)); do
    CUDA_VISIBLE_DEVICES=$i "$INR" render "$model" "${common[@]}" --brick "$i/$N" -o "$SCRATCH/$name.b$i.npy" \
      --stats-json "$OUT/$name.b$i.stats.json" > "$OUT/$name.b$i.log" 2>&1 &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || echo "brick process $p failed"; done
  echo "wall $(echo "$(date +%s.%N) - $t0" | bc) s" | tee "$OUT/$name.bricks.wall"
  cp "$SCRATCH/$name.whole.brick.json" "$OUT/"
  for ((i = 0; i < N; i++)); do cp "$SCRATCH/$name.b$i.brick.json" "$OUT/"; done
  python3 Benchmarks/composite_bricks.py "$SCRATCH/$name".b*.npy --reference "$SCRATCH/$name.whole.npy" \
    -o "$OUT/$name.composite.png" --csv "$OUT/$name.bricks.csv" | tee "$OUT/$name.composite.txt"
done
python3 Benchmarks/brick_scaling_summary.py "$OUT" "$@" | tee "$OUT/brick_scaling.txt"
