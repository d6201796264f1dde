#pragma once
// The sample-space split's exactness property (RenderSettings::sampleShare), checked the same way
// on every backend: N shares, share r rendering the frames r, r + N, r + 2N, ... of one renderer
// (ceil((T - r) / N) of them), averaged with weights of their frame counts, equal that renderer
// after T frames up to the accumulation's float rounding, frame for frame in their statistics;
// and shares that all draw the same frames (no mapping) do not.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"
#include "Render/WavefrontRenderer.h"
#include "TestSupport/TestScene.h"

namespace inr::test {

// One render: its image and each frame's statistics. The image is the premultiplied one, or the
// one composited over the background (affine in it, so the weighted mean commutes with that).
struct ShareRun {
  ImageRGBA image;
  std::vector<FrameStats> frames;
};
// Renders `frames` frames with `settings` on a fresh renderer (and fresh macrocells) of a backend.
using ShareRenderer = std::function<ShareRun(const RenderSettings& settings, int frames)>;

// Gives a renderer of any backend its settings and scene and renders `frames` frames, keeping
// each one's statistics.
template <typename Renderer>
std::vector<FrameStats> renderEachFrame(Renderer& renderer, const RenderSettings& settings, const RenderScene& scene,
                                        int frames) {
  renderer.setSettings(settings);
  renderer.setScene(scene);
  std::vector<FrameStats> out;
  for (int f = 0; f < frames; ++f) out.push_back(renderer.renderFrame());
  return out;
}

// The frames share `index` of `count` renders so that the shares together render frames 0..total-1.
inline int sampleShareFrames(int index, int count, int total) { return sampleShareFrameCount(SampleShare{index, count}, total); }

// The frame-weighted mean of the runs' images (what composite_bricks.py does with
// sample shares).
inline std::vector<double> frameWeightedMean(const std::vector<ShareRun>& runs) {
  std::vector<double> mean(runs[0].image.data.size(), 0.0);
  double frames = 0.0;
  for (const ShareRun& r : runs) {
    const double w = double(r.frames.size());
    frames += w;
    for (std::size_t p = 0; p < mean.size(); ++p) mean[p] += w * double(r.image.data[p]);
  }
  for (double& v : mean) v /= frames;
  return mean;
}

// Largest |a - b| / (1 + |b|) over every channel of every pixel.
inline double largestRelativeDifference(const std::vector<double>& a, const std::vector<float>& b) {
  double worst = 0.0;
  for (std::size_t p = 0; p < b.size(); ++p)
    worst = std::max(worst, std::fabs(a[p] - double(b[p])) / (1.0 + std::fabs(double(b[p]))));
  return worst;
}

// `count` shares of `totalFrames` frames (settings.sampleShare set per share) against one render
// of totalFrames frames with `settings` as they are. Per frame: share r's local frame f does
// exactly the work of the single renderer's frame f * count + r (rays, queries, shadow queries,
// iterations). Images: the running means round once per frame, so the shares' weighted mean
// and the single image differ by a few float epsilons per frame at most.
inline void expectSharesEqualOneRenderer(const ShareRenderer& render, const RenderSettings& settings, int count,
                                         int totalFrames, const std::string& what) {
  ASSERT_EQ(settings.sampleShare.count, 1) << what << ": pass the single renderer's settings";
  const ShareRun whole = render(settings, totalFrames);
  ASSERT_EQ(int(whole.frames.size()), totalFrames) << what;
  double coverage = 0.0;
  for (std::size_t p = 3; p < whole.image.data.size(); p += 4) coverage += whole.image.data[p];
  // The mean opacity over the picture: a thin volume (coordnet_blobs on the GPU: 0.063) still shows.
  ASSERT_GT(coverage / double(whole.image.data.size() / 4), 0.03) << what << ": the scene must show the volume";

  std::vector<ShareRun> shares, unmapped;
  for (int r = 0; r < count; ++r) {
    RenderSettings s = settings;
    s.sampleShare = SampleShare{r, count};
    const int frames = sampleShareFrames(r, count, totalFrames);
    shares.push_back(render(s, frames));
    ASSERT_EQ(int(shares.back().frames.size()), frames) << what;
    for (int f = 0; f < frames; ++f) {
      const FrameStats& a = shares.back().frames[std::size_t(f)];
      const FrameStats& b = whole.frames[std::size_t(f * count + r)];
      ASSERT_EQ(a.rays, b.rays) << what << ": share " << r << "/" << count << ", local frame " << f;
      ASSERT_EQ(a.queries, b.queries) << what << ": share " << r << "/" << count << ", local frame " << f;
      ASSERT_EQ(a.shadowQueries, b.shadowQueries) << what << ": share " << r << "/" << count << ", frame " << f;
      ASSERT_EQ(a.iterations, b.iterations) << what << ": share " << r << "/" << count << ", local frame " << f;
    }
    // The control: the same frame counts without the mapping (every run draws frames 0, 1, ...).
    unmapped.push_back(render(settings, frames));
  }
  const double tolerance = 8.0 * double(totalFrames) * double(FLT_EPSILON);
  const double error = largestRelativeDifference(frameWeightedMean(shares), whole.image.data);
  const double controlError = largestRelativeDifference(frameWeightedMean(unmapped), whole.image.data);
  std::printf("%s, %d shares of %d frames: largest difference %.3g (tolerance %.3g); without the frame mapping %.3g\n",
              what.c_str(), count, totalFrames, error, tolerance, controlError);
  EXPECT_LE(error, tolerance) << what << ", " << count << " shares";
  EXPECT_GT(controlError, 100.0 * tolerance) << what << ": the check cannot tell shares apart";
}

// The smooth test field's oblique view (obliqueCubeScene), size x size pixels, partly
// translucent, lit with ratio-tracked shadows on request.
inline SceneSetup sampleShareScene(int size, bool shadows) {
  SceneSetup s = obliqueCubeScene(size, 5);
  s.scene.transferFunction = TransferFunction::preset(0.3, 0.95, 0.7);
  s.scene.transferFunction.unitDistance = 0.25;
  lightScene(s.scene, shadows, ShadowEstimator::Ratio);
  return s;
}

// expectSharesEqualOneRenderer for every primary estimator (delta, ratio, march), without and with
// shadows, on sampleShareScene(size): `makeRenderer(scene, tracking)` gives a backend's renderer;
// `splits` lists {share count, total frames}.
inline void expectSharesEqualOneRendererForEveryEstimator(
    const std::string& backend, int size,
    const std::function<ShareRenderer(const SceneSetup&, const TrackingOptions&)>& makeRenderer,
    const std::vector<std::array<int, 2>>& splits) {
  const std::pair<const char*, TrackingOptions> estimators[] = {
      {"delta", TrackingOptions{}}, {"ratio", ratioTracking(4.0, 8)}, {"march", unbiasedMarch(4.0, 1.0, 8)}};
  for (const auto& [name, tracking] : estimators)
    for (bool shadows : {false, true}) {
      const SceneSetup s = sampleShareScene(size, shadows);
      const ShareRenderer render = makeRenderer(s, tracking);
      for (const auto& [count, total] : splits)
        expectSharesEqualOneRenderer(render, s.settings, count, total,
                                     backend + " " + name + (shadows ? " with shadows" : ""));
    }
}

}  // namespace inr::test
