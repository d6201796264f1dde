// Ray budgeting (paper §4.2.1) and reprojection on the CPU backend: the per-pixel decision's
// guarantees (staleness bound, render fractions, the weighted floor), convergence of every
// scheme to the unbudgeted image, and reprojection after a camera translation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/Finalize.h"
#include "Render/RayInit.h"
#include "Render/RayStateArrays.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

const Box3f kBox = test::kCubeBox;

TEST(Budgeting, ResidualThresholdIsTheBinWhereTheCdfReachesOneMinusRho) {
  std::uint32_t h[kResidualBins] = {};
  h[0] = 50;   // half the pixels stable
  h[10] = 30;
  h[200] = 20;
  EXPECT_FLOAT_EQ(residualThreshold(h, 0.5), 0.5f / 256.f);    // CDF reaches 0.5 in bin 0
  EXPECT_FLOAT_EQ(residualThreshold(h, 0.4), 10.5f / 256.f);   // 0.6 reached in bin 10
  EXPECT_FLOAT_EQ(residualThreshold(h, 0.2), 10.5f / 256.f);   // 0.8 reached in bin 10
  EXPECT_FLOAT_EQ(residualThreshold(h, 0.1), 200.5f / 256.f);  // 0.9 reached in bin 200
  EXPECT_EQ(residualThreshold(h, 1.0), 0.f);                    // everything renders
  std::uint32_t empty[kResidualBins] = {};
  EXPECT_EQ(residualThreshold(empty, 0.5), 0.f);
}

// Pixel state of n pixels that have accumulated something, for calling budgetPixel directly.
struct Pixels {
  explicit Pixels(int n) {
    arrays.resize(std::size_t(n));
    view = arrays.view();
    for (int i = 0; i < n; ++i) {
      resetPixel(view, i);
      view.sampleCount[i] = 1;
    }
  }
  PixelStateArrays<HostArray> arrays;
  AccumulationView view;
};

TEST(Budgeting, HistogramCountdownRendersEveryPixelOncePerSmaxPlusOneFrames) {
  const int n = 4096, frames = 200;
  Pixels px(n);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < n; ++i) px.view.residual[i] = 0.2f * u(rng) * u(rng);
  BudgetConstants b;
  b.scheme = int(BudgetScheme::Histogram);
  b.tau = 0.1f;
  std::vector<int> run(n, 0);
  int longest = 0;
  std::size_t skipped = 0;
  for (int f = 0; f < frames; ++f) {
    b.maxSkip = std::min(6, f / 4);  // the renderer's S_max = min(K, n / 4), K = 6
    for (int i = 0; i < n; ++i) {
      if (budgetPixel(b, px.view, i, i % 64, i / 64)) {
        px.view.skip[i] = -1;  // as finalisation does
        px.view.residual[i] = 0.2f * u(rng) * u(rng);
        run[i] = 0;
      } else {
        longest = std::max(longest, ++run[i]);
        ++skipped;
        ASSERT_LE(run[i], b.maxSkip) << "pixel " << i << " frame " << f;
      }
    }
  }
  EXPECT_EQ(longest, 6);  // the bound is reached, so the check above is not vacuous
  EXPECT_GT(skipped, std::size_t(n) * frames / 4);
  // Pixels at or above tau always render.
  px.view.residual[0] = 0.1f;
  px.view.skip[0] = -1;
  EXPECT_TRUE(budgetPixel(b, px.view, 0, 0, 0));
}

TEST(Budgeting, StbnRendersRhoOfEachFrameAndEachPixelRoundRhoNTimesPerCycle) {
  const BlueNoiseMask& mask = shippedBlueNoiseMask();
  const int w = mask.width, h = mask.height, d = mask.depth;
  Pixels px(w * h);
  BudgetConstants b;
  b.scheme = int(BudgetScheme::Stbn);
  b.mask = mask.view();
  for (double rho : {0.25, 0.5, 0.75}) {
    b.rho = float(rho);
    std::vector<int> count(std::size_t(w) * h, 0);
    for (int f = 0; f < d; ++f) {
      b.noiseFrame = std::uint32_t(f + 3 * d);  // any cycle
      int rendered = 0;
      for (int i = 0; i < w * h; ++i) {
        const bool r = budgetPixel(b, px.view, i, i % w, i / w);
        rendered += r ? 1 : 0;
        count[std::size_t(i)] += r ? 1 : 0;
      }
      EXPECT_NEAR(double(rendered) / (w * h), rho, 0.02) << "frame " << f << " rho " << rho;
    }
    const int expected = int(std::lround(rho * d));
    for (int i = 0; i < w * h; ++i)
      ASSERT_NEAR(count[std::size_t(i)], expected, 1) << "pixel " << i << " rho " << rho;
  }
}

