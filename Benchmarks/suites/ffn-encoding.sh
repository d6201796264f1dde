# Issue 30 item 1: the FFN on the wgmma kernel with its Fourier encoding computed once per tile
# (stored: a row instruction writes it into a shared-memory buffer; stored split: its first 256
# columns in the MMAs' shared operand layout, the rest held in registers with the first GEMM's
# output written over them) against the fused encoding (computed in the operand load for every
# weight chunk) and the mma.sync kernel. The GPU evaluator tests (every forced wgmma
# configuration, the stored forms included, against the CPU reference and the fp16 emulation),
# then per FFN (paper FFN, ffn_mri_head) the autotuned evaluator (its launch report times every
# candidate) and each form forced, batch 2^21, and the autotuned one at 8 k .. 2 M queries.
# Logs in OUT/ffn_logs, all of them in OUT/ffn_checks.tar.gz.
SUITE_ABOUT="FFN encoding forms on the wgmma kernel: fused / stored / stored split vs mma.sync (gpu_evaluator_benchmark)"
SUITE_COST="about 8 min on one H100 (build 4)"
SUITE_NEEDS="GPU (Hopper: sm_90)"
SUITE_BEFORE=rerun
SUITE_HELP='(no settings)'

suite_build() { bench_build cuda_evaluator_tests gpu_evaluator_benchmark; }

suite_run() {
  local L="$OUT/ffn_logs" status=0
  mkdir -p "$L"
  nvidia-smi > "$L/nvidia-smi.txt" 2>&1
  bench_gpu_name
  git log -1 --format='%H %s' > "$L/commit.txt" 2> /dev/null
  stamp "GPU evaluator tests"
  x timeout 300 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." -V > "$L/ctest_cuda.log" 2>&1
  grep -E "tests passed|Failed|\*\*\*" "$L/ctest_cuda.log" | head -10
  grep -q "100% tests passed" "$L/ctest_cuda.log" || status=1
  grep -iE "ffn.*(stored|does not fit)|FAILED|Failure" "$L/ctest_cuda.log" | sed 's/^[0-9]*: //' | cut -c1-230 | head -40

  local bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
  show() { grep -vE "^\s+fused launch" "$1" | grep -vE "^GPU evaluator|^model"; grep -E "^\s+fused launch" "$1" | cut -c1-2000; }
  run() {  # run NAME ARGS...: one benchmark run, its log in $L/NAME.txt
    local name=$1
    shift
    stamp "$name: $*"
    x timeout 90 "$bench" "$@" --csv "$L/$name.csv" > "$L/$name.txt" 2>&1 || { echo "($name: exit $?)"; status=1; }
    show "$L/$name.txt"
  }
  local wg=(--mma wgmma --no-autotune) m sel tag
  for m in paper_ffn Testing/Data/real/ffn_mri_head.inr; do
    if [ "$m" = paper_ffn ]; then sel=(--only paper_ffn) tag=paper_ffn; else sel=(--only ffn_mri_head.inr "$m") tag=ffn_mri_head; fi
    run "${tag}_auto" "${sel[@]}"
    run "${tag}_mmasync" "${sel[@]}" --mma mma.sync
    run "${tag}_wgmma_fused_2x128" "${sel[@]}" "${wg[@]}" --stored-encoding 0 --wgmma-consumers 2 --wgmma-columns 128 --ping-pong 1
    if [ "$tag" = paper_ffn ]; then
      run "${tag}_wgmma_split_2x64" "${sel[@]}" "${wg[@]}" --stored-encoding 2 --wgmma-consumers 2 --wgmma-columns 64 --ping-pong 1
      run "${tag}_wgmma_split_1x128" "${sel[@]}" "${wg[@]}" --stored-encoding 2 --wgmma-consumers 1 --wgmma-columns 128
      run "${tag}_wgmma_stored_1x64" "${sel[@]}" "${wg[@]}" --stored-encoding 1 --wgmma-consumers 1 --wgmma-columns 64
    else
      run "${tag}_wgmma_stored_2x128" "${sel[@]}" "${wg[@]}" --stored-encoding 1 --wgmma-consumers 2 --wgmma-columns 128 --ping-pong 1
      run "${tag}_wgmma_stored_2x64" "${sel[@]}" "${wg[@]}" --stored-encoding 1 --wgmma-consumers 2 --wgmma-columns 64 --ping-pong 1
    fi
    run "${tag}_batches" "${sel[@]}" --batches 8192,32768,262144,2097152
  done
  tar -czf "$OUT/ffn_checks.tar.gz" -C "$OUT" ffn_logs
  return $status
}
