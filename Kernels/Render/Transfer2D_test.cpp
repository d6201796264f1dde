// 2D transfer functions (TransferFunction::transfer2D: colour and opacity over the value and the
// gradient magnitude |grad f|; Render/TransferFunctionTable.h): the table, its bounds, the file
// reader and the CPU renderers. On the Gaussian blob (TestFields.h) |grad f| is a function of the
// value, |grad f| = (2 / w) f sqrt(-ln f), so a 2D transfer function T(s, g) there is the same
// medium as the 1D transfer function s -> T(s, |grad f|(s)): the ray marcher must render both
// alike, and every estimator must converge to that picture. A 2D transfer function whose rows are
// all the same is the 1D one: the renderers must give the 1D image.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include "Common/ImageIO.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/Evaluate.h"
#include "Render/RayMarcher.h"
#include "Render/SceneChange.h"
#include "TestSupport/BlobRenders.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

double blobGradientNorm(double v) {
  if (!(v > 0.0 && v < 1.0)) return 0.0;
  return 2.0 / test::kBlobWidth * v * std::sqrt(-std::log(v));
}

// A 2D transfer function from a function of (scalar, gradient magnitude) sampled at the pixels
// (end to end over the ranges).
template <typename F>
TransferFunction::Transfer2D sampled2D(int width, int height, double sLo, double sHi, double gLo, double gHi, F&& f) {
  TransferFunction::Transfer2D t;
  t.width = width;
  t.height = height;
  t.scalarLo = sLo;
  t.scalarHi = sHi;
  t.gradientLo = gLo;
  t.gradientHi = gHi;
  t.rgba.resize(std::size_t(4) * width * height);
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i < width; ++i) {
      const double s = width > 1 ? sLo + i * (sHi - sLo) / (width - 1) : sLo;
      const double g = height > 1 ? gLo + j * (gHi - gLo) / (height - 1) : gLo;
      const std::array<double, 4> c = f(s, g);
      for (int k = 0; k < 4; ++k) t.rgba[std::size_t(4) * (std::size_t(j) * width + i) + k] = float(c[k]);
    }
  }
  return t;
}

double ramp(double x, double a, double b) { return std::clamp((x - a) / (b - a), 0.0, 1.0); }

// The blob's 2D transfer function: a shell where the gradient is steep (|grad f| from 0.75 up,
// the blob's largest about 1.43) coloured by the magnitude, and a faint core of any gradient;
// colour and opacity depend on both axes.
std::array<double, 4> blobTf2D(double s, double g) {
  const double shell = 0.9 * ramp(s, 0.1, 0.3) * ramp(g, 0.75, 1.1);
  const double core = 0.25 * ramp(s, 0.8, 0.95);
  return {0.2 + 0.8 * ramp(g, 0.6, 1.4), 0.3 + 0.6 * s, 0.9 - 0.7 * ramp(g, 0.4, 1.4), std::max(shell, core)};
}

test::SceneSetup blobScene(int size, bool shadows = false) {
  test::SceneSetup s = test::orthographicCubeView(size, 5);
  TransferFunction tf;
  tf.unitDistance = 0.2;
  tf.transfer2D = sampled2D(64, 48, 0.0, 1.0, 0.0, 1.6, blobTf2D);
  s.scene.transferFunction = tf;
  s.scene.background = {0.1f, 0.1f, 0.1f};
  s.scene.shadows = shadows;
  s.scene.toLight = {0.5, 0.6, 0.8};
  return s;
}

