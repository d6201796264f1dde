# Issue 33, the fused kernel's tangent rows (value + gradient in the same tensor-core GEMMs):
#   tests  the GPU tests of gradients, shading and the evaluator (ctest -L cuda -R ...) with the
#          errors they print (tangent_errors.txt), and the CPU tests of the tangent emulation and
#          the CPU gradient
#   bench  gpu_evaluator_benchmark --gradient: value + gradient G q/s, per-thread fp32 against
#          tangent rows, on the paper-size networks and the shipped real models; then
#          gpu_render_benchmark: shaded against unshaded 1024^2 frames on the three full-size real
#          models with the tangent rows, then with --per-thread-gradient (the path before)
# PHASE=test or PHASE=bench runs one part (with --no-build after a --build-only call, for
# machines whose command limit the whole does not fit; the build folder persists).
SUITE_ABOUT="tangent rows: value + gradient throughput, shaded vs unshaded frames (gpu_evaluator/render_benchmark)"
SUITE_COST="about 8 min on one H100 (build 4)"
SUITE_NEEDS="GPU (Hopper: sm_90)"
SUITE_BEFORE=rerun
SUITE_HELP='PHASE=all         all, test or bench'
SUITE_TABLES="tangent_errors.txt"

suite_build() {
  nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
  git log --oneline -1 > "$OUT/commit.txt" 2> /dev/null
  bench_build cuda_evaluator_tests cuda_pipeline_tests fused_tangent_emulation_tests evaluator_gradient_tests \
    mlp_program_tests gpu_evaluator_benchmark gpu_render_benchmark
}

suite_run() {
  local phase=${PHASE:-all}
  want() { [ "$phase" = all ] || [ "$phase" = "$1" ]; }
  case "$phase" in all | test | bench) ;; *) echo "tangents: PHASE must be all, test or bench, got '$phase'" >&2; return 2 ;; esac
  if want test; then
    stamp "tests"
    # The tests are listed first (gtest_discover_tests), so a filter that matches nothing is visible.
    x ctest --test-dir "$BUILD" -N -L cuda -R "Shading|Gradient|Tangent|Evaluator" | tail -3
    x timeout 300 ctest --test-dir "$BUILD" -L cuda -R "Shading|Gradient|Tangent|Evaluator" --output-on-failure -V \
      > "$OUT/ctest_cuda.log" 2>&1
    echo "ctest (cuda) exit $?"
    grep -E "tests passed|tests failed|\(Failed\)|\(Timeout\)|\(SEGFAULT\)|Not Run" "$OUT/ctest_cuda.log" | tail -20
    # The measured errors the tests print (tangent rows vs fp32 and vs emulation, per model).
    grep -E "tangent rows vs fp32|per-thread fp32 \(|gradient: worst" "$OUT/ctest_cuda.log" | sed 's/^[0-9]*: //' \
      > "$OUT/tangent_errors.txt"
    cut -c1-200 "$OUT/tangent_errors.txt"
    x timeout 120 ctest --test-dir "$BUILD" -R "FusedTangentEmulation|CpuInrEvaluatorGradient" --output-on-failure \
      > "$OUT/ctest_cpu.log" 2>&1
    echo "ctest (CPU tangent emulation, CPU gradient) exit $?"; grep -E "tests passed|tests failed" "$OUT/ctest_cpu.log"
  fi
  if want bench; then
    stamp "evaluator benchmark: value + gradient throughput"
    local real="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr
      Testing/Data/real/coordnet_cylinder_u.inr Testing/Data/real/hashgrid_mri_head_small.inr"
    # shellcheck disable=SC2086
    x timeout 150 "$BUILD/Benchmarks/gpu_evaluator_benchmark" --gradient --gradient-batch 65536 --reps 10 \
      --csv "$OUT/evaluator_gradient.csv" $real > "$OUT/evaluator_gradient.txt" 2>&1
    echo "exit $?"
    grep -E "grad-|fused-fp16|value \+ gradient" "$OUT/evaluator_gradient.txt" | cut -c1-200

    stamp "render benchmark: shaded vs unshaded, 1024^2, tangent rows"
    local three="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr
      Testing/Data/real/coordnet_cylinder_u.inr"
    # shellcheck disable=SC2086
    x timeout 150 "$BUILD/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 20 --warmup 5 \
      --csv "$OUT/render_shade.csv" $three > "$OUT/render_shade.txt" 2>&1
    echo "exit $?"
    grep -E "^== |value \+ gradient|wavefront|unshaded frame" "$OUT/render_shade.txt" | cut -c1-200

    stamp "render benchmark: the same with --per-thread-gradient (the earlier path)"
    # shellcheck disable=SC2086
    x timeout 120 "$BUILD/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 5 --warmup 2 \
      --per-thread-gradient --csv "$OUT/render_shade_per_thread.csv" $three > "$OUT/render_shade_per_thread.txt" 2>&1
    echo "exit $?"
    grep -E "^== |value \+ gradient|wavefront\+shade|unshaded frame" "$OUT/render_shade_per_thread.txt" | cut -c1-200
  fi
  return 0
}
