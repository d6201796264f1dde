// The debiased ray march (DebiasedMarch.h) on the CPU backend: its levels are drawn with the
// documented probabilities, a homogeneous medium comes out exact, the estimate converges to the
// image of delta tracking under a transfer function with sharp edges while the same march without
// its random refinement does not, its convergence estimate is honest, and its image does not
// depend on how the points are batched or on the thread count. The stratified sub-pixel jitter
// (RayInit.h) is uniform per frame and evenly spread over each half's frames, and the halves stay
// balanced.
#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "Render/DebiasedMarch.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/RayInit.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::SceneSetup;

TrackingOptions debiased(double comb, int maxLevel = 5, double ratio = 0.3, double minimumSteps = 0.0,
                         int points = 32) {
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Debiased;
  t.majorantScale = comb;
  t.maxLevel = maxLevel;
  t.levelRatio = ratio;
  t.combMinimumSteps = minimumSteps;
  t.pointsPerIteration = points;
  return t;
}

// A transfer function with sharp edges, as the shipped ones have (PreintegratedMarch_test.cpp's).
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

// ---- the levels

TEST(DebiasedMarch, LevelsFollowTheirProbabilities) {
  // P(level >= k) = r^k up to the cap, which takes the rest.
  FrameConstants fc;
  fc.levelRatio = 0.3f;
  fc.maxLevel = 4;
  const int n = 1 << 20;
  int counts[8] = {};
  for (int k = 0; k < n; ++k) ++counts[debiasedLevel(fc, (float(k) + 0.5f) / float(n))];
  double atLeast = n;
  for (int k = 0; k <= fc.maxLevel; ++k) {
    const double expected = k < fc.maxLevel ? std::pow(0.3, k) * 0.7 : std::pow(0.3, k);
    EXPECT_NEAR(counts[k] / double(n), expected, 1e-4) << "level " << k;
    atLeast -= counts[k];
  }
  EXPECT_EQ(atLeast, 0.0);
  EXPECT_EQ(debiasedLevel(fc, 0.f), 0);  // u = 0: v = 1, never refined
}

// ---- the estimator

TEST(DebiasedMarch, HomogeneousMediumIsExactWhateverTheLevels) {
  // A constant field: every level's march is exact, and the levels' weights sum to 1, so every
  // frame is the exact image (up to rounding), whatever levels its intervals drew.
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  SceneSetup s;
  s.settings.width = s.settings.height = 32;
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
  TrackingOptions t = debiased(2.0, 5, 0.45);  // many refined intervals
  t.rouletteThreshold = 1e-6;                  // (roulette would add noise)
  const Rendered one = render(f, s, t, 3);  // (the variance needs two frames)
  for (int px : {0, 100, 500, 1000}) {
    EXPECT_NEAR(one.premultiplied.data[4 * px + 3], p, 2e-5) << "pixel " << px;
    EXPECT_NEAR(one.premultiplied.data[4 * px + 2] / one.premultiplied.data[4 * px + 3], 1.0f, 1e-5);
  }
  EXPECT_LT(one.total.varianceSum, 1e-7);  // rounding only (a tracker's is of order 1 here)
  EXPECT_EQ(one.total.cappedRays, 0u);
}

// The image the estimators converge to: ratio tracking (tested against delta tracking in
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

TEST(DebiasedMarch, ConvergesToDeltaTrackingWhereTheMarchDoesNot) {
  test::FunctionField f(test::smoothField);
  const Reference& ref = sharpReference();
  const SceneSetup setup = sharpScene(24);
  // A coarse comb (two points per unit of majorant optical depth, at least 16 per box diagonal),
  // so the march's own error is large and the refinement has much to correct.
  const TrackingOptions coarse = debiased(2.0, 5, 0.3, 16.0);
  const Rendered m = render(f, setup, coarse, 256);
  const double vsRatio = psnrAgainst(m, ref.ratio), vsDelta = psnrAgainst(m, ref.delta);
  const double refs = psnrAgainst(ref.ratio, ref.delta);
  std::printf("debiased (256 frames, k 2): %.2f dB against ratio tracking (2048 frames), %.2f dB against delta "
              "tracking (1500 frames; ratio against delta: %.2f dB)\n",
              vsRatio, vsDelta, refs);
  EXPECT_GE(vsRatio, 45.0);
  // Delta tracking's frames are the noisier reference, and the march's own remaining noise adds
  // to theirs: within 1.5 dB of what ratio tracking's converged image scores against them.
  EXPECT_GE(vsDelta, refs - 1.5);
  // Controls, so that the comparison can fail: the same comb without refinement (max level 0:
  // the plain march, biased) stays off by its bias however many frames it averages; one frame of
  // the debiased march is far from converged.
  TrackingOptions plain = coarse;
  plain.maxLevel = 0;
  const Rendered biased = render(f, setup, plain, 256);
  const Rendered one = render(f, setup, coarse, 1);
  const double psnrBiased = psnrAgainst(biased, ref.ratio), psnrOne = psnrAgainst(one, ref.ratio);
  std::printf("the march without refinement (256 frames): %.2f dB; one debiased frame: %.2f dB\n", psnrBiased, psnrOne);
  EXPECT_LT(psnrBiased, vsRatio - 5.0);
  EXPECT_LT(psnrOne, 40.0);
}

