// Unbiased ray marching with a pre-integrated control (PreintegratedMarch.h) on the CPU backend:
// the control's integrals are exact, the estimate converges to the image of delta tracking under a
// transfer function with sharp edges, its convergence estimate is honest, and its image does not
// depend on how the points are batched or on the thread count.
#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/PreintegratedMarch.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::SceneSetup;

TrackingOptions preintegrated(double comb, double residual = 1.0, int points = 32) {
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Preintegrated;
  t.majorantScale = comb;
  t.residualScale = residual;
  t.pointsPerIteration = points;
  return t;
}

// A transfer function with sharp edges, as the shipped ones have: transparent below 0.45, a step
// to 0.7 over 0.02 and a narrow opaque band near 0.75, colours changing across the range.
TransferFunction sharpTf() {
  TransferFunction tf;
  tf.color = {{0.0, 0.1, 0.2, 0.9}, {0.5, 0.9, 0.8, 0.2}, {0.75, 1.0, 0.2, 0.1}, {1.0, 0.3, 1.0, 0.3}};
  tf.opacity = {{0.0, 0.0}, {0.45, 0.0}, {0.47, 0.5}, {0.72, 0.5}, {0.74, 0.95}, {0.78, 0.95}, {0.8, 0.3}, {1.0, 0.3}};
  tf.unitDistance = 0.2;
  return tf;
}

SceneSetup sharpScene(int size) {
  SceneSetup s = test::obliqueCubeScene(size, 3);
  s.settings.pixelJitter = false;
  s.scene.transferFunction = sharpTf();
  return s;
}

struct Rendered {
  ImageRGBA image, premultiplied;
  FrameStats total;  // summed; varianceSum and coveredPixels are the last frame's
};

Rendered render(const FieldEvaluator& f, const SceneSetup& setup, TrackingOptions options, int frames) {
  MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 4));
  CpuWavefrontRenderer r(f, grid, options);
  Rendered out;
  out.total = test::renderFrames(r, setup.settings, setup.scene, frames);
  out.image = r.image();
  out.premultiplied = r.premultipliedImage();
  return out;
}

// ---- the control's arithmetic

TEST(PreintegratedMarch, ControlIntegralsAreExact) {
  const TransferFunctionTable table(sharpTf(), 64);  // few entries: many interval boundaries
  const TransferFunctionView tf = table.view();
  // A fine midpoint sum of the control extinction: exact per piece inside an interval, so split
  // at the entries and the table's ends.
  auto reference = [&](double a, double b) {
    double sum = 0.0;
    const int n = 20000;
    for (int k = 0; k < n; ++k) {
      const double x0 = a + (b - a) * k / n, x1 = a + (b - a) * (k + 1) / n;
      sum += (x1 - x0) * controlExtinctionAt(tf, float(0.5 * (x0 + x1)));
    }
    return sum;
  };
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> x(-10.0, 73.0);
  for (int k = 0; k < 200; ++k) {
    double a = x(rng), b = x(rng);
    if (k % 4 == 0) b = a + 1e-3 * (x(rng) - 30.0) / 40.0;  // short spans, across an entry or not
    if (a > b) std::swap(a, b);
    const double exact = reference(a, b);
    const Vec4f got = controlIntegral(tf, float(a), float(b));
    EXPECT_NEAR(got.w, exact, 1e-4 * (1.0 + std::fabs(exact))) << a << " .. " << b;
    // The mean over a span is the same integral over its length, in either order.
    if (b - a > 1e-6)
      EXPECT_NEAR(meanControlExtinction(tf, float(b), float(a)), exact / (b - a), 1e-3 * (1.0 + exact / (b - a)));
    // The mean colour is a weighted mean of the table's colours: inside their range.
    const ControlSegment seg = controlSegment(tf, float(a), float(b));
    if (got.w > 0.f) {
      EXPECT_GE(seg.colour.x, 0.1f - 1e-4f);
      EXPECT_LE(seg.colour.x, 1.0f + 1e-4f);
    }
  }
  // The control is the renderer's own extinction (extinctionAt) at every scalar, between the
  // entries too: where the network is linear between comb points the residual is 0.
  std::uniform_real_distribution<float> scalar(tf.lo - 0.1f * (tf.hi - tf.lo), tf.hi + 0.1f * (tf.hi - tf.lo));
  for (int k = 0; k < 500; ++k) {
    const float s = scalar(rng);
    EXPECT_NEAR(controlExtinctionAt(tf, controlCoordinate(tf, s)), extinctionAt(tf, s), 1e-5f * (1.f + extinctionAt(tf, s)))
        << s;
  }
  // The control is the entries' extinction at the entries.
  for (int i : {0, 17, 40, 63}) EXPECT_FLOAT_EQ(controlExtinctionAt(tf, float(i)), tf.entryExtinction[i]);
  // Beyond the ends: the end entries' extinction.
  EXPECT_FLOAT_EQ(controlExtinctionAt(tf, -5.f), tf.entryExtinction[0]);
  EXPECT_FLOAT_EQ(controlExtinctionAt(tf, 99.f), tf.entryExtinction[63]);
}

