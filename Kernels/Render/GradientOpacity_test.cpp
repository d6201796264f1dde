// Gradient opacity (TransferFunction::gradientOpacity; Render/Evaluate.h): the table, and the CPU
// renderers. On the Gaussian blob (TestFields.h) the gradient magnitude is a function of the
// value, |grad f| = (2 / w) f sqrt(-ln f), so a gradient opacity function is the same medium as
// a transfer function with the factor baked into its scalar opacity: the ray marcher must render
// both alike, and every estimator must converge to that picture.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/Evaluate.h"
#include "Render/RayMarcher.h"
#include "Render/RatioTracking.h"
#include "Render/RayStateArrays.h"
#include "Render/SceneChange.h"
#include "TestSupport/BlobRenders.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

// Fades the blob's core (value near 1, gradient near 0) and its outer tail: the factor ramps from
// 0 at |grad f| = 1.0 to 1 at 1.45 (the blob's largest magnitude is about 1.43).
const std::vector<TransferFunction::OpacityPoint> kRamp = {{1.0, 0.0}, {1.45, 1.0}};

double blobGradientNorm(double v) {
  if (!(v > 0.0 && v < 1.0)) return 0.0;
  return 2.0 / test::kBlobWidth * v * std::sqrt(-std::log(v));
}

TEST(GradientOpacity, TableFollowsTheFunctionAndIsOffWhenEmpty) {
  TransferFunction tf = TransferFunction::preset(0.0, 1.0);
  EXPECT_FALSE(tf.usesGradientOpacity());
  EXPECT_EQ(TransferFunctionTable(tf).view().gradientOpacity, nullptr);
  EXPECT_EQ(gradientOpacityAt(TransferFunctionTable(tf).view(), 5.f), 1.f);  // off: factor 1
  tf.gradientOpacity = {{0.0, 0.2}, {2.0, 1.0}};
  const TransferFunctionTable table(tf);
  const TransferFunctionView v = table.view();
  ASSERT_NE(v.gradientOpacity, nullptr);
  for (float g : {0.f, 0.3f, 1.f, 1.77f, 2.f}) EXPECT_NEAR(gradientOpacityAt(v, g), 0.2f + 0.4f * g, 1e-5f) << g;
  EXPECT_NEAR(gradientOpacityAt(v, 7.f), 1.f, 1e-6f);        // beyond the last node: clamped
  EXPECT_NEAR(gradientOpacityAt(v, INFINITY), 1.f, 1e-6f);   // an overflowed gradient: the last entry
  EXPECT_NEAR(gradientOpacityAt(v, NAN), 0.2f, 1e-6f);       // NaN: the first entry
  EXPECT_NEAR(gradientTermOf(v, Vec3f{0.6f, 0.f, 0.8f}), 0.6f, 1e-5f);  // of |g| = 1
  // Factors above 1 are clamped as scalar opacities are (the majorants rely on factor <= 1).
  tf.gradientOpacity = {{0.0, 3.0}, {1.0, 3.0}};
  EXPECT_EQ(gradientOpacityAt(TransferFunctionTable(tf).view(), 0.5f), 1.f);
}

TEST(GradientOpacity, TableKeepsANarrowRampBesideAFarNodeAndFollowsBentSegments) {
  TransferFunction tf = TransferFunction::preset(0.0, 1.0);
  // A ramp 1/1000 of the function's span wide, then a node far out holding the factor flat.
  tf.gradientOpacity = {{0.0, 0.0}, {0.1, 1.0}, {100.0, 1.0}};
  const TransferFunctionTable narrow(tf);
  EXPECT_NEAR(gradientOpacityAt(narrow.view(), 0.05f), 0.5f, 1e-6f);
  EXPECT_NEAR(gradientOpacityAt(narrow.view(), 0.01f), 0.1f, 1e-6f);
  EXPECT_EQ(gradientOpacityAt(narrow.view(), 50.f), 1.f);
  // vtkPiecewiseFunction's midpoint and sharpness bend a segment: the table follows the function.
  tf.gradientOpacity = {{0.0, 0.0, 0.2, 0.6}, {2.0, 1.0}, {3.0, 0.5, 0.8, 0.0}, {4.0, 0.0}};
  const TransferFunctionTable bent(tf);
  double worst = 0.0;
  for (int k = 0; k <= 400; ++k) {
    const double g = 4.0 * k / 400;
    worst = std::max(worst, std::abs(double(gradientOpacityAt(bent.view(), float(g))) - tf.gradientOpacityAt(g)));
  }
  std::printf("bent segments: largest difference from the piecewise function %.2e\n", worst);
  EXPECT_LT(worst, 0.02);
}

