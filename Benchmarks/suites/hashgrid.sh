# Issue 34's hash-grid checks: the GPU evaluator tests and every hash-grid test (ctest label cuda)
# and their CPU counterparts, the evaluator benchmark on the network (autotuned, each
# gather lane arrangement fixed, and with the L2-persisting window over the tables), the SIREN and
# FFN rows (unchanged programs, for comparison), and the shipped hash-grid model's render to an
# estimated 40 dB. Logs and CSV in OUT.
SUITE_ABOUT="hash-grid network: gathers, lane pairs, L2 window; shipped hash-grid model to 40 dB (gpu_evaluator_benchmark, inr)"
SUITE_COST="about 8 min on one H100 (the build most)"
SUITE_NEEDS="GPU"
SUITE_BEFORE=rerun
SUITE_HELP='(no settings)'

suite_build() {
  nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
  git log -1 --format='%H %s' > "$OUT/commit.txt" 2> /dev/null
  BENCH_BUILD_SECONDS=330 bench_build cuda_evaluator_tests cuda_pipeline_tests hashgrid_tests mlp_program_tests \
    gpu_evaluator_benchmark inr
}

suite_run() {
  local status=0 pairs m
  stamp "GPU tests (evaluator, and every cuda test with a hash grid in its name)"
  x timeout 150 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\.|[Hh]ash" --output-on-failure 2>&1 \
    | tee "$OUT/ctest_cuda.log" | grep -vE "^\s*(Start|Test command)" | tail -25
  grep -q "100% tests passed" "$OUT/ctest_cuda.log" || status=1
  grep -E "HashGrid|hashgrid" "$OUT/ctest_cuda.log" | grep -E "vs fp32|vs emulation" | head -30

  stamp "CPU tests (hash grid, program and emulation)"
  x timeout 60 ctest --test-dir "$BUILD" -R "^(HashGrid|Configs/HashGridVariants|MlpProgram)\." --output-on-failure \
    > "$OUT/ctest_cpu.log" 2>&1
  tail -3 "$OUT/ctest_cpu.log"
  grep -q "100% tests passed" "$OUT/ctest_cpu.log" || status=1

  local bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
  stamp "evaluator benchmark, issue network (autotuned: every candidate's rate in the launch report)"
  x timeout 90 "$bench" --only hashgrid --csv "$OUT/hashgrid_bench.csv" --checksum 2>&1 | tee "$OUT/hashgrid_bench.txt"
  for pairs in 1 0; do
    stamp "evaluator benchmark, gather lane pairs = $pairs (mma.sync, tile and chunk autotuned)"
    x timeout 60 "$bench" --only hashgrid --mma mma.sync --hash-pairs "$pairs" --checksum \
      --csv "$OUT/hashgrid_bench_pairs$pairs.csv" 2>&1 | tee "$OUT/hashgrid_bench_pairs$pairs.txt"
  done
  stamp "evaluator benchmark, tables in an L2-persisting window"
  x timeout 90 "$bench" --only hashgrid --l2-persist --csv "$OUT/hashgrid_bench_l2persist.csv" 2>&1 \
    | tee "$OUT/hashgrid_bench_l2persist.txt"

  stamp "evaluator benchmark, SIREN and FFN (the kernels' other programs: rates and checksums against RESULTS)"
  for m in paper_siren paper_ffn; do
    x timeout 60 "$bench" --only "$m" --checksum --csv "$OUT/bench_$m.csv" 2>&1 | tee "$OUT/bench_$m.txt"
  done

  stamp "render: shipped hash-grid model to 40 dB (512x512, CUDA)"
  local model=Testing/Data/real/hashgrid_mri_head_small
  x timeout 60 "$BUILD/bin/inr" render "$model.inr" --tf "$model.tf.json" --time 1.5 --converge 40 --frames 256 \
    --backend cuda -o "$OUT/hashgrid_render.png" --stats-json "$OUT/hashgrid_render.json" > "$OUT/hashgrid_render.txt" 2>&1
  head -1 "$OUT/hashgrid_render.txt"
  grep -iE "converge|dB|frames in" "$OUT/hashgrid_render.txt" | tail -3
  return $status
}
