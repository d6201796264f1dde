# Gradient opacity: which estimator gives a clean image first, and what the first frame that asks
# for gradients waits (issue 33). Steps (each cut to the time left of BUDGET seconds):
#   1. the GPU tests of gradients and gradient opacity (OptixTraversal.*, CudaShading.*);
#   2. gpu_evaluator_benchmark --gradient on the shipped real models with the tangent rows timed
#      on 2^18 queries (the values' batch) and on the default (CudaEvaluatorOptions::
#      tangentAutotuneBatch): each row says how long its first gradient call took to choose the
#      tangent scale and configurations (evaluator_first_call.txt);
#   3. the time-to-image protocol (the time-to-image suite) at 1024^2 on the shipped real models
#      with a gradient opacity ramp on every render (factor 0 below half the model's median
#      |grad f|, 1 above twice it: flat regions fade): delta tracking, ratio tracking (majorant
#      scale 1 and 4, 16 points per iteration) and unbiased ray marching, each against a
#      4096-frame delta-tracking reference with the same ramp, and the GPU ray marcher at four
#      steps (run.txt, the CSVs).
# All of it but the images in OUT/gradient_opacity_tti.tar.gz.
SUITE_ABOUT="gradient opacity: time to a clean image with a ramp, the first gradient call's wait (query_reduction_benchmark)"
SUITE_COST="about 9.5 min on one H100 (kept within BUDGET)"
SUITE_NEEDS="GPU (OptiX headers for the OptiX tests)"
SUITE_BEFORE=rerun
SUITE_HELP='BUDGET=570        seconds for the whole run, build included
CONFIGS=delta;ratio:1:16;ratio:4:16;march   estimator configurations
RAMP=0.5,0,2,1    the gradient opacity ramp, in units of the median |grad f| (--gradient-opacity-median)
MODELS=...        the models (default: the three full-size real models)'
SUITE_TABLES="run.txt"

suite_build() {
  bench_build query_reduction_benchmark gpu_evaluator_benchmark optix_traversal_tests cuda_pipeline_tests
}

suite_run() {
  local status=0 m b args
  local configs=${CONFIGS:-"delta;ratio:1:16;ratio:4:16;march"} ramp=${RAMP:-"0.5,0,2,1"}
  local models=${MODELS:-$TIME_TO_IMAGE_MODELS}
  # Seconds left of the budget, at least 1 (timeout 0 would mean no limit).
  left() { local s=$((${BUDGET:-570} - ($(date +%s) - bench_start))); echo $((s > 1 ? s : 1)); }
  mkdir -p "$OUT/logs"
  bench_gpu_name | tee "$OUT/gpu.txt"
  stamp "GPU tests of gradients and gradient opacity"
  x timeout $(($(left) < 150 ? $(left) : 150)) ctest --test-dir "$BUILD" -R "OptixTraversal|CudaShading" \
    --output-on-failure > "$OUT/logs/ctest.log" 2>&1 || status=1
  grep -E "tests passed|Failed|\*\*\*|Not Run" "$OUT/logs/ctest.log" | head -12

  stamp "the first gradient call: tangent rows timed on 2^18 queries, then on the default"
  for m in $models; do
    for b in 262144 default; do
      args=()
      [ "$b" = default ] || args=(--tangent-autotune-batch "$b")
      echo "-- $(basename "$m" .inr): tangent rows timed on $b queries" >> "$OUT/evaluator_first_call.txt"
      x timeout 60 "$BUILD/Benchmarks/gpu_evaluator_benchmark" --gradient --batch 65536 --reps 5 "${args[@]}" \
        --only "$(basename "$m" .inr)" "$m" >> "$OUT/evaluator_first_call.txt" 2>&1 || status=1
    done
  done
  grep -E "^-- |chosen at the first call" "$OUT/evaluator_first_call.txt" | sed 's/(batch.*->/... ->/' | cut -c1-200

  stamp "time to a clean image with gradient opacity ($ramp x the median |grad f|)"
  # shellcheck disable=SC2086
  x timeout $(($(left) > 16 ? $(left) - 15 : 1)) "$BUILD/Benchmarks/query_reduction_benchmark" "${TIME_TO_IMAGE_ARGS[@]}" \
    --configs "$configs" --gradient-opacity-median "$ramp" --out "$OUT" $models 2>&1 \
    | grep -v "per frame: init" > "$OUT/run.txt"
  [ "${PIPESTATUS[0]}" = 0 ] || status=1
  grep -E "^== |reference:|^   (delta|ratio|march|raymarch) " "$OUT/run.txt" | cut -c1-170
  tar -czf "$OUT/gradient_opacity_tti.tar.gz" -C "$OUT" --exclude=images --exclude='*.tar.gz' .
  return $status
}