// The convergence estimate (from the halves of the pixels' frames, FrameStats::varianceSum)
// predicts the error against the converged image within 1 dB; the reference's own error is taken off.
TEST(DebiasedMarch, ConvergenceEstimateIsHonest) {
  test::FunctionField f(test::smoothField);
  const Reference& ref = sharpReference();
  const double referenceMse = estimatedMse(ref.ratio);
  for (int frames : {4, 16, 64}) {
    const Rendered m = render(f, sharpScene(24), debiased(2.0, 5, 0.3, 16.0), frames);
    const double estimate = -10.0 * std::log10(estimatedMse(m));
    const double againstReference = psnrAgainst(m, ref.ratio);
    const double measured = -10.0 * std::log10(std::pow(10.0, -againstReference / 10.0) - referenceMse);
    std::printf("%4d frames: estimated %.2f dB, measured %.2f dB (%.2f dB against the reference, whose own estimate "
                "is %.2f dB)\n",
                frames, estimate, measured, againstReference, -10.0 * std::log10(referenceMse));
    EXPECT_NEAR(estimate, measured, 1.0) << frames << " frames";
  }
}

// The same at the shipped defaults (TrackingOptions::recommended()), the sub-pixel jitter on:
// the stratified jitter makes a pixel's frames negatively correlated (they fill the pixel evenly),
// so their sample variance over-states the error of their mean; the estimate from the
// accumulation's two independent halves (Finalize.h) holds within 1 dB of the error measured
// against a 1024-frame image of the same renderer (another seed, its own estimated error taken
// off). The control: the frames' sample variance (what the estimate was before) is computed here
// from the same frames and is more than 1 dB pessimistic, so the bound can fail.
TEST(DebiasedMarch, ConvergenceEstimateIsHonestWithTheStratifiedJitter) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(40);
  setup.settings.pixelJitter = true;
  const TrackingOptions shipped = TrackingOptions::recommended();
  ASSERT_TRUE(shipped.stratifiedJitter);
  SceneSetup referenceSetup = setup;
  referenceSetup.settings.seed = 977;
  const Rendered ref = render(f, referenceSetup, shipped, 1024);
  const double referenceMse = estimatedMse(ref);

  MacrocellGrid grid(f, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 4));
  CpuWavefrontRenderer r(f, grid, shipped);
  r.setSettings(setup.settings);
  r.setScene(setup.scene);
  const int pixels = setup.settings.width * setup.settings.height;
  // Welford over each pixel's frame estimates, recovered from successive displayed means.
  std::vector<double> previous(3 * std::size_t(pixels), 0.0), mean(previous.size(), 0.0), m2(previous.size(), 0.0);
  int checked = 0;
  for (int frame = 1; frame <= 128; ++frame) {
    const FrameStats st = r.renderFrame();
    const ImageRGBA shown = r.image();
    for (int p = 0; p < pixels; ++p) {
      for (int c = 0; c < 3; ++c) {
        const std::size_t k = 3 * std::size_t(p) + c;
        const double now = shown.data[4 * std::size_t(p) + c];
        const double x = frame * now - (frame - 1) * previous[k];  // this frame's estimate
        previous[k] = now;
        const double d = x - mean[k];
        mean[k] += d / frame;
        m2[k] += d * (x - mean[k]);
      }
    }
    if (frame != 16 && frame != 32 && frame != 128) continue;
    ++checked;
    double iidSum = 0.0;
    std::size_t covered = 0;
    const ImageRGBA coverage = r.premultipliedImage();
    for (int p = 0; p < pixels; ++p) {
      if (!(coverage.data[4 * std::size_t(p) + 3] > 0.f)) continue;
      ++covered;
      for (int c = 0; c < 3; ++c) iidSum += m2[3 * std::size_t(p) + c] / (3.0 * frame * (frame - 1));
    }
    const double estimate = -10.0 * std::log10(st.varianceSum / double(st.coveredPixels));
    const double iid = -10.0 * std::log10(iidSum / double(covered));
    const double againstReference = test::psnrOverCoverage(shown, ref.image, ref.premultiplied);
    const double measured = -10.0 * std::log10(std::pow(10.0, -againstReference / 10.0) - referenceMse);
    std::printf("%4d frames, %zu covered pixels: estimated %.2f dB, measured %.2f dB (%.2f dB against the "
                "reference, whose own estimate is %.2f dB); the frames' sample variance says %.2f dB\n",
                frame, covered, estimate, measured, againstReference, -10.0 * std::log10(referenceMse), iid);
    EXPECT_NEAR(estimate, measured, 1.0) << frame << " frames";
    if (frame == 128) EXPECT_LT(iid, measured - 1.0) << "control: the frames' sample variance";
  }
  EXPECT_EQ(checked, 3);
}

