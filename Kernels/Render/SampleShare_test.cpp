// The sample-space split (RenderSettings::sampleShare) on the CPU backend: share r of N renders the
// single renderer's frames r, r + N, ..., so the shares' frame-weighted mean equals one render
// over all their frames (every estimator, with and without shadows; the ray marcher too); the
// blue-noise budgeting slices and the ghost passes follow; bad shares and two splits at once are
// refused. The GPU twin is Render/Cuda/CudaSampleShare_test.cpp.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/MacrocellGrid.h"
#include "Render/RayMarcher.h"
#include "TestSupport/SampleShareCheck.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::SceneSetup;

// Macrocells and tracking that do not adapt to the samples: no refinement (query reduction is off
// by default), so the shares' and the single renderer's frames see the same majorants.
test::ShareRenderer cpuRenderer(const FieldEvaluator& field, const SceneSetup& s, TrackingOptions tracking,
                                QueryReductionSettings reduction = {}) {
  tracking.refineMacrocells = false;
  return [&field, s, tracking, reduction](const RenderSettings& settings, int frames) {
    MacrocellGrid grid(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2));
    CpuWavefrontRenderer r(field, grid, tracking);
    r.setQueryReduction(reduction);
    test::ShareRun run;
    run.frames = test::renderEachFrame(r, settings, s.scene, frames);
    run.image = r.premultipliedImage();
    return run;
  };
}

TEST(SampleShare, FramesOfTheSharesAreTheSingleRenderersFramesOnce) {
  EXPECT_EQ(sampleShareFrame(SampleShare{}, 7u), 7u);
  EXPECT_EQ(sampleShareFrame(SampleShare{1, 4}, 0u), 1u);
  EXPECT_EQ(sampleShareFrame(SampleShare{3, 4}, 2u), 11u);
  for (int count : {1, 2, 3, 4, 7}) {
    const int total = 23;
    std::set<std::uint32_t> seen;
    for (int r = 0; r < count; ++r)
      for (int f = 0; f < test::sampleShareFrames(r, count, total); ++f)
        EXPECT_TRUE(seen.insert(sampleShareFrame(SampleShare{r, count}, std::uint32_t(f))).second) << count;
    ASSERT_EQ(int(seen.size()), total) << count << " shares";
    EXPECT_EQ(*seen.rbegin(), std::uint32_t(total - 1)) << count << " shares";
  }
}

// 9 frames over 2 shares (5 + 4) and 13 over 3 (5 + 4 + 4): uneven shares, weighted.
TEST(SampleShare, SharesAverageToOneRendererOverTheirFrames) {
  const test::FunctionField field(test::smoothField);
  test::expectSharesEqualOneRendererForEveryEstimator(
      "CPU", 20, [&](const SceneSetup& s, const TrackingOptions& t) { return cpuRenderer(field, s, t); },
      {{2, 9}, {3, 13}});
}

// With macrocell refinement each share widens its own grid from its own samples, so later frames
// draw against other majorants than the single renderer's: no longer the same numbers, still an
// estimate of the same image. Accumulated, the shares' mean stays far closer to the single render
// than a render with another seed (which shares none of its random numbers).
TEST(SampleShare, WithRefinementTheSharesStayCloseToOneRenderer) {
  const test::FunctionField field(test::smoothField);
  const SceneSetup s = test::sampleShareScene(20, true);
  const auto render = [&](const RenderSettings& settings, int frames) {
    MacrocellGrid grid(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2));
    CpuWavefrontRenderer r(field, grid);  // refinement on (the default)
    test::renderEachFrame(r, settings, s.scene, frames);
    return r.premultipliedImage().data;
  };
  const int count = 2, total = 160;
  const std::vector<float> whole = render(s.settings, total);
  RenderSettings otherSeed = s.settings;
  otherSeed.seed = 77;
  const std::vector<float> other = render(otherSeed, total);
  std::vector<double> mean(whole.size(), 0.0);
  for (int r = 0; r < count; ++r) {
    RenderSettings settings = s.settings;
    settings.sampleShare = SampleShare{r, count};
    const std::vector<float> share = render(settings, total / count);
    for (std::size_t p = 0; p < mean.size(); ++p) mean[p] += double(share[p]) / count;
  }
  double shares = 0.0, seeds = 0.0;
  for (std::size_t p = 0; p < whole.size(); ++p) {
    shares += (mean[p] - whole[p]) * (mean[p] - whole[p]);
    seeds += double(other[p] - whole[p]) * (other[p] - whole[p]);
  }
  std::printf("refinement on, %d shares of %d frames: rms vs one renderer %.5f (another seed %.5f)\n", count, total,
              std::sqrt(shares / double(whole.size())), std::sqrt(seeds / double(whole.size())));
  ASSERT_GT(seeds, 0.0);
  // Shares drawing the same frames would stand at about 0.7 of the other seed's distance.
  EXPECT_LT(std::sqrt(shares / seeds), 0.2);
}

