#!/usr/bin/env bash
# One command on a GPU machine (no ParaView needed): builds the engine with CUDA for this GPU,
# runs the GPU tests, then the evaluator benchmark against PyTorch fp16 on the same networks.
# Results (logs, CSV, PNG) go to ${OUT:-gpu-results}.
#   bash Benchmarks/run_gpu.sh [extra CMake args]
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu-results}
mkdir -p "$OUT"
BUILD=${INR_BUILD_DIR:-build-gpu}
arch=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d .)
cmake -S . -B "$BUILD" -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DCMAKE_CUDA_ARCHITECTURES="${arch:-90}" "$@" \
  > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }
cmake --build "$BUILD" -j "$(nproc)" > "$OUT/build.log" 2>&1 || { grep -E "error" "$OUT/build.log" | head -30; exit 1; }
echo "== GPU tests"
ctest --test-dir "$BUILD" -L cuda --output-on-failure 2>&1 | tee "$OUT/ctest_cuda.log" | grep -vE "^\s*(Start|Test command)" | tail -40
echo "== evaluator benchmark"
models=$(ls Testing/Data/models/*.inr Testing/Data/real/*.inr 2>/dev/null)
"$BUILD/Benchmarks/gpu_evaluator_benchmark" --write-models "$OUT/models" --csv "$OUT/evaluator_ours.csv" $models \
  | tee "$OUT/evaluator_ours.txt"
python3 Benchmarks/pytorch_baseline.py --csv "$OUT/evaluator_torch.csv" "$OUT"/models/*.inr $models \
  | tee "$OUT/evaluator_torch.txt"
python3 Benchmarks/compare_evaluators.py "$OUT/evaluator_ours.csv" "$OUT/evaluator_torch.csv" "$OUT/evaluator_compare" \
  | tee "$OUT/evaluator_compare.txt"
rm -rf "$OUT/models"
