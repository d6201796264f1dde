# Gradient opacity's frame cost (issue 33, item 2): every GPU test (`ctest -L "cuda|optix"`, with
# CudaShading.GradientOpacityGpuImageMatchesCpuImage: GPU against CPU images with the factor,
# delta and ratio tracking, with and without shadows; and CudaPipeline.GpuRayMarcherRunsTheCpu-
# MarchersRays with it), then `inr render --backend cuda` at 1024^2 on the shipped real models,
# ratio tracking (the default) and delta tracking, without gradient opacity and with a function
# that keeps (almost) every sample (--gradient-opacity 0,0,1e-6,1: the same picture), so the
# difference is the cost of the gradients the evaluation stage asks for
# (gradient_opacity_queries of --stats-json). Logs in OUT/gradient_opacity.tar.gz.
SUITE_ABOUT="gradient opacity: frame cost with and without it, ratio and delta tracking (inr render)"
SUITE_COST="about 7 min on one H100 (with every GPU test)"
SUITE_NEEDS="GPU"
SUITE_BEFORE=rerun
SUITE_HELP='(no settings)'

suite_build() { bench_build; }  # (every target: the GPU tests all run)

suite_run() {
  local L="$OUT/logs" status=0 m model est go args name
  mkdir -p "$L"
  bench_gpu_name | tee "$L/gpu.txt"
  stamp "GPU tests"
  x timeout 400 ctest --test-dir "$BUILD" -L "cuda|optix" -j4 --output-on-failure > "$L/ctest_gpu.log" 2>&1
  grep -E "tests passed|Failed|\*\*\*|Not Run" "$L/ctest_gpu.log" | head -20
  grep -q "100% tests passed" "$L/ctest_gpu.log" || status=1
  grep -E "gradient opacity" "$L/ctest_gpu.log" | sed 's/^[0-9]*: //' | cut -c1-220 | head -24

  stamp "frames, 1024^2, 48 frames: without gradient opacity, with one that keeps every sample"
  for m in siren_cylinder_vorticity ffn_mri_head coordnet_cylinder_u; do
    model=Testing/Data/real/$m
    for est in ratio delta; do
      for go in off on; do
        args=()
        [ "$go" = on ] && args=(--gradient-opacity 0,0,1e-6,1)
        name="${m}_${est}_$go"
        x timeout 120 "$BUILD/bin/inr" render "$model.inr" --tf "$model.tf.json" --backend cuda --estimator $est \
          "${args[@]}" --size 1024x1024 --frames 48 -o "/tmp/go_$name.png" --stats-json "$L/$name.json" \
          > "$L/$name.txt" 2>&1 || status=1
        echo "$m $est gradient-opacity $go: frame 48 $(grep -h '^frame 48/48' "$L/$name.txt" | grep -oE '[0-9.]+ ms$');" \
          "$(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); t=d['total']; \
print('queries', t.get('queries'), '+', t.get('shadow_queries'), 'gradient', t.get('gradient_opacity_queries'))" \
          "$L/$name.json" 2>/dev/null)"
      done
    done
  done
  tar -czf "$OUT/gradient_opacity.tar.gz" -C "$OUT" logs
  rm -rf "$L"
  return $status
}
