// Ray budgeting and reprojection on the GPU against the CPU backend (ctest label `cuda`; skipped,
// with the reason, without a usable GPU). The decisions are the same INR_HD stage code on both.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "Render/Cuda/AnalyticDeviceField.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/CpuWavefrontRenderer.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

const Box3f kBox = test::kCubeBox;

MacrocellOptions cells() { return test::cubeMacrocells(16, 2); }

using test::SceneSetup;

SceneSetup smoothScene(int size) {
  SceneSetup s = test::obliqueCubeScene(size, 9);
  s.scene.transferFunction = TransferFunction::preset(0.45, 0.95, 0.7);
  s.scene.transferFunction.unitDistance = 0.2;
  return s;
}

QueryReductionSettings scheme(BudgetScheme b, double rho) {
  QueryReductionSettings q;
  q.budget = b;
  q.budgetFraction = rho;
  q.budgetMaxSkip = 8;
  q.budgetAlpha = 0.5;
  return q;
}

TEST(CudaBudgeting, SameDecisionsAndConvergedImagesAsTheCpu) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  const SceneSetup s = smoothScene(96);
  for (BudgetScheme b : {BudgetScheme::Histogram, BudgetScheme::Stbn, BudgetScheme::WeightedStbn}) {
    CudaMacrocellGrid gpuGrid(field, kBox, 0, 1, cells());
    MacrocellGrid cpuGrid(field, kBox, 0, 1, cells());
    CudaWavefrontRenderer gpu(field, gpuGrid);
    CpuWavefrontRenderer cpu(field, cpuGrid);
    gpu.setQueryReduction(scheme(b, 0.5));
    cpu.setQueryReduction(scheme(b, 0.5));
    gpu.setSettings(s.settings);
    cpu.setSettings(s.settings);
    gpu.setScene(s.scene);
    cpu.setScene(s.scene);
    const int frames = 512;
    std::size_t worstDifference = 0, skippedGpu = 0, skippedCpu = 0;
    for (int f = 0; f < frames; ++f) {
      const FrameStats g = gpu.renderFrame(), c = cpu.renderFrame();
      const std::size_t d = g.budgetSkipped > c.budgetSkipped ? g.budgetSkipped - c.budgetSkipped
                                                               : c.budgetSkipped - g.budgetSkipped;
      worstDifference = std::max(worstDifference, d);
      skippedGpu += g.budgetSkipped;
      skippedCpu += c.budgetSkipped;
      if (b == BudgetScheme::Stbn) ASSERT_EQ(g.budgetSkipped, c.budgetSkipped) << "frame " << f;
    }
    const double psnr = test::psnrOverCoverage(gpu.image(), cpu.image(), cpu.premultipliedImage());
    std::printf("%-14s: skipped %zu (GPU) vs %zu (CPU), worst frame difference %zu of %d pixels; "
                "GPU vs CPU %.2f dB over the volume's pixels\n",
                budgetSchemeName(b), skippedGpu, skippedCpu, worstDifference, 96 * 96, psnr);
    // The residual-driven schemes see the residuals of images that differ by the field's ulps
    // (host and device sinf/expf) and the accumulation's rounding: a few decisions may differ.
    EXPECT_LE(worstDifference, std::size_t(96 * 96 / 50)) << budgetSchemeName(b);
    EXPECT_GT(skippedGpu, std::size_t(frames) * 96 * 96 / 5) << budgetSchemeName(b);
    EXPECT_GE(psnr, 40.0) << budgetSchemeName(b);
  }
}

TEST(CudaBudgeting, ReprojectionMatchesTheCpu) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  const SceneSetup s = smoothScene(96);
  RenderScene moved = s.scene;
  for (int k = 0; k < 3; ++k) {
    moved.camera.position[k] += 0.05 * (k == 0 ? 1 : -1);
    moved.camera.focalPoint[k] += 0.05 * (k == 0 ? 1 : -1);
  }
  CudaMacrocellGrid gpuGrid(field, kBox, 0, 1, cells());
  MacrocellGrid cpuGrid(field, kBox, 0, 1, cells());
  CudaWavefrontRenderer gpu(field, gpuGrid);
  CpuWavefrontRenderer cpu(field, cpuGrid);
  QueryReductionSettings q;
  q.reproject = true;
  gpu.setQueryReduction(q);
  cpu.setQueryReduction(q);
  test::renderFrames(gpu, s.settings, s.scene, 128);
  test::renderFrames(cpu, s.settings, s.scene, 128);
  gpu.setScene(moved);
  cpu.setScene(moved);
  EXPECT_EQ(gpu.counters().reprojections, 1);
  EXPECT_EQ(cpu.counters().reprojections, 1);
  const double psnr = test::psnrOverCoverage(gpu.image(), cpu.image(), cpu.premultipliedImage());
  std::printf("reprojected accumulations, GPU vs CPU: %.2f dB over the volume's pixels\n", psnr);
  EXPECT_GE(psnr, 38.0);  // two independent 128-frame accumulations, reprojected the same way
}

}  // namespace
}  // namespace inr
