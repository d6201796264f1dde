#!/usr/bin/env bash
# Issue 33, the fused kernel's tangent rows (value + gradient in the same tensor-core GEMMs), on
# one GPU machine, from the repository root (no ParaView):
#   1. configure + build the engine with CUDA (sm_90) in $BUILD (default /tmp/bt)
#   2. the GPU tests of gradients, shading and the evaluator (ctest -L cuda -R ...), and the CPU
#      tests of the tangent emulation and the CPU gradient
#   3. gpu_evaluator_benchmark --gradient: value + gradient G q/s, per-thread fp32 vs tangent
#      rows, on the paper-size networks and the shipped real models
#   4. gpu_render_benchmark: shaded vs unshaded 1024² frames on the three full-size real models,
#      with the tangent rows, then with --per-thread-gradient (the path before, for the ratio)
# Logs and CSV go to $OUT (default ./out); each step's wall time is printed. Aim: under 8 min.
# A phase argument runs one part (build, test or bench; default all), for machines whose command
# limit the whole does not fit: set BUILD to a directory that persists between the calls.
#   OUT=dir bash Benchmarks/run_tangent_checks.sh [all|build|test|bench]
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
OUT=${OUT:-./out}
BUILD=${BUILD:-/tmp/bt}
PHASE=${1:-all}
mkdir -p "$OUT"
t0=$(date +%s)
step() { echo "== [$(($(date +%s) - t0)) s] $*"; }
want() { [ "$PHASE" = all ] || [ "$PHASE" = "$1" ]; }

if want build; then
step "configure"
nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
git log --oneline -1 > "$OUT/commit.txt" 2>/dev/null
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=ON \
  -DCMAKE_CUDA_ARCHITECTURES=90 > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }

step "build"
targets="cuda_evaluator_tests cuda_pipeline_tests fused_tangent_emulation_tests evaluator_gradient_tests
         mlp_program_tests gpu_evaluator_benchmark gpu_render_benchmark"
ninja -C "$BUILD" -j16 $targets > "$OUT/build.log" 2>&1 || { grep -E "error" "$OUT/build.log" | head -40; exit 1; }
grep -E "spill" "$OUT/build.log" > "$OUT/spills.txt"
echo "register spills (tangent kernels expected, value kernels none):"; sed 's/^/  /' "$OUT/spills.txt" | cut -c1-160
fi

if want test; then

step "tests"
# The tests are listed first (gtest_discover_tests), so a filter that matches nothing is visible.
(cd "$BUILD" && ctest -N -L cuda -R "Shading|Gradient|Tangent|Evaluator" | tail -3)
(cd "$BUILD" && timeout 300 ctest -L cuda -R "Shading|Gradient|Tangent|Evaluator" --output-on-failure -V) \
  > "$OUT/ctest_cuda.log" 2>&1
echo "ctest (cuda) exit $?"
grep -E "tests passed|tests failed|\(Failed\)|\(Timeout\)|\(SEGFAULT\)|Not Run" "$OUT/ctest_cuda.log" | tail -20
# The measured errors the tests print (tangent rows vs fp32 and vs emulation, per model).
grep -E "tangent rows vs fp32|per-thread fp32 \(|gradient: worst" "$OUT/ctest_cuda.log" | sed 's/^[0-9]*: //' \
  > "$OUT/tangent_errors.txt"
cat "$OUT/tangent_errors.txt" | cut -c1-200
(cd "$BUILD" && timeout 120 ctest -R "FusedTangentEmulation|CpuInrEvaluatorGradient" --output-on-failure) \
  > "$OUT/ctest_cpu.log" 2>&1
echo "ctest (CPU tangent emulation, CPU gradient) exit $?"; grep -E "tests passed|tests failed" "$OUT/ctest_cpu.log"
fi

if want bench; then

step "evaluator benchmark: value + gradient throughput"
real="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr
      Testing/Data/real/coordnet_cylinder_u.inr Testing/Data/real/hashgrid_mri_head_small.inr"
timeout 150 "$BUILD/Benchmarks/gpu_evaluator_benchmark" --gradient --gradient-batch 65536 --reps 10 \
  --csv "$OUT/evaluator_gradient.csv" $real > "$OUT/evaluator_gradient.txt" 2>&1
echo "exit $?"
grep -E "grad-|fused-fp16|value \+ gradient" "$OUT/evaluator_gradient.txt" | cut -c1-200

step "render benchmark: shaded vs unshaded, 1024², tangent rows"
three="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr
       Testing/Data/real/coordnet_cylinder_u.inr"
timeout 150 "$BUILD/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 20 --warmup 5 \
  --csv "$OUT/render_shade.csv" $three > "$OUT/render_shade.txt" 2>&1
echo "exit $?"
grep -E "^== |value \+ gradient|wavefront|unshaded frame" "$OUT/render_shade.txt" | cut -c1-200

step "render benchmark: the same with --per-thread-gradient (the earlier path)"
timeout 120 "$BUILD/Benchmarks/gpu_render_benchmark" --no-paper --no-baselines --frames 5 --warmup 2 \
  --per-thread-gradient --csv "$OUT/render_shade_per_thread.csv" $three > "$OUT/render_shade_per_thread.txt" 2>&1
echo "exit $?"
grep -E "^== |value \+ gradient|wavefront\+shade|unshaded frame" "$OUT/render_shade_per_thread.txt" | cut -c1-200

fi
step "done; results in $OUT"
