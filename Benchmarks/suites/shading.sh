# Every GPU test (ctest -L "cuda|optix", OptiX where $OptiX_INSTALL_DIR or ./.optix holds its
# headers) and the CLI's marcher check, then: `inr render --method raymarch --backend cuda
# --shade` on the shipped real models, this tree (the GPU marcher) against BEFORE (default
# a1840c4: the CPU marcher on the GPU evaluator), built beside it; the shaded wavefront frame
# under a headlight against ParaView's light kit (`--light-kit`: five lights per lit sample); and
# gpu_render_benchmark's frames of the same models, autotuned against the evaluator without two
# consumers on one tile (`--column-split 0`: its candidates before that kernel form).
# Logs in OUT/logs, all of them in OUT/gpu_checks.tar.gz.
SUITE_ABOUT="shading: GPU ray-marched shading vs before, headlight vs light kit, frames with/without the column split (inr, gpu_render_benchmark)"
SUITE_COST="about 10 min on one H100 (with every GPU test)"
SUITE_NEEDS="GPU (OptiX headers in ./.optix for the optix tests)"
SUITE_BEFORE="own: the before build's inr for the ray-marched rows (default a1840c4: the CPU marcher on the GPU evaluator; --before none: this tree only)"
SUITE_DEFAULT_BEFORE=a1840c4
SUITE_HELP='(no settings; --before COMMIT picks the marcher to compare with)'

suite_build() {
  export OptiX_INSTALL_DIR=${OptiX_INSTALL_DIR:-$PWD/.optix}
  bench_build -- inr  # (every target: the GPU tests all run)
}

suite_run() {
  local L="$OUT/logs" status=0 m model which bin lights name
  mkdir -p "$L"
  bench_gpu_name | tee "$L/gpu.txt"
  stamp "GPU tests"
  x timeout 420 ctest --test-dir "$BUILD" -L "cuda|optix" -j4 --output-on-failure > "$L/ctest_gpu.log" 2>&1
  grep -E "tests passed|Failed|\*\*\*|Not Run" "$L/ctest_gpu.log" | head -20
  grep -q "100% tests passed" "$L/ctest_gpu.log" || status=1
  x "$BUILD/Kernels/Render/Cuda/cuda_pipeline_tests" --gtest_filter='*GpuRayMarcherRunsTheCpuMarchersRays*' 2>&1 \
    | grep -E "shaded" | cut -c1-200 | head -12
  x timeout 120 ctest --test-dir "$BUILD" -R "cli.raymarch_backend" --output-on-failure > "$L/ctest_cli_raymarch.log" 2>&1
  grep -E "tests passed|Failed" "$L/ctest_cli_raymarch.log"
  grep -q "100% tests passed" "$L/ctest_cli_raymarch.log" || status=1

  local models=(siren_cylinder_vorticity ffn_mri_head coordnet_cylinder_u)
  stamp "ray-marched shading, 512^2, 4 frames: this tree (GPU marcher)${BEFORE:+ against $BEFORE}"
  for m in "${models[@]}"; do
    model=Testing/Data/real/$m
    for which in now ${BEFORE:+before}; do
      bin="$BUILD/bin/inr"
      [ "$which" = before ] && bin=$BEFORE_BUILD/bin/inr
      x timeout 300 "$bin" render "$model.inr" --tf "$model.tf.json" --method raymarch --backend cuda --shade --size 512x512 \
        --frames 4 -o "$L/march_${m}_$which.png" --stats-json "$L/march_${m}_$which.json" > "$L/march_${m}_$which.txt" 2>&1
      echo "$m $which: $(grep -E '^ray marcher' "$L/march_${m}_$which.txt"); $(grep -E '^frame 4/4' "$L/march_${m}_$which.txt")"
    done
  done

  stamp "shaded wavefront frames, 1024^2, 48 frames: headlight against the light kit"
  for m in "${models[@]}"; do
    model=Testing/Data/real/$m
    for lights in "" --light-kit; do
      name=${lights:-headlight}
      x timeout 120 "$BUILD/bin/inr" render "$model.inr" --tf "$model.tf.json" --backend cuda --shade $lights \
        --size 1024x1024 --frames 48 -o "$L/shade_${m}_${name#--}.png" > "$L/shade_${m}_${name#--}.txt" 2>&1
      echo "$m ${name#--}: $(grep -oE '[0-9.]+ ms per frame' "$L/shade_${m}_${name#--}.txt" | head -1)"
    done
  done

  stamp "frames, 1024^2 (gpu_render_benchmark): autotuned against --column-split 0"
  local inrs=() args
  for m in "${models[@]}"; do inrs+=("Testing/Data/real/$m.inr"); done
  for which in auto no-column-split; do
    args=()
    [ "$which" != auto ] && args=(--column-split 0)
    x timeout 240 "$BUILD/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines "${args[@]}" \
      --csv "$L/render_$which.csv" "${inrs[@]}" > "$L/render_$which.txt" 2>&1
    echo "-- $which"; grep -E "^== |evaluator|^   wavefront" "$L/render_$which.txt" | cut -c1-160 | head -24
  done
  tar -czf "$OUT/gpu_checks.tar.gz" -C "$OUT" logs
  return $status
}
