// The ratio-tracking primary estimator (RatioTracking.h) on the CPU backend: unbiased (the same
// converged image as delta tracking), less noise per frame, independent of how its points are
// batched and of the thread count.
#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <stdexcept>

#include "Render/CpuWavefrontRenderer.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::meanCoverage;
using test::SceneSetup;

// Orthographic view down -z through [-1, 1]^3 (every ray crosses 2 units of medium), 48 x 48.
SceneSetup slabScene(double alpha, double unitDistance) {
  SceneSetup s;
  s.settings.width = s.settings.height = 48;
  s.settings.seed = 7;
  s.scene.camera = Camera::framing(test::kCubeBox);
  s.scene.camera.parallelProjection = true;
  s.scene.camera.parallelScale = 0.9;
  TransferFunction tf;
  tf.color = {{0, 0.2, 0.6, 1.0}, {1, 0.2, 0.6, 1.0}};
  tf.opacity = {{0, alpha}, {1, alpha}};
  tf.unitDistance = unitDistance;
  s.scene.transferFunction = tf;
  return s;
}

SceneSetup smoothScene(int size, bool shadows) {
  SceneSetup s = test::obliqueCubeScene(size, 3);
  s.settings.pixelJitter = false;
  s.scene.transferFunction = TransferFunction::preset(0.2, 0.9, 0.5);
  s.scene.transferFunction.unitDistance = 0.25;
  test::lightScene(s.scene, shadows);
  return s;
}

struct Rendered {
  ImageRGBA image, premultiplied;
  FrameStats total;
};

Rendered render(const FieldEvaluator& f, const SceneSetup& setup, TrackingOptions options, int frames,
                const QueryReductionSettings& q = QueryReductionSettings{}) {
  MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 4));
  CpuWavefrontRenderer r(f, grid, options);
  r.setQueryReduction(q);
  Rendered out;
  out.total = test::renderFrames(r, setup.settings, setup.scene, frames);
  out.image = r.image();
  out.premultiplied = r.premultipliedImage();
  return out;
}

TEST(RatioTracking, HomogeneousSlabIsUnbiasedWithLessNoise) {
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  const SceneSetup setup = slabScene(0.3, 0.5);
  const double sigma = -std::log(1.0 - 0.3) / 0.5;
  const double p = 1.0 - std::exp(-sigma * 2.0);  // the slab's opacity
  const int frames = 20;
  const Rendered delta = render(f, setup, TrackingOptions{}, frames);
  const Rendered r4 = render(f, setup, test::ratioTracking(4.0), frames);
  // Delta tracking's coverage is a mean of Bernoulli(p) draws; ratio tracking's has a smaller
  // variance, so delta's 4-sigma bound is a loose bound for it.
  const double n = 48.0 * 48.0 * frames;
  const double bound = 4.0 * std::sqrt(p * (1 - p) / n);
  EXPECT_NEAR(meanCoverage(delta.premultiplied), p, bound);
  EXPECT_NEAR(meanCoverage(r4.premultiplied), p, bound);
  // Emission over coverage is the medium's colour.
  EXPECT_NEAR(r4.premultiplied.data[4 * 100 + 2] / r4.premultiplied.data[4 * 100 + 3], 1.0f, 1e-4);
  // Per-pixel variance of the displayed mean (the convergence estimate's input): several times
  // lower, for about k times the queries.
  EXPECT_LT(r4.total.varianceSum, 0.25 * delta.total.varianceSum);
  EXPECT_GT(r4.total.queries, 2 * delta.total.queries);
  // With an exact majorant and k = 1 every point is a real collision: ratio tracking's weights
  // are 1, it is the collision estimator again.
  const Rendered r1 = render(f, setup, test::ratioTracking(1.0), frames);
  EXPECT_NEAR(meanCoverage(r1.premultiplied), p, bound);
}

// `options` after `frames` frames against a long delta-tracking reference, over the pixels the
// volume covers.
double psnrAgainstDelta(bool shadows, int frames, const TrackingOptions& options) {
  test::FunctionField f(test::smoothField);
  const SceneSetup setup = smoothScene(32, shadows);
  const Rendered reference = render(f, setup, TrackingOptions{}, 3000);
  const Rendered r = render(f, setup, options, frames);
  return test::psnrOverCoverage(r.image, reference.image, reference.premultiplied);
}
double psnrAgainstDelta(bool shadows, int frames, double scale) { return psnrAgainstDelta(shadows, frames, test::ratioTracking(scale)); }

TEST(RatioTracking, ConvergesToDeltaTracking) {
  const double psnr = psnrAgainstDelta(false, 400, 4.0);
  std::printf("ratio tracking (400 frames, k = 4) vs delta tracking (3000 frames): %.2f dB over the volume\n", psnr);
  EXPECT_GE(psnr, 40.0);
}

