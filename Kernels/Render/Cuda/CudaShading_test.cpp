// Gradient shading on the GPU (ctest label `cuda`; skipped, with the reason, without a usable
// GPU): the per-thread network's fp32 forward-mode gradient and the fused kernel's fp16 tangent
// rows against the CPU reference's gradient (the latter also against its CPU emulation), and
// the shaded GPU wavefront image (tangent rows where the model runs fused) against the shaded
// CPU image of the same shipped networks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.cuh"
#include "Evaluator/MlpProgram.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/ModelBox.h"
#include "TestSupport/DevicePoints.h"
#include "TestSupport/FusedTangents.h"
#include "TestSupport/GradientErrors.h"
#include "TestSupport/GradientNorms.h"
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

// The per-thread path (CudaGradientPath::PerThread; the fallback where the tangent rows cannot
// run). Both sides are fp32 forward mode over the same graph (the GPU through the compiled
// program, the CPU through Eigen), so they differ by summation order: relative to the
// gradient's typical size over the sample, within the 1e-3 for fp32.
TEST(CudaShading, GpuGradientMatchesCpuGradient) {
  REQUIRE_GPU();
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpu(model);
    CudaEvaluatorOptions perThread;
    perThread.gradientPath = CudaGradientPath::PerThread;
    const CudaInrEvaluator gpu(model, perThread);
    ASSERT_FALSE(gpu.usesFusedTangents()) << gpu.gradientPath();
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

// The fused kernel's tangent rows on every family: against the fp32 CPU reference within the
// fp16 bounds its emulation is held to on the CPU (TestSupport/FusedTangents.h), and against
// that emulation (the same arithmetic but for summation order and the special-function forms,
// so a quarter of those bounds). 4099 points: not a multiple of any tile's queries.
TEST(CudaShading, FusedTangentGradientMatchesCpuAndEmulation) {
  REQUIRE_GPU();
  for (const test::NamedModel& m : test::tangentTestModels()) {
    SCOPED_TRACE(m.name);
    const CudaInrEvaluator gpu(m.model);
    MlpProgram program = MlpProgram::compile(m.model.architecture);
    if (!program.fusable) {
      EXPECT_FALSE(gpu.usesFusedTangents());
      std::printf("%-40s %s\n", m.name.c_str(), gpu.gradientPath().c_str());
      continue;
    }
    ASSERT_TRUE(gpu.usesFusedTangents()) << gpu.gradientPath();
    program.tangentScale = gpu.tangentScale();
    const float time = float(0.5 * (m.model.domain.timeBegin + m.model.domain.timeEnd));
    const std::vector<QueryPoint> pts = test::randomQueryPoints(m.model, 4099, 31, time);
    const test::ValuesAndWorldGradients got = test::referenceWorldGradients(gpu, pts);
    const test::ValuesAndWorldGradients ref = test::referenceWorldGradients(CpuInrEvaluator(m.model), pts);
    // The emulation is slow (scalar, four directions): its first 512 points.
    const std::vector<QueryPoint> few(pts.begin(), pts.begin() + 512);
    const test::ValuesAndWorldGradients emu = test::emulatedWorldGradients(m.model, program, few);
    const auto asDouble = [](const std::vector<float>& v) { return std::vector<double>(v.begin(), v.end()); };
    const test::GradientError vsCpu = test::relativeErrors(got.gradients, asDouble(ref.gradients));
    const test::GradientError vsEmu = test::relativeErrors(
        std::vector<float>(got.gradients.begin(), got.gradients.begin() + 3 * few.size()), asDouble(emu.gradients));
    double valueErr = 0, range = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      ASSERT_TRUE(std::isfinite(got.values[i]) && std::isfinite(got.gradients[3 * i]) && std::isfinite(got.gradients[3 * i + 1]) &&
                  std::isfinite(got.gradients[3 * i + 2]))
          << "point " << i;
      valueErr = std::max(valueErr, std::fabs(double(got.values[i]) - ref.values[i]));
      range = std::max(range, std::fabs(double(ref.values[i])));
    }
    std::printf("%-40s tangent rows vs fp32: median %.3g p90 %.3g max %.3g; vs emulation: median %.3g p90 %.3g; value max "
                "abs %.3g; %s\n",
                m.name.c_str(), vsCpu.median, vsCpu.quantile90, vsCpu.maxRelative, vsEmu.median, vsEmu.quantile90, valueErr,
                gpu.gradientPath().c_str());
    EXPECT_LE(vsCpu.median, test::kTangentMedianBound);
    EXPECT_LE(vsCpu.quantile90, test::kTangentQuantile90Bound);
    EXPECT_LE(vsEmu.median, test::kTangentMedianBound / 4);
    EXPECT_LE(vsEmu.quantile90, test::kTangentQuantile90Bound / 4);
    EXPECT_LT(valueErr, 3e-2 * std::max(1.0, range));
  }
}

