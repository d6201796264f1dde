#!/usr/bin/env bash
# The multi-GPU scaling table of issue 31 in one command: for each image size, each model and
# each split (pixel shares and sample shares), N = 1, 2, 4 GPUs of this machine
# (run_brick_scaling.sh per size), then one table, CSV and plot over all of them
# (brick_scaling_summary.py): frame time, time to 40 dB over the volume's pixels, frames, queries
# per GPU, the composite against the 1-GPU image, speed-up and efficiency.
# The single run stops at TARGET (default 41: past 40, so every row has a time to 40 dB) or
# MAX_FRAMES; sample shares render the single run's frames between them (run_brick_scaling.sh).
# Default models: the full-size real models whose time range holds the rendered time (TIME,
# default 2): coordnet_cylinder_u, ffn_mri_head, siren_cylinder_vorticity (siren_sphere_plate_
# vorticity starts at 3.5: OUT=another-dir TIME=5 bash Benchmarks/run_scaling_table.sh MODEL).
# TARGET and MAX_FRAMES are meant to keep the whole table within about 6 minutes on 4 H100s,
# after the build (`inr` is built once, first).
#   OUT=dir [SIZES="1024 2048"] [N="2 4"] [SPLIT="pixels samples"] [TARGET=41] [MAX_FRAMES=1500] \
#     bash Benchmarks/run_scaling_table.sh [MODEL.inr...]
# Output: OUT/scaling.txt (the table), OUT/scaling.csv, OUT/scaling.png, OUT/SIZE/ (per-run logs,
# statistics, composites).
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
OUT=${OUT:-scaling-results}
SIZES=${SIZES:-1024 2048}
export N=${N:-2 4} SPLIT=${SPLIT:-pixels samples} TARGET=${TARGET:-41} MAX_FRAMES=${MAX_FRAMES:-1500}
if [ "$#" -gt 0 ]; then
  models=("$@")
else
  models=(Testing/Data/real/{coordnet_cylinder_u,ffn_mri_head,siren_cylinder_vorticity}.inr)
fi
if [ "${BACKEND:-cuda}" != cpu ]; then
  gpus=$(nvidia-smi --list-gpus 2>/dev/null | wc -l)
  for n in ${N//,/ }; do
    [ "$n" -le "$gpus" ] || { echo "run_scaling_table.sh: N=$n needs $n GPUs, nvidia-smi lists $gpus" >&2; exit 2; }
  done
fi
# The compositing needs numpy: the first interpreter with it.
if [ -z "${PYTHON:-}" ]; then
  for py in python3 /usr/bin/python3; do
    if "$py" -c "import numpy" 2>/dev/null; then export PYTHON=$py; break; fi
  done
  [ -n "${PYTHON:-}" ] || { echo "run_scaling_table.sh: no python3 with numpy (set PYTHON)" >&2; exit 2; }
fi
mkdir -p "$OUT"
start=$SECONDS
dirs=()
for size in ${SIZES//,/ }; do
  echo "==== ${size}x${size}"
  OUT="$OUT/$size" SIZE=$size bash Benchmarks/run_brick_scaling.sh "${models[@]}" > "$OUT/run_$size.log" 2>&1
  grep -E "^== |failed|FAILED" "$OUT/run_$size.log"
  dirs+=("$OUT/$size")
done
"$PYTHON" Benchmarks/brick_scaling_summary.py "${dirs[@]}" "${models[@]}" --target 40 \
  --csv "$OUT/scaling.csv" --plot "$OUT/scaling.png" | tee "$OUT/scaling.txt"
echo "run_scaling_table.sh: $(( SECONDS - start )) s in all" | tee -a "$OUT/scaling.txt"