// The sub-pixel jitter's control variate (Finalize.h, jitterControlled) in an accumulation's
// first frames (TrackingOptions::jitterControlFrames; 32 in the shipped defaults). A first frame
// with it is closer to the converged image: its mean squared error (six seeds, against a
// 256-frame image without the variate) falls by more than a fifth. And it keeps the limit: a
// 128-frame image with it and one without (other seeds) differ by what their two estimated
// errors add up to, within 1 dB; a biased control would add its bias to that difference. The
// control: without the variate the first frames' error is the larger one.
TEST(DebiasedMarch, JitterControlVariateKeepsTheLimitAndCleansTheFirstFrames) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(40);
  setup.settings.pixelJitter = true;
  const TrackingOptions withControl = TrackingOptions::recommended();
  ASSERT_GT(withControl.jitterControlFrames, 0);
  TrackingOptions without = withControl;
  without.jitterControlFrames = 0;
  auto seeded = [&](std::uint32_t seed) {
    SceneSetup s = setup;
    s.settings.seed = seed;
    return s;
  };
  auto mse = [](const ImageRGBA& a, const Rendered& ref) {
    return std::pow(10.0, -test::psnrOverCoverage(a, ref.image, ref.premultiplied) / 10.0);
  };
  const Rendered ref = render(f, seeded(977), without, 256);
  double firstWith = 0.0, firstWithout = 0.0;
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    firstWith += mse(render(f, seeded(seed), withControl, 1).image, ref) / 6.0;
    firstWithout += mse(render(f, seeded(seed), without, 1).image, ref) / 6.0;
  }
  std::printf("first frame against a 256-frame image: %.2f dB with the control variate, %.2f dB without\n",
              -10.0 * std::log10(firstWith), -10.0 * std::log10(firstWithout));
  EXPECT_LT(firstWith, 0.8 * firstWithout);

  const Rendered a = render(f, seeded(31), withControl, 128), b = render(f, seeded(32), without, 128);
  const double expected = estimatedMse(a) + estimatedMse(b);
  const double measured = mse(a.image, b);
  std::printf("128 frames with and without it: %.2f dB apart, their estimated errors add up to %.2f dB\n",
              -10.0 * std::log10(measured), -10.0 * std::log10(expected));
  EXPECT_NEAR(10.0 * std::log10(measured / expected), 0.0, 1.0);
}

TEST(DebiasedMarch, ImageDoesNotDependOnPointsPerIteration) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(40);
  setup.settings.pixelJitter = true;
  auto run = [&](int points) {
    TrackingOptions t = debiased(2.0, 4, 0.3, 0.0, points);
    t.refineMacrocells = false;
    return render(f, setup, t, 2);
  };
  // One point per iteration asked: the renderer takes 2^maxLevel (an interval must fit a batch).
  const Rendered one = run(1), many = run(64);
  EXPECT_TRUE(one.image.data == many.image.data);
  EXPECT_LT(many.total.iterations, one.total.iterations);
  EXPECT_EQ(one.total.cappedRays, 0u);
}

TEST(DebiasedMarch, IdenticalImagesForOneAndManyThreads) {
  auto run = [](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    test::FunctionField f(test::smoothField);
    SceneSetup setup = sharpScene(96);  // above kParallelMinItems
    setup.settings.pixelJitter = true;
    TrackingOptions t = debiased(2.0);
    t.stratifiedJitter = true;
    const Rendered r = render(f, setup, t, 2);
    omp_set_num_threads(saved);
    return r.image.data;
  };
  EXPECT_TRUE(run(1) == run(4));
}