TEST(Budgeting, WeightedStbnFloorKeepsStablePixelsRendering) {
  const BlueNoiseMask& mask = shippedBlueNoiseMask();
  const int w = mask.width, h = mask.height;
  Pixels px(w * h);
  BudgetConstants b;
  b.scheme = int(BudgetScheme::WeightedStbn);
  b.mask = mask.view();
  b.rho = 0.5f;
  b.alpha = 1.f;  // rho_eff = r_i: fully residual-driven, the floor is all that is left
  b.rhoFloor = budgetRhoFloor(mask.depth);
  for (int i = 0; i < w * h; ++i) px.view.residual[i] = 0.f;
  std::vector<int> count(std::size_t(w) * h, 0);
  for (int f = 0; f < mask.depth; ++f) {
    b.noiseFrame = std::uint32_t(f);
    for (int i = 0; i < w * h; ++i) count[std::size_t(i)] += budgetPixel(b, px.view, i, i % w, i / w) ? 1 : 0;
  }
  int least = mask.depth, most = 0;
  for (int c : count) {
    least = std::min(least, c);
    most = std::max(most, c);
  }
  EXPECT_GE(least, 1);  // the floor: nobody starves
  EXPECT_LE(most, 1);   // and it is only a floor: once per cycle
  // The paper's 2/256 alone would starve pixels of a 64-slice mask: the raise is needed.
  b.rhoFloor = 2.f / 256.f;
  int starved = 0;
  for (int i = 0; i < w * h; ++i) {
    int c = 0;
    for (int f = 0; f < mask.depth; ++f) {
      b.noiseFrame = std::uint32_t(f);
      c += budgetPixel(b, px.view, i, i % w, i / w) ? 1 : 0;
    }
    starved += c == 0 ? 1 : 0;
  }
  EXPECT_GT(starved, w * h / 4);
  b.rhoFloor = budgetRhoFloor(mask.depth);
  // Unstable pixels (r_i = 1) always render.
  for (int i = 0; i < w * h; ++i) px.view.residual[i] = 1.f;
  for (int i = 0; i < w * h; ++i) ASSERT_TRUE(budgetPixel(b, px.view, i, i % w, i / w));
}

TEST(Budgeting, PixelsWithNothingAccumulatedAlwaysRender) {
  Pixels px(16);
  BudgetConstants b;
  b.scheme = int(BudgetScheme::Stbn);
  b.mask = shippedBlueNoiseMask().view();
  b.rho = 1.f / 256.f;
  for (int i = 0; i < 16; ++i) px.view.sampleCount[i] = 0;
  for (int i = 0; i < 16; ++i) EXPECT_TRUE(budgetPixel(b, px.view, i, i, 0));
}

// The sparse blobs seen obliquely: mostly background, the volume's pixels are what matter.
struct BlobScene {
  BlobScene() : field(test::sparseField), grid(field, kBox, 0, 1, test::cubeMacrocells(16, 2)) {
    const test::SceneSetup s = test::obliqueCubeScene(64, 5);
    settings = s.settings;
    scene = s.scene;
    scene.transferFunction = TransferFunction::preset(0.0, 1.0, 0.6);
    scene.transferFunction.unitDistance = 0.15;
  }
  test::FunctionField field;
  MacrocellGrid grid;
  RenderSettings settings;
  RenderScene scene;
};

struct Converged {
  ImageRGBA image, premultiplied;
};

Converged render(BlobScene& s, const QueryReductionSettings& q, int frames, std::uint32_t seed, FrameStats* total = nullptr) {
  CpuWavefrontRenderer r(s.field, s.grid);
  r.setQueryReduction(q);
  RenderSettings settings = s.settings;
  settings.seed = seed;
  const FrameStats st = test::renderFrames(r, settings, s.scene, frames);
  if (total) *total = st;
  return Converged{r.image(), r.premultipliedImage()};
}

TEST(Budgeting, EverySchemeConvergesToTheUnbudgetedImage) {
  BlobScene s;
  const Converged reference = render(s, {}, 2048, 99);
  struct Case {
    BudgetScheme scheme;
    double rho;
  };
  for (const Case c : {Case{BudgetScheme::Histogram, 0.5}, Case{BudgetScheme::Stbn, 0.5},
                       Case{BudgetScheme::WeightedStbn, 0.5}}) {
    QueryReductionSettings q;
    q.budget = c.scheme;
    q.budgetFraction = c.rho;
    q.budgetMaxSkip = 8;
    FrameStats st;
    const int frames = 1600;  // about 800 samples per pixel at rho = 0.5
    const Converged img = render(s, q, frames, 17, &st);
    const double psnr = test::psnrOverCoverage(img.image, reference.image, reference.premultiplied);
    std::printf("%-14s rho %.2f: %.2f dB over the volume's pixels, %.1f%% of pixels skipped\n",
                budgetSchemeName(c.scheme), c.rho, psnr, 100.0 * double(st.budgetSkipped) / double(st.pixels));
    EXPECT_GE(psnr, 40.0) << budgetSchemeName(c.scheme);
    EXPECT_GT(st.budgetSkipped, st.pixels / 4) << budgetSchemeName(c.scheme) << " did not skip";
  }
}

TEST(Budgeting, ReprojectedTranslationMatchesAFreshConvergedRenderInItsFirstFrame) {
  BlobScene s;
  RenderScene moved = s.scene;
  const std::array<double, 3> shift{0.06, -0.04, 0.0};  // a small sideways pan (~1.5 pixels)
  for (int k = 0; k < 3; ++k) {
    moved.camera.position[k] += shift[k];
    moved.camera.focalPoint[k] += shift[k];
  }
  BlobScene fresh;
  fresh.scene = moved;
  const Converged reference = render(fresh, {}, 1024, 31);

  for (bool reproject : {true, false}) {
    CpuWavefrontRenderer r(s.field, s.grid);
    QueryReductionSettings q;
    q.reproject = reproject;
    r.setQueryReduction(q);
    test::renderFrames(r, s.settings, s.scene, 256);
    r.setScene(moved);
    EXPECT_EQ(r.counters().reprojections, reproject ? 1 : 0);
    const double reprojected = test::psnrOverCoverage(r.image(), reference.image, reference.premultiplied);
    r.renderFrame();
    const double psnr = test::psnrOverCoverage(r.image(), reference.image, reference.premultiplied);
    std::printf("after the pan, reprojection %s: %.2f dB before its first frame, %.2f dB after it "
                "(over the volume's pixels)\n", reproject ? "on" : "off", reprojected, psnr);
    if (reproject)
      EXPECT_GE(psnr, 35.0);
    else
      EXPECT_LT(psnr, 30.0);  // what the user would see without it: the test discriminates
  }
}

}  // namespace
}  // namespace inr
