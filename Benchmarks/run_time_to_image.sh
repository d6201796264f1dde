#!/usr/bin/env bash
# Time to a clean image (issue 26), one command on a GPU machine (no ParaView needed): builds
# query_reduction_benchmark with CUDA for this GPU and runs it at 1024^2 on the shipped full-size
# real models with their transfer functions: delta tracking (the paper's estimator), ratio
# tracking at several majorant scales K and points per iteration P, and the ray marcher at
# several steps, each against a long delta-tracking reference (PSNR over the volume's pixels and
# over the whole image against render time; time to 35 / 40 dB; iterations and queries per
# frame). Results (run.txt, CSV, PNG) go to ${OUT:-gpu-results}.
#   bash Benchmarks/run_time_to_image.sh [extra benchmark args, e.g. --seconds 2]
#
# The CPU variant (256^2, the *_small models):
#   cmake -S . -B build -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=OFF
#   ninja -C build query_reduction_benchmark
#   build/Benchmarks/query_reduction_benchmark --backend cpu --configs "$INR_ESTIMATOR_CONFIGS" \
#     --orbit-steps 0 --heatmap-frames 0 --out cpu-results Testing/Data/real/*_small.inr
source "$(dirname "$0")/gpu_common.sh"
CONFIGS=${INR_ESTIMATOR_CONFIGS:-"delta;ratio:1:16;ratio:4:16;ratio:8:32;ratio:16:64"}
MODELS=${INR_MODELS:-$TIME_TO_IMAGE_MODELS}
gpu=$(nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv,noheader 2>&1 | head -1)
echo "$gpu" > "$OUT/gpu.txt"
gpu_configure
cmake --build "$BUILD" -j "$(nproc)" --target query_reduction_benchmark > "$OUT/build.log" 2>&1 \
  || { grep -E "error" -A3 "$OUT/build.log" | head -40; exit 1; }
echo "== time to a clean image on $gpu"
# shellcheck disable=SC2086
"$BUILD/Benchmarks/query_reduction_benchmark" "${TIME_TO_IMAGE_ARGS[@]}" --configs "$CONFIGS" \
  --out "$OUT" "$@" $MODELS 2>&1 | tee "$OUT/run.txt"
status=${PIPESTATUS[0]}
python3 Benchmarks/plot_query_reduction.py "$OUT" --title "${gpu%%,*}, 1024^2" > "$OUT/plot.txt" 2>&1
tail -3 "$OUT/plot.txt"
exit "$status"
