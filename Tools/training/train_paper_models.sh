#!/bin/sh
# Train the paper-size INRs (SIREN 4->256x5->1 x2, Reed FFN 6x256, CoordNet 48/6) on the real
# datasets in .data/ and write NAME.inr, NAME.json (settings, PSNR), NAME.tf.json (suggested
# transfer function) and summary.json to OUTDIR.
#
#   Tools/training/train_paper_models.sh OUTDIR [MINUTES_PER_MODEL] [extra train.py options]
#
# Needs only python3 with torch and numpy (no scipy, no Gerris): the datasets must already be
# in .data/ (made by Tools/data/, see Docs/DATA.md; about 43 MB of .npy + .json):
#   gerris_cylinder_vorticity, gerris_sphere_plate_vorticity, gerris_cylinder_u,
#   mri_head_deform
# Default training budget 1.6 min per model (Docs/DATA.md has the whole run's time). Uses CUDA when present, the CPU otherwise. PYTHON overrides the interpreter
# (default: the first of python3, /usr/bin/python3 that imports torch and numpy).
set -eu
if [ $# -lt 1 ]; then
    echo "usage: $0 OUTDIR [MINUTES_PER_MODEL] [train.py options]" >&2
    exit 2
fi
OUT=$1
shift
MIN=1.6
if [ $# -ge 1 ]; then
    MIN=$1
    shift
fi
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
if [ -z "${PYTHON:-}" ]; then
    # the first interpreter that has torch and numpy (GPU machine: python3 on PATH;
    # Debian development machine: /usr/bin/python3, the PATH one may be a pyenv without torch)
    for c in python3 /usr/bin/python3; do
        if "$c" -c "import torch, numpy" > /dev/null 2>&1; then PYTHON=$c; break; fi
    done
    if [ -z "${PYTHON:-}" ]; then
        echo "$0: no python3 with torch and numpy found (set PYTHON=...)" >&2
        exit 1
    fi
fi
for d in gerris_cylinder_vorticity gerris_sphere_plate_vorticity gerris_cylinder_u \
         mri_head_deform; do
    if [ ! -f "$REPO/.data/$d.npy" ] || [ ! -f "$REPO/.data/$d.json" ]; then
        echo "$0: missing $REPO/.data/$d.npy/.json (generate with Tools/data/, Docs/DATA.md)" >&2
        exit 1
    fi
done
mkdir -p "$OUT"
exec "$PYTHON" "$HERE/train.py" --config paper --device auto --minutes "$MIN" \
    --data "$REPO/.data" --out "$OUT" "$@"