// The same medium as a 1D transfer function: the 2D table at the blob's own gradient for each
// value (through the engine's lookup, finely sampled).
test::SceneSetup bakedScene(int size) {
  test::SceneSetup s = blobScene(size);
  const TransferFunctionTable table(s.scene.transferFunction);
  const TransferFunctionView v = table.view();
  TransferFunction tf;
  tf.unitDistance = s.scene.transferFunction.unitDistance;
  const int n = 2048;
  for (int k = 0; k <= n; ++k) {
    const double x = double(k) / n;
    const Vec4f c = lookupTransferFunction2D(v, float(x), float(blobGradientNorm(x)));
    tf.color.push_back({x, c.x, c.y, c.z});
    tf.opacity.push_back({x, c.w});
  }
  s.scene.transferFunction = tf;
  return s;
}

// The control: the 2D table with the gradient axis ignored (its first row everywhere).
test::SceneSetup firstRowScene(int size) {
  test::SceneSetup s = blobScene(size);
  TransferFunction::Transfer2D& t = s.scene.transferFunction.transfer2D;
  for (int j = 1; j < t.height; ++j)
    std::copy(t.rgba.begin(), t.rgba.begin() + 4 * t.width, t.rgba.begin() + std::size_t(4) * j * t.width);
  return s;
}

TEST(Transfer2D, TableIsBilinearOverThePixelsAndClamps) {
  // 3 x 2 pixels over scalars [0.5, 2.5] and magnitudes [0.5, 1.5]: at s = 0.5, 1.5, 2.5, g = 0.5, 1.5.
  TransferFunction tf;
  tf.transfer2D = sampled2D(3, 2, 0.5, 2.5, 0.5, 1.5, [](double s, double g) {
    return std::array<double, 4>{s / 3.0, g / 2.0, 0.5, 0.1 * s + 0.2 * g};
  });
  EXPECT_TRUE(tf.usesTransfer2D());
  EXPECT_TRUE(tf.usesGradient());
  EXPECT_FALSE(tf.usesGradientOpacity());
  const TransferFunctionTable table(tf);
  const TransferFunctionView v = table.view();
  ASSERT_NE(v.rgba2D, nullptr);
  EXPECT_TRUE(usesGradient(v));
  EXPECT_EQ(v.gradientOpacity, nullptr);
  EXPECT_EQ(v.size, 3);
  EXPECT_EQ(v.gradientSize, 2);
  auto opacity = [](double s, double g) { return 0.1 * s + 0.2 * g; };
  for (double s : {0.5, 1.0, 1.5, 2.2, 2.5}) {
    for (double g : {0.5, 0.8, 1.5}) {
      const Vec4f c = lookupTransferFunction2D(v, float(s), float(g));
      EXPECT_NEAR(c.w, opacity(s, g), 1e-6) << s << " " << g;  // bilinear: exact on a bilinear function
      EXPECT_NEAR(c.x, s / 3.0, 1e-6);
      EXPECT_NEAR(c.y, g / 2.0, 1e-6);
    }
  }
  // Beyond the ends: the edge pixels (a texture clamped to its edge); NaN: the low end.
  EXPECT_NEAR(lookupTransferFunction2D(v, -5.f, 9.f).w, opacity(0.5, 1.5), 1e-6);
  EXPECT_NEAR(lookupTransferFunction2D(v, 0.2f, 0.1f).w, opacity(0.5, 0.5), 1e-6);
  EXPECT_NEAR(lookupTransferFunction2D(v, NAN, NAN).w, opacity(0.5, 0.5), 1e-6);
  EXPECT_NEAR(lookupTransferFunction2D(v, 3.f, INFINITY).w, opacity(2.5, 1.5), 1e-6);
  // The 1D table holds each column's largest opacity: here the upper row's.
  for (double s : {0.5, 1.7, 2.5}) EXPECT_NEAR(lookupTransferFunction(v, float(s)).w, opacity(s, 1.5), 1e-6) << s;
  // The stage code's one lookup: the gradient term is |grad f| itself, the empty term is empty.
  EXPECT_EQ(gradientTermOf(v, Vec3f{0.6f, 0.f, 0.8f}), 1.f);
  const Vec4f viaTerm = sampleColourOpacity(v, 1.2f, 0.9f);
  const Vec4f direct = lookupTransferFunction2D(v, 1.2f, 0.9f);
  EXPECT_EQ(viaTerm.w, direct.w);
  EXPECT_EQ(viaTerm.x, direct.x);
  EXPECT_EQ(sampleColourOpacity(v, 1.2f, emptyGradientTerm(v)).w, 0.f);
  // One pixel wide or high: constant along that axis.
  TransferFunction one;
  one.transfer2D = sampled2D(1, 1, 0.0, 1.0, 0.0, 1.0, [](double, double) { return std::array<double, 4>{0.3, 0.4, 0.5, 0.6}; });
  const TransferFunctionTable oneTable(one);
  for (float s : {-1.f, 0.3f, 2.f}) EXPECT_NEAR(lookupTransferFunction2D(oneTable.view(), s, 0.7f).w, 0.6f, 1e-7f);
}

