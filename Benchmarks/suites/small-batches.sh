# Issue 30's small-batch checks: the GPU evaluator tests (every fused kernel configuration against
# the CPU reference and the fp16 emulation), then, side by side in one run:
#   - the evaluator at batch sizes 2 k .. 2 M, autotuned, and with the wgmma candidates of before
#     one-consumer blocks (blocks of two consumers); with --before, also that commit's evaluator
#     (built beside) at the same sizes;
#   - the hash-grid network on ray-ordered against random points;
#   - the frame rows of the shipped real models, autotuned and with the candidates of before.
# Logs and CSV in OUT/logs, all of them in OUT/small_batch_checks.tar.gz.
SUITE_ABOUT="small batches: evaluator 2 k .. 2 M queries, hash grid ray-ordered vs random, frames (gpu_evaluator/render_benchmark)"
SUITE_COST="about 10 min on one H100 (the build half)"
SUITE_NEEDS="GPU (Hopper: sm_90)"
SUITE_BEFORE="own: the before build's evaluator at the same batch sizes"
SUITE_HELP='(no settings)'

suite_build() {
  bench_build cuda_evaluator_tests gpu_evaluator_benchmark gpu_render_benchmark -- gpu_evaluator_benchmark
}

suite_run() {
  local L="$OUT/logs" status=0
  mkdir -p "$L"
  nvidia-smi > "$L/nvidia-smi.txt" 2>&1
  bench_gpu_name
  git log -1 --format='%H %s' > "$L/commit.txt" 2> /dev/null
  stamp "GPU evaluator tests"
  x timeout 240 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." --output-on-failure > "$L/ctest_cuda.log" 2>&1
  grep -E "tests passed|Failed|\*\*\*" "$L/ctest_cuda.log" | head -10
  grep -q "100% tests passed" "$L/ctest_cuda.log" || status=1
  x "$BUILD/Kernels/Evaluator/Cuda/cuda_evaluator_tests" --gtest_filter='*WgmmaKernel*' 2>&1 | grep -E "paper_siren.*1x64" \
    | cut -c1-220 | head -6

  local bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
  local real=(Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr Testing/Data/real/coordnet_cylinder_u.inr)
  local sizes="2048 8192 32768 262144 2097152" b pts c
  show() { grep -vE "^\s+fused launch" "$1"; grep -E "^\s+fused launch" "$1" | sed 's/.*-> /    -> /' | cut -c1-200; }
  stamp "evaluator at batch sizes $sizes: autotuned"
  x timeout 240 "$bench" --batches "${sizes// /,}" --csv "$L/batches_auto.csv" "${real[@]}" > "$L/batches_auto.txt" 2>&1 || status=1
  show "$L/batches_auto.txt"
  stamp "the same, the wgmma candidates of before one-consumer blocks (two consumers, two tiles)"
  x timeout 240 "$bench" --batches "${sizes// /,}" --wgmma-consumers 2 --column-split 0 --csv "$L/batches_before_candidates.csv" \
    "${real[@]}" > "$L/batches_before_candidates.txt" 2>&1 || status=1
  show "$L/batches_before_candidates.txt"
  if [ -n "${BEFORE:-}" ]; then
    stamp "the same sizes, $BEFORE's evaluator (one run per size: fused-fp16 rows)"
    for b in $sizes; do
      x timeout 120 "$BEFORE_BUILD/Benchmarks/gpu_evaluator_benchmark" --batch "$b" --csv "$L/before_$b.csv" "${real[@]}" \
        > "$L/before_$b.txt" 2>&1 || status=1
      grep -E "fused-fp16" "$L/before_$b.txt" | sed "s/^/batch $b: /"
    done
  fi

  stamp "hash-grid network, ray-ordered against random points (batch 8192 and 2^21)"
  for pts in random rays; do
    x timeout 90 "$bench" --only hashgrid --points "$pts" --batches 8192,2097152 --csv "$L/hashgrid_$pts.csv" \
      > "$L/hashgrid_$pts.txt" 2>&1 || status=1
    grep -E "^paper" "$L/hashgrid_$pts.txt" | sed "s/^/$pts: /"
  done

  local render="$BUILD/Benchmarks/gpu_render_benchmark"
  for c in 0 2; do
    stamp "frames, shipped real models, 1024^2 (wgmma consumers $c; 0: autotuned)"
    x timeout 200 "$render" --no-paper --no-baselines --frames 30 --wgmma-consumers "$c" \
      --csv "$L/render_c$c.csv" "${real[@]}" > "$L/render_c$c.txt" 2>&1 || status=1
    grep -E "^== .*inr|^4b" "$L/render_c$c.txt" | cut -c1-190
  done
  tar -czf "$OUT/small_batch_checks.tar.gz" -C "$OUT" logs
  return $status
}
