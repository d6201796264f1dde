#!/usr/bin/env bash
# One command on a GPU machine (no ParaView needed): builds the engine with CUDA for this GPU,
# runs the GPU tests, then the evaluator benchmark against PyTorch fp16 on the same networks.
# Results (logs, CSV, PNG) go to ${OUT:-gpu-results}.
#   bash Benchmarks/run_gpu.sh [extra CMake args]
source "$(dirname "$0")/gpu_common.sh"
gpu_configure "$@"
cmake --build "$BUILD" -j "$(nproc)" > "$OUT/build.log" 2>&1 || { grep -E "error" "$OUT/build.log" | head -30; exit 1; }
gpu_ctest
echo "== evaluator benchmark"
models=$(ls Testing/Data/models/*.inr Testing/Data/real/*.inr 2>/dev/null)
"$BUILD/Benchmarks/gpu_evaluator_benchmark" --write-models "$OUT/models" --csv "$OUT/evaluator_ours.csv" $models \
  | tee "$OUT/evaluator_ours.txt"
python3 Benchmarks/pytorch_baseline.py --csv "$OUT/evaluator_torch.csv" "$OUT"/models/*.inr $models \
  | tee "$OUT/evaluator_torch.txt"
# torch.compile on the three paper-size networks only (compiling every model takes minutes).
python3 Benchmarks/pytorch_baseline.py --compile --csv "$OUT/evaluator_torch_compile.csv" "$OUT"/models/*.inr \
  | tee "$OUT/evaluator_torch_compile.txt"
python3 Benchmarks/compare_evaluators.py "$OUT/evaluator_ours.csv" "$OUT/evaluator_torch.csv" "$OUT/evaluator_compare" \
  | tee "$OUT/evaluator_compare.txt"
rm -rf "$OUT/models"
