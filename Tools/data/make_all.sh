#!/bin/sh
# Make every real dataset in .data/ (Docs/DATA.md): the MR head deformation (seconds) and the
# two Gerris CFD cases (run in parallel, nice'd; ~5-8 min of CPU each, longer on a busy
# machine). Needs: apt-get install gerris libgfs-dev pkg-config python3-numpy python3-scipy
#   Tools/data/make_all.sh [OUTDIR]     (default: .data in the repository root)
set -eu
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
OUT=${1:-$REPO/.data}
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
mkdir -p "$OUT/logs"
"$PY" "$HERE/make_mri_deform.py" --out "$OUT" > "$OUT/logs/mri_head_deform.log"
nice -n 10 "$PY" "$HERE/gerris_flow.py" cylinder --out "$OUT" > "$OUT/logs/gerris_cylinder.log" 2>&1 &
P1=$!
nice -n 10 "$PY" "$HERE/gerris_flow.py" sphere_plate --out "$OUT" > "$OUT/logs/gerris_sphere_plate.log" 2>&1 &
P2=$!
wait $P1
wait $P2
rm -f "$OUT"/work/gerris_*/points.txt
ls -l "$OUT"/*.npy
