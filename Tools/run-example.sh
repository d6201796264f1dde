#!/usr/bin/env bash
# The main job on the bundled example model: installs dependencies, builds, then describes the
# model, evaluates it at a few points and renders it at three times into example-output/.
# Another model: INR_EXAMPLE_MODEL=path/to/model.inr bash Tools/run-example.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash Tools/install-deps.sh
bash Tools/build.sh "$@"
BUILD_DIR=${INR_BUILD_DIR:-build}
INR="$BUILD_DIR/Tools/inr/inr"
MODEL=${INR_EXAMPLE_MODEL:-Testing/Data/models/siren_blobs.inr}
OUT=example-output
mkdir -p "$OUT"

echo "== inr info $MODEL"
"$INR" info "$MODEL"
read -r T0 T1 < <("$INR" info "$MODEL" --json | /usr/bin/python3 -c \
  'import json,sys; j=json.load(sys.stdin); print(*j["time_range"])')
read -r CX CY CZ < <("$INR" info "$MODEL" --json | /usr/bin/python3 -c \
  'import json,sys; b=json.load(sys.stdin)["bounds"]; print((b[0]+b[1])/2, (b[2]+b[3])/2, (b[4]+b[5])/2)')
echo "== inr eval at the box centre, t = $T0 and $T1"
for T in "$T0" "$T1"; do echo "$CX $CY $CZ" | "$INR" eval "$MODEL" --time "$T"; done

TIMES=$(/usr/bin/python3 -c "t0,t1=$T0,$T1; print(*[t0+f*(t1-t0) for f in (0.0,0.5,1.0)])")
i=0
for T in $TIMES; do
  "$INR" slice "$MODEL" --time "$T" --axis z --size 256 -o "$OUT/slice_t$i.png"
  if "$INR" render --help >/dev/null 2>&1; then
    "$INR" render "$MODEL" --time "$T" --size 512x512 --frames 64 -o "$OUT/render_t$i.png"
  fi
  i=$((i + 1))
done
echo "== wrote $(ls "$OUT" | wc -l) images to $OUT/"
