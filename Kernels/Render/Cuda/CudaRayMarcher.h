#pragma once
// The ray-marching baseline on the GPU: the per-ray logic of RayMarchRenderer (Render/RayMarch.h:
// the same camera rays and jitter draws, segments, samples and compositing, here in float), the
// samples evaluated in large batches through CudaInrEvaluator::evaluateDevice: per chunk of
// pixels a kernel cuts each ray and counts its samples, a device prefix sum (CUB) places them, a
// kernel writes the points, the evaluator fills the values, a kernel composites and accumulates.
// Shadows are not implemented on the GPU (setScene throws when they are requested).
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/RayMarcher.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"

namespace inr {

class CudaInrEvaluator;

class CudaRayMarcher {
public:
  CudaRayMarcher(const CudaInrEvaluator& evaluator, const Box3f& box, RayMarchOptions options = {});
  ~CudaRayMarcher();
  void setSettings(const RenderSettings& settings);
  void setScene(const RenderScene& scene);
  FrameStats renderFrame();
  void resetAccumulation();
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;
  float step() const { return step_; }

private:
  struct Impl;
  const CudaInrEvaluator& evaluator_;
  Box3f box_;
  RayMarchOptions options_;
  float step_ = 0.f;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  int frameIndex_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
