# Run time against error for query reduction (issue 11 item 5): query_reduction_benchmark on
# every shipped full-size real model at 1024^2 (--backend cuda, no CPU fallback): ray budgeting,
# reprojection over a camera orbit and homogeneity pruning against tracing every pixel; then the
# plots (run.txt, CSV, PNG, tables.md).
# Under a per-command time limit, one model per call (--no-build after the first; --append adds
# rows): bench.sh query-reduction -- --append Testing/Data/real/siren_cylinder_vorticity.inr
# BACKEND=cpu: the CPU run (256^2, the *_small models; a few minutes per model on a desktop).
SUITE_ABOUT="query reduction: budgeting, reprojection, pruning against error over time (query_reduction_benchmark)"
SUITE_COST="tens of minutes on one H100 for every model (one model per call fits a device call); BACKEND=cpu: minutes per model"
SUITE_NEEDS="GPU (BACKEND=cpu: CPU)"
SUITE_BEFORE=rerun
SUITE_HELP='BACKEND=cuda      cuda, or cpu for the CPU run
(-- ARGS: extra query_reduction_benchmark arguments and models, e.g. -- --seconds 2 --orbit-steps 30)'
SUITE_TABLES="run.txt"

suite_needs_gpu() { [ "${BACKEND:-cuda}" != cpu ]; }
suite_build() { bench_build query_reduction_benchmark; }

suite_run() {
  local gpu status backend=${BACKEND:-cuda}
  if [ "$backend" = cpu ]; then gpu="CPU, 256^2"; else gpu="$(bench_gpu_name | cut -d, -f1), 1024^2"; fi
  bench_gpu_name > "$OUT/gpu.txt"
  stamp "query reduction benchmark ($gpu)"
  x "$BUILD/Benchmarks/query_reduction_benchmark" --backend "$backend" --out "$OUT" "$@" 2>&1 | tee "$OUT/run.txt"
  status=${PIPESTATUS[0]}
  stamp "plot"
  x python3 Benchmarks/plot_query_reduction.py "$OUT" --title "$gpu" > "$OUT/plot.txt" 2>&1
  tail -3 "$OUT/plot.txt"
  return "$status"
}
