#pragma once
// Baseline: fixed-step ray marching of the same emission–absorption integral, with the same
// scene inputs, the same camera rays (same jitter draws) and the same transfer-function table.
// Each ray is cut into equal segments of at most `step`, sampled at their midpoints (offset by a
// per-frame random shift when jitter is on), composited front to back with opacity correction
// alpha = 1 - exp(-sigma * ds) (= VTK's 1 - (1 - alpha)^(ds / u)). Shadows march towards the light
// from every sample that contributes. Evaluation is batched per chunk of pixels. It is the
// dense reference the delta tracker converges to (and the slow baseline of the benchmarks).
#include <cstdint>
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Evaluator/FieldEvaluator.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"

namespace inr {

struct RayMarchOptions {
  float step = 0.f;        // world units; 0 = box diagonal / 512
  float shadowStep = 0.f;  // world units; 0 = 2 * step
  int chunkPixels = 256;   // pixels whose samples form one evaluation batch
  std::size_t maxShadowBatch = std::size_t(1) << 20;  // shadow points per evaluator call
};

class RayMarchRenderer {
public:
  RayMarchRenderer(const FieldEvaluator& evaluator, const Box3f& box, RayMarchOptions options = {});
  void setSettings(const RenderSettings& settings);
  void setScene(const RenderScene& scene);
  FrameStats renderFrame();
  void resetAccumulation();
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;
  ImageRGBA premultipliedImage() const;
  float step() const { return step_; }
  float shadowStep() const { return shadowStep_; }

private:
  const FieldEvaluator& evaluator_;
  Box3f box_;
  RayMarchOptions options_;
  float step_ = 0.f, shadowStep_ = 0.f;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  std::unique_ptr<TransferFunctionTable> tfTable_;
  std::vector<Vec4f> accum_;
  int frameIndex_ = 0;
};

}  // namespace inr