// A camera move with reprojection keeps reprojectHistory frames of one renderer's history; N
// shares keep their part of it each (frames r, r + N, ... among the last reprojectHistory), so
// their frames after the move add up to one renderer's and the composite refines as long as one
// renderer's image does (plugin sample shares under MPI reported the whole Maximum Frames after a
// move while they kept N times the history).
TEST(SampleShare, ReprojectionKeepsOneRenderersHistoryAcrossTheShares) {
  const test::FunctionField field(test::smoothField);
  const SceneSetup s = test::sampleShareScene(20, false);
  QueryReductionSettings reduction;
  reduction.reproject = true;
  reduction.reprojectHistory = 8;
  RenderScene moved = s.scene;
  const std::array<double, 3> shift{0.03, -0.02, 0.0};
  for (int k = 0; k < 3; ++k) {
    moved.camera.position[k] += shift[k];
    moved.camera.focalPoint[k] += shift[k];
  }
  TrackingOptions tracking;
  tracking.refineMacrocells = false;
  // Frames before and after the move.
  const auto renderAndMove = [&](const RenderSettings& settings, int frames) {
    MacrocellGrid grid(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2));
    CpuWavefrontRenderer r(field, grid, tracking);
    r.setQueryReduction(reduction);
    test::renderEachFrame(r, settings, s.scene, frames);
    const int before = r.accumulatedFrames();
    r.setScene(moved);
    EXPECT_EQ(r.counters().reprojections, 1);
    return std::array<int, 2>{before, r.accumulatedFrames()};
  };
  for (const int total : {24, 6}) {
    const int one = renderAndMove(s.settings, total)[1];
    ASSERT_EQ(one, std::min(total, reduction.reprojectHistory));
    for (const int count : {2, 3, 5}) {
      int before = 0, after = 0;
      for (int r = 0; r < count; ++r) {
        RenderSettings settings = s.settings;
        settings.sampleShare = SampleShare{r, count};
        const std::array<int, 2> frames = renderAndMove(settings, test::sampleShareFrames(r, count, total));
        before += frames[0];
        after += frames[1];
      }
      EXPECT_EQ(before, total) << count << " shares";
      EXPECT_EQ(after, one) << count << " shares of " << total << " frames";
    }
  }
}

// A jittered ray marcher keys its jitter by the frame too: its shares follow the same mapping.
TEST(SampleShare, RayMarcherSharesAverageToOneMarcher) {
  const test::FunctionField field(test::smoothField);
  const SceneSetup s = test::sampleShareScene(20, false);
  RayMarchOptions o;
  o.step = 0.05f;
  const test::ShareRenderer march = [&](const RenderSettings& settings, int frames) {
    RayMarchRenderer r(field, test::kCubeBox, o);
    test::ShareRun run;
    run.frames = test::renderEachFrame(r, settings, s.scene, frames);
    run.image = r.premultipliedImage();
    return run;
  };
  test::expectSharesEqualOneRenderer(march, s.settings, 3, 10, "CPU ray marcher");
}

