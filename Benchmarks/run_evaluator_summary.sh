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
#   3. pytorch_baseline.py on the same files: eager at 2^21 and at 8192, torch.compile at 2^21 on
#      the paper networks;
#   4. ncu on the first timed launch (the benchmark brackets its timed launches with
#      cudaProfilerStart/Stop) of each paper network at 2^21 and 8192: speed of light, compute and
#      memory workload, warp states, tensor pipe;
#   5. evaluator_summary.py joins it all into summary.md / summary.csv.
# Logs in $OUT/summary_logs (default ./out), all of them in $OUT/evaluator_summary.tar.gz; a failed
# step makes the exit status 1.
#   OUT=out bash Benchmarks/run_evaluator_summary.sh
OUT=${OUT:-./out}
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
BUILD=${INR_BUILD_DIR:-/tmp/bsummary}
L="$OUT/summary_logs"
mkdir -p "$L/ncu"
status=0
finish() {
  rm -rf "$L/models"
  tar -czf "$OUT/evaluator_summary.tar.gz" -C "$OUT" summary_logs
  stamp "done (status $status)"
  exit $status
}

nvidia-smi > "$L/nvidia-smi.txt" 2>&1
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$L/gpu.txt"
git log -1 --format='%H %s' > "$L/commit.txt" 2>/dev/null

stamp "configure and build"
gpu_configure_release . "$BUILD" > "$L/configure.log" 2>&1 || { tail -30 "$L/configure.log"; status=1; finish; }
timeout 480 ninja -C "$BUILD" -j16 cuda_evaluator_tests gpu_evaluator_benchmark > "$L/build.log" 2>&1 \
  || { tail -40 "$L/build.log"; status=1; finish; }
grep -E "spill|C75[0-9][0-9]" "$L/build.log" | grep -iE "hopper|C75" | sed 's/.*function //' | cut -c1-200

stamp "GPU evaluator tests"
timeout 300 ctest --test-dir "$BUILD" -L cuda -R "CudaInrEvaluator\." > "$L/ctest_cuda.log" 2>&1
grep -E "tests passed|Failed|\*\*\*" "$L/ctest_cuda.log" | head -10
grep -q "100% tests passed" "$L/ctest_cuda.log" || status=1

bench="$BUILD/Benchmarks/gpu_evaluator_benchmark"
models=$(ls Testing/Data/real/*.inr | grep -v _small)
stamp "ours, batch 2^21"
timeout 240 "$bench" --write-models "$L/models" --csv "$L/ours.csv" $models > "$L/ours.txt" 2>&1 || { echo "(ours: exit $?)"; status=1; }
grep -vE "^\s+fused launch" "$L/ours.txt" | head -60
stamp "ours, 2 k .. 2 M queries"
timeout 240 "$bench" --batches 2048,8192,32768,2097152 --csv "$L/batches.csv" $models > "$L/batches.txt" 2>&1 \
  || { echo "(batches: exit $?)"; status=1; }
grep -vE "^\s+fused launch" "$L/batches.txt" | head -60

paper=$(ls "$L"/models/paper_*.inr)
stamp "PyTorch fp16 eager, 2^21"
timeout 300 python3 Benchmarks/pytorch_baseline.py --csv "$L/torch.csv" $paper $models > "$L/torch.txt" 2>&1 || { echo "(torch: exit $?)"; status=1; }
cat "$L/torch.txt"
stamp "PyTorch fp16 eager, 8192"
timeout 300 python3 Benchmarks/pytorch_baseline.py --batch 8192 --csv "$L/torch_8k.csv" $paper $models > "$L/torch_8k.txt" 2>&1 \
  || { echo "(torch 8k: exit $?)"; status=1; }
cat "$L/torch_8k.txt"
stamp "torch.compile, 2^21 (paper networks)"
timeout 600 python3 Benchmarks/pytorch_baseline.py --compile --csv "$L/torch_compile.csv" $paper > "$L/torch_compile.txt" 2>&1 \
  || { echo "(torch.compile: exit $?)"; status=1; }
grep compile "$L/torch_compile.txt"

for net in paper_siren paper_ffn paper_coordnet paper_hashgrid.inr; do
  for batch in 2097152 8192; do
    tag="${net%.inr}_$batch"
    stamp "ncu $tag"
    timeout 180 ncu --profile-from-start off --launch-count 1 -k regex:MlpKernel -f -o "$L/ncu/$tag" \
      --section SpeedOfLight --section ComputeWorkloadAnalysis --section MemoryWorkloadAnalysis \
      --section WarpStateStats --section LaunchStats --section Occupancy \
      --metrics sm__pipe_tensor_op_hmma_cycles_active.avg.pct_of_peak_sustained_active \
      "$bench" --only "$net" --batch "$batch" --reps 3 > "$L/ncu/$tag.txt" 2>&1 \
      || { echo "(ncu $tag: exit $?)"; tail -5 "$L/ncu/$tag.txt"; status=1; }
    ncu --import "$L/ncu/$tag.ncu-rep" --csv --page raw > "$L/ncu/$tag.csv" 2>> "$L/ncu/$tag.txt"
    ncu --import "$L/ncu/$tag.ncu-rep" --page details > "$L/ncu/$tag.details.txt" 2>> "$L/ncu/$tag.txt"
  done
done

stamp "summary"
python3 Benchmarks/evaluator_summary.py "$L" | tee "$L/summary.md" || status=1
finish