// ---- the estimator

TEST(PreintegratedMarch, HomogeneousSlabIsUnbiasedWithLittleNoise) {
  // A constant field: from the ray's first comb point on the control is the medium itself and
  // every residual term is 0; before it (at most 1 / k of majorant optical depth) the residual
  // points are plain ratio tracking. Unbiased, with far less noise than delta tracking.
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  SceneSetup s;
  s.settings.width = s.settings.height = 48;
  s.settings.seed = 7;
  s.scene.camera = Camera::framing(test::kCubeBox);
  s.scene.camera.parallelProjection = true;
  s.scene.camera.parallelScale = 0.9;
  TransferFunction tf;
  tf.color = {{0, 0.2, 0.6, 1.0}, {1, 0.2, 0.6, 1.0}};
  tf.opacity = {{0, 0.3}, {1, 0.3}};
  tf.unitDistance = 0.5;
  s.scene.transferFunction = tf;
  const double p = 1.0 - std::pow(1.0 - 0.3, 2.0 / 0.5);  // two units of medium
  const int frames = 20;
  const Rendered delta = render(f, s, TrackingOptions{}, frames);
  const Rendered m = render(f, s, preintegrated(4.0), frames);
  const double n = 48.0 * 48.0 * frames;
  // A quarter of delta tracking's 4-sigma bound.
  EXPECT_NEAR(test::meanCoverage(m.premultiplied), p, std::sqrt(p * (1 - p) / n));
  EXPECT_NEAR(m.premultiplied.data[4 * 100 + 2] / m.premultiplied.data[4 * 100 + 3], 1.0f, 1e-4);  // colour
  EXPECT_LT(m.total.varianceSum, 0.05 * delta.total.varianceSum);
  std::printf("slab: coverage %.5f (exact %.5f), variance %.3g of delta tracking's\n", test::meanCoverage(m.premultiplied),
              p, m.total.varianceSum / delta.total.varianceSum);
}

// The image the estimators converge to: ratio tracking (itself tested against delta tracking in
// RatioTracking_test.cpp) at 2048 frames, and delta tracking at 1500 frames as a second check.
struct Reference {
  Rendered ratio, delta;
};
const Reference& sharpReference() {
  static const Reference ref = [] {
    test::FunctionField f(test::smoothField);
    const SceneSetup setup = sharpScene(24);
    Reference r;
    r.ratio = render(f, setup, test::ratioTracking(8.0, 32), 2048);
    r.delta = render(f, setup, TrackingOptions{}, 1500);
    return r;
  }();
  return ref;
}

double psnrAgainst(const Rendered& r, const Rendered& ref) {
  return test::psnrOverCoverage(r.image, ref.image, ref.premultiplied);
}

// The convergence estimate's mean squared error (FrameStats::varianceSum over the covered pixels).
double estimatedMse(const Rendered& r) { return r.total.varianceSum / double(r.total.coveredPixels); }

