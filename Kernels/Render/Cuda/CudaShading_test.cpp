// Gradient shading on the GPU (ctest label `cuda`; skipped, with the reason, without a usable
// GPU): the per-thread network's fp32 forward-mode gradient against the CPU reference's, and the
// shaded GPU wavefront image against the shaded CPU image of the same shipped networks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.cuh"
#include "Evaluator/MlpProgram.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/CudaDeltaTrackingRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/DeltaTrackingRenderer.h"
#include "Render/ModelBox.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

namespace fs = std::filesystem;

// The per-thread network's forward mode is host and device code: run on the CPU (no GPU
// needed) over the compiled program with host scratch, it must give the reference's gradient.
// This checks every instruction's Jacobian (and the Fourier encoding's tangent) on any machine.
TEST(CudaShading, PerThreadForwardModeOnTheHostMatchesCpuGradient) {
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpu(model);
    const MlpProgram program = MlpProgram::compile(model.architecture);
    PerThreadMlpView v = perThreadMlpBase(model, program, program.instrs.data(), program.floatWeights.data());
    v.stride = 1;
    std::vector<float> scratch(std::size_t(4) * v.numBuffers * v.width);
    v.scratch = scratch.data();
    const float time = float(0.5 * (model.domain.timeBegin + model.domain.timeEnd));
    model.output.affineAt(time, v.outA, v.outB);
    const std::vector<QueryPoint> points = test::randomQueryPoints(model, 256, 23, time);
    const std::size_t n = points.size();
    std::vector<float> cv(n), cg(3 * n);
    cpu.evaluateWithGradient(points.data(), n, cv.data(), cg.data());
    double rms = 0;
    for (float g : cg) rms += double(g) * g;
    rms = std::sqrt(rms / double(n));
    ASSERT_GT(rms, 0.0) << path;
    double worst = 0, worstValue = 0, valueScale = 0;
    for (float c : cv) valueScale = std::max(valueScale, double(std::fabs(c)));
    for (std::size_t i = 0; i < n; ++i) {
      float g[3];
      const QueryPoint& q = points[i];
      const float value = cuda::perThreadForward<true>(v, q.x, q.y, q.z, q.t, 0, g);
      const float plain = cuda::perThreadForward<false>(v, q.x, q.y, q.z, q.t, 0, nullptr);
      // The same arithmetic up to the compiler's contraction of each instantiation into FMAs.
      ASSERT_NEAR(value, plain, 1e-6 * std::max(valueScale, 1e-30)) << path << ": the tangents changed the value";
      worstValue = std::max(worstValue, std::fabs(double(value) - cv[i]) / std::max(valueScale, 1e-30));
      for (int k = 0; k < 3; ++k) worst = std::max(worst, std::fabs(double(g[k]) - cg[3 * i + k]) / rms);
    }
    std::printf("%-32s per-thread forward mode on the host: worst |d - CPU| / rms %.2e, value %.2e\n",
                fs::path(path).filename().c_str(), worst, worstValue);
    EXPECT_LE(worst, 1e-3) << path;
    EXPECT_LE(worstValue, 1e-4) << path;
  }
}

// Both sides are fp32 forward mode over the same graph (the GPU through the compiled program, the
// CPU through Eigen), so they differ by summation order: relative to the gradient's typical
// size over the sample, within the 1e-3 for fp32.
TEST(CudaShading, GpuGradientMatchesCpuGradient) {
  REQUIRE_GPU();
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpu(model);
    const CudaInrEvaluator gpu(model);
    ASSERT_TRUE(gpu.providesGradient());
    ASSERT_TRUE(gpu.providesDeviceGradient());
    const std::vector<QueryPoint> points = test::randomQueryPoints(model, 4096, 17);
    const std::size_t n = points.size();
    std::vector<float> cv(n), gv(n), cg(3 * n), gg(3 * n);
    cpu.evaluateWithGradient(points.data(), n, cv.data(), cg.data());
    gpu.evaluateWithGradient(points.data(), n, gv.data(), gg.data());
    double rms = 0, valueScale = 0;
    for (std::size_t i = 0; i < n; ++i) {
      rms += double(cg[3 * i]) * cg[3 * i] + double(cg[3 * i + 1]) * cg[3 * i + 1] + double(cg[3 * i + 2]) * cg[3 * i + 2];
      valueScale = std::max(valueScale, double(std::fabs(cv[i])));
    }
    rms = std::sqrt(rms / double(n));
    ASSERT_GT(rms, 0.0) << path;
    double worst = 0, worstValue = 0;
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        ASSERT_TRUE(std::isfinite(gg[3 * i + k])) << path << " point " << i;
        worst = std::max(worst, std::fabs(double(gg[3 * i + k]) - cg[3 * i + k]) / rms);
      }
      worstValue = std::max(worstValue, std::fabs(double(gv[i]) - cv[i]) / std::max(valueScale, 1e-30));
    }
    std::printf("%-32s gradient: worst |GPU - CPU| / rms %.2e (rms %.3g); value: worst relative %.2e\n",
                fs::path(path).filename().c_str(), worst, rms, worstValue);
    EXPECT_LE(worst, 1e-3) << path;
    EXPECT_LE(worstValue, 1e-4) << path;
  }
}