TEST(GradientOpacity, NodesOutOfOrderAreRefused) {
  TransferFunction tf = TransferFunction::preset(0.0, 1.0);
  tf.gradientOpacity = {{0.0, 0.0}, {2.0, 1.0}, {1.0, 0.5}};
  try {
    TransferFunctionTable table(tf);
    FAIL() << "nodes out of order were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gradient opacity point 2"), std::string::npos) << e.what();
  }
}

TEST(GradientOpacity, NonFiniteNodeIsRefusedByName) {
  TransferFunction tf = TransferFunction::preset(0.0, 1.0);
  tf.gradientOpacity = {{0.0, 0.0}, {NAN, 1.0}};
  try {
    TransferFunctionTable table(tf);
    FAIL() << "a NaN node was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gradient opacity point 1"), std::string::npos) << e.what();
  }
}

// Unbiased ray marching runs without its control extinction under gradient opacity
// (marchUsesControl, RatioTracking.h): the factor switches the extinction off from one sample to
// the next, and with the control a residual point where it is off multiplies the transmittance by
// 1 + control / mu > 1. One ray, a comb point where the factor keeps the scalar opacity, then a
// residual point where the factor is 0: the transmittance must stay in [0, 1]. Without gradient
// opacity the control is kept (the same step through a value the scalar opacity leaves empty
// gives the factor above 1), and so it is with residual points sparser than the majorant
// (residualScale < 1), which could not carry the transmittance alone.
TEST(GradientOpacity, UnbiasedMarchDropsItsControlUnderTheFactor) {
  auto transmittanceAfter = [](const TransferFunction& tf, float residualValue, float residualFactor) {
    const TransferFunctionTable table(tf);
    TrackingMedium medium{};
    medium.tf = table.view();
    FrameConstants fc;
    fc.estimator = PrimaryEstimator::March;
    fc.rouletteThreshold = 0.f;
    RayStateArrays<HostArray> rays;
    rays.resize(1);
    PointStateArrays<HostArray> points;
    points.resize(2);
    const RayStateView rs = rays.view();
    const PointStateView pts = points.view();
    rs.visibility[0] = 1.f;
    rs.radiance[0] = Vec4f{0.f, 0.f, 0.f, 0.f};
    rs.collisionProduct[0] = 0.f;
    rs.lastExtinction[0] = NAN;
    rs.hitT[0] = NAN;
    rs.hitWeight[0] = 0.f;
    const float t[2] = {0.1f, 0.2f}, rate[2] = {0.25f, 4.f}, gap[2] = {0.f, 0.1f};
    const float value[2] = {0.9f, residualValue}, factor[2] = {1.f, residualFactor};
    const std::uint8_t kind[2] = {kPointComb, 0};
    for (int j = 0; j < 2; ++j) {
      const int slot = pointSlot(pts, 1, 0, j);
      pts.t[slot] = t[j];
      pts.majorant[slot] = rate[j];
      pts.gap[slot] = gap[j];
      pts.sample[slot] = value[j];
      pts.opacityScale[slot] = factor[j];
      pts.cell[slot] = 0;
      pts.kind[slot] = kind[j];
    }
    resolveRatioPoints(fc, medium, rs, pts, 0, 2, RngStream{0u, 0u, 1u, 0u}, [](int, float) {});
    return rs.visibility[0];
  };
  TransferFunction tf = TransferFunction::preset(0.0, 1.0);
  tf.opacity = {{0.0, 0.0}, {0.5, 0.0}, {0.6, 0.5}, {1.0, 0.5}};  // empty below 0.5
  const float withoutFactor = transmittanceAfter(tf, 0.1f, 1.f);
  tf.gradientOpacity = kRamp;
  const float withFactor = transmittanceAfter(tf, 0.9f, 0.f);
  std::printf("march transmittance after a step into a point with no extinction: %.4f with the control, %.4f "
              "under gradient opacity\n",
              withoutFactor, withFactor);
  EXPECT_GT(withoutFactor, 1.f) << "without gradient opacity the control is used";
  EXPECT_GE(withFactor, 0.f);
  EXPECT_LE(withFactor, 1.f) << "under gradient opacity every residual factor lies in [0, 1]";
  const TransferFunctionTable table(tf);
  FrameConstants fc;
  fc.residualScale = 1.f;
  EXPECT_FALSE(marchUsesControl(fc, table.view()));
  fc.residualScale = 0.5f;
  EXPECT_TRUE(marchUsesControl(fc, table.view())) << "too few residual points to go without the control";
  fc.residualScale = 0.f;
  EXPECT_TRUE(marchUsesControl(fc, table.view())) << "no residual points at all: the plain jittered marcher";
}