TEST(RatioTracking, ConvergesToDeltaTrackingWithShadows) {
  const double psnr = psnrAgainstDelta(true, 400, 4.0);
  std::printf("ratio tracking with shadows (400 frames, k = 4) vs delta tracking (3000 frames): %.2f dB\n", psnr);
  EXPECT_GE(psnr, 38.0);
}

TEST(RatioTracking, NotConvergedAfterOneFrame) {
  // Guards the two tests above against a comparison that cannot fail.
  EXPECT_LT(psnrAgainstDelta(false, 1, 4.0), 36.0);
}

// The batching (points per iteration) does not change the estimate: the same points, folded in
// the same order with the same draws. Refinement off and no shadows: a bigger batch draws points
// past the one where roulette ends a ray, and those still refine their macrocells (changing later
// frames' majorants) and advance the ray's stream (which the shadow leg continues).
TEST(RatioTracking, ImageDoesNotDependOnPointsPerIteration) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = smoothScene(40, false);
  setup.settings.pixelJitter = true;
  auto run = [&](int points) {
    TrackingOptions t = test::ratioTracking(3.0, points);
    t.refineMacrocells = false;
    return render(f, setup, t, 3);
  };
  const Rendered one = run(1), many = run(16);
  EXPECT_TRUE(one.image.data == many.image.data);
  EXPECT_GE(many.total.queries, one.total.queries);  // points past a roulette end are drawn too
  // ... while the batches are fuller: far fewer traverse-evaluate iterations.
  EXPECT_LT(4 * many.total.iterations, one.total.iterations);
}

TEST(RatioTracking, IdenticalImagesForOneAndManyThreads) {
  auto run = [](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    test::FunctionField f(test::smoothField);
    SceneSetup setup = smoothScene(96, true);  // above kParallelMinItems
    setup.settings.pixelJitter = true;
    const Rendered r = render(f, setup, test::ratioTracking(2.0, 8), 2);
    omp_set_num_threads(saved);
    return r.image.data;
  };
  EXPECT_TRUE(run(1) == run(4));
}

TEST(RatioTracking, PruningAnswersPointsWithoutQueries) {
  test::FunctionField f(test::smoothField);
  const SceneSetup setup = smoothScene(40, false);
  const Rendered plain = render(f, setup, test::ratioTracking(4.0), 4);
  const Rendered pruned = render(f, setup, test::ratioTracking(4.0), 4, test::pruningAt(0.5, 0.1));
  EXPECT_GT(pruned.total.pruned, 0u);
  EXPECT_LT(pruned.total.queries, plain.total.queries);
  EXPECT_EQ(test::nonFinitePixels(pruned.image), 0u);
  // K-independence holds with pruning too (pruned points are folded in at once); one frame, so
  // refinement has not changed any majorant yet.
  const Rendered prunedOne = render(f, setup, test::ratioTracking(4.0, 1), 1, test::pruningAt(0.5, 0.1));
  const Rendered prunedMany = render(f, setup, test::ratioTracking(4.0, 16), 1, test::pruningAt(0.5, 0.1));
  EXPECT_TRUE(prunedOne.image.data == prunedMany.image.data);
}

TEST(RatioTracking, WorkIsBoundedInOpaqueMedia) {
  // A tiny unit distance: extinction ~2e5 per unit, so a ray could draw hundreds of thousands of
  // points. Roulette ends rays in opaque matter after a few tens of points (T falls by 1 - 1/k
  // per point); with k = 1024 the collision cap (2 x maxCollisionsPerRay points) ends them,
  // counted and warned about once.
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  const SceneSetup setup = slabScene(0.9, 1e-5);
  auto run = [&](double scale, std::string& warning) {
    TrackingOptions t = test::ratioTracking(scale, 64);
    t.maxCollisionsPerRay = 64;
    MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 4));
    CpuWavefrontRenderer r(f, grid, t);
    r.setWarningHandler([&](const std::string& m) { warning = m; });
    const FrameStats st = test::renderFrames(r, setup.settings, setup.scene, 1);
    EXPECT_EQ(test::nonFinitePixels(r.image()), 0u);
    return st;
  };
  std::string warning;
  const FrameStats roulette = run(4.0, warning);
  EXPECT_EQ(roulette.cappedRays, 0u);
  EXPECT_LE(roulette.queries, std::size_t(48 * 48) * 64);
  EXPECT_TRUE(warning.empty());
  const FrameStats capped = run(1024.0, warning);
  EXPECT_GT(capped.cappedRays, 0u);
  EXPECT_LE(capped.queries, std::size_t(48 * 48) * (2 * 64 + 32));
  EXPECT_NE(warning.find("cut off"), std::string::npos);
}

// ---- unbiased ray marching (PrimaryEstimator::March) ----