// The device interface of the tangent rows: a device-side count below maxN (the renderer's
// shading batch) writes exactly that many results, a batch of one works, and the generic path's
// models fall back to the per-thread forward mode (a request for tangent rows there throws).
TEST(CudaShading, FusedTangentsTakeTheDeviceCountAndFallBackOffTheFusedPath) {
  REQUIRE_GPU();
  const InrModel model = InrModel::loadFile(test::shippedModels().front());
  const CudaInrEvaluator gpu(model);
  ASSERT_TRUE(gpu.usesFusedTangents()) << gpu.gradientPath();
  const float time = float(model.domain.timeBegin);
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 1000, 5, time);
  cuda::DeviceBuffer<float4> points = test::devicePoints(pts);
  cuda::DeviceBuffer<float4> out(pts.size());
  INR_CUDA_CHECK(cudaMemset(out.get(), 0xff, pts.size() * sizeof(float4)));  // NaN sentinels
  const unsigned count = 777;
  cuda::DeviceBuffer<unsigned> deviceCount(1);
  INR_CUDA_CHECK(cudaMemcpy(deviceCount.get(), &count, sizeof count, cudaMemcpyHostToDevice));
  gpu.evaluateWithGradientDevice(points.get(), deviceCount.get(), int(pts.size()), time, out.get(), nullptr);
  const std::vector<float4> results = out.download(nullptr);
  std::vector<float> values(pts.size()), gradients(3 * pts.size());
  gpu.evaluateWithGradient(pts.data(), pts.size(), values.data(), gradients.data());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i < count) {
      EXPECT_EQ(results[i].x, values[i]) << i;
      EXPECT_EQ(results[i].y, gradients[3 * i]) << i;
    } else {
      EXPECT_TRUE(std::isnan(results[i].x) && std::isnan(results[i].w)) << i << ": past the device count";
    }
  }
  float one, oneGradient[3];
  gpu.evaluateWithGradient(pts.data() + 3, 1, &one, oneGradient);
  EXPECT_EQ(one, values[3]);
  EXPECT_EQ(oneGradient[2], gradients[11]);

  CudaEvaluatorOptions generic;
  generic.path = CudaEvaluatorPath::Generic;
  const CudaInrEvaluator fallback(model, generic);
  EXPECT_FALSE(fallback.usesFusedTangents());
  EXPECT_EQ(fallback.gradientPath().rfind("per-thread", 0), 0u) << fallback.gradientPath();
  generic.gradientPath = CudaGradientPath::FusedTangents;
  EXPECT_THROW(CudaInrEvaluator(model, generic), std::runtime_error);
}

// The tangent rows' configurations are timed at the first gradient call (inside a frame), on
// CudaEvaluatorOptions::tangentAutotuneBatch queries, not the values' autotuneBatch; 0 takes the
// first that fits without timing, a negative batch is refused by name.
TEST(CudaShading, TangentRowsAreTimedOnTheirOwnBatch) {
  REQUIRE_GPU();
  const InrModel model = InrModel::loadFile(test::shippedModels().front());
  CudaEvaluatorOptions options;
  options.tangentAutotuneBatch = 1 << 14;
  const CudaInrEvaluator timed(model, options);
  ASSERT_TRUE(timed.usesFusedTangents()) << timed.gradientPath();
  if (timed.gradientPath().find("(the only configuration)") != std::string::npos)
    GTEST_SKIP() << "one tangent configuration fits this GPU: nothing to time (" << timed.gradientPath() << ")";
  EXPECT_NE(timed.gradientPath().find("batch 16384 / 8192:"), std::string::npos) << timed.gradientPath();
  options.tangentAutotuneBatch = 0;
  const CudaInrEvaluator untimed(model, options);
  EXPECT_EQ(untimed.gradientPath().find("Gq/s"), std::string::npos) << untimed.gradientPath();
  options.tangentAutotuneBatch = -1;
  try {
    CudaInrEvaluator refused(model, options);
    ADD_FAILURE() << "a negative tangentAutotuneBatch was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tangentAutotuneBatch"), std::string::npos) << e.what();
  }
}

