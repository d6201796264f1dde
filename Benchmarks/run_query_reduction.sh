#!/usr/bin/env bash
# Run time against error for query reduction (issue 11 item 5), one command on a GPU machine (no
# ParaView needed): builds query_reduction_benchmark with CUDA for this GPU, runs it on every
# shipped full-size real model at 1024^2 (--backend cuda, no CPU fallback), then plots.
# Results (run.txt, CSV, PNG, tables.md for Benchmarks/RESULTS.md) go to ${OUT:-gpu-results}.
#   bash Benchmarks/run_query_reduction.sh [extra benchmark args, e.g. --seconds 2 --orbit-steps 30]
# Under a per-command time limit, one model per call (the build is kept; --append adds rows):
#   bash Benchmarks/run_query_reduction.sh Testing/Data/real/ffn_mri_head.inr
#   bash Benchmarks/run_query_reduction.sh --append Testing/Data/real/siren_cylinder_vorticity.inr
#
# The CPU run (256^2, the *_small models; a few minutes per model on a desktop):
#   cmake -S . -B build -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=OFF
#   ninja -C build query_reduction_benchmark
#   build/Benchmarks/query_reduction_benchmark --backend cpu --out cpu-results | tee cpu-results/run.txt
#   python3 Benchmarks/plot_query_reduction.py cpu-results --title "CPU, 256^2"
source "$(dirname "$0")/gpu_common.sh"
gpu=$(nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv,noheader 2>&1 | head -1)
echo "$gpu" > "$OUT/gpu.txt"
gpu_configure
cmake --build "$BUILD" -j "$(nproc)" --target query_reduction_benchmark > "$OUT/build.log" 2>&1 \
  || { grep -E "error" -A3 "$OUT/build.log" | head -40; exit 1; }
echo "== query reduction benchmark on $gpu"
"$BUILD/Benchmarks/query_reduction_benchmark" --backend cuda --out "$OUT" "$@" 2>&1 | tee "$OUT/run.txt"
status=${PIPESTATUS[0]}
python3 Benchmarks/plot_query_reduction.py "$OUT" --title "${gpu%%,*}, 1024^2" > "$OUT/plot.txt" 2>&1
tail -3 "$OUT/plot.txt"
exit "$status"