struct ShadedRun {
  ImageRGBA image, premultiplied;
  FrameStats stats;
};

// A headlight with a highlight: every term of the lighting in the picture.
RenderScene shadedScene(const InrModel& model, const std::array<float, 2>& range, bool shade) {
  RenderScene scene = test::testScene(model, range, false);
  scene.shading.enabled = shade;
  scene.shading.headlight = true;
  scene.shading.specular = 0.3f;
  scene.ambient = 0.2f;
  return scene;
}

template <typename Grid, typename Renderer, typename Evaluator>
ShadedRun renderShaded(const Evaluator& evaluator, const InrModel& model, const RenderScene& scene,
                       const TrackingOptions& options, int size, int frames) {
  RenderSettings settings;
  settings.width = settings.height = size;
  settings.seed = 13;
  settings.pixelJitter = false;
  Grid grid(evaluator, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, test::testMacrocells());
  Renderer r(evaluator, grid, options);
  ShadedRun out;
  out.stats = test::renderFrames(r, settings, scene, frames);
  out.image = r.image();
  out.premultiplied = r.premultipliedImage();
  return out;
}

// The same per-ray code and lighting on both backends; the GPU's collisions come from its fp16
// network, so the images agree statistically (as the unshaded ones do: CudaRatioTracking), not
// bit for bit.
TEST(CudaShading, ShadedGpuImageMatchesShadedCpuImage) {
  REQUIRE_GPU();
  const int size = 64, frames = 64;
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpuEval(model);
    const CudaInrEvaluator gpuEval(model);
    const auto range = valueRangeFor(model, cpuEval);
    for (const TrackingOptions& options : {TrackingOptions{}, test::ratioTracking(4.0, 16)}) {
      const RenderScene scene = shadedScene(model, range, true);
      const ShadedRun cpu =
          renderShaded<MacrocellGrid, DeltaTrackingRenderer>(cpuEval, model, scene, options, size, frames);
      const ShadedRun gpu =
          renderShaded<CudaMacrocellGrid, CudaDeltaTrackingRenderer>(gpuEval, model, scene, options, size, frames);
      const ShadedRun flat = renderShaded<CudaMacrocellGrid, CudaDeltaTrackingRenderer>(
          gpuEval, model, shadedScene(model, range, false), options, size, frames);
      const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, cpu.premultiplied);
      const double flatPsnr = test::psnrOverCoverage(flat.image, cpu.image, cpu.premultiplied);
      std::printf("%-32s %s, shaded, %dx%d, %d frames: GPU vs CPU %.2f dB (unshaded GPU vs shaded CPU %.2f dB); "
                  "shading queries GPU %zu CPU %zu, rays %zu\n",
                  fs::path(path).filename().c_str(), primaryEstimatorName(options.estimator), size, size, frames, psnr,
                  flatPsnr, gpu.stats.shadingQueries, cpu.stats.shadingQueries, gpu.stats.rays);
      EXPECT_GE(psnr, 36.0) << path;
      EXPECT_LT(flatPsnr, psnr - 6.0) << path << ": shading changed too little to tell";
      EXPECT_GT(gpu.stats.shadingQueries, 0u) << path;
      EXPECT_LE(gpu.stats.shadingQueries, gpu.stats.rays) << path;  // at most one per ray
      EXPECT_EQ(flat.stats.shadingQueries, 0u) << path;
      EXPECT_EQ(test::nonFinitePixels(gpu.image), 0u) << path;
    }
  }
}

}  // namespace
}  // namespace inr