// STBN budgeting picks each frame's pixels from a blue-noise slice keyed by the frame: share r's
// local frame f picks the pixels of the single renderer's frame f * N + r. (The first frame of
// every share renders every pixel: nothing is accumulated there yet; the per-pixel weights then
// differ from the single renderer's, so budgeting keeps the estimate unbiased, not the same.)
TEST(SampleShare, BlueNoiseBudgetingFollowsTheShare) {
  const test::FunctionField field(test::smoothField);
  const SceneSetup s = test::sampleShareScene(20, false);
  QueryReductionSettings stbn;
  stbn.budget = BudgetScheme::Stbn;
  stbn.budgetFraction = 0.5;
  const test::ShareRenderer render = cpuRenderer(field, s, TrackingOptions{}, stbn);
  const int count = 3, total = 12;
  const test::ShareRun whole = render(s.settings, total);
  for (int r = 0; r < count; ++r) {
    RenderSettings settings = s.settings;
    settings.sampleShare = SampleShare{r, count};
    const test::ShareRun share = render(settings, total / count);
    for (std::size_t f = 1; f < share.frames.size(); ++f) {
      const FrameStats& single = whole.frames[f * count + std::size_t(r)];
      EXPECT_EQ(share.frames[f].budgetSkipped, single.budgetSkipped) << "share " << r << ", local frame " << f;
      EXPECT_EQ(share.frames[f].queries, single.queries) << "share " << r << ", local frame " << f;
      EXPECT_GT(share.frames[f].budgetSkipped, 0u) << "the budget must skip pixels for the check to mean anything";
    }
  }
}

// Ghost passes refine the grid every share tracks against: each share draws the ghost frames a
// single renderer draws, so their work and refinements are the same on every share.
TEST(SampleShare, GhostPassesAreTheSameOnEveryShare) {
  const test::FunctionField field(test::smoothField);
  const SceneSetup s = test::sampleShareScene(20, false);
  const auto ghost = [&](SampleShare share) {
    MacrocellGrid grid(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2));
    CpuWavefrontRenderer r(field, grid);
    RenderSettings settings = s.settings;
    settings.sampleShare = share;
    r.setSettings(settings);
    r.setScene(s.scene);
    return r.runGhostPasses(3);
  };
  const FrameStats whole = ghost(SampleShare{});
  ASSERT_GT(whole.queries, 0u);
  for (int r = 0; r < 3; ++r) {
    const FrameStats g = ghost(SampleShare{r, 3});
    EXPECT_EQ(g.queries, whole.queries) << "share " << r;
    EXPECT_EQ(g.refinements, whole.refinements) << "share " << r;
  }
}

TEST(SampleShare, RefusesBadSharesAndASecondSplit) {
  const test::FunctionField field(test::smoothField);
  MacrocellGrid grid(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2));
  CpuWavefrontRenderer r(field, grid);
  const auto refusal = [&](const RenderSettings& settings) -> std::string {
    try {
      r.setSettings(settings);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  RenderSettings bad;
  for (const SampleShare share : {SampleShare{2, 2}, SampleShare{0, 0}, SampleShare{-1, 2}}) {
    bad.sampleShare = share;
    EXPECT_NE(refusal(bad).find("sample share"), std::string::npos) << share.index << "/" << share.count;
  }
  bad.sampleShare = SampleShare{1, 2};
  bad.pixelShare = PixelShare{0, 2};
  EXPECT_NE(refusal(bad).find("choose one"), std::string::npos);
  bad.pixelShare = PixelShare{};
  bad.clipToBrick = true;
  bad.brick = Box3f{{-1.f, -1.f, -1.f}, {0.f, 1.f, 1.f}};
  EXPECT_NE(refusal(bad).find("choose one"), std::string::npos);
  bad.sampleShare = SampleShare{};
  EXPECT_EQ(refusal(bad), "");  // a brick alone is fine
}

}  // namespace
}  // namespace inr