TEST(Transfer2D, ColumnMaximaBoundTheOpacityAtEveryGradient) {
  // Random pixels: the 1D table (what majorants and the choice of which samples need a gradient
  // read) bounds the 2D opacity at any (s, g), and maxExtinctionOver bounds it over an interval.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  TransferFunction tf;
  tf.transfer2D = sampled2D(37, 23, -2.0, 5.0, 0.5, 9.0, [&](double, double) {
    const double a = u(rng) < 0.3 ? 0.0 : u(rng);
    return std::array<double, 4>{u(rng), u(rng), u(rng), a};
  });
  const TransferFunctionTable table(tf);
  const TransferFunctionView v = table.view();
  int violations = 0;
  for (int k = 0; k < 20000; ++k) {
    const float s = float(-3.0 + 9.0 * u(rng)), g = float(-1.0 + 12.0 * u(rng));
    const float a2 = lookupTransferFunction2D(v, s, g).w;
    if (a2 > lookupTransferFunction(v, s).w + 1e-6f) ++violations;
    const float s0 = s - float(u(rng)), s1 = s + float(u(rng));
    if (opacityToExtinction(a2, v.invUnitDistance) > maxExtinctionOver(v, s0, s1) * (1.f + 1e-5f) + 1e-6f) ++violations;
  }
  EXPECT_EQ(violations, 0);
}