// Calls f(path, model, cpu evaluator, GPU evaluator, value range) for every shipped model.
template <typename F>
void forEachShippedModel(F&& f) {
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpuEval(model);
    const CudaInrEvaluator gpuEval(model);
    f(path, model, cpuEval, gpuEval, valueRangeFor(model, cpuEval));
  }
}

struct ShadedRun {
  ImageRGBA image, premultiplied;
  FrameStats stats;
};

// A headlight with a highlight: every term of the lighting in the picture. lightKit: ParaView's
// default view lights instead (VTK's light-list lighting, coloured camera lights).
RenderScene shadedScene(const InrModel& model, const std::array<float, 2>& range, bool shade, bool lightKit = false) {
  RenderScene scene = test::testScene(model, range, false);
  scene.shading.enabled = shade;
  scene.shading.headlight = !lightKit;
  scene.shading.lightList = lightKit;
  if (lightKit) scene.shading.lights = paraviewLightKit();
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
  forEachShippedModel([&](const std::string& path, const InrModel& model, const CpuInrEvaluator& cpuEval,
                          const CudaInrEvaluator& gpuEval, const std::array<float, 2>& range) {
    for (const TrackingOptions& options : {TrackingOptions{}, test::ratioTracking(4.0, 16)})
    for (const bool kit : {false, true}) {
      const RenderScene scene = shadedScene(model, range, true, kit);
      const ShadedRun cpu =
          renderShaded<MacrocellGrid, CpuWavefrontRenderer>(cpuEval, model, scene, options, size, frames);
      const ShadedRun gpu =
          renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(gpuEval, model, scene, options, size, frames);
      const ShadedRun flat = renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(
          gpuEval, model, shadedScene(model, range, false), options, size, frames);
      const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, cpu.premultiplied);
      const double flatPsnr = test::psnrOverCoverage(flat.image, cpu.image, cpu.premultiplied);
      std::printf("%-32s %s, shaded (%s), %dx%d, %d frames: GPU vs CPU %.2f dB (unshaded GPU vs shaded CPU %.2f dB); "
                  "shading queries GPU %zu CPU %zu, rays %zu\n",
                  fs::path(path).filename().c_str(), primaryEstimatorName(options.estimator),
                  kit ? "light kit" : "headlight", size, size, frames, psnr,
                  flatPsnr, gpu.stats.shadingQueries, cpu.stats.shadingQueries, gpu.stats.rays);
      EXPECT_GE(psnr, 36.0) << path;
      EXPECT_LT(flatPsnr, psnr - 6.0) << path << ": shading changed too little to tell";
      EXPECT_GT(gpu.stats.shadingQueries, 0u) << path;
      EXPECT_LE(gpu.stats.shadingQueries, gpu.stats.rays) << path;  // at most one per ray
      EXPECT_EQ(flat.stats.shadingQueries, 0u) << path;
      EXPECT_EQ(test::nonFinitePixels(gpu.image), 0u) << path;
    }
  });
}

// Gradient opacity (Render/Evaluate.h): the GPU loop's queries come with the fused tangent rows'
// gradients and their factor lands beside the value (scatterOpacityKernel); the stage code is
// the CPU's. The images agree statistically (fp16 network and gradient on the GPU), and the factor
// must change the picture (the GPU without it is farther from the CPU with it).
TEST(CudaShading, GradientOpacityGpuImageMatchesCpuImage) {
  REQUIRE_GPU();
  const int size = 64, frames = 64;
  forEachShippedModel([&](const std::string& path, const InrModel& model, const CpuInrEvaluator& cpuEval,
                          const CudaInrEvaluator& gpuEval, const std::array<float, 2>& range) {
    for (const bool shadows : {false, true})
    for (const TrackingOptions& options : {TrackingOptions{}, test::ratioTracking(4.0, 16)}) {
      const RenderScene without = test::testScene(model, range, shadows);
      RenderScene scene = without;
      const double g = test::medianGradientNorm(cpuEval, model, float(scene.time));
      scene.transferFunction.gradientOpacity = {{0.5 * g, 0.0}, {2.0 * g, 1.0}};
      const ShadedRun cpu =
          renderShaded<MacrocellGrid, CpuWavefrontRenderer>(cpuEval, model, scene, options, size, frames);
      const ShadedRun gpu =
          renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(gpuEval, model, scene, options, size, frames);
      const ShadedRun off =
          renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(gpuEval, model, without, options, size, frames);
      const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, off.premultiplied);
      const double offPsnr = test::psnrOverCoverage(off.image, cpu.image, off.premultiplied);
      std::printf("%-32s %s%s, gradient opacity (median |grad| %.3g), %dx%d, %d frames: GPU vs CPU %.2f dB "
                  "(GPU without it %.2f dB); queries GPU %zu CPU %zu\n",
                  fs::path(path).filename().c_str(), primaryEstimatorName(options.estimator),
                  shadows ? " + shadows" : "", g, size, size, frames, psnr, offPsnr, gpu.stats.queries,
                  cpu.stats.queries);
      EXPECT_GE(psnr, 34.0) << path;
      EXPECT_LT(offPsnr, psnr - 6.0) << path << ": the gradient opacity changed too little to tell";
      EXPECT_EQ(test::nonFinitePixels(gpu.image), 0u) << path;
    }
  });
}

