// The OptiX GAS traversal against the DDA (label optix): the same converged images with and
// without shadows and with gradient opacity, the same query counts within statistical bounds, and
// a GAS rebuilt after a time change and a transfer-function edit that renders what a fresh session
// renders. Without a GPU, or in a build or on a driver without OptiX, the tests report skipped and
// say why.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/DeviceTraversal.h"
#include "TestSupport/GradientNorms.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

int envInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : fallback;
}

// Skips (with the reason) unless a GPU is usable and OptiX initialises on it.
#define REQUIRE_OPTIX()                                                                   \
  do {                                                                                    \
    const CudaDeviceInfo dev_ = queryCudaDevice();                                        \
    if (!dev_.usable) GTEST_SKIP() << "no GPU: " << dev_.reason;                          \
    try {                                                                                 \
      (void)makeOptixTraversal(TraversalOptions{});                                       \
    } catch (const std::exception& e_) {                                                  \
      GTEST_SKIP() << "OptiX unavailable: " << e_.what();                                 \
    }                                                                                     \
  } while (0)

InrModel testModel() { return InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr"); }

std::unique_ptr<RenderSession> session(const InrModel& model, TraversalKind kind, bool refine = true) {
  RenderSessionOptions o;
  o.backend = RenderBackend::Cuda;
  o.allowFallback = false;
  o.macrocells = test::testMacrocells();
  o.traversal.kind = kind;
  o.tracking.refineMacrocells = refine;
  auto s = RenderSession::create(model, o);
  EXPECT_NE(s->description().find(kind == TraversalKind::Optix ? "traversal optix" : "traversal dda"),
            std::string::npos)
      << s->description();
  return s;
}

RenderSettings settingsOf(int size) {
  RenderSettings s;
  s.width = s.height = size;
  s.seed = 5;
  return s;
}

struct Rendered {
  ImageRGBA image, premultiplied;
  std::vector<double> queries;  // per frame, both legs
  FrameStats last;
};

Rendered render(RenderSession& s, const RenderSettings& settings, const RenderScene& scene, int frames) {
  s.setSettings(settings);
  s.setScene(scene);
  Rendered r;
  for (int k = 0; k < frames; ++k) {
    r.last = s.renderFrame();
    r.queries.push_back(double(r.last.totalQueries()));
  }
  r.image = s.image();
  r.premultiplied = s.premultipliedImage();
  return r;
}

void meanAndVariance(const std::vector<double>& v, double& mean, double& variance) {
  mean = 0;
  for (double x : v) mean += x;
  mean /= double(v.size());
  variance = 0;
  for (double x : v) variance += (x - mean) * (x - mean);
  variance /= double(v.size() - 1);
}

// Converged images agree over the covered pixels (the two traversals draw different random
// numbers, so the difference is the two estimates' noise), and the mean queries per frame agree
// within six standard errors.
TEST(OptixTraversal, ConvergedImagesAndQueryCountsMatchTheDda) {
  REQUIRE_OPTIX();
  const InrModel model = testModel();
  const int size = envInt("INR_GPU_TEST_SIZE", 64), frames = envInt("INR_OPTIX_TEST_FRAMES", 4096);
  auto dda = session(model, TraversalKind::Dda);
  auto optix = session(model, TraversalKind::Optix);
  const std::array<float, 2> range = valueRangeFor(model, dda->evaluator());
  for (bool shadows : {false, true}) {
    const RenderScene scene = test::testScene(model, range, shadows);
    const Rendered a = render(*dda, settingsOf(size), scene, frames);
    const Rendered b = render(*optix, settingsOf(size), scene, frames);
    const double psnr = test::psnrOverCoverage(b.image, a.image, a.premultiplied);
    double ma, va, mb, vb;
    meanAndVariance(a.queries, ma, va);
    meanAndVariance(b.queries, mb, vb);
    const double z = std::fabs(ma - mb) / std::sqrt((va + vb) / double(frames));
    std::printf("%s %dx%d, %d frames: PSNR optix vs dda %.2f dB (covered pixels); queries/frame dda %.1f optix %.1f "
                "(z %.2f); GAS %zu cells, %zu bytes\n",
                shadows ? "shadows" : "no shadows", size, size, frames, psnr, ma, mb, z, b.last.traversalPrimitives,
                b.last.traversalBytes);
    EXPECT_GE(psnr, 40.0) << (shadows ? "with shadows" : "without shadows");
    EXPECT_LT(z, 6.0) << "mean queries per frame differ beyond statistical bounds";
    EXPECT_EQ(test::nonFinitePixels(b.image), 0u);
    EXPECT_GT(b.last.traversalPrimitives, 0u);
    EXPECT_GT(b.last.traversalBytes, 0u);
    EXPECT_EQ(a.last.traversalPrimitives, 0u) << "the DDA keeps no structure";
  }
}

// Gradient opacity through OptiX: the intersection program resolves candidates with the stage
// code that reads the factor the evaluation stage stored beside each value (Render/Traverse.h), so
// with a ramp over |grad f| the OptiX image converges to the DDA's, and the ramp must change the
// picture (the DDA without it is farther from the DDA with it).
TEST(OptixTraversal, GradientOpacityImagesMatchTheDda) {
  REQUIRE_OPTIX();
  const InrModel model = testModel();
  const int size = envInt("INR_GPU_TEST_SIZE", 64), frames = envInt("INR_OPTIX_TEST_FRAMES", 4096) / 2;
  auto dda = session(model, TraversalKind::Dda);
  auto optix = session(model, TraversalKind::Optix);
  const std::array<float, 2> range = valueRangeFor(model, dda->evaluator());
  const CpuInrEvaluator cpu(model);
  for (bool shadows : {false, true}) {
    const RenderScene without = test::testScene(model, range, shadows);
    RenderScene scene = without;
    const double g = test::medianGradientNorm(cpu, model, float(scene.time));
    scene.transferFunction.gradientOpacity = {{0.5 * g, 0.0}, {2.0 * g, 1.0}};
    const Rendered a = render(*dda, settingsOf(size), scene, frames);
    const Rendered b = render(*optix, settingsOf(size), scene, frames);
    const Rendered off = render(*dda, settingsOf(size), without, frames);
    const double psnr = test::psnrOverCoverage(b.image, a.image, off.premultiplied);
    const double offPsnr = test::psnrOverCoverage(off.image, a.image, off.premultiplied);
    std::printf("%s %dx%d, %d frames, gradient opacity (median |grad| %.3g): PSNR optix vs dda %.2f dB (dda without "
                "it %.2f dB); gradient queries in the last frame dda %zu optix %zu\n",
                shadows ? "shadows" : "no shadows", size, size, frames, g, psnr, offPsnr,
                a.last.gradientOpacityQueries, b.last.gradientOpacityQueries);
    EXPECT_GE(psnr, 40.0) << (shadows ? "with shadows" : "without shadows");
    EXPECT_LT(offPsnr, psnr - 6.0) << "the gradient opacity changed too little to tell";
    EXPECT_GT(b.last.gradientOpacityQueries, 0u);
    EXPECT_EQ(test::nonFinitePixels(b.image), 0u);
  }
}

// A session whose GAS was rebuilt after a time change and a transfer-function edit renders what
// a fresh session given the final scene renders (refinement off, so both see the same majorants:
// the same GAS, the same random numbers). A GAS left stale would miss cells the edit made
// non-empty, or keep ones it emptied.
TEST(OptixTraversal, RebuiltGasRendersLikeAFreshSession) {
  REQUIRE_OPTIX();
  const InrModel model = testModel();
  const int frames = 64;
  auto edited = session(model, TraversalKind::Optix, /*refine=*/false);
  const std::array<float, 2> range = valueRangeFor(model, edited->evaluator());
  RenderScene scene = test::testScene(model, range, true);
  const Rendered before = render(*edited, settingsOf(64), scene, 4);
  // Time change, then a transfer-function edit that empties the low half of the value range.
  scene.time = model.domain.timeBegin + 0.2 * (model.domain.timeEnd - model.domain.timeBegin);
  const Rendered afterTime = render(*edited, settingsOf(64), scene, 2);
  scene.transferFunction.opacity = {{range[0], 0.0}, {range[0] + 0.5 * (range[1] - range[0]), 0.0}, {range[1], 0.9}};
  const Rendered a = render(*edited, settingsOf(64), scene, frames);
  auto fresh = session(model, TraversalKind::Optix, /*refine=*/false);
  const Rendered b = render(*fresh, settingsOf(64), scene, frames);
  const double psnr = test::psnrOverCoverage(a.image, b.image, b.premultiplied);
  std::printf("rebuilt vs fresh: PSNR %.2f dB; GAS cells %zu -> %zu -> %zu (fresh %zu); build %.3f ms\n", psnr,
              before.last.traversalPrimitives, afterTime.last.traversalPrimitives, a.last.traversalPrimitives,
              b.last.traversalPrimitives, a.last.traversalBuildMs);
  EXPECT_EQ(a.last.traversalPrimitives, b.last.traversalPrimitives);
  EXPECT_NE(before.last.traversalPrimitives, a.last.traversalPrimitives) << "the edit should change the non-empty cells";
  EXPECT_GE(psnr, 60.0) << "same majorants, same GAS, same draws: the same image up to evaluator rounding";
}

MajorantGridView gridOver(const float* majorant, int m) {
  MajorantGridView g{};
  g.box = Box3f{Vec3f{-1.f, -1.f, -1.f}, Vec3f{1.f, 1.f, 1.f}};
  g.dims = Int3{m, m, m};
  g.cellSize = Vec3f{2.f / m, 2.f / m, 2.f / m};
  g.invCellSize = Vec3f{m / 2.f, m / 2.f, m / 2.f};
  g.majorant = majorant;
  return g;
}

std::size_t deviceBytesInUse() {
  std::size_t freeBytes = 0, total = 0;
  EXPECT_EQ(cudaMemGetInfo(&freeBytes, &total), cudaSuccess);
  return total - freeBytes;
}

// The GAS is built only when the set of selected cells changes (the intersection program reads
// the majorants themselves from the grid): widened majorants reuse it, an emptied or a filled
// cell rebuilds it; a new grid shape reserves anew. Its device memory is reserved once per grid
// shape for the worst case, so hundreds of updates with varying selections allocate nothing.
TEST(OptixTraversal, BuildsOnlyWhenTheSelectedCellsChangeAndNeverAllocatesAgain) {
  REQUIRE_OPTIX();
  auto t = makeOptixTraversal(TraversalOptions{});
  const int m = 32, cells = m * m * m;
  std::vector<float> host(cells, 0.f);
  for (int c = 0; c < cells; c += 3) host[c] = 1.f;  // a third of the cells
  cuda::DeviceBuffer<float> majorant(cells);
  auto upload = [&] {
    INR_CUDA_CHECK(cudaMemcpy(majorant.get(), host.data(), cells * sizeof(float), cudaMemcpyHostToDevice));
  };
  upload();
  const MajorantGridView g = gridOver(majorant.get(), m);
  t->majorantsChanged(g, nullptr);
  TraversalBuildInfo info = t->buildInfo();
  EXPECT_EQ(info.builds, 1u);
  EXPECT_EQ(info.primitives, std::size_t((cells + 2) / 3));
  EXPECT_EQ(info.reservations, 1u);
  const std::size_t reserved = info.reservedBytes;

  for (float& v : host) v *= 2.f;  // widened majorants (refinement): same cells
  upload();
  t->majorantsChanged(g, nullptr);
  info = t->buildInfo();
  EXPECT_EQ(info.builds, 1u) << "same selected cells: no build";
  EXPECT_EQ(info.reuses, 1u);
  EXPECT_FALSE(info.lastRebuilt);

  host[1] = 0.5f;  // a cell becomes non-empty
  upload();
  t->majorantsChanged(g, nullptr);
  info = t->buildInfo();
  EXPECT_EQ(info.builds, 2u);
  EXPECT_TRUE(info.lastRebuilt);
  EXPECT_EQ(info.primitives, std::size_t((cells + 2) / 3 + 1));

  host[0] = 0.f;  // a cell becomes empty
  upload();
  t->majorantsChanged(g, nullptr);
  info = t->buildInfo();
  EXPECT_EQ(info.builds, 3u);
  EXPECT_EQ(info.primitives, std::size_t((cells + 2) / 3));

  // Hundreds of updates with selections from nearly empty to full (consecutive strides always
  // differ: 7 is invertible mod 11), each one a build, none an allocation.
  const std::size_t before = deviceBytesInUse();
  const std::size_t buildsBefore = t->buildInfo().builds, reusesBefore = t->buildInfo().reuses;
  for (int k = 0; k < 300; ++k) {
    const int stride = 1 + (k * 7) % 11;
    for (int c = 0; c < cells; ++c) host[c] = (c % stride == 0) ? 1.f : 0.f;
    upload();
    t->majorantsChanged(g, nullptr);
  }
  INR_CUDA_CHECK(cudaDeviceSynchronize());
  const std::size_t after = deviceBytesInUse();
  info = t->buildInfo();
  std::printf("300 updates: %zu builds, %zu reuses; reserved %.2f MB; device memory %+.2f MB\n", info.builds,
              info.reuses, info.reservedBytes / 1048576.0, (double(after) - double(before)) / 1048576.0);
  EXPECT_EQ(info.reservedBytes, reserved);
  EXPECT_EQ(info.reservations, 1u) << "an update allocated";
  EXPECT_EQ(info.builds - buildsBefore, 300u) << "every changed selection builds";
  EXPECT_EQ(info.reuses, reusesBefore);
  EXPECT_LE(after, before + (std::size_t(2) << 20)) << "device memory grew over updates";

  // Another grid shape: reserved for it, built.
  cuda::DeviceBuffer<float> small(8 * 8 * 8);
  std::vector<float> ones(8 * 8 * 8, 1.f);
  INR_CUDA_CHECK(cudaMemcpy(small.get(), ones.data(), ones.size() * sizeof(float), cudaMemcpyHostToDevice));
  const std::size_t builds = info.builds;
  t->majorantsChanged(gridOver(small.get(), 8), nullptr);
  info = t->buildInfo();
  EXPECT_EQ(info.builds, builds + 1);
  EXPECT_EQ(info.reservations, 2u);
  EXPECT_EQ(info.primitives, 512u);
  EXPECT_LT(info.reservedBytes, reserved);
  // The same shape and cells in another box (other AABBs): built.
  MajorantGridView moved = gridOver(small.get(), 8);
  moved.box.hi = Vec3f{2.f, 2.f, 2.f};
  t->majorantsChanged(moved, nullptr);
  EXPECT_EQ(t->buildInfo().builds, builds + 2) << "a moved box must rebuild";
}

// Explicit OptiX where it cannot run is an error naming the reason; auto reports its choice.
TEST(OptixTraversal, AutoReportsItsChoice) {
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) GTEST_SKIP() << "no GPU: " << dev.reason;
  std::string reason;
  auto t = makeDeviceTraversal(TraversalOptions{}, reason);
  std::printf("auto: %s\n", reason.c_str());
  EXPECT_NE(reason.find("auto"), std::string::npos) << reason;
  EXPECT_STREQ(t->name(), reason.rfind("optix", 0) == 0 ? "optix" : "dda");
  TraversalOptions bad;
  bad.gasMinMajorant = -1.f;
  EXPECT_THROW(makeDeviceTraversal(bad, reason), std::invalid_argument);
}

}  // namespace
}  // namespace inr