TEST(GradientOpacity, ChangingItIsATransferFunctionChange) {
  RenderScene a;
  a.transferFunction = TransferFunction::preset(0.0, 1.0);
  RenderScene b = a;
  b.transferFunction.gradientOpacity = kRamp;
  EXPECT_TRUE(diffScenes(&a, b).transferFunction);
  RenderScene c = b;
  c.transferFunction.gradientOpacity[1].alpha = 0.5;
  EXPECT_TRUE(diffScenes(&b, c).transferFunction);
  EXPECT_FALSE(diffScenes(&c, c).transferFunction);
}

// Orthographic view down -z of the blob; a soft shell, so the factor shows through its depth.
test::SceneSetup blobScene(int size, bool gradientOpacity, bool shadows = false) {
  test::SceneSetup s = test::orthographicCubeView(size, 5);
  TransferFunction tf;
  tf.color = {{0.0, 0.2, 0.4, 0.9}, {0.5, 0.9, 0.9, 0.9}, {1.0, 0.9, 0.5, 0.1}};
  tf.opacity = {{0.0, 0.0}, {0.2, 0.0}, {0.5, 0.8}, {1.0, 0.8}};
  tf.unitDistance = 0.2;
  if (gradientOpacity) tf.gradientOpacity = kRamp;
  s.scene.transferFunction = tf;
  s.scene.background = {0.1f, 0.1f, 0.1f};
  s.scene.shadows = shadows;
  s.scene.toLight = {0.5, 0.6, 0.8};
  return s;
}

// The same medium without gradient opacity: the factor at the blob's gradient for each value,
// multiplied into the scalar opacity (finely sampled).
test::SceneSetup bakedScene(int size) {
  test::SceneSetup s = blobScene(size, true);
  TransferFunction& tf = s.scene.transferFunction;
  const TransferFunction withRamp = tf;
  tf.gradientOpacity.clear();
  tf.opacity.clear();
  const int n = 2048;
  for (int k = 0; k <= n; ++k) {
    const double v = double(k) / n;
    tf.opacity.push_back({v, withRamp.opacityAt(v) * withRamp.gradientOpacityAt(blobGradientNorm(v))});
  }
  return s;
}

using test::BlobRender;

BlobRender marched(const test::SceneSetup& setup) { return test::marchedBlob(setup); }

BlobRender tracked(const test::SceneSetup& setup, const TrackingOptions& options, int frames,
                   const QueryReductionSettings& reduction = {}) {
  return test::trackedBlob(setup, options, frames, reduction);
}

TEST(GradientOpacityRender, MarcherRendersTheFactorAsABakedTransferFunction) {
  const int size = 32;
  const BlobRender withFactor = marched(blobScene(size, true));
  const BlobRender baked = marched(bakedScene(size));
  const BlobRender without = marched(blobScene(size, false));
  const double psnr = test::psnrOverCoverage(withFactor.image, baked.image, without.premultiplied);
  const double control = test::psnrOverCoverage(without.image, baked.image, without.premultiplied);
  std::printf("marcher, gradient opacity vs the factor baked into the TF: %.2f dB; without it: %.2f dB\n", psnr,
              control);
  EXPECT_GE(psnr, 40.0);
  EXPECT_LT(control, 30.0);  // the factor changes the picture: the comparison can fail
  // Every primary sample asked for its gradient (one frame, no shading).
  EXPECT_EQ(withFactor.gradientPoints, withFactor.total.queries);
  EXPECT_EQ(without.gradientPoints, 0u);
  EXPECT_EQ(test::nonFinitePixels(withFactor.image), 0u);
}