TEST(PreintegratedMarch, ConvergesToDeltaTracking) {
  test::FunctionField f(test::smoothField);
  const Reference& ref = sharpReference();
  const SceneSetup setup = sharpScene(24);
  const Rendered m = render(f, setup, preintegrated(4.0, 1.0), 256);
  const double vsRatio = psnrAgainst(m, ref.ratio), vsDelta = psnrAgainst(m, ref.delta);
  const double refs = psnrAgainst(ref.ratio, ref.delta);
  std::printf("preintegrated (256 frames, k 4, kr 1): %.2f dB against ratio tracking (2048 frames), %.2f dB against "
              "delta tracking (1500 frames; ratio against delta: %.2f dB)\n",
              vsRatio, vsDelta, refs);
  EXPECT_GE(vsRatio, 45.0);
  // Delta tracking's frames are themselves only this close to the converged image: the march
  // agrees with them as well as ratio tracking's does.
  EXPECT_GE(vsDelta, refs - 1.0);
  // Controls, so that the comparison can fail: one frame is far from converged; and without its
  // residual points (residual scale 0: the plain pre-integrated marcher) the march stays off by its
  // bias however many frames it averages.
  const Rendered one = render(f, setup, preintegrated(4.0, 1.0), 1);
  const Rendered biased = render(f, setup, preintegrated(1.0, 0.0), 256);
  const double psnrOne = psnrAgainst(one, ref.ratio), psnrBiased = psnrAgainst(biased, ref.ratio);
  std::printf("one frame: %.2f dB; without residual points (256 frames, k 1): %.2f dB\n", psnrOne, psnrBiased);
  EXPECT_LT(psnrOne, 40.0);
  EXPECT_LT(psnrBiased, 40.0);
}

// The convergence estimate (from the halves of the pixels' frames, FrameStats::varianceSum)
// predicts the error against the converged image within 1 dB. The measured error against the
// reference holds the reference's own (independent) error too, which its own estimate gives: that
// is taken off.
TEST(PreintegratedMarch, ConvergenceEstimateIsHonest) {
  test::FunctionField f(test::smoothField);
  const Reference& ref = sharpReference();
  const double referenceMse = estimatedMse(ref.ratio);
  for (int frames : {4, 16, 64}) {
    const Rendered m = render(f, sharpScene(24), preintegrated(4.0, 1.0), frames);
    const double estimate = -10.0 * std::log10(estimatedMse(m));
    const double againstReference = psnrAgainst(m, ref.ratio);
    const double measured = -10.0 * std::log10(std::pow(10.0, -againstReference / 10.0) - referenceMse);
    std::printf("%4d frames: estimated %.2f dB, measured %.2f dB (%.2f dB against the reference, whose own estimate "
                "is %.2f dB)\n",
                frames, estimate, measured, againstReference, -10.0 * std::log10(referenceMse));
    EXPECT_NEAR(estimate, measured, 1.0) << frames << " frames";
  }
}

TEST(PreintegratedMarch, ImageDoesNotDependOnPointsPerIteration) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(40);
  setup.settings.pixelJitter = true;
  auto run = [&](int points) {
    TrackingOptions t = preintegrated(2.0, 1.0, points);
    t.refineMacrocells = false;
    return render(f, setup, t, 2);
  };
  // One point per iteration asked: the renderer takes kMinPreintegratedPoints (a segment must fit
  // in a batch).
  const Rendered one = run(1), many = run(64);
  EXPECT_TRUE(one.image.data == many.image.data);
  EXPECT_LT(many.total.iterations, one.total.iterations);
  EXPECT_EQ(one.total.cappedRays, 0u);
}

TEST(PreintegratedMarch, IdenticalImagesForOneAndManyThreads) {
  auto run = [](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    test::FunctionField f(test::smoothField);
    SceneSetup setup = sharpScene(96);  // above kParallelMinItems
    setup.settings.pixelJitter = true;
    const Rendered r = render(f, setup, preintegrated(2.0, 1.0, 16), 2);
    omp_set_num_threads(saved);
    return r.image.data;
  };
  EXPECT_TRUE(run(1) == run(4));
}

TEST(PreintegratedMarch, ShadowsAndShadingRunRatioTracking) {
  // No single emission point for a shadow ray: the renderer runs ratio tracking instead, with the
  // same scales; the image is ratio tracking's bit for bit.
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(24);
  test::lightScene(setup.scene, true);
  TrackingOptions ratio = preintegrated(3.0);
  ratio.estimator = PrimaryEstimator::Ratio;
  const Rendered a = render(f, setup, preintegrated(3.0), 2), b = render(f, setup, ratio, 2);
  EXPECT_TRUE(a.image.data == b.image.data);
}

TEST(PreintegratedMarch, OptionsAreValidatedAndNamed) {
  EXPECT_NO_THROW(preintegrated(4.0).validate());
  EXPECT_EQ(parsePrimaryEstimator("preintegrated"), PrimaryEstimator::Preintegrated);
  EXPECT_STREQ(primaryEstimatorName(PrimaryEstimator::Preintegrated), "preintegrated");
  TrackingOptions bad = preintegrated(4.0);
  bad.estimator = static_cast<PrimaryEstimator>(5);
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace inr
