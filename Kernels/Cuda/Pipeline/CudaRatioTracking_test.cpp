// The ratio-tracking primary estimator (Render/RatioTracking.h) on the GPU pipeline, against the
// CPU backend and against delta tracking (ctest label `cuda`; skipped, with the reason, without a
// usable GPU).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "Cuda/CudaInrEvaluator.h"
#include "Cuda/Pipeline/AnalyticDeviceField.h"
#include "Cuda/Pipeline/CudaDeltaTrackingRenderer.h"
#include "Cuda/Pipeline/CudaMacrocellGrid.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/DeltaTrackingRenderer.h"
#include "Render/ModelBox.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

namespace fs = std::filesystem;

TrackingOptions ratio(double scale, int points) {
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Ratio;
  t.majorantScale = scale;
  t.pointsPerIteration = points;
  return t;
}

int envInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v ? std::max(1, std::atoi(v)) : fallback;
}

struct RatioRun {
  ImageRGBA image, premultiplied;
  FrameStats stats;
};

template <typename Grid, typename Renderer, typename Field>
RatioRun renderAnalytic(const Field& field, const TrackingOptions& options, bool shadows, int size, int frames) {
  Grid grid(field, test::kCubeBox, 0.0, 1.0, test::cubeMacrocells(16, 4));
  Renderer r(field, grid, options);
  test::SceneSetup s = test::obliqueCubeScene(size, 5);
  s.settings.pixelJitter = false;
  s.scene.transferFunction = TransferFunction::preset(0.2, 0.9, 0.5);
  s.scene.transferFunction.unitDistance = 0.25;
  test::lightScene(s.scene, shadows, ShadowEstimator::Ratio);
  RatioRun out;
  out.stats = test::renderFrames(r, s.settings, s.scene, frames);
  out.image = r.image();
  out.premultiplied = r.premultipliedImage();
  return out;
}

// Same random streams and per-ray code on both backends: the GPU's ratio-tracked image is the
// CPU's up to the device's ulps (sinf, expf in the field) and its concurrent refinement.
TEST(CudaRatioTracking, GpuImageMatchesCpuImageOnAnalyticField) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  for (bool shadows : {false, true}) {
    const RatioRun cpu = renderAnalytic<MacrocellGrid, DeltaTrackingRenderer>(static_cast<const FieldEvaluator&>(field),
                                                                          ratio(4.0, 16), shadows, 64, 4);
    const RatioRun gpu = renderAnalytic<CudaMacrocellGrid, CudaDeltaTrackingRenderer>(
        static_cast<const DeviceFieldEvaluator&>(field), ratio(4.0, 16), shadows, 64, 4);
    const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, cpu.premultiplied);
    std::printf("ratio tracking%s, 64x64, 4 frames: GPU vs CPU %.2f dB; queries GPU %zu CPU %zu; iterations GPU %d "
                "CPU %d\n",
                shadows ? " (shadows)" : "", psnr, gpu.stats.queries, cpu.stats.queries, gpu.stats.iterations,
                cpu.stats.iterations);
    EXPECT_GE(psnr, 50.0);
    const double q = double(cpu.stats.queries);
    EXPECT_NEAR(double(gpu.stats.queries), q, 0.01 * q);
    EXPECT_EQ(gpu.stats.iterations, cpu.stats.iterations);
    EXPECT_EQ(test::nonFinitePixels(gpu.image), 0u);
  }
}

// The GPU's batching (points per iteration, the listed rays, the speculative loop) does not
// change the image (no shadows, refinement off: see RatioTracking.ImageDoesNotDependOnPointsPerIteration).
TEST(CudaRatioTracking, ImageDoesNotDependOnPointsPerIteration) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  auto gpu = [&](int points) {
    TrackingOptions t = ratio(3.0, points);
    t.refineMacrocells = false;
    return renderAnalytic<CudaMacrocellGrid, CudaDeltaTrackingRenderer>(static_cast<const DeviceFieldEvaluator&>(field),
                                                                        t, false, 64, 2);
  };
  const RatioRun one = gpu(1), again = gpu(1);
  if (one.image.data != again.image.data)
    GTEST_SKIP() << "the GPU pipeline is not bit-reproducible run to run on this device: nothing to compare";
  const RatioRun many = gpu(32);
  EXPECT_TRUE(one.image.data == many.image.data);
  EXPECT_GE(many.stats.queries, one.stats.queries);
  EXPECT_LT(4 * many.stats.iterations, one.stats.iterations);
}

// The shipped networks (fp16 tensor-core evaluator) with ratio tracking: the GPU image agrees
// with the CPU's (fp32) like delta tracking's does, and converges to delta tracking's image.
TEST(CudaRatioTracking, ShippedModelsMatchCpuAndDeltaTracking) {
  REQUIRE_GPU();
  const int size = envInt("INR_GPU_TEST_SIZE", 64), frames = envInt("INR_GPU_TEST_FRAMES", 256);
  for (const auto& path : test::shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpuEval(model);
    const CudaInrEvaluator gpuEval(model);
    const auto range = valueRangeFor(model, cpuEval);
    const Box3f box = modelWorldBox(model);
    RenderSettings settings;
    settings.width = settings.height = size;
    settings.seed = 9;
    settings.pixelJitter = false;
    const RenderScene scene = test::testScene(model, range, false);
    const double t0 = model.domain.timeBegin, t1 = model.domain.timeEnd;

    MacrocellGrid cpuGrid(cpuEval, box, t0, t1, test::testMacrocells());
    DeltaTrackingRenderer cpu(cpuEval, cpuGrid, ratio(4.0, 16));
    test::renderFrames(cpu, settings, scene, frames / 4);
    CudaMacrocellGrid gpuGrid(gpuEval, box, t0, t1, test::testMacrocells());
    CudaDeltaTrackingRenderer gpu(gpuEval, gpuGrid, ratio(4.0, 16));
    const FrameStats g = test::renderFrames(gpu, settings, scene, frames / 4);
    CudaMacrocellGrid deltaGrid(gpuEval, box, t0, t1, test::testMacrocells());
    CudaDeltaTrackingRenderer delta(gpuEval, deltaGrid);
    test::renderFrames(delta, settings, scene, 8 * frames);

    const ImageRGBA reference = delta.image(), coverage = delta.premultipliedImage();
    const double vsCpu = test::psnrOverCoverage(gpu.image(), cpu.image(), cpu.premultipliedImage());
    const double vsDelta = test::psnrOverCoverage(gpu.image(), reference, coverage);
    std::printf("%-28s ratio k=4, %dx%d, %d frames: GPU vs CPU %.2f dB, vs GPU delta (%d frames) %.2f dB; "
                "%.1f iterations, %zu queries per frame\n",
                fs::path(path).filename().c_str(), size, size, frames / 4, vsCpu, 8 * frames, vsDelta,
                double(g.iterations) / (frames / 4), g.queries / std::size_t(frames / 4));
    EXPECT_GE(vsCpu, 40.0) << path;
    EXPECT_GE(vsDelta, 38.0) << path;
    EXPECT_EQ(test::nonFinitePixels(gpu.image()), 0u) << path;
    EXPECT_EQ(gpu.counters().truncatedFrames, 0) << path;
  }
}

}  // namespace
}  // namespace inr
