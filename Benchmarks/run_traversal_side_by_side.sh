#!/usr/bin/env bash
# GPU traversal before/after in one run on one GPU (what Benchmarks/RESULTS.md's "GPU DDA
# traversal" table came from): builds the checked-out tree (the "before"), keeps its binaries,
# applies PATCH (the "after"), rebuilds incrementally, runs the cuda tests, the render benchmark
# for both builds twice, renders the shipped scenes with both at a fixed seed and compares the
# images bit for bit, and records ncu per-launch figures of ddaTraverseKernel. Output in $OUT.
#   OUT=dir bash Benchmarks/run_traversal_side_by_side.sh PATCH
set -o pipefail
PATCH=${1:?usage: run_traversal_side_by_side.sh PATCH}
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu-results}; mkdir -p "$OUT"
R=Testing/Data/real; M="siren_cylinder_vorticity ffn_mri_head"; B=build-gpu
BIN=$(mktemp -d); mkdir -p "$BIN/base" "$BIN/new"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; git log --oneline -1
cmake -S . -B $B -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DCMAKE_CUDA_ARCHITECTURES=90 -DCMAKE_BUILD_TYPE=Release > "$OUT/build.log" 2>&1 || exit 1
ninja -C $B gpu_render_benchmark inr >> "$OUT/build.log" 2>&1 || exit 1
cp $B/Benchmarks/gpu_render_benchmark $B/bin/inr "$BIN/base/"
patch -p1 < "$PATCH" || exit 1
ninja -C $B cuda_evaluator_tests cuda_pipeline_tests cuda_stress_tests gpu_render_benchmark inr >> "$OUT/build.log" 2>&1 || exit 1
cp $B/Benchmarks/gpu_render_benchmark $B/bin/inr "$BIN/new/"
(cd $B && ctest -L cuda --output-on-failure -j4) > "$OUT/ctest.log" 2>&1; echo "ctest rc=$?"
for r in 1 2; do for v in base new; do
  "$BIN/$v/gpu_render_benchmark" --no-paper --no-baselines --frames 30 --csv "$OUT/bench_${v}_$r.csv" \
    $R/siren_cylinder_vorticity.inr $R/ffn_mri_head.inr > "$OUT/bench_${v}_$r.txt" 2>&1
  echo "== $v run $r"; grep "^4b" "$OUT/bench_${v}_$r.txt"
done; done
for m in $M; do for sh in "" "--shadows"; do
  for v in base new; do
    "$BIN/$v/inr" render $R/$m.inr --tf $R/$m.tf.json --time 2 --backend cuda --size 1024x1024 --frames 20 \
      --macrocells 64 --seed 7 $sh --output "$BIN/$v/$m$sh.pfm" --stats-json "$OUT/stats_${v}_$m$sh.json" > /dev/null
  done
  python3 Benchmarks/compare_pfm.py "$BIN/base/$m$sh.pfm" "$BIN/new/$m$sh.pfm" "$m shipped tf $sh"
done; done | tee "$OUT/images.txt"
for m in $M; do for v in base new; do
  ncu --clock-control none --cache-control none --kernel-name ddaTraverseKernel --csv \
    --metrics gpu__time_duration.sum,launch__grid_size,launch__registers_per_thread,smsp__warps_active.avg.pct_of_peak_sustained_active,smsp__thread_inst_executed_per_inst_executed.ratio,sm__throughput.avg.pct_of_peak_sustained_elapsed,smsp__inst_executed.sum \
    "$BIN/$v/gpu_render_benchmark" --no-paper --no-baselines --frames 2 --warmup 1 $R/$m.inr > "$OUT/ncu_${v}_$m.csv" 2>&1
done; done