TEST(RatioTracking, MarchHomogeneousSlabIsUnbiasedWithLittleNoise) {
  // A constant field: after the first comb point the control is exact, the residual factors are
  // 1 and the comb integrates T sigma c; only the comb's offsets vary.
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  const SceneSetup setup = slabScene(0.3, 0.5);
  const double sigma = -std::log(1.0 - 0.3) / 0.5;
  const double p = 1.0 - std::exp(-sigma * 2.0);
  const int frames = 20;
  const Rendered delta = render(f, setup, TrackingOptions{}, frames);
  const Rendered m = render(f, setup, test::unbiasedMarch(4.0), frames);
  const double n = 48.0 * 48.0 * frames;
  EXPECT_NEAR(meanCoverage(m.premultiplied), p, 0.25 * 4.0 * std::sqrt(p * (1 - p) / n));
  EXPECT_NEAR(m.premultiplied.data[4 * 100 + 2] / m.premultiplied.data[4 * 100 + 3], 1.0f, 1e-4);
  // (Most of what is left is the start of each ray, before its first comb point, where the control
  // is half the majorant.)
  EXPECT_LT(m.total.varianceSum, 0.1 * delta.total.varianceSum);
}

TEST(RatioTracking, MarchConvergesToDeltaTracking) {
  const double psnr = psnrAgainstDelta(false, 100, test::unbiasedMarch(2.0, 1.0));
  std::printf("march (100 frames, k = 2, kr = 1) vs delta tracking (3000 frames): %.2f dB over the volume\n", psnr);
  EXPECT_GE(psnr, 40.0);
}

TEST(RatioTracking, MarchConvergesToDeltaTrackingWithShadows) {
  const double psnr = psnrAgainstDelta(true, 400, test::unbiasedMarch(2.0, 1.0));
  std::printf("march with shadows (400 frames, k = 2, kr = 1) vs delta tracking (3000 frames): %.2f dB\n", psnr);
  EXPECT_GE(psnr, 38.0);
}

TEST(RatioTracking, MarchImageDoesNotDependOnPointsPerIteration) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = smoothScene(40, false);
  setup.settings.pixelJitter = true;
  auto run = [&](int points) {
    TrackingOptions t = test::unbiasedMarch(2.0, 0.5, points);
    t.refineMacrocells = false;
    return render(f, setup, t, 2);
  };
  const Rendered one = run(1), many = run(32);
  EXPECT_TRUE(one.image.data == many.image.data);
  EXPECT_LT(4 * many.total.iterations, one.total.iterations);
}

TEST(RatioTracking, MarchWorkIsBoundedInOpaqueMedia) {
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  const SceneSetup setup = slabScene(0.9, 1e-5);
  TrackingOptions t = test::unbiasedMarch(4.0, 1.0, 64);
  t.maxCollisionsPerRay = 64;
  MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 4));
  CpuWavefrontRenderer r(f, grid, t);
  r.setWarningHandler([](const std::string&) {});
  const FrameStats st = test::renderFrames(r, setup.settings, setup.scene, 1);
  EXPECT_LE(st.queries, std::size_t(48 * 48) * (2 * 64 + 32));
  EXPECT_EQ(test::nonFinitePixels(r.image()), 0u);
  // Opaque, but the comb's spacing (1e-6) is near a float ulp of the ray parameter (~6 here), so
  // the positions round: a sanity range, not an accuracy check.
  EXPECT_NEAR(meanCoverage(r.premultipliedImage()), 1.0, 0.5);
}

TEST(RatioTracking, OptionsAreValidated) {
  TrackingOptions t = test::ratioTracking(4.0);
  EXPECT_NO_THROW(t.validate());
  t.majorantScale = 0.5;
  EXPECT_THROW(t.validate(), std::invalid_argument);
  t = test::ratioTracking(4.0, 0);
  EXPECT_THROW(t.validate(), std::invalid_argument);
  t = test::ratioTracking(4.0, TrackingOptions::kMaxPointsPerIteration + 1);
  EXPECT_THROW(t.validate(), std::invalid_argument);
  t = test::ratioTracking(4.0);
  t.rouletteThreshold = 0.0;
  EXPECT_THROW(t.validate(), std::invalid_argument);
  t = test::unbiasedMarch(2.0, -1.0);
  EXPECT_THROW(t.validate(), std::invalid_argument);
  EXPECT_NO_THROW(test::unbiasedMarch(2.0, 0.0).validate());  // a plain marcher (biased), for comparisons
  EXPECT_EQ(parsePrimaryEstimator("march"), PrimaryEstimator::March);
  EXPECT_EQ(parsePrimaryEstimator("ratio"), PrimaryEstimator::Ratio);
  EXPECT_THROW(parsePrimaryEstimator("ratio-tracking"), std::invalid_argument);
  // A renderer refuses them and keeps its options.
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(4, 1));
  CpuWavefrontRenderer r(f, grid, test::ratioTracking(2.0));
  TrackingOptions bad = test::ratioTracking(2.0);
  bad.majorantScale = NAN;
  EXPECT_THROW(r.setTrackingOptions(bad), std::invalid_argument);
  EXPECT_EQ(r.trackingOptions().majorantScale, 2.0);
}

}  // namespace
}  // namespace inr
