#!/usr/bin/env bash
# The evaluator's figures in one run on one GPU machine (an H100 or H200), from the repository
# root: ours against PyTorch fp16 eager and torch.compile on the same networks and batch, at the
# full batch (2^21) and at the small batches a frame makes, and the profile of each paper network's
# chosen kernel at both sizes. Steps:
#   1. builds cuda_evaluator_tests and gpu_evaluator_benchmark (Release, sm_90; prints the Hopper
#      kernel's spills) and runs the GPU evaluator tests (every kernel and form against the CPU
#      reference and the fp16 emulation);
#   2. gpu_evaluator_benchmark, autotuned, batch 2^21, the paper networks and the shipped models
#      (ours.txt: the launch reports, every candidate's timing); the same at 2 k .. 2 M queries
#      (batches.txt);
#   3. pytorch_baseline.py on the same files: eager at 2^21 and at 8192;
#   4. ncu on the first timed launch (the benchmark brackets its timed launches with
#      cudaProfilerStart/Stop) of each paper network at 2^21 and 8192: speed of light, compute and
#      memory workload, warp states, tensor pipe;
#   then torch.compile at 2^21 on the paper networks;
#   5. evaluator_summary.py joins it all into summary.md / summary.csv.
# BEFORE=COMMIT also builds that commit's gpu_evaluator_benchmark beside this tree's
# (gpu_start_before_build: `git archive`, /tmp/before-build, during this build) and runs its
# sweep at 8192 and 2^21 right after ours (before_batches.csv): a kernel change's before and after
# in one run on one GPU. NCU=0 skips the profiles (step 4).
# Logs in $OUT/summary_logs (default ./out), all of them in $OUT/evaluator_summary.tar.gz (and the
# tables in $OUT/summary.md); a failed
# step makes the exit status 1. The whole run keeps within $BUDGET seconds (default 570: a device
# call's limit is 600): each step's timeout is cut to what is left, the order is the figures'
# priority (torch.compile, the slowest, last), and a step with under 20 s left is skipped and
# says so.
#   OUT=out bash Benchmarks/run_evaluator_summary.sh
OUT=${OUT:-./out}
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
BUILD=${INR_BUILD_DIR:-/tmp/bsummary}
L="$OUT/summary_logs"
mkdir -p "$L/ncu"
status=0
deadline=$(($(date +%s) + ${BUDGET:-570}))
# within N: the seconds a step may take, at most N and what the budget leaves (0: skip it)
within() {
  local left=$((deadline - $(date +%s) - 15))
  [ "$left" -lt 20 ] && { echo 0; return; }
  echo $((left < $1 ? left : $1))
}
# run_step NAME N COMMAND...: COMMAND under `within N`, or a line saying it was skipped
run_step() {
  local name=$1 t
  t=$(within "$2")
  shift 2
  if [ "$t" = 0 ]; then echo "($name: skipped, the time budget is spent)"; status=1; return 1; fi
  timeout "$t" "$@" || { echo "($name: exit $?)"; status=1; return 1; }
}
finish() {
  # an early finish (a failed or skipped build) leaves no before build running
  [ -n "${before_pid:-}" ] && kill "$before_pid" 2> /dev/null  # (timeout passes the signal to ninja)
  rm -rf "$L/models"
  # (ncu's reports stay out: several MB each; the raw CSV and details pages hold their figures)
  tar --exclude='*.ncu-rep' -czf "$OUT/evaluator_summary.tar.gz" -C "$OUT" summary_logs
  [ -f "$L/summary.md" ] && cp "$L/summary.md" "$OUT/summary.md"
  stamp "done (status $status)"
  exit $status
}

nvidia-smi > "$L/nvidia-smi.txt" 2>&1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$L/gpu.txt"
git log -1 --format='%H %s' > "$L/commit.txt" 2>/dev/null

stamp "configure and build"
gpu_configure_release . "$BUILD" > "$L/configure.log" 2>&1 || { tail -30 "$L/configure.log"; status=1; finish; }
before_pid=
if [ -n "${BEFORE:-}" ]; then
  if ! git rev-parse --verify --quiet "$BEFORE^{commit}" > "$L/before_commit.txt"; then
    echo "(BEFORE=$BEFORE names no commit of this checkout: no before build)"; status=1
  else
    t=$(within 400)  # (0: no time left; `timeout 0` would mean no limit)
    if [ "$t" != 0 ] && gpu_start_before_build "$L" 8 "$t" gpu_evaluator_benchmark; then
      before_pid=$gpu_before_pid
    else
      echo "(no before build)"; status=1
    fi
  fi
