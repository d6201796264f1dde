#pragma once
// Fixed scenes for the bit-for-bit regression tests of the CPU (Render/RenderRegression_test.cpp)
// and GPU (Render/Cuda/CudaRenderRegression_test.cpp) pipelines: images and counts that must
// not change when code is restructured. Each case's fingerprint folds the per-frame counts, the
// final image, residual and majorants into one FNV-1a hash; the tests hold the values recorded at
// a reference commit (INR_RECORD_FINGERPRINTS=1 prints them). A change meant to alter images (a
// new estimator, different random draws) re-records them and says why.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "Render/MacrocellGrid.h"
#include "Render/SceneInputs.h"
#include "Render/CpuWavefrontRenderer.h"

namespace inr::regression {

struct Case {
  const char* name;
  bool sparse, shadows, ratio, naive, depth;
  int ghostPasses, skipBlock;
  int cells = 12;  // macrocells along y (x: +2, z: -2); coarse grids miss extrema: refinement
};

inline const std::vector<Case>& cases() {
  static const std::vector<Case> c = {
      {"dense", false, false, false, false, false, 0, 4},
      {"sparse", true, false, false, false, false, 0, 4},
      {"sparse-no-skip", true, false, false, false, false, 0, 0},
      {"shadows-delta", true, true, false, false, false, 0, 4},
      {"shadows-ratio", false, true, true, false, false, 0, 2},
      {"ghost-passes", true, false, false, false, false, 3, 2, 4},
      {"coarse-refine", true, true, false, false, false, 0, 2, 4},
      {"depth-limit", false, true, false, false, true, 1, 4},
      {"naive", true, true, true, true, false, 0, 4},
  };
  return c;
}

inline bool recording() { return std::getenv("INR_RECORD_FINGERPRINTS") != nullptr; }

inline std::uint64_t fnv1a(const void* data, std::size_t bytes, std::uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

inline MacrocellOptions macrocells(const Case& c) {
  MacrocellOptions o;
  o.dims = Int3{c.cells + 2, c.cells, c.cells - 2};
  o.temporalSlices = 5;
  o.skipBlockCells = c.skipBlock;
  return o;
}

inline TrackingOptions tracking(const Case& c) {
  TrackingOptions t;
  t.ghostPassesOnUpdate = c.ghostPasses;
  t.ghostPixelStride = 3;
  return t;
}

inline RenderSettings settings() {
  RenderSettings s;
  s.width = 41;
  s.height = 29;
  s.seed = 17;
  return s;
}

// An oblique view of `box`, a TF transparent below 15% of [lo, hi], time `time`.
inline RenderScene scene(const Case& c, const Box3f& box, float lo, float hi, double time) {
  RenderScene scene;
  scene.camera = Camera::framing(box);
  const Vec3f centre = (box.lo + box.hi) * 0.5f, half = (box.hi - box.lo) * 0.5f;
  scene.camera.position = {centre.x + 2.1 * half.x, centre.y + 1.4 * half.y, centre.z + 3.0 * half.z};
  scene.camera.viewUp = {0, 0, 1};
  scene.time = time;
  scene.transferFunction = TransferFunction::preset(lo, hi, 0.7);
  scene.transferFunction.opacity = {{lo, 0.0}, {lo + 0.15 * (hi - lo), 0.0}, {hi, 0.8}};
  scene.transferFunction.unitDistance = 0.09 * length(box.hi - box.lo);
  scene.background = {0.1f, 0.2f, 0.3f};
  scene.shadows = c.shadows;
  scene.shadowEstimator = c.ratio ? ShadowEstimator::Ratio : ShadowEstimator::Delta;
  scene.toLight = defaultLightDirection(scene.camera);
  if (c.depth) {
    const RenderSettings s = settings();
    const float d = length(toVec3(scene.camera.position) - centre);
    scene.depthLimit.assign(std::size_t(s.width) * s.height, 1e30f);
    for (std::size_t i = 0; i < scene.depthLimit.size(); i += 3) scene.depthLimit[i] = d * (1.f + 0.001f * float(i % 97));
  }
  return scene;
}

// Six frames with a time change after the third (working grid, majorants, ghost passes, reset).
// `renderOne(renderer)` renders one frame (delta tracking or the naive baseline). The image is
// the renderer's accumulation (premultiplied, as it leaves the pipeline): compositing over the
// background happens on the host and rounds as that translation unit's compiler contracts.
// `withRefinementCounts` = false leaves the per-frame refinement counts out: on the GPU, racing
// queries in one cell can both count a widening (the bounds themselves, hashed through the
// majorants, are order-independent).
template <typename Renderer, typename RenderOne>
std::uint64_t fingerprint(Renderer& r, RenderScene scene, double laterTime, RenderOne&& renderOne,
                          bool withRefinementCounts = true) {
  r.setSettings(settings());
  r.setScene(scene);
  std::uint64_t h = 1469598103934665603ull;
  for (int k = 0; k < 6; ++k) {
    if (k == 3) {
      scene.time = laterTime;
      r.setScene(scene);
    }
    const FrameStats st = renderOne(r);
    const std::uint64_t counts[] = {st.rays, st.queries, std::uint64_t(st.iterations), st.shadowRays,
                                    st.shadowQueries, std::uint64_t(st.shadowIterations),
                                    withRefinementCounts ? st.refinements : 0};
    h = fnv1a(counts, sizeof(counts), h);
  }
  const ImageRGBA img = r.premultipliedImage();
  const std::vector<float> residual = r.residual(), majorants = r.majorants();
  if (recording()) {  // which part differs, when one does
    std::printf("      counts %016llx image %016llx residual %016llx majorants %016llx\n", (unsigned long long)h,
                (unsigned long long)fnv1a(img.data.data(), img.data.size() * sizeof(float)),
                (unsigned long long)fnv1a(residual.data(), residual.size() * sizeof(float)),
                (unsigned long long)fnv1a(majorants.data(), majorants.size() * sizeof(float)));
  }
  h = fnv1a(img.data.data(), img.data.size() * sizeof(float), h);
  h = fnv1a(residual.data(), residual.size() * sizeof(float), h);
  h = fnv1a(majorants.data(), majorants.size() * sizeof(float), h);
  return h;
}

}  // namespace inr::regression
