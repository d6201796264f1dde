#pragma once
// The scene-change policy, written once for every renderer and the plugin: what differs between
// two scenes, and what each difference costs.
//   time               working grid (interpolated slices) + majorants + accumulation reset
//   transfer function  table + majorants + accumulation reset
//   camera, depth limit, light (shadows on/off; with shadows on: direction, ambient,
//                      estimator; shading options; with shading on: ambient, and the
//                      direction unless it has a headlight or a list of lights, whose
//                      lights are then compared), background
//                      accumulation reset only (a camera-only move reprojects instead when
//                      QueryReductionSettings::reproject is on)
//   nothing            nothing: a host re-sending an identical scene keeps accumulating
// After a time or TF change, optional ghost passes sweep cosine-bump TFs over the working grid's
// value range so under-estimated macrocells get refined (GhostSweep).
#include <array>
#include <string>

#include "Render/RenderMath.h"
#include "Render/SceneInputs.h"

namespace inr {

struct SceneChange {
  bool first = false;  // no scene before: everything must be built
  bool time = false, transferFunction = false, camera = false, depthLimit = false, light = false,
       background = false;

  bool majorants() const { return first || time || transferFunction; }
  bool resetsAccumulation() const {
    return first || time || transferFunction || camera || depthLimit || light || background;
  }
  bool any() const { return resetsAccumulation(); }
  // " camera time tf" (the changed parts, each with a leading space), or " nothing".
  std::string describe() const;
};

// What changes from `before` (null: no scene yet) to `after`.
SceneChange diffScenes(const RenderScene* before, const RenderScene& after);

bool sameCamera(const Camera& a, const Camera& b);
bool sameTransferFunction(const TransferFunction& a, const TransferFunction& b);

// Checks a scene against the image settings (depth limit size, light direction, camera);
// throws std::invalid_argument naming the problem. Returns the camera's view.
CameraView validateScene(const RenderScene& scene, const RenderSettings& settings);

// Ghost passes: `count` primary passes, not displayed, whose TFs are cosine bumps of half-width
// span/count centred on a sweep over the working grid's value range [lo, lo + span]: neighbours
// overlap, so every scalar value gets a non-zero ghost extinction in some pass. Peak opacity 0.5
// per mean cell size: about one tentative collision per cell, so rays sample the cells they cross.
class GhostSweep {
public:
  GhostSweep(const std::array<float, 2>& workingRange, const Vec3f& cellSize, int count);
  int count() const { return count_; }
  TransferFunction transferFunction(int pass) const;
  // Frame number of ghost pass k (k counts every pass a renderer ran): a stream apart from the
  // displayed frames' numbers.
  static std::uint32_t frameNumber(std::uint32_t k) { return 0x80000000u + k; }

private:
  double lo_, span_, meanCell_;
  int count_;
};

}  // namespace inr
