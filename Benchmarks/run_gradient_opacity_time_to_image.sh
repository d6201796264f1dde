#!/usr/bin/env bash
# Gradient opacity: which estimator gives a clean image first, and what the first frame that asks
# for gradients waits, on one GPU machine, from the repository root. Steps (each cut to the time
# left of $BUDGET seconds, default 570: a device call's limit is 600):
#   1. builds the OptiX and CUDA pipeline tests, gpu_evaluator_benchmark and
#      query_reduction_benchmark (Release, sm_90, OptiX when $OptiX_INSTALL_DIR has the headers);
#   2. runs the GPU tests of gradients and gradient opacity (OptixTraversal.*, CudaShading.*);
#   3. gpu_evaluator_benchmark --gradient on the shipped real models with the tangent rows timed
#      on 2^18 queries (the values' batch) and on the default (CudaEvaluatorOptions::
#      tangentAutotuneBatch): each row says how long its first gradient call took to choose the
#      tangent scale and configurations;
#   4. the time-to-image run of run_time_to_image.sh at 1024^2 on the shipped real models with a
#      gradient opacity ramp on every render (factor 0 below half the model's median |grad f|, 1
#      above twice it: flat regions fade): delta tracking, ratio tracking (majorant scale 1 and 4,
#      16 points per iteration) and unbiased ray marching, each against a 4096-frame
#      delta-tracking reference with the same ramp, and the GPU ray marcher at four steps.
#   OUT=dir bash Benchmarks/run_gradient_opacity_time_to_image.sh
# Results in $OUT (run.txt, the CSVs, evaluator_first_call.txt, logs/), all of them but the
# images in $OUT/gradient_opacity_tti.tar.gz.
OUT=${OUT:-./out}
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
BUILD=${INR_BUILD_DIR:-/tmp/bgo}
BUDGET=${BUDGET:-570}
CONFIGS=${INR_ESTIMATOR_CONFIGS:-"delta;ratio:1:16;ratio:4:16;march"}
RAMP=${INR_GRADIENT_OPACITY_MEDIAN:-"0.5,0,2,1"}
MODELS=${INR_MODELS:-$TIME_TO_IMAGE_MODELS}
mkdir -p "$OUT/logs"
status=0
# Seconds left of the budget, at least 1 (timeout 0 would mean no limit).
left() { local s=$((BUDGET - ($(date +%s) - gpu_start))); echo $((s > 1 ? s : 1)); }
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/gpu.txt"

stamp "configure and build"
gpu_build_with_before "$OUT/logs" -- query_reduction_benchmark gpu_evaluator_benchmark optix_traversal_tests \
  cuda_pipeline_tests

stamp "GPU tests of gradients and gradient opacity"
timeout $(($(left) < 150 ? $(left) : 150)) ctest --test-dir "$BUILD" -R "OptixTraversal|CudaShading" \
  --output-on-failure > "$OUT/logs/ctest.log" 2>&1 || status=1
grep -E "tests passed|Failed|\*\*\*|Not Run" "$OUT/logs/ctest.log" | head -12

stamp "the first gradient call: tangent rows timed on 2^18 queries, then on the default"
for m in $MODELS; do
  for b in 262144 default; do
    args=()
    [ "$b" = default ] || args=(--tangent-autotune-batch "$b")
    echo "-- $(basename "$m" .inr): tangent rows timed on $b queries" >> "$OUT/evaluator_first_call.txt"
    timeout 60 "$BUILD/Benchmarks/gpu_evaluator_benchmark" --gradient --batch 65536 --reps 5 "${args[@]}" \
      --only "$(basename "$m" .inr)" "$m" >> "$OUT/evaluator_first_call.txt" 2>&1 || status=1
  done
done
grep -E "^-- |chosen at the first call" "$OUT/evaluator_first_call.txt" | sed 's/(batch.*->/... ->/' | cut -c1-200

stamp "time to a clean image with gradient opacity ($RAMP x the median |grad f|)"
# shellcheck disable=SC2086
timeout $(($(left) > 16 ? $(left) - 15 : 1)) "$BUILD/Benchmarks/query_reduction_benchmark" "${TIME_TO_IMAGE_ARGS[@]}" \
  --configs "$CONFIGS" --gradient-opacity-median "$RAMP" --out "$OUT" $MODELS 2>&1 \
  | grep -v "per frame: init" > "$OUT/run.txt"
[ "${PIPESTATUS[0]}" = 0 ] || status=1
grep -E "^== |reference:|^   (delta|ratio|march|raymarch) " "$OUT/run.txt" | cut -c1-170
tar -czf "$OUT/gradient_opacity_tti.tar.gz" -C "$OUT" --exclude=images --exclude='*.tar.gz' .
stamp "done (status $status)"
exit $status
