# The evaluator's figures in one run on one GPU (issue 30): ours against PyTorch fp16 eager and
# torch.compile on the same networks and batch, at the full batch (2^21) and at the small
# batches a frame makes, and the profile of each paper network's chosen kernel at both sizes:
#   1. the GPU evaluator tests (every kernel and form against the CPU reference and the fp16
#      emulation);
#   2. gpu_evaluator_benchmark, autotuned, batch 2^21, the paper networks and the shipped models
#      (ours.txt: the launch reports, every candidate's timing); the same at 2 k .. 2 M queries
#      (batches.txt; a launch alone and launches queued back to back);
#   3. pytorch_baseline.py on the same files: eager at 2^21 and at 8192;
#   4. ncu on the first timed launch of each paper network at 2^21 and 8192 (the benchmark
#      brackets its timed launches with cudaProfilerStart/Stop): speed of light, compute and
#      memory workload, warp states, tensor pipe;
#   then torch.compile at 2^21 on the paper networks;
#   5. evaluator_summary.py joins it all into summary_logs/summary.md / summary.csv.
# --before COMMIT: that commit's gpu_evaluator_benchmark, built beside, sweeps 8192 and 2^21 right
# after ours (before_batches.csv): a kernel change's before and after in one run on one GPU.
# The whole run keeps within BUDGET seconds (a device call's limit is 600): each step's timeout is
# cut to what is left, the order is the figures' priority (torch.compile, the slowest, last), and
# a step with under 20 s left is skipped and says so.
SUITE_ABOUT="evaluator: ours vs PyTorch eager / torch.compile, 2^21 and small batches, ncu profiles (gpu_evaluator_benchmark)"
SUITE_COST="about 9.5 min on one H100 or H200 (kept within BUDGET)"
SUITE_NEEDS="GPU (python3-torch; ncu for the profiles)"
SUITE_BEFORE="own: the before build's sweep at 8192 and 2^21 beside ours"
SUITE_HELP='BUDGET=570        seconds for the whole run, build included
NCU=1             0 skips the ncu profiles'
SUITE_TABLES="summary_logs/summary.md"

evaluator_deadline() { echo $((bench_start + ${BUDGET:-570})); }
# within N: the seconds a step may take, at most N and what the budget leaves (0: skip it)
within() {
  local left=$(($(evaluator_deadline) - $(date +%s) - 15))
  [ "$left" -lt 20 ] && { echo 0; return; }
  echo $((left < $1 ? left : $1))
}
# run_step NAME N COMMAND...: COMMAND under `within N`, or a line saying it was skipped
run_step() {
  local name=$1 t
  t=$(within "$2")
  [ "$DRY_RUN" = 1 ] && t=$2
  shift 2
  if [ "$t" = 0 ]; then echo "($name: skipped, the time budget is spent)"; return 1; fi
  x timeout "$t" "$@" || { echo "($name: exit $?)"; return 1; }
}

suite_build() {
  local L="$OUT/summary_logs"
  mkdir -p "$L"
  nvidia-smi > "$L/nvidia-smi.txt" 2>&1
  bench_gpu_name | tee "$L/gpu.txt"
  git log -1 --format='%H %s' > "$L/commit.txt" 2> /dev/null
  [ -n "${BEFORE:-}" ] && git rev-parse --verify --quiet "$BEFORE^{commit}" > "$L/before_commit.txt"
  BENCH_BUILD_SECONDS=$(within 400) bench_build cuda_evaluator_tests gpu_evaluator_benchmark -- gpu_evaluator_benchmark
}

