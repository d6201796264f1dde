# The end-to-end render benchmark (issue 6, groups 4b-4d): gpu_render_benchmark's frames per
# second, stage times, the naive and ray-marching baselines and the time-step latency, on the
# paper-size architectures and the shipped model files; the pipeline tests' printed PSNRs and
# errors beside it (ctest keeps them only on failure; `ctest -L cuda` is the pass/fail).
SUITE_ABOUT="frames: end-to-end wavefront frames, stage times, baselines, time-step latency (gpu_render_benchmark)"
SUITE_COST="about 8 min on one H100 (build 3)"
SUITE_NEEDS="GPU"
SUITE_BEFORE=rerun
SUITE_HELP='MODELS=...        the models (default Testing/Data/real/*.inr Testing/Data/models/*.inr)
(-- ARGS: extra gpu_render_benchmark arguments, e.g. -- --size 512 --frames 10)'
SUITE_TABLES="render.txt"

suite_build() { bench_build cuda_pipeline_tests gpu_render_benchmark; }

suite_run() {
  local models status
  models=${MODELS:-$(ls Testing/Data/real/*.inr Testing/Data/models/*.inr 2> /dev/null)}
  bench_gpu_name > "$OUT/gpu.txt"
  stamp "pipeline tests' printed figures"
  x "$BUILD/Kernels/Render/Cuda/cuda_pipeline_tests" > "$OUT/cuda_pipeline_tests.txt" 2>&1
  stamp "render benchmark"
  # shellcheck disable=SC2086
  x "$BUILD/Benchmarks/gpu_render_benchmark" --csv "$OUT/render.csv" "$@" $models 2>&1 | tee "$OUT/render.txt"
  status=${PIPESTATUS[0]}
  stamp "plot"
  x python3 Benchmarks/plot_render_benchmark.py "$OUT/render.csv" "$OUT/render" 2>&1 | tail -3
  return "$status"
}
