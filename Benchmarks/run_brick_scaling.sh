#!/usr/bin/env bash
# Sub-domain rendering over several GPUs without MPI (issues 16 and 31): for each model, one
# single-GPU render on GPU 0 (the 1-GPU image and timing), then for each split and each N in the
# lists, N parts at once, one process per GPU (CUDA_VISIBLE_DEVICES), composited by
# composite_bricks.py and compared with the 1-GPU image. The table (brick_scaling_summary.py) gives
# frame times and the render time to 40 dB read from the per-frame estimates.
# SPLIT (a list): pixels (the plugin's image-space split, `inr render --pixel-share I/N`; default),
# samples (`--sample-share I/N`: every GPU renders every pixel of its own frames) or bricks
# (`--brick I/N`).
# The single run and the pixel or brick parts stop at an estimated PSNR of TARGET dB over the
# volume (or MAX_FRAMES). The sample shares render fixed frame counts instead: share I renders
# ceil((F - I) / N) frames, F the single run's, so together they render exactly its frames and
# their frame-weighted mean is the 1-GPU image up to rounding (composite vs 1 GPU at equal frames).
# BACKEND=cpu INR_BIN=build/bin/inr: CPU processes instead (no build, no GPU): the single run
# uses every core, each of the N parallel ones nproc/N threads (CPU "ranks" on one machine).
# PYTHON: the interpreter with numpy for the compositing (default python3). TIME: the model time
# rendered (default 2, inside the cylinder and head models' ranges).
#   OUT=dir [N="2 4"] [SPLIT="pixels samples"] [TARGET=46] [MAX_FRAMES=3000] [SIZE=1024] \
#     bash Benchmarks/run_brick_scaling.sh MODEL.inr...
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
NS=${N:-2}
SPLITS=${SPLIT:-pixels}
for split in ${SPLITS//,/ }; do
  case "$split" in
    pixels | samples | bricks) ;;
    *) echo "run_brick_scaling.sh: SPLIT must list pixels, samples or bricks, got '$split'" >&2; exit 2 ;;
  esac
done
split_option() {
  case "$1" in pixels) echo --pixel-share ;; samples) echo --sample-share ;; bricks) echo --brick ;; esac
}
TARGET=${TARGET:-46}
MAX_FRAMES=${MAX_FRAMES:-3000}
SIZE=${SIZE:-1024}
SCRATCH=$(mktemp -d)  # the float images stay out of $OUT (16 MB each at 1024^2)
trap 'rm -rf "$SCRATCH"' EXIT
BACKEND=${BACKEND:-cuda}
if [ "$BACKEND" = cpu ]; then
  INR=${INR_BIN:?BACKEND=cpu needs INR_BIN=path/to/inr}
  nproc | sed 's/^/cpu cores: /' | tee "$OUT/gpus.txt"
else
  gpu_configure -DCMAKE_BUILD_TYPE=Release
  cmake --build "$BUILD" -j"$(nproc)" --target inr > "$OUT/build.log" 2>&1 || { tail -30 "$OUT/build.log"; exit 1; }
  INR=$BUILD/bin/inr
  nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$OUT/gpus.txt"
fi
# CPU threads of a run with `parts` processes at once (the CPU backend only).
threads_for() {
  if [ "$BACKEND" = cpu ]; then
    local per=$(( $(nproc) / $1 )); [ "$per" -ge 1 ] || per=1
    echo --threads "$per"
  fi
}
ms_now() { echo $(( $(date +%s%N) / 1000000 )); }
for model in "$@"; do
  name=$(basename "$model" .inr)
  tf="${model%.inr}.tf.json"
  common=(--time "${TIME:-2}" --size "${SIZE}x${SIZE}" --macrocells 64 --backend "$BACKEND" --quiet)
  [ -f "$tf" ] && common+=(--tf "$tf")
  converge=(--converge "$TARGET" --frames "$MAX_FRAMES")
  echo "== $name: 1 GPU"
  t0=$(ms_now)
  # A 1/1 split is the plain renderer; it writes the .npy and .brick.json the compositing reads.
  CUDA_VISIBLE_DEVICES=0 "$INR" render "$model" "${common[@]}" "${converge[@]}" $(threads_for 1) --pixel-share 0/1 \
    -o "$SCRATCH/$name.whole.npy" --stats-json "$OUT/$name.whole.stats.json" | tail -2
  echo "wall $(( $(ms_now) - t0 )) ms" | tee "$OUT/$name.whole.wall"
  if [ ! -f "$SCRATCH/$name.whole.brick.json" ]; then
    echo "$name: the 1-GPU run failed; skipped"
    continue
  fi
  cp "$SCRATCH/$name.whole.brick.json" "$OUT/"
  whole_frames=$("${PYTHON:-python3}" -c 'import json, sys; print(json.load(open(sys.argv[1]))["frames"])' \
                 "$SCRATCH/$name.whole.brick.json")
  for split in ${SPLITS//,/ }; do
    option=$(split_option "$split")
    for n in ${NS//,/ }; do
      tag="$name.$split$n"
      echo "== $name: $n parts ($split) on $n GPUs"
      t0=$(ms_now)
      pids=()
      for ((i = 0; i < n; i++)); do
        if [ "$split" = samples ]; then
          frames=(--frames $(( (whole_frames - i + n - 1) / n )))
        else
          frames=("${converge[@]}")
        fi
        CUDA_VISIBLE_DEVICES=$i "$INR" render "$model" "${common[@]}" "${frames[@]}" $(threads_for "$n") "$option" "$i/$n" \
          -o "$SCRATCH/$tag.b$i.npy" --stats-json "$OUT/$tag.b$i.stats.json" > "$OUT/$tag.b$i.log" 2>&1 &
        pids+=($!)
      done
      for p in "${pids[@]}"; do wait "$p" || echo "part process $p failed (log: $OUT/$tag.b*.log)"; done
      echo "wall $(( $(ms_now) - t0 )) ms" | tee "$OUT/$tag.wall"
      for ((i = 0; i < n; i++)); do cp "$SCRATCH/$tag.b$i.brick.json" "$OUT/" 2>/dev/null; done
      "${PYTHON:-python3}" Benchmarks/composite_bricks.py "$SCRATCH/$tag".b*.npy --reference "$SCRATCH/$name.whole.npy" \
        --min-psnr 40 -o "$OUT/$tag.composite.png" --csv "$OUT/$tag.csv" | tee "$OUT/$tag.composite.txt"
      rm -f "$SCRATCH/$tag".b*.npy
    done
  done
  rm -f "$SCRATCH/$name.whole.npy"
done
"${PYTHON:-python3}" Benchmarks/brick_scaling_summary.py "$OUT" "$@" | tee "$OUT/brick_scaling.txt"
