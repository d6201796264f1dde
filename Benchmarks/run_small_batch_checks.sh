#!/usr/bin/env bash
# Issue 30's small-batch checks on one GPU machine (an H100 or H200), from the repository root:
# builds the engine with CUDA for sm_90 (only the targets below), runs the GPU evaluator tests
# (every fused kernel configuration against the CPU reference and the fp16 emulation), then, side
# by side in one run, the evaluator at batch sizes 2 k .. 2 M with the wgmma kernel's blocks of
# two consumers only (the candidates before one-consumer blocks) and autotuned over both, the
# hash-grid network on ray-ordered against random points, and the frame rows of the shipped real
# models with both candidate sets.
# Logs and CSV go to $OUT (default ./out); about 9 minutes (the build takes half).
#   bash Benchmarks/run_small_batch_checks.sh
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
OUT=${OUT:-./out}
BUILD=${INR_BUILD_DIR:-/tmp/bsb}
mkdir -p "$OUT"
start=$(date +%s)
stamp() { echo "== $1 ($(($(date +%s) - start)) s)"; }
status=0

nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
git log -1 --format='%H %s' > "$OUT/commit.txt" 2>/dev/null

stamp configure
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES=90 > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }
stamp build
timeout 360 ninja -C "$BUILD" -j16 cuda_evaluator_tests gpu_evaluator_benchmark gpu_render_benchmark \
  > "$OUT/build.log" 2>&1 || { grep -E "error|FAILED" "$OUT/build.log" | head -30; exit 1; }
grep -iE "spill" "$OUT/build.log" | sed 's/.*function//' | sort | uniq -c | head -20

stamp "GPU evaluator tests"
timeout 200 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." --output-on-failure > "$OUT/ctest_cuda.log" 2>&1
grep -E "tests passed|Failed|\*\*\*" "$OUT/ctest_cuda.log" | head -10
grep -q "100% tests passed" "$OUT/ctest_cuda.log" || status=1
"$BUILD/Kernels/Evaluator/Cuda/cuda_evaluator_tests" --gtest_filter='*Wgmma*' 2>&1 | grep -E "consumers|1x64|2x64|OK|FAILED" \
  | grep -E "paper|FAILED|OK" | cut -c1-200 | head -24

bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
real=(Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr Testing/Data/real/coordnet_cylinder_u.inr)
sizes=2048,8192,32768,262144,2097152
for consumers in 2 0; do
  stamp "evaluator at batch sizes $sizes, wgmma consumers ${consumers/0/autotuned (1 or 2)}"
  timeout 240 "$bench" --batches "$sizes" --wgmma-consumers "$consumers" --csv "$OUT/batches_consumers$consumers.csv" \
    "${real[@]}" > "$OUT/batches_consumers$consumers.txt" 2>&1
  grep -vE "^\s+fused launch" "$OUT/batches_consumers$consumers.txt"
  grep -E "^\s+fused launch" "$OUT/batches_consumers$consumers.txt" | sed 's/.*-> /    -> /' | cut -c1-220
done

stamp "hash-grid network, ray-ordered against random points (batch 2^21 and 8192)"
for pts in random rays; do
  timeout 90 "$bench" --only hashgrid --points "$pts" --batches 8192,2097152 --csv "$OUT/hashgrid_$pts.csv" \
    > "$OUT/hashgrid_$pts.txt" 2>&1
  grep -vE "^\s+fused launch" "$OUT/hashgrid_$pts.txt"
done

render="$BUILD/Benchmarks/gpu_render_benchmark"
for consumers in 2 0; do
  stamp "frames, shipped real models, 1024^2, wgmma consumers ${consumers/0/autotuned}"
  timeout 200 "$render" --no-paper --no-baselines --frames 30 --wgmma-consumers "$consumers" \
    --csv "$OUT/render_consumers$consumers.csv" "${real[@]}" > "$OUT/render_consumers$consumers.txt" 2>&1
  grep -E "^==|evaluator|ms/frame|^4b|^group" "$OUT/render_consumers$consumers.txt" | cut -c1-160 | head -30
done

stamp "done (status $status)"
exit $status
