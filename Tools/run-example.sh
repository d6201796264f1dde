#!/usr/bin/env bash
# The main job on the bundled example model: installs dependencies, builds, renders the model at
# three times through ParaView (pvpython + the INR Volume plugin) into example-output/, then
# describes it with the CLI, evaluates it at a few points and writes CLI slices/renders too.
# Another model: INR_EXAMPLE_MODEL=path/to/model.inr bash Tools/run-example.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash Tools/install-deps.sh
# Only what the example runs: the engine, the inr CLI and the ParaView plugin (no tests, no
# benchmark programs). The CUDA code is built as the test command builds it, so that
# Tools/run-tests.sh afterwards reuses this build: for the present GPU only where one is usable,
# compile-checked where none is (the renders then run on the CPU). Arguments given here decide
# instead (e.g. -DINR_ENABLE_CUDA=OFF).
example_args=(-DINR_BUILD_TESTS=OFF -DINR_BUILD_BENCHMARKS=OFF)
if [[ " $* " != *CMAKE_CUDA_ARCHITECTURES* && " $* " != *INR_CUDA_COMPILE_CHECK* ]]; then
  if nvidia-smi -L >/dev/null 2>&1; then
    example_args+=("-DINR_CUDA_COMPILE_CHECK=OFF")
  else
    example_args+=("-DINR_CUDA_COMPILE_CHECK=ON")
    echo "run-example: no usable GPU: the renders run on the CPU; CUDA code (if nvcc is found) is only compile-checked"
  fi
fi
bash Tools/build.sh "${example_args[@]}" "$@"
BUILD_DIR=${INR_BUILD_DIR:-build}
INR="$BUILD_DIR/bin/inr"
MODEL=${INR_EXAMPLE_MODEL:-Testing/Data/real/siren_cylinder_vorticity_small.inr}  # Gerris flow, real data
[ -f "$MODEL" ] || MODEL=Testing/Data/Plugin/clouds.inr  # plugin test model as a fallback
OUT=example-output
mkdir -p "$OUT"

# --- ParaView: open the model, show it as "INR Volume", render three times, each accumulated
# until its estimated PSNR over the volume's pixels reaches 40 dB (512 frames at most), the
# camera framed on the part the colour map shows.
PLUGIN_DIR="$BUILD_DIR/lib/paraview-plugins/InrVolume"
if command -v pvpython >/dev/null && [ -f "$PLUGIN_DIR/InrVolume.so" ]; then
  source Tools/xvfb.sh
  start_xvfb
  echo "== ParaView (pvpython + INR Volume plugin): $MODEL at three times"
  PV_PLUGIN_PATH="$(cd "$PLUGIN_DIR" && pwd)" pvpython --force-offscreen-rendering \
    Tools/paraview/render_inr.py "$MODEL" --count 3 --size 384 384 --frames 512 --converge 40 --out "$OUT" \
    $([ -f "${MODEL%.inr}.tf.json" ] && echo --tf "${MODEL%.inr}.tf.json")
  stop_xvfb
else
  echo "== ParaView plugin not built (no ParaView SDK?): skipping the ParaView renders"
fi

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
  TF=()
  [ -f "${MODEL%.inr}.tf.json" ] && TF=(--tf "${MODEL%.inr}.tf.json")  # the model's suggested colour map
  "$INR" render "$MODEL" "${TF[@]}" --time "$T" --size 512x512 --frames 64 --quiet -o "$OUT/render_t$i.png"
  i=$((i + 1))
done
echo "== wrote $(ls "$OUT" | wc -l) images to $OUT/"