TEST(DebiasedMarch, ShadowsAndShadingRunRatioTracking) {
  // No single emission point for a shadow ray: the renderer runs ratio tracking instead, with the
  // comb density as its majorant scale (fallbackMajorantScale 0); the image is ratio tracking's
  // bit for bit.
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(24);
  test::lightScene(setup.scene, true);
  TrackingOptions ratio = debiased(3.0);
  ratio.estimator = PrimaryEstimator::Ratio;
  const Rendered a = render(f, setup, debiased(3.0), 2), b = render(f, setup, ratio, 2);
  EXPECT_TRUE(a.image.data == b.image.data);
}

TEST(DebiasedMarch, FallbackTakesItsOwnMajorantScale) {
  // With fallbackMajorantScale set, the ratio tracking that renders a shadowed scene takes that
  // scale, not the comb's: the image is ratio tracking's at that scale bit for bit, and not the
  // one at the comb's scale (so the option is not ignored).
  test::FunctionField f(test::smoothField);
  SceneSetup setup = sharpScene(24);
  test::lightScene(setup.scene, true);
  TrackingOptions asked = debiased(2.0);
  asked.fallbackMajorantScale = 5.0;
  TrackingOptions atFallback = debiased(5.0), atComb = debiased(2.0);
  atFallback.estimator = atComb.estimator = PrimaryEstimator::Ratio;
  const Rendered a = render(f, setup, asked, 2), b = render(f, setup, atFallback, 2), c = render(f, setup, atComb, 2);
  EXPECT_TRUE(a.image.data == b.image.data);
  EXPECT_FALSE(a.image.data == c.image.data);
  // Without shadows or shading the debiased march runs and the fallback scale changes nothing.
  SceneSetup plain = sharpScene(24);
  TrackingOptions noFallback = debiased(2.0);
  EXPECT_TRUE(render(f, plain, asked, 2).image.data == render(f, plain, noFallback, 2).image.data);
}

// The comb floor that follows the transfer function (TrackingOptions::combFloorDepth): the density
// is the majorant's, at least the floor, but the floor only up to majorant / D.
TEST(DebiasedMarch, CombFloorFollowsTheMajorant) {
  FrameConstants fc;
  fc.majorantScale = 2.f;
  fc.combMinimumDensity = 100.f;
  for (float m : {0.01f, 1.f, 30.f, 1000.f}) EXPECT_EQ(combDensity(fc, m), std::max(2.f * m, 100.f)) << m;
  fc.combFloorDepth = 0.05f;
  EXPECT_FLOAT_EQ(combDensity(fc, 0.01f), 0.2f);   // faint: 0.05 of optical depth per interval
  EXPECT_FLOAT_EQ(combDensity(fc, 1.f), 20.f);
  EXPECT_FLOAT_EQ(combDensity(fc, 30.f), 100.f);   // the floor, reached at m = 5
  EXPECT_FLOAT_EQ(combDensity(fc, 1000.f), 2000.f);  // the majorant's own density above the floor
}

// Where the transfer function is faint, the floor's points cost queries for error nobody sees:
// following the majorant, the same scene takes far fewer queries a frame and still converges to
// ratio tracking's image; the control (the floor everywhere) shows what was spent.
TEST(DebiasedMarch, FaintCellsTakeFewerFloorPointsAndStillConverge) {
  test::FunctionField f(test::smoothField);
  SceneSetup faint = sharpScene(24);
  // The sharp transfer function with a faint band below its opaque one: most non-empty cells
  // hold little optical depth.
  faint.scene.transferFunction.opacity = {{0.0, 0.0}, {0.2, 0.0}, {0.22, 0.01}, {0.72, 0.01}, {0.74, 0.95},
                                          {0.78, 0.95}, {0.8, 0.01}, {1.0, 0.01}};
  const Rendered ref = render(f, faint, test::ratioTracking(8.0, 32), 2048);
  TrackingOptions everywhere = debiased(2.0, 5, 0.25, 64.0), following = everywhere;
  following.combFloorDepth = 0.05;
  const Rendered all = render(f, faint, everywhere, 256), few = render(f, faint, following, 256);
  const double perFrameAll = double(all.total.queries) / 256.0, perFrameFew = double(few.total.queries) / 256.0;
  const double psnrAll = psnrAgainst(all, ref), psnrFew = psnrAgainst(few, ref);
  std::printf("floor everywhere: %.0f queries a frame, %.2f dB after 256 frames; following the majorant (D 0.05): "
              "%.0f queries, %.2f dB\n",
              perFrameAll, psnrAll, perFrameFew, psnrFew);
  EXPECT_LT(perFrameFew, 0.7 * perFrameAll);
  EXPECT_GE(psnrFew, 45.0);
  EXPECT_GE(psnrAll, 45.0);
}