fi
run_step build 400 ninja -C "$BUILD" -j16 cuda_evaluator_tests gpu_evaluator_benchmark > "$L/build.log" 2>&1 \
  || { tail -40 "$L/build.log"; finish; }
gpu_hopper_spills "$L/build.log"
if [ -n "$before_pid" ] && ! wait "$before_pid"; then
  echo "(the build of BEFORE=$BEFORE failed)"; tail -n 20 "$L/build_before.log"; status=1; before_pid=
fi

stamp "GPU evaluator tests"
run_step tests 200 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." -V > "$L/ctest_cuda.log" 2>&1
grep -E "tests passed|Failed|\*\*\*" "$L/ctest_cuda.log" | head -10
grep -q "100% tests passed" "$L/ctest_cuda.log" || status=1

bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
models=$(ls Testing/Data/real/*.inr | grep -v _small)
stamp "ours, batch 2^21"
run_step ours 150 "$bench" --write-models "$L/models" --csv "$L/ours.csv" $models > "$L/ours.txt" 2>&1
grep -vE "^\s+fused launch" "$L/ours.txt" | head -60
stamp "ours, 2 k .. 2 M queries"
run_step batches 120 "$bench" --batches 2048,8192,32768,2097152 --csv "$L/batches.csv" $models > "$L/batches.txt" 2>&1
grep -vE "^\s+fused launch" "$L/batches.txt" | head -60

if [ -n "$before_pid" ]; then
  stamp "before ($BEFORE), 8192 and 2^21"
  run_step before 120 /tmp/before-build/Benchmarks/gpu_evaluator_benchmark --batches 8192,2097152 --csv "$L/before_batches.csv" \
    $models > "$L/before_batches.txt" 2>&1
  grep -vE "^\s+fused launch" "$L/before_batches.txt" | head -40
fi

paper=$(ls "$L"/models/paper_*.inr)
stamp "PyTorch fp16 eager, 2^21"
run_step torch 120 python3 Benchmarks/pytorch_baseline.py --reps 10 --csv "$L/torch.csv" $paper $models > "$L/torch.txt" 2>&1
cat "$L/torch.txt"
stamp "PyTorch fp16 eager, 8192"
run_step "torch 8k" 60 python3 Benchmarks/pytorch_baseline.py --batch 8192 --csv "$L/torch_8k.csv" $paper $models > "$L/torch_8k.txt" 2>&1
cat "$L/torch_8k.txt"
[ "${NCU:-1}" = 0 ] && echo "(profiles skipped: NCU=0)"
for net in $([ "${NCU:-1}" = 0 ] || echo paper_siren paper_ffn paper_coordnet paper_hashgrid.inr); do
  for batch in 2097152 8192; do
    tag="${net%.inr}_$batch"
    stamp "ncu $tag"
    run_step "ncu $tag" 60 ncu --profile-from-start off --launch-count 1 -k regex:MlpKernel -f -o "$L/ncu/$tag" \
      --section SpeedOfLight --section ComputeWorkloadAnalysis --section MemoryWorkloadAnalysis \
      --section WarpStateStats --section LaunchStats --section Occupancy \
      --metrics sm__pipe_tensor_op_hmma_cycles_active.avg.pct_of_peak_sustained_active \
      "$bench" --only "$net" --batch "$batch" --reps 3 > "$L/ncu/$tag.txt" 2>&1 || { tail -5 "$L/ncu/$tag.txt"; continue; }
    ncu --import "$L/ncu/$tag.ncu-rep" --csv --page raw > "$L/ncu/$tag.csv" 2>> "$L/ncu/$tag.txt"
    ncu --import "$L/ncu/$tag.ncu-rep" --page details > "$L/ncu/$tag.details.txt" 2>> "$L/ncu/$tag.txt"
  done
done

stamp "torch.compile, 2^21 (paper networks)"
run_step torch.compile 400 python3 Benchmarks/pytorch_baseline.py --compile --reps 10 --csv "$L/torch_compile.csv" $paper > "$L/torch_compile.txt" 2>&1
grep compile "$L/torch_compile.txt"

stamp "summary"
python3 Benchmarks/evaluator_summary.py "$L" | tee "$L/summary.md" || status=1
finish