TEST(Transfer2D, MalformedIsRefusedNamingTheProblem) {
  auto refused = [](TransferFunction::Transfer2D t, const std::string& what) {
    TransferFunction tf;
    tf.transfer2D = std::move(t);
    try {
      TransferFunctionTable table(tf);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  auto good = [] { return sampled2D(4, 3, 0.0, 1.0, 0.0, 1.0, [](double, double) { return std::array<double, 4>{1, 1, 1, 0.5}; }); };
  auto t = good();
  t.rgba.pop_back();
  refused(t, "RGBA values for 4 x 3 pixels");
  t = good();
  t.rgba[4 * (1 * 4 + 2) + 3] = NAN;
  refused(t, "pixel (2, 1) is not finite");
  t = good();
  t.scalarHi = t.scalarLo;
  refused(t, "scalar range");
  t = good();
  t.gradientHi = INFINITY;
  refused(t, "gradient magnitude range");
}

TEST(Transfer2D, ChangingItIsATransferFunctionChange) {
  RenderScene a = blobScene(4).scene;
  RenderScene b = a;
  EXPECT_FALSE(diffScenes(&a, b).transferFunction);
  b.transferFunction.transfer2D.rgba[7] = 0.123f;
  EXPECT_TRUE(diffScenes(&a, b).transferFunction);
  RenderScene c = a;
  c.transferFunction.transfer2D.gradientHi = 2.0;
  EXPECT_TRUE(diffScenes(&a, c).transferFunction);
  RenderScene d = a;
  d.transferFunction.transfer2D = {};
  EXPECT_TRUE(diffScenes(&a, d).transferFunction);
}

std::string writeFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(Transfer2D, JsonFileWithNumbersOrAPng) {
  const std::string numbers = writeFile("tf2d_numbers.json",
                                        R"({"ScalarRange": [-1, 3], "GradientRange": [0, 2], "Width": 2, "Height": 1,
                                            "RGBA": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]})");
  const TransferFunction::Transfer2D t = TransferFunction::transfer2DFromJsonFile(numbers);
  EXPECT_EQ(t.width, 2);
  EXPECT_EQ(t.height, 1);
  EXPECT_EQ(t.scalarLo, -1.0);
  EXPECT_EQ(t.gradientHi, 2.0);
  ASSERT_EQ(t.rgba.size(), 8u);
  EXPECT_FLOAT_EQ(t.rgba[7], 0.8f);
  // A PNG: its bottom row is the smallest magnitude.
  ImageRGBA png(3, 2);
  for (int x = 0; x < 3; ++x) {
    float* top = png.pixel(x, 0);
    float* bottom = png.pixel(x, 1);
    top[0] = 1.f, top[3] = 1.f;          // red, opaque: high magnitudes
    bottom[2] = 1.f, bottom[3] = 0.2f;   // blue, faint: low magnitudes
  }
  writePng(::testing::TempDir() + "tf2d_image.png", png, true);
  const std::string image =
      writeFile("tf2d_image.json", R"({"ScalarRange": [0, 1], "GradientRange": [0, 5], "Image": "tf2d_image.png"})");
  const TransferFunction::Transfer2D p = TransferFunction::transfer2DFromJsonFile(image);
  ASSERT_EQ(p.width, 3);
  ASSERT_EQ(p.height, 2);
  EXPECT_NEAR(p.rgba[2], 1.f, 1e-6f);        // row 0 (bottom): blue
  EXPECT_NEAR(p.rgba[3], 0.2f, 0.5f / 255);
  EXPECT_NEAR(p.rgba[4 * 3 + 0], 1.f, 1e-6f);  // row 1 (top): red
  // Errors name the file and the key.
  const std::string bad = writeFile("tf2d_bad.json", R"({"GradientRange": [0, 1], "Width": 1, "Height": 1, "RGBA": [0,0,0,0]})");
  try {
    TransferFunction::transfer2DFromJsonFile(bad);
    FAIL() << "a file without ScalarRange was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("ScalarRange"), std::string::npos) << e.what();
  }
  const std::string shortList = writeFile("tf2d_short.json",
                                          R"({"ScalarRange": [0, 1], "GradientRange": [0, 1], "Width": 2, "Height": 2, "RGBA": [0, 0, 0, 0]})");
  EXPECT_THROW(TransferFunction::transfer2DFromJsonFile(shortList), std::runtime_error);
}

using test::BlobRender;

// A 1D transfer function and the 2D one with its table in every row, lined up with the 1D table's
// entries (1024 columns at the 1D entries): the same medium, the same table entries, so the same
// majorants and random streams.
test::SceneSetup oneDimensionalScene(int size, bool shadows) {
  test::SceneSetup s = test::orthographicCubeView(size, 5);
  TransferFunction tf;
  tf.color = {{0.0, 0.2, 0.4, 0.9}, {0.5, 0.9, 0.9, 0.9}, {1.0, 0.9, 0.5, 0.1}};
  tf.opacity = {{0.0, 0.0}, {0.2, 0.0}, {0.5, 0.8}, {1.0, 0.8}};
  tf.unitDistance = 0.2;
  s.scene.transferFunction = tf;
  s.scene.background = {0.1f, 0.1f, 0.1f};
  s.scene.shadows = shadows;
  s.scene.toLight = {0.5, 0.6, 0.8};
  return s;
}