TEST(DebiasedMarch, OptionsAreValidatedAndNamed) {
  EXPECT_NO_THROW(debiased(4.0).validate());
  EXPECT_EQ(parsePrimaryEstimator("debiased"), PrimaryEstimator::Debiased);
  EXPECT_STREQ(primaryEstimatorName(PrimaryEstimator::Debiased), "debiased");
  for (double ratio : {0.0, 1.0, -0.5, double(NAN)}) {
    TrackingOptions t = debiased(4.0, 5, ratio);
    EXPECT_THROW(t.validate(), std::invalid_argument) << ratio;
  }
  for (int level : {-1, TrackingOptions::kMaxDebiasedLevel + 1}) {
    TrackingOptions t = debiased(4.0, level);
    EXPECT_THROW(t.validate(), std::invalid_argument) << level;
  }
  for (double scale : {0.5, -1.0, 2000.0, double(NAN)}) {
    TrackingOptions t = debiased(4.0);
    t.fallbackMajorantScale = scale;
    EXPECT_THROW(t.validate(), std::invalid_argument) << scale;
  }
  for (double depth : {-0.1, 17.0, double(NAN)}) {
    TrackingOptions t = debiased(4.0);
    t.combFloorDepth = depth;
    EXPECT_THROW(t.validate(), std::invalid_argument) << depth;
  }
}

// ---- the stratified jitter

TEST(StratifiedJitter, UniformPerFrameAndEvenOverFrames) {
  // Over the pixels of one frame the positions are uniform (each frame's estimate is unbiased):
  // a 4 x 4 histogram within 5 sigma of flat.
  const int pixels = 1 << 16;
  int histogram[16] = {};
  for (int p = 0; p < pixels; ++p) {
    float u0, u1;
    stratifiedJitter(std::uint32_t(p), 37u, 5u, u0, u1);
    ++histogram[int(u0 * 4) * 4 + int(u1 * 4)];
  }
  const double expected = pixels / 16.0;
  for (int c = 0; c < 16; ++c) EXPECT_NEAR(histogram[c], expected, 5.0 * std::sqrt(expected)) << "cell " << c;
  // Over the frames of one half of one pixel's accumulation they spread evenly: with 64 frames
  // every cell of an 8 x 8 grid holds at most 3 (independent draws put 4 or more into some cell of
  // most pixels: the control).
  int stratifiedWorst = 0, randomWorst = 0;
  for (std::uint32_t pixel = 0; pixel < 64; ++pixel) {
    for (std::uint32_t half = 0; half < 2; ++half) {
      int cells[64] = {}, randomCells[64] = {}, frames = 0;
      for (std::uint32_t frame = 0; frame < 128; ++frame) {
        if (frameHalf(frame) != half) continue;
        ++frames;
        float u0, u1;
        stratifiedJitter(pixel, frame, 5u, u0, u1);
        ++cells[int(u0 * 8) * 8 + int(u1 * 8)];
        RngStream rng{pixel, frame, 5u, 0u};
        const float r0 = rng.next(), r1 = rng.next();
        ++randomCells[int(r0 * 8) * 8 + int(r1 * 8)];
      }
      ASSERT_EQ(frames, 64);
      stratifiedWorst = std::max(stratifiedWorst, *std::max_element(cells, cells + 64));
      randomWorst = std::max(randomWorst, *std::max_element(randomCells, randomCells + 64));
    }
  }
  EXPECT_LE(stratifiedWorst, 3);
  EXPECT_GE(randomWorst, 4);
}

// The accumulation's halves (frameHalf): frames 2j and 2j + 1 fall in different halves, so one
// renderer's halves differ by at most one frame; a sample share of every 2nd or 4th frame
// (SampleShare) splits its own frames the same way; and each half's frames take consecutive
// terms of its jitter sequence.
TEST(StratifiedJitter, HalvesStayBalancedForOneRendererAndForSampleShares) {
  for (std::uint32_t j = 0; j < 5000; ++j) ASSERT_NE(frameHalf(2 * j), frameHalf(2 * j + 1)) << j;
  for (std::uint32_t shares : {1u, 2u, 4u}) {
    for (std::uint32_t index = 0; index < shares; ++index) {
      int inSecond = 0;
      for (std::uint32_t local = 0; local < 1000; ++local) {
        inSecond += int(frameHalf(local * shares + index));
        const int n = int(local) + 1;
        ASSERT_LE(std::abs(2 * inSecond - n), 2) << shares << " shares, share " << index << ", " << n << " frames";
      }
    }
  }
}

}  // namespace
}  // namespace inr