void expectConvergesToMarcher(const test::SceneSetup& setup, TrackingOptions options, int frames, double minPsnr) {
  const BlobRender t = tracked(setup, options, frames);
  const BlobRender reference = marched(setup);
  test::SceneSetup off = setup;
  off.scene.transferFunction.gradientOpacity.clear();
  const BlobRender without = marched(off);
  const double psnr = test::psnrOverCoverage(t.image, reference.image, without.premultiplied);
  const double control = test::psnrOverCoverage(without.image, reference.image, without.premultiplied);
  std::printf("gradient opacity, %s (%d frames%s) vs ray marching: %.2f dB over the volume; without the factor %.2f dB\n",
              primaryEstimatorName(options.estimator), frames, setup.scene.shadows ? ", shadows" : "", psnr, control);
  EXPECT_GE(psnr, minPsnr);
  EXPECT_LT(control, minPsnr - 8.0);
  // Gradients only where the factor can change the outcome (Evaluate.h): fewer than the queries,
  // and every one of them counted.
  const std::size_t tracking = t.total.queries + t.total.shadowQueries;
  std::printf("  gradients asked for %zu of %zu tracking queries (%.0f%%)\n", t.total.gradientOpacityQueries, tracking,
              100.0 * double(t.total.gradientOpacityQueries) / double(tracking));
  EXPECT_EQ(t.gradientPoints, t.total.gradientOpacityQueries);
  EXPECT_GT(t.total.gradientOpacityQueries, 0u);
  EXPECT_LT(t.total.gradientOpacityQueries, tracking);
  EXPECT_EQ(test::nonFinitePixels(t.image), 0u);
}

TEST(GradientOpacityRender, DeltaTrackingConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32, true), TrackingOptions{}, 300, 36.0);
}

TEST(GradientOpacityRender, RatioTrackingConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32, true), test::ratioTracking(4.0), 60, 38.0);
}

// Under gradient opacity march runs without its control (marchUsesControl): on this smooth blob,
// where the control would fit well, that costs frames (the estimate rises about 6 dB per 4x
// frames, as unbiased noise does), hence 480.
TEST(GradientOpacityRender, UnbiasedMarchConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32, true), test::unbiasedMarch(2.0), 480, 35.0);
}

TEST(GradientOpacityRender, ShadowRaysSeeTheFactorToo) {
  // Against the marcher with shadows, whose shadow samples carry the factor as its primary ones
  // do; the shadow rays' queries come with gradients (expectConvergesToMarcher counts them).
  expectConvergesToMarcher(blobScene(32, true, true), test::ratioTracking(4.0), 200, 34.0);
}

TEST(GradientOpacityRender, NaiveTrackerRendersTheSame) {
  // Same streams, same stage code: the unbatched baseline reproduces the wavefront image.
  const test::SceneSetup setup = blobScene(16, true, true);
  const test::FunctionField f(test::blobField, "blob", test::blobGradient);
  EXPECT_TRUE(test::naiveImageEqualsWavefront(f, setup, test::cubeMacrocells(8, 2)));
}

TEST(GradientOpacityRender, PruningStandsDown) {
  // A pruned candidate's expected scalar has no gradient: with gradient opacity nothing is pruned.
  const QueryReductionSettings pruning = test::pruningAt(0.2, 0.0);
  const BlobRender off = tracked(blobScene(24, false), TrackingOptions{}, 6, pruning);
  const BlobRender on = tracked(blobScene(24, true), TrackingOptions{}, 6, pruning);
  EXPECT_GT(off.total.pruned, 0u);  // the settings do prune without it: the check can fail
  EXPECT_EQ(on.total.pruned, 0u);
}

TEST(GradientOpacityRender, FieldWithoutGradientIsRefused) {
  test::expectRefusedWithoutGradient(blobScene(8, true), "gradient opacity");
}

}  // namespace
}  // namespace inr
