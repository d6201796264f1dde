#!/usr/bin/env bash
# Gradient opacity on one GPU machine, from the repository root: builds the engine with CUDA for
# sm_90, runs every GPU test (`ctest -L "cuda|optix"`, with CudaShading.GradientOpacityGpuImage-
# MatchesCpuImage: GPU against CPU images with the factor, delta and ratio tracking, with and
# without shadows), then times `inr render --backend cuda` at 1024^2 on the shipped real models
# without gradient opacity and with a function that keeps (almost) every sample
# (--gradient-opacity 0,0,1e-6,1: the same picture, every query asking for its gradient), so the
# difference is the cost of the gradients alone; and the same with shading on.
# Logs in $OUT/gradient_opacity.tar.gz, the summary on stdout; about 7 minutes.
#   OUT=dir bash Benchmarks/run_gradient_opacity_checks.sh
OUT=${OUT:-./out}
source "$(dirname "${BASH_SOURCE[0]}")/gpu_common.sh"
BUILD=${INR_BUILD_DIR:-/tmp/bg}
BEFORE=
mkdir -p "$OUT/logs"
L="$OUT/logs"
status=0
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$L/gpu.txt"

stamp "configure and build"
gpu_build_with_before "$L" --

stamp "GPU tests"
timeout 400 ctest --test-dir "$BUILD" -L "cuda|optix" -j4 --output-on-failure > "$L/ctest_gpu.log" 2>&1
grep -E "tests passed|Failed|\*\*\*|Not Run" "$L/ctest_gpu.log" | head -20
grep -q "100% tests passed" "$L/ctest_gpu.log" || status=1
grep -E "gradient opacity" "$L/ctest_gpu.log" | sed 's/^[0-9]*: //' | cut -c1-220 | head -24

stamp "frames, 1024^2, 48 frames: without gradient opacity, with one that keeps every sample"
for m in siren_cylinder_vorticity ffn_mri_head coordnet_cylinder_u; do
  model=Testing/Data/real/$m
  for shade in "" --shade; do
    for go in off on; do
      args=()
      [ "$go" = on ] && args=(--gradient-opacity 0,0,1e-6,1)
      name="${m}${shade:+_shade}_$go"
      timeout 120 "$BUILD/bin/inr" render "$model.inr" --tf "$model.tf.json" --backend cuda $shade "${args[@]}" \
        --size 1024x1024 --frames 48 -o "/tmp/go_$name.png" --stats-json "$L/$name.json" > "$L/$name.txt" 2>&1 || status=1
      echo "$m ${shade:-unshaded} gradient-opacity $go: $(grep -oE '[0-9.]+ ms per frame' "$L/$name.txt" | head -1)"
    done
  done
done

tar -czf "$OUT/gradient_opacity.tar.gz" -C "$OUT" logs
rm -rf "$L"
stamp "done (status $status)"
exit $status