test::SceneSetup rowsAreTheOneDimensionalTable(test::SceneSetup s) {
  const TransferFunctionTable table(s.scene.transferFunction);
  const TransferFunctionView v = table.view();
  TransferFunction::Transfer2D t;
  t.width = v.size;
  t.height = 3;
  t.scalarLo = v.lo;
  t.scalarHi = v.hi;
  t.gradientLo = 0.0;
  t.gradientHi = 2.0;
  for (int j = 0; j < t.height; ++j)
    for (int i = 0; i < t.width; ++i)
      for (float c : {v.rgba[i].x, v.rgba[i].y, v.rgba[i].z, v.rgba[i].w}) t.rgba.push_back(c);
  s.scene.transferFunction.transfer2D = t;
  return s;
}

double largestDifference(const ImageRGBA& a, const ImageRGBA& b) {
  double worst = 0.0;
  for (std::size_t k = 0; k < a.data.size(); ++k) worst = std::max(worst, double(std::abs(a.data[k] - b.data[k])));
  return worst;
}

TEST(Transfer2DRender, GradientFreeTableReproducesTheOneDimensionalImage) {
  for (const bool shadows : {false, true}) {
    const test::SceneSetup one = oneDimensionalScene(24, shadows);
    const test::SceneSetup two = rowsAreTheOneDimensionalTable(one);
    ASSERT_TRUE(two.scene.transferFunction.usesTransfer2D());
    // The tables' 1D entries (so the majorants) are the same.
    const TransferFunctionTable t1(one.scene.transferFunction), t2(two.scene.transferFunction);
    EXPECT_EQ(t2.view().lo, t1.view().lo);
    EXPECT_EQ(t2.view().hi, t1.view().hi);
    for (int i = 0; i < t1.view().size; ++i) ASSERT_EQ(t2.view().rgba[i].w, t1.view().rgba[i].w) << i;
    struct Case {
      const char* name;
      TrackingOptions options;
    };
    for (const Case& c : {Case{"delta", TrackingOptions{}}, Case{"ratio", test::ratioTracking(4.0)}}) {
      const BlobRender a = test::trackedBlob(one, c.options, 6);
      const BlobRender b = test::trackedBlob(two, c.options, 6);
      const double worst = largestDifference(a.image, b.image);
      std::printf("rows = the 1D table, %s%s, 6 frames: largest pixel difference from the 1D image %.3g\n", c.name,
                  shadows ? " with shadows" : "", worst);
      EXPECT_LE(worst, 1e-5) << c.name;
      EXPECT_GT(b.gradientPoints, 0u) << "the 2D table asked for gradients";
      EXPECT_EQ(a.gradientPoints, 0u);
    }
    const BlobRender a = test::marchedBlob(one), b = test::marchedBlob(two);
    const double worst = largestDifference(a.image, b.image);
    std::printf("rows = the 1D table, ray marcher%s: largest pixel difference %.3g\n", shadows ? " with shadows" : "",
                worst);
    EXPECT_LE(worst, 1e-5);
  }
}

TEST(Transfer2DRender, MarcherRendersTheTableAsTheBakedTransferFunction) {
  const int size = 32;
  const BlobRender two = test::marchedBlob(blobScene(size));
  const BlobRender baked = test::marchedBlob(bakedScene(size));
  const BlobRender firstRow = test::marchedBlob(firstRowScene(size));
  const double psnr = test::psnrOverCoverage(two.image, baked.image, baked.premultiplied);
  const double control = test::psnrOverCoverage(firstRow.image, baked.image, baked.premultiplied);
  std::printf("marcher, 2D TF vs the table at the blob's gradient baked into a 1D TF: %.2f dB; the table's first "
              "row alone: %.2f dB\n",
              psnr, control);
  EXPECT_GE(psnr, 40.0);
  EXPECT_LT(control, 25.0);  // the gradient axis changes the picture: the comparison can fail
  EXPECT_EQ(two.gradientPoints, two.total.queries);
  EXPECT_EQ(test::nonFinitePixels(two.image), 0u);
}

