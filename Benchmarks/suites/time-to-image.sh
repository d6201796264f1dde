# Time to a clean image (issue 26): query_reduction_benchmark at 1024^2 on the shipped full-size
# real models with their transfer functions: delta tracking (the paper's estimator), ratio
# tracking at several majorant scales K and points per iteration P, and the ray marcher at
# several steps, each against a long delta-tracking reference (PSNR over the volume's pixels and
# over the whole image against render time; time to 35 / 40 dB; iterations and queries per
# frame). Results: run.txt, the benchmark's CSV and PNG.
# BACKEND=cpu: the CPU variant (256^2 by the benchmark's default, the *_small models, no orbit
# or heatmaps): a CPU build, no GPU.
SUITE_ABOUT="time to a clean image: delta / ratio tracking / ray marcher against a reference (query_reduction_benchmark)"
SUITE_COST="about 6 min on one H100 (build 3); BACKEND=cpu: minutes per model on 2 cores"
SUITE_NEEDS="GPU (BACKEND=cpu: CPU)"
SUITE_BEFORE=rerun
SUITE_HELP='CONFIGS=delta;ratio:1:16;ratio:4:16;ratio:8:32;ratio:16:64   estimator configurations (--configs)
MODELS=...        the models (default: the three full-size real models; BACKEND=cpu: Testing/Data/real/*_small.inr)
BACKEND=cuda      cuda, or cpu for the CPU variant
(-- ARGS: extra query_reduction_benchmark arguments, e.g. -- --seconds 2)'
SUITE_TABLES="run.txt"

suite_needs_gpu() { [ "${BACKEND:-cuda}" != cpu ]; }
suite_build() { bench_build query_reduction_benchmark; }

suite_run() {
  local configs=${CONFIGS:-"delta;ratio:1:16;ratio:4:16;ratio:8:32;ratio:16:64"} protocol models gpu
  if [ "${BACKEND:-cuda}" = cpu ]; then
    protocol=(--backend cpu --orbit-steps 0 --heatmap-frames 0)
    models=${MODELS:-$(echo Testing/Data/real/*_small.inr)}
    gpu="CPU, 256^2"
  else
    protocol=("${TIME_TO_IMAGE_ARGS[@]}")
    models=${MODELS:-$TIME_TO_IMAGE_MODELS}
    gpu="$(bench_gpu_name | cut -d, -f1), 1024^2"
  fi
  bench_gpu_name > "$OUT/gpu.txt"
  stamp "time to a clean image ($gpu)"
  # shellcheck disable=SC2086
  x "$BUILD/Benchmarks/query_reduction_benchmark" "${protocol[@]}" --configs "$configs" --out "$OUT" "$@" $models 2>&1 \
    | tee "$OUT/run.txt"
  local status=${PIPESTATUS[0]}
  stamp "plot"
  x python3 Benchmarks/plot_query_reduction.py "$OUT" --title "$gpu" > "$OUT/plot.txt" 2>&1
  tail -3 "$OUT/plot.txt"
  return "$status"
}
