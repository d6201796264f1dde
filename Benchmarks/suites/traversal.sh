# GPU traversal before and after in one run on one GPU (what RESULTS' "GPU DDA traversal" table
# came from): the before commit (--before) and this tree built side by side; the cuda tests of
# this tree; the render benchmark of both builds twice, alternating; the shipped scenes rendered by
# both at a fixed seed and the images compared bit for bit (compare_pfm.py); ncu's per-launch
# figures of ddaTraverseKernel for both. Without --before: this tree's rows alone.
SUITE_ABOUT="DDA traversal before/after: render benchmark twice, images bit for bit, ncu of ddaTraverseKernel"
SUITE_COST="about 10 min on one H100 (two builds)"
SUITE_NEEDS="GPU (ncu)"
SUITE_BEFORE="own: before and this tree alternate in each step, images compared"
SUITE_HELP='(no settings; --before COMMIT is the "before")'

suite_build() {
  bench_build cuda_evaluator_tests cuda_pipeline_tests cuda_stress_tests gpu_render_benchmark inr -- gpu_render_benchmark inr
}

suite_run() {
  local R=Testing/Data/real M="siren_cylinder_vorticity ffn_mri_head" r v m sh scratch versions=(now)
  [ -n "${BEFORE:-}" ] && versions=(before now)
  scratch=$(mktemp -d)
  bindir() { if [ "$1" = before ]; then echo "$BEFORE_BUILD"; else echo "$BUILD"; fi; }
  bench_gpu_name; git log --oneline -1
  stamp "cuda tests"
  x ctest --test-dir "$BUILD" -L cuda --output-on-failure -j4 > "$OUT/ctest.log" 2>&1; echo "ctest rc=$?"
  stamp "render benchmark, two runs each"
  for r in 1 2; do for v in "${versions[@]}"; do
    x "$(bindir $v)/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 30 --csv "$OUT/bench_${v}_$r.csv" \
      $R/siren_cylinder_vorticity.inr $R/ffn_mri_head.inr > "$OUT/bench_${v}_$r.txt" 2>&1
    echo "== $v run $r"; grep "^4b" "$OUT/bench_${v}_$r.txt"
  done; done
  stamp "images at a fixed seed"
  for m in $M; do for sh in "" "--shadows"; do
    for v in "${versions[@]}"; do
      mkdir -p "$scratch/$v"
      x "$(bindir $v)/bin/inr" render $R/$m.inr --tf $R/$m.tf.json --time 2 --backend cuda --size 1024x1024 --frames 20 \
        --macrocells 64 --seed 7 $sh --output "$scratch/$v/$m$sh.pfm" --stats-json "$OUT/stats_${v}_$m$sh.json" > /dev/null
    done
    [ -n "${BEFORE:-}" ] && x python3 Benchmarks/compare_pfm.py "$scratch/before/$m$sh.pfm" "$scratch/now/$m$sh.pfm" "$m shipped tf $sh"
  done; done | tee "$OUT/images.txt"
  stamp "ncu, ddaTraverseKernel"
  for m in $M; do for v in "${versions[@]}"; do
    x ncu --clock-control none --cache-control none --kernel-name ddaTraverseKernel --csv \
      --metrics gpu__time_duration.sum,launch__grid_size,launch__registers_per_thread,smsp__warps_active.avg.pct_of_peak_sustained_active,smsp__thread_inst_executed_per_inst_executed.ratio,sm__throughput.avg.pct_of_peak_sustained_elapsed,smsp__inst_executed.sum \
      "$(bindir $v)/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 2 --warmup 1 $R/$m.inr > "$OUT/ncu_${v}_$m.csv" 2>&1
  done; done
  rm -rf "$scratch"
  return 0
}