// Each estimator, at a fixed seed, against the fine ray march of the same 2D TF: the PSNR over the
// volume's pixels must reach a bound that the table's first row alone (the gradient axis ignored)
// misses by far.
void expectConvergesToMarcher(const test::SceneSetup& setup, TrackingOptions options, int frames, double minPsnr) {
  const BlobRender t = test::trackedBlob(setup, options, frames);
  const BlobRender reference = test::marchedBlob(setup);
  test::SceneSetup off = firstRowScene(setup.settings.width);
  off.scene.shadows = setup.scene.shadows;
  const BlobRender without = test::marchedBlob(off);
  const double psnr = test::psnrOverCoverage(t.image, reference.image, reference.premultiplied);
  const double control = test::psnrOverCoverage(without.image, reference.image, reference.premultiplied);
  std::printf("2D TF, %s (%d frames%s) vs ray marching: %.2f dB over the volume; gradient axis ignored %.2f dB\n",
              primaryEstimatorName(options.estimator), frames, setup.scene.shadows ? ", shadows" : "", psnr, control);
  EXPECT_GE(psnr, minPsnr);
  EXPECT_LT(control, minPsnr - 8.0);
  // Gradients only where they can change the outcome (Evaluate.h), every one counted.
  const std::size_t tracking = t.total.queries + t.total.shadowQueries;
  std::printf("  gradients asked for %zu of %zu tracking queries\n", t.total.gradientOpacityQueries, tracking);
  EXPECT_EQ(t.gradientPoints, t.total.gradientOpacityQueries);
  EXPECT_GT(t.total.gradientOpacityQueries, 0u);
  EXPECT_LE(t.total.gradientOpacityQueries, tracking);
  EXPECT_EQ(test::nonFinitePixels(t.image), 0u);
}

TEST(Transfer2DRender, DeltaTrackingConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32), TrackingOptions{}, 300, 36.0);
}

TEST(Transfer2DRender, RatioTrackingConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32), test::ratioTracking(4.0), 60, 38.0);
}

TEST(Transfer2DRender, UnbiasedMarchConvergesToRayMarching) {
  expectConvergesToMarcher(blobScene(32), test::unbiasedMarch(2.0), 480, 35.0);
}

TEST(Transfer2DRender, PreintegratedMarchConvergesToRayMarching) {
  // (It runs ratio tracking with its comb density as the majorant scale: WavefrontRenderer.cpp.)
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Preintegrated;
  t.majorantScale = 4.0;
  t.pointsPerIteration = 32;
  expectConvergesToMarcher(blobScene(32), t, 60, 38.0);
}

TEST(Transfer2DRender, ShadowRaysSeeTheTableToo) {
  expectConvergesToMarcher(blobScene(32, true), test::ratioTracking(4.0), 200, 34.0);
}

TEST(Transfer2DRender, NaiveTrackerRendersTheSame) {
  const test::SceneSetup setup = blobScene(16, true);
  const test::FunctionField f(test::blobField, "blob", test::blobGradient);
  EXPECT_TRUE(test::naiveImageEqualsWavefront(f, setup, test::cubeMacrocells(8, 2)));
}

TEST(Transfer2DRender, PruningStandsDown) {
  const QueryReductionSettings pruning = test::pruningAt(0.2, 0.0);
  const BlobRender off = test::trackedBlob(oneDimensionalScene(24, false), TrackingOptions{}, 6, pruning);
  const BlobRender on = test::trackedBlob(blobScene(24), TrackingOptions{}, 6, pruning);
  EXPECT_GT(off.total.pruned, 0u);  // the settings do prune without it: the check can fail
  EXPECT_EQ(on.total.pruned, 0u);
}

TEST(Transfer2DRender, FieldWithoutGradientIsRefused) {
  test::expectRefusedWithoutGradient(blobScene(8), "2D transfer function");
}

}  // namespace
}  // namespace inr
