#!/usr/bin/env bash
# Issue 48 (isosurface frames: 32 refinement points a round on the GPU, launches sized for the
# active rays) and issue 50 (the rendering GPU suites with INR_GENERATED_KERNELS=auto), one call.
# Binaries built here for sm_90: inr-before = 310730e, the rest = 310730e + the working tree.
set -u
R=$OUT/r; mkdir -p $R
nvidia-smi --query-gpu=name,driver_version --format=csv > $R/gpu.txt 2>&1; cat $R/gpu.txt
tar xJf bench-results/carry/all.tar.xz
export INR_KERNEL_CACHE_DIR=/tmp/inr-kcache
run() {  # name seconds command...
  local n=$1 s=$2; shift 2
  local t0=$(date +%s.%N)
  timeout $s stdbuf -oL "$@" > $R/$n.txt 2>&1
  echo "rc=$? wall=$(echo "$(date +%s.%N) - $t0" | bc) s" >> $R/$n.txt
  echo "== $n"; grep -E "^\[  (PASSED|FAILED) |^\[  FAILED  \]|rc=|Failure|SKIPPED" $R/$n.txt | cut -c1-200 | head -20
}
(cd build-sm90/Kernels/Render/Cuda && run cuda_surface_tests 120 ./cuda_surface_tests)
grep -E "iterations|dB" $R/cuda_surface_tests.txt | head
B=build-sm90/bin
blend() {  # name binary seconds args...
  local n=$1 bin=$2 s=$3; shift 3
  timeout $s python3 Benchmarks/blend_cpu_benchmark.py $bin Testing/Data $R/$n --backend cuda --size 1024 --frames 6 "$@" > $R/$n.log 2>&1
  echo "== $n rc=$?"; grep "^| " $R/$n.log
}
blend iso-before $B/inr-before 90 --modes isosurface
blend iso-after $B/inr 90 --modes isosurface
blend iso-after-r8 $B/inr 90 --modes isosurface --iso-args "--iso-refine-points 8"
blend iso-before-2 $B/inr-before 90 --modes isosurface
blend iso-after-2 $B/inr 90 --modes isosurface
blend paper-after $B/inr 120 --models siren_cylinder_vorticity ffn_mri_head coordnet_cylinder_u siren_sphere_plate_vorticity
tar czf $OUT/r.tgz -C $OUT r
M=Testing/Data/real/coordnet_cylinder_u_small
timeout 100 ncu --metrics gpu__time_duration.sum --csv --launch-count 900 $B/inr render $M.inr --blend isosurface --iso 0.06157 --tf $M.tf.json --size 1024x1024 --frames 2 --backend cuda -o /tmp/n.png > $R/ncu_coordnet_iso.csv 2> $R/ncu_coordnet_iso.err
echo "== ncu rc=$? $(wc -l < $R/ncu_coordnet_iso.csv) lines"
tar czf $OUT/r.tgz -C $OUT r
export INR_GENERATED_KERNELS=auto
E=build-sm90/Kernels/Evaluator/Cuda/cuda_evaluator_tests
run evaluator_auto 120 $E
for t in Render/Cuda/cuda_pipeline_tests:150 Backends/cuda_oom_tests:60 Backends/cuda_stress_tests:150; do
  b=${t%%:*}; s=${t##*:}; n=$(basename $b)
  (cd build-sm90/Kernels/$(dirname $b) && run ${n}_auto $s ./$n)
done
tar czf $OUT/r.tgz -C $OUT r
