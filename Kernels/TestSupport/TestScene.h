#pragma once
// The scene the model tests and the GPU render benchmark render (an oblique view of the model's
// world box, the preset transfer function over the value range, shadows on request), the
// macrocells they use, and small helpers for rendering and checking images.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "Common/ImageIO.h"
#include "Model/InrModel.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/MacrocellGrid.h"
#include "Render/ModelBox.h"
#include "Render/QueryReduction.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"
#include "Render/WavefrontRenderer.h"

namespace inr::test {

// Oblique view, so rays cross the box at varied lengths; time in the middle of the range.
// Ratio-tracked shadow transmittance by default: same expectation as delta tracking's binary
// visibility (DeltaTracking.RatioTrackedShadowsAgreeWithDeltaShadows), less noise per frame.
inline RenderScene testScene(const InrModel& model, const std::array<float, 2>& range, bool shadows,
                             ShadowEstimator shadowEstimator = ShadowEstimator::Ratio, double maxOpacity = 0.6) {
  const Box3f box = modelWorldBox(model);
  RenderScene scene;
  scene.camera = Camera::framing(box);
  const auto& f = scene.camera.focalPoint;
  const double d = scene.camera.position[2] - f[2];
  scene.camera.position = {f[0] + 0.55 * d, f[1] + 0.4 * d, f[2] + 0.75 * d};
  scene.time = 0.5 * (model.domain.timeBegin + model.domain.timeEnd);
  scene.transferFunction = TransferFunction::preset(range[0], range[1], maxOpacity);
  scene.transferFunction.unitDistance = length(box.hi - box.lo) / 12.0;
  scene.background = {0.1f, 0.1f, 0.15f};
  scene.shadows = shadows;
  scene.ambient = 0.3f;
  scene.toLight = defaultLightDirection(scene.camera);
  scene.shadowEstimator = shadowEstimator;
  return scene;
}

// The macrocells the model tests render with: 16^3 cells, 8 temporal slices.
inline MacrocellOptions testMacrocells() {
  MacrocellOptions o;
  o.dims = Int3{16, 16, 16};
  o.temporalSlices = 8;
  return o;
}

// The analytic-field tests' domain (TestFields.h: the fields live on [-1, 1]^3).
const Box3f kCubeBox{{-1.f, -1.f, -1.f}, {1.f, 1.f, 1.f}};

// Image settings and scene of one analytic-field test.
struct SceneSetup {
  RenderSettings settings;
  RenderScene scene;
};

// The blob tests' view (TestFields.h's Gaussian blob): [-1, 1]^3 seen orthographically down -z,
// 1.5 units across, size x size pixels without jitter, with `seed`. Callers add the medium.
inline SceneSetup orthographicCubeView(int size, std::uint32_t seed) {
  SceneSetup s;
  s.settings.width = s.settings.height = size;
  s.settings.seed = seed;
  s.settings.pixelJitter = false;
  s.scene.camera = Camera::framing(kCubeBox);
  s.scene.camera.parallelProjection = true;
  s.scene.camera.parallelScale = 0.75;
  return s;
}

// Whether the naive (unbatched) tracker's image after `frames` frames equals the wavefront
// renderer's, bit for bit, for `field` over [-1, 1]^3 with `macrocells` (a grid of its own each):
// the same random streams and stage code give the same picture.
inline bool naiveImageEqualsWavefront(const FieldEvaluator& field, const SceneSetup& setup,
                                      const MacrocellOptions& macrocells, int frames = 3) {
  MacrocellGrid gridA(field, kCubeBox, 0, 1, macrocells);
  MacrocellGrid gridB(field, kCubeBox, 0, 1, macrocells);
  CpuWavefrontRenderer wavefront(field, gridA), naive(field, gridB);
  wavefront.setSettings(setup.settings);
  wavefront.setScene(setup.scene);
  naive.setSettings(setup.settings);
  naive.setScene(setup.scene);
  for (int k = 0; k < frames; ++k) {
    wavefront.renderFrame();
    naive.renderFrameNaive();
  }
  return wavefront.image().data == naive.image().data;
}

// The analytic-field tests' view: [-1, 1]^3 seen obliquely from (2.2, 1.6, 3.4), background
// (0.1, 0.2, 0.3), time 0.3, size x size pixels with `seed`. Callers choose the transfer function.
inline SceneSetup obliqueCubeScene(int size, std::uint32_t seed) {
  SceneSetup s;
  s.settings.width = s.settings.height = size;
  s.settings.seed = seed;
  s.scene.camera = Camera::framing(kCubeBox);
  s.scene.camera.position = {2.2, 1.6, 3.4};
  s.scene.background = {0.1f, 0.2f, 0.3f};
  s.scene.time = 0.3;
  return s;
}

// Their lighting: shadows on or off, ambient 0.3 and the default light for the camera.
inline void lightScene(RenderScene& scene, bool shadows, ShadowEstimator estimator = ShadowEstimator::Delta) {
  scene.shadows = shadows;
  scene.ambient = 0.3f;
  scene.toLight = defaultLightDirection(scene.camera);
  scene.shadowEstimator = estimator;
}

// n^3 macrocells with `temporalSlices` slices.
inline MacrocellOptions cubeMacrocells(int n, int temporalSlices) {
  MacrocellOptions o;
  o.dims = Int3{n, n, n};
  o.temporalSlices = temporalSlices;
  return o;
}

// Ratio tracking (RatioTracking.h) at `scale` x the majorant, `points` points per iteration.
inline TrackingOptions ratioTracking(double scale, int points = 16) {
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Ratio;
  t.majorantScale = scale;
  t.pointsPerIteration = points;
  return t;
}

// Unbiased ray marching: comb density `scale`, residual points at `residual` x the majorant.
inline TrackingOptions unbiasedMarch(double scale, double residual = 1.0, int points = 16) {
  TrackingOptions t = ratioTracking(scale, points);
  t.estimator = PrimaryEstimator::March;
  t.residualScale = residual;
  return t;
}

// Query reduction with pruning at (epsilon, falloff) and everything else at its defaults.
inline QueryReductionSettings pruningAt(double epsilon, double falloff) {
  QueryReductionSettings q;
  q.pruneEpsilon = epsilon;
  q.pruneFalloff = falloff;
  return q;
}

// Gives a renderer of any backend its settings and scene, renders `frames` frames and returns
// their summed statistics.
template <typename Renderer>
FrameStats renderFrames(Renderer& renderer, const RenderSettings& settings, const RenderScene& scene, int frames) {
  renderer.setSettings(settings);
  renderer.setScene(scene);
  FrameStats total;
  for (int k = 0; k < frames; ++k) total += renderer.renderFrame();
  return total;
}

// PSNR (RGB, peak 1) of `a` against `reference` over the pixels the volume covers in the
// reference (`referenceCoverage`: its premultiplied image, alpha > 0): a mostly-background image
// would make a whole-image PSNR look good. Infinite when they agree there exactly.
inline double psnrOverCoverage(const ImageRGBA& a, const ImageRGBA& reference, const ImageRGBA& referenceCoverage) {
  double se = 0.0;
  std::size_t n = 0;
  for (int i = 0; i < reference.width * reference.height; ++i) {
    if (!(referenceCoverage.data[4 * std::size_t(i) + 3] > 0.f)) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.data[4 * std::size_t(i) + c]) - double(reference.data[4 * std::size_t(i) + c]);
      se += d * d;
    }
    ++n;
  }
  if (n == 0) return 0.0;  // nothing covered: no evidence either way
  const double mse = se / (3.0 * double(n));
  return mse > 0.0 ? -10.0 * std::log10(mse) : INFINITY;
}

// Mean alpha (coverage) of a premultiplied image: the opacity the analytic-medium tests predict.
inline double meanCoverage(const ImageRGBA& premultiplied) {
  double s = 0;
  for (int i = 0; i < premultiplied.width * premultiplied.height; ++i) s += premultiplied.data[4 * i + 3];
  return s / (premultiplied.width * premultiplied.height);
}

inline std::size_t nonFinitePixels(const ImageRGBA& img) {
  std::size_t bad = 0;
  for (float v : img.data) bad += std::isfinite(v) ? 0 : 1;
  return bad;
}

}  // namespace inr::test
