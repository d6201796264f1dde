#!/usr/bin/env bash
# GPU call: build, the CUDA pipeline tests, time to image at the shipped macrocells with a warm time change.
set -u
R=$OUT/r; mkdir -p $R
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $R/gpu.txt
git rev-parse HEAD > $R/tree.txt 2>/dev/null; git status --short >> $R/tree.txt 2>/dev/null
t0=$(date +%s)
cmake -S . -B build-gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES=90 -DINR_BUILD_TESTS=ON -DINR_BUILD_BENCHMARKS=ON > $R/cmake.log 2>&1
ninja -C build-gpu -j16 cuda_pipeline_tests query_reduction_benchmark inr > $R/build.log 2>&1 || { tail -50 $R/build.log; tar -C $OUT -czf $OUT/r.tgz r; exit 1; }
echo "build $(( $(date +%s) - t0 )) s" | tee -a $R/steps.txt
t0=$(date +%s)
stdbuf -oL build-gpu/Kernels/Render/Cuda/cuda_pipeline_tests --gtest_brief=1 > $R/cuda_pipeline_tests.log 2>&1
echo "cuda_pipeline_tests rc=$? $(( $(date +%s) - t0 )) s" | tee -a $R/steps.txt
tail -5 $R/cuda_pipeline_tests.log
B=build-gpu/Benchmarks/query_reduction_benchmark
run_model() {  # model reference_frames warm_time
  t0=$(date +%s)
  stdbuf -oL $B --backend cuda --size 1024 --seconds 0.8 --min-frames 4 --reference-frames $2 --orbit-steps 0 \
    --heatmap-frames 0 --march-steps 64,128,256 --macrocells 32 --warm-time $3 \
    --configs "ratio:8:32;debiased:2:0.25:5:32:192:1;debiased:2:0.25:5:32:128:1;debiased:2:0.25:5:32:96:1;debiased:2:0.25:5:32:64:1" \
    --out $R/$1 Testing/Data/real/$1.inr > $R/$1-stdout.txt 2>&1
  echo "$1 rc=$? $(( $(date +%s) - t0 )) s" | tee -a $R/steps.txt
  grep -E "first frame|t35|time to" $R/$1-stdout.txt | head -20
}
run_model siren_cylinder_vorticity 4096 0.15
run_model ffn_mri_head 4096 0.0
run_model hashgrid_mri_head_small 4096 0.0
run_model coordnet_cylinder_u 2048 0.15
tar -C $OUT -czf $OUT/r.tgz r && rm -rf $R
