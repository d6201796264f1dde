# The CPU evaluator's queries per second (issue 2): cpu_evaluator_benchmark on the paper-size
# architectures and the shipped models (Eigen fp32, every core; median of the repetitions).
SUITE_ABOUT="CPU evaluator throughput, paper-size networks and shipped models (cpu_evaluator_benchmark)"
SUITE_COST="about 2 min on 2 cores after a CPU build"
SUITE_NEEDS="CPU"
SUITE_BEFORE=rerun
SUITE_HELP='BATCH=65536       queries per timed call
REPS=5            repetitions (the median is reported)
(-- MODEL.inr ...: the models; default Testing/Data/models/*.inr Testing/Data/real/*.inr)'
SUITE_TABLES="cpu_evaluator.txt"

suite_build() { bench_build cpu_evaluator_benchmark; }

suite_run() {
  local models=("$@")
  [ "${#models[@]}" -gt 0 ] || models=(Testing/Data/models/*.inr Testing/Data/real/*.inr)
  stamp "CPU evaluator, batch ${BATCH:-65536}"
  x "$BUILD/Benchmarks/cpu_evaluator_benchmark" --batch "${BATCH:-65536}" --reps "${REPS:-5}" \
    --csv "$OUT/cpu_evaluator.csv" "${models[@]}" | tee "$OUT/cpu_evaluator.txt"
  return "${PIPESTATUS[0]}"
}
