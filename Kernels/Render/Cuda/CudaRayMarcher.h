#pragma once
// The ray-marching baseline on the GPU: the per-ray logic of RayMarchRenderer (Render/RayMarch.h:
// the same camera rays and jitter draws, segments, samples and compositing, here in float), the
// samples evaluated in large batches through CudaInrEvaluator::evaluateDevice: per chunk of
// pixels a kernel cuts each ray and counts its samples, a device prefix sum (CUB) places them, a
// kernel writes the points, the evaluator fills the values, a kernel composites and accumulates.
// Shadows as the CPU marcher casts them: per chunk, each emitting sample's shadow points are
// counted and placed by a second prefix sum, evaluated in calls of at most maxShadowBatch points,
// and summed per sample in the order of its points. Gradient shading as the CPU marcher lights
// its samples: every sample's value and gradient in one pass (evaluateWithGradientDevice: the
// fused kernel's tangent rows, or the per-thread fp32 forward mode for a model off the fused
// path), each sample lit by Render/Shading.h's sampleLightAt.
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/RayMarcher.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"

namespace inr {

class CudaInrEvaluator;
struct MarchShadowParams;
struct TransferFunctionView;

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
  float shadowStep() const { return shadowStep_; }

private:
  struct Impl;
  void castShadows(int total, const TransferFunctionView& tf, const MarchShadowParams& sp, FrameStats& st);
  const CudaInrEvaluator& evaluator_;
  Box3f box_;
  RayMarchOptions options_;
  float step_ = 0.f, shadowStep_ = 0.f;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  int frameIndex_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