// 2D transfer functions (TransferFunction::transfer2D): the same gradient path as gradient
// opacity, the 2D table uploaded (DeviceTransferFunction) and looked up by the shared stage code.
// The table: the scene's 1D colour and opacity in every row, the opacity faded below twice the
// median |grad f| and the colour turning orange with it. GPU and CPU images agree statistically;
// the GPU with the 1D function alone must be farther from the CPU's 2D picture.
TransferFunction::Transfer2D gradientFaded2D(const TransferFunction& tf, double medianGradient) {
  const TransferFunctionTable table(tf);
  const TransferFunctionView v = table.view();
  TransferFunction::Transfer2D t;
  t.width = 256;
  t.height = 16;
  t.scalarLo = v.lo;
  t.scalarHi = v.hi;
  t.gradientLo = 0.0;
  t.gradientHi = 4.0 * medianGradient;
  for (int j = 0; j < t.height; ++j) {
    const double g = t.gradientHi * j / (t.height - 1);
    const double fade = std::clamp((g - 0.5 * medianGradient) / (1.5 * medianGradient), 0.0, 1.0);
    const double tint = g / t.gradientHi;
    for (int i = 0; i < t.width; ++i) {
      const Vec4f c = lookupTransferFunction(v, float(v.lo + (double(v.hi) - v.lo) * i / (t.width - 1)));
      t.rgba.push_back(float(c.x + (1.0 - c.x) * tint));
      t.rgba.push_back(float(c.y + (0.55 - c.y) * tint));
      t.rgba.push_back(float(c.z + (0.1 - c.z) * tint));
      t.rgba.push_back(float(c.w * fade));
    }
  }
  return t;
}

TEST(CudaShading, Transfer2DGpuImageMatchesCpuImage) {
  REQUIRE_GPU();
  const int size = 64, frames = 64;
  forEachShippedModel([&](const std::string& path, const InrModel& model, const CpuInrEvaluator& cpuEval,
                          const CudaInrEvaluator& gpuEval, const std::array<float, 2>& range) {
    for (const bool shadows : {false, true})
    for (const TrackingOptions& options : {TrackingOptions{}, test::ratioTracking(4.0, 16), test::unbiasedMarch(2.0)}) {
      const RenderScene without = test::testScene(model, range, shadows);
      RenderScene scene = without;
      const double g = test::medianGradientNorm(cpuEval, model, float(scene.time));
      scene.transferFunction.transfer2D = gradientFaded2D(without.transferFunction, g);
      const ShadedRun cpu =
          renderShaded<MacrocellGrid, CpuWavefrontRenderer>(cpuEval, model, scene, options, size, frames);
      const ShadedRun gpu =
          renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(gpuEval, model, scene, options, size, frames);
      const ShadedRun off =
          renderShaded<CudaMacrocellGrid, CudaWavefrontRenderer>(gpuEval, model, without, options, size, frames);
      const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, off.premultiplied);
      const double offPsnr = test::psnrOverCoverage(off.image, cpu.image, off.premultiplied);
      std::printf("%-32s %s%s, 2D transfer function (median |grad| %.3g), %dx%d, %d frames: GPU vs CPU %.2f dB "
                  "(GPU with the 1D function %.2f dB); queries GPU %zu CPU %zu\n",
                  fs::path(path).filename().c_str(), primaryEstimatorName(options.estimator),
                  shadows ? " + shadows" : "", g, size, size, frames, psnr, offPsnr, gpu.stats.queries,
                  cpu.stats.queries);
      EXPECT_GE(psnr, 34.0) << path;
      EXPECT_LT(offPsnr, psnr - 6.0) << path << ": the 2D transfer function changed too little to tell";
      EXPECT_EQ(test::nonFinitePixels(gpu.image), 0u) << path;
    }
  });
}

}  // namespace
}  // namespace inr