suite_run() {
  local L="$OUT/summary_logs" status=0
  mkdir -p "$L/ncu"
  stamp "GPU evaluator tests"
  run_step tests 200 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." -V > "$L/ctest_cuda.log" 2>&1
  grep -E "tests passed|Failed|\*\*\*" "$L/ctest_cuda.log" | head -10
  grep -q "100% tests passed" "$L/ctest_cuda.log" || status=1

  local bench="$BUILD/Benchmarks/gpu_evaluator_benchmark" models paper
  models=$(ls Testing/Data/real/*.inr | grep -v _small)
  stamp "ours, batch 2^21"
  # shellcheck disable=SC2086
  run_step ours 150 "$bench" --write-models "$L/models" --csv "$L/ours.csv" $models > "$L/ours.txt" 2>&1 || status=1
  grep -vE "^\s+fused launch" "$L/ours.txt" | head -60
  stamp "ours, 2 k .. 2 M queries"
  # shellcheck disable=SC2086
  run_step batches 120 "$bench" --batches 2048,8192,32768,2097152 --csv "$L/batches.csv" $models > "$L/batches.txt" 2>&1 || status=1
  grep -vE "^\s+fused launch" "$L/batches.txt" | head -60

  if [ -n "${BEFORE:-}" ]; then
    stamp "before ($BEFORE), 8192 and 2^21"
    # shellcheck disable=SC2086
    run_step before 120 "$BEFORE_BUILD/Benchmarks/gpu_evaluator_benchmark" --batches 8192,2097152 \
      --csv "$L/before_batches.csv" $models > "$L/before_batches.txt" 2>&1 || status=1
    grep -vE "^\s+fused launch" "$L/before_batches.txt" | head -40
  fi

  # The paper-size networks' files, written by the first benchmark run.
  paper=$(ls "$L"/models/paper_*.inr 2> /dev/null)
  [ "$DRY_RUN" = 1 ] && paper="$L/models/paper_siren.inr $L/models/paper_ffn.inr $L/models/paper_coordnet.inr $L/models/paper_hashgrid.inr"
  stamp "PyTorch fp16 eager, 2^21"
  # shellcheck disable=SC2086
  run_step torch 120 python3 Benchmarks/pytorch_baseline.py --reps 10 --csv "$L/torch.csv" $paper $models > "$L/torch.txt" 2>&1 || status=1
  cat "$L/torch.txt"
  stamp "PyTorch fp16 eager, 8192"
  # shellcheck disable=SC2086
  run_step "torch 8k" 60 python3 Benchmarks/pytorch_baseline.py --batch 8192 --csv "$L/torch_8k.csv" $paper $models > "$L/torch_8k.txt" 2>&1 || status=1
  cat "$L/torch_8k.txt"
  [ "${NCU:-1}" = 0 ] && echo "(profiles skipped: NCU=0)"
  local net batch tag
  for net in $([ "${NCU:-1}" = 0 ] || echo paper_siren paper_ffn paper_coordnet paper_hashgrid.inr); do
    for batch in 2097152 8192; do
      tag="${net%.inr}_$batch"
      stamp "ncu $tag"
      run_step "ncu $tag" 60 ncu --profile-from-start off --launch-count 1 -k regex:MlpKernel -f -o "$L/ncu/$tag" \
        --section SpeedOfLight --section ComputeWorkloadAnalysis --section MemoryWorkloadAnalysis \
        --section WarpStateStats --section LaunchStats --section Occupancy \
        --metrics sm__pipe_tensor_op_hmma_cycles_active.avg.pct_of_peak_sustained_active \
        "$bench" --only "$net" --batch "$batch" --reps 3 > "$L/ncu/$tag.txt" 2>&1 || { status=1; tail -5 "$L/ncu/$tag.txt"; continue; }
      x ncu --import "$L/ncu/$tag.ncu-rep" --csv --page raw > "$L/ncu/$tag.csv" 2>> "$L/ncu/$tag.txt"
      x ncu --import "$L/ncu/$tag.ncu-rep" --page details > "$L/ncu/$tag.details.txt" 2>> "$L/ncu/$tag.txt"
    done
  done

  stamp "torch.compile, 2^21 (paper networks)"
  # shellcheck disable=SC2086
  run_step torch.compile 400 python3 Benchmarks/pytorch_baseline.py --compile --reps 10 --csv "$L/torch_compile.csv" $paper \
    > "$L/torch_compile.txt" 2>&1 || status=1
  grep compile "$L/torch_compile.txt"

  stamp "summary"
  x python3 Benchmarks/evaluator_summary.py "$L" | tee "$L/summary.md" || status=1
  rm -rf "$L/models"
  # (ncu's reports stay out: several MB each; the raw CSV and details pages hold their figures)
  tar --exclude='*.ncu-rep' -czf "$OUT/evaluator_summary.tar.gz" -C "$OUT" summary_logs
  return $status
}
