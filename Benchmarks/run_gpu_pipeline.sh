#!/usr/bin/env bash
# One command on a GPU machine (no ParaView needed): builds the engine with CUDA for this GPU,
# runs the GPU tests (ctest -L cuda: evaluator and pipeline), then the end-to-end render
# benchmark (groups 4b-4d) on the paper-size architectures and the model files.
# Results (logs, CSV, PNG) go to ${OUT:-gpu-results}.
#   bash Benchmarks/run_gpu_pipeline.sh [extra benchmark args, e.g. --size 512 --frames 10]
source "$(dirname "$0")/gpu_common.sh"
nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv,noheader > "$OUT/gpu.txt" 2>&1
gpu_configure
cmake --build "$BUILD" -j "$(nproc)" --target cuda_pipeline_tests cuda_evaluator_tests gpu_render_benchmark \
  > "$OUT/build.log" 2>&1 || { grep -E "error" -A3 "$OUT/build.log" | head -40; exit 1; }
gpu_ctest --timeout 900
# The pipeline tests' printed PSNRs and errors (ctest keeps them only on failure).
"$BUILD/Kernels/Render/Cuda/cuda_pipeline_tests" > "$OUT/cuda_pipeline_tests.txt" 2>&1
echo "== render benchmark"
models=$(ls Testing/Data/real/*.inr Testing/Data/models/*.inr 2>/dev/null)
"$BUILD/Benchmarks/gpu_render_benchmark" --csv "$OUT/render.csv" "$@" $models 2>&1 | tee "$OUT/render.txt"
python3 Benchmarks/plot_render_benchmark.py "$OUT/render.csv" "$OUT/render" 2>&1 | tail -3
