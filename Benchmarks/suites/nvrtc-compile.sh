# NVRTC's time for the kernels generated per network (issue 50: cold compile at model load):
# nvrtc_compile_benchmark on the paper-size networks, each kernel alone on one thread and the
# evaluator's whole set on every core (its load's wall time). Needs NVRTC (the CUDA toolkit), no
# GPU: a cubin for a real architecture is compiled without one.
SUITE_ABOUT="NVRTC compile time of the generated kernels, per kernel and per model load (nvrtc_compile_benchmark)"
SUITE_COST="about 4 min on one core of a 2-core machine, plus a build with the CUDA compile check"
SUITE_NEEDS="CPU + the CUDA toolkit's NVRTC (a build with -DINR_CUDA_COMPILE_CHECK=ON or CUDA)"
SUITE_BEFORE=rerun
SUITE_HELP='ARCH=sm_90        the architecture (sm_XY: NVVM and ptxas; compute_XY: NVVM only)
THREADS=$(nproc)  threads of the second pass (a model load on this machine)
(-- MODEL ...: siren, ffn, coordnet, siren-depth-N or .inr files; default the three paper networks)'
SUITE_TABLES="nvrtc_one_thread.txt nvrtc_threads.txt"

suite_build() { bench_build nvrtc_compile_benchmark; }

suite_run() {
  local models=("$@")
  [ "${#models[@]}" -gt 0 ] || models=(siren ffn coordnet)
  stamp "NVRTC, ${ARCH:-sm_90}, one kernel at a time"
  x "$BUILD/Benchmarks/nvrtc_compile_benchmark" --arch "${ARCH:-sm_90}" --threads 1 \
    --csv "$OUT/nvrtc_one_thread.csv" "${models[@]}" | tee "$OUT/nvrtc_one_thread.txt"
  [ "${PIPESTATUS[0]}" -eq 0 ] || return 1
  stamp "NVRTC, ${ARCH:-sm_90}, ${THREADS:-$(nproc)} threads"
  x "$BUILD/Benchmarks/nvrtc_compile_benchmark" --arch "${ARCH:-sm_90}" --threads "${THREADS:-$(nproc)}" \
    --csv "$OUT/nvrtc_threads.csv" "${models[@]}" | tee "$OUT/nvrtc_threads.txt"
  return "${PIPESTATUS[0]}"
}
