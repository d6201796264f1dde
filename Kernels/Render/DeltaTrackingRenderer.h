#pragma once
// The CPU backend of the four-stage wavefront pipeline (paper §4.1): it owns the persistent ray
// state, the query batch, the accumulation buffer, the transfer-function table and the majorant
// grids, and runs the stages over all rays with OpenMP, frame after frame. The per-ray work is
// the INR_HD stage code in RayInit.h / Traverse.h / Evaluate.h / Shadows.h / Finalize.h — the
// same functions the CUDA backend compiles.
//
// It also hosts the naive baseline (renderFrameNaive): the same estimator and random streams,
// but each ray evaluates the network inside its own loop, one point per call, no batching.
#include <cstdint>
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Evaluator/FieldEvaluator.h"
#include "Render/Finalize.h"
#include "Render/MacrocellGrid.h"
#include "Render/QueryBatch.h"
#include "Render/RayState.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"

namespace inr {

struct TrackingOptions {
  bool refineMacrocells = true;  // widen under-estimated cells from evaluated samples
  int ghostPassesOnUpdate = 0;   // ghost passes run after each time / TF change
  int ghostPixelStride = 4;      // ghost passes trace every n-th pixel in x and y
};

class DeltaTrackingRenderer {
public:
  // `macrocells` must outlive the renderer; it is shared so a session keeps its built slices.
  DeltaTrackingRenderer(const FieldEvaluator& evaluator, MacrocellGrid& macrocells,
                        TrackingOptions options = {});

  void setSettings(const RenderSettings& settings);
  // Applies a scene, doing only the work its changes need (see RenderScene).
  void setScene(const RenderScene& scene);

  FrameStats renderFrame();        // one wavefront frame, accumulated
  FrameStats renderFrameNaive();   // baseline: per-ray, one query per evaluator call
  // Ghost passes: primary passes with cosine-bump TFs sweeping the value range, not displayed,
  // so under-estimated macrocells get visited and refined. Returns their summed stats.
  FrameStats runGhostPasses(int count);

  void resetAccumulation();
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;               // composited over the background, alpha = coverage
  ImageRGBA premultipliedImage() const;  // volume only (rgb premultiplied, alpha = coverage)
  const std::vector<float>& residual() const { return residual_; }
  const std::vector<float>& majorants() const { return majorants_.cell; }
  const std::vector<float>& blockMajorants() const { return majorants_.block; }  // skip level
  const MacrocellGrid& macrocells() const { return macrocells_; }
  double lastUpdateMs() const { return pendingUpdateMs_; }

private:
  FrameConstants frameConstants(std::uint32_t frame) const;
  RayStateView rayView();
  AccumulationView accumulationView();
  double applyDirtyMajorants();
  void runTrackingLoop(const FrameConstants& fc, const TrackingMedium& medium, int& iterations,
                       std::size_t& queries, double& traverseMs, double& evaluateMs,
                       std::size_t& refinements);
  void resize();

  const FieldEvaluator& evaluator_;
  MacrocellGrid& macrocells_;
  TrackingOptions options_;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  CameraView cameraView_{};
  std::unique_ptr<TransferFunctionTable> tfTable_;
  MajorantArrays majorants_;

  // Persistent ray state (struct of arrays).
  std::vector<Vec3f> origin_, direction_, tNext_;
  std::vector<float> t_, tEnd_, sample_, collisionProduct_, visibility_;
  std::vector<std::uint32_t> rngCounter_;
  std::vector<std::uint8_t> flags_;
  std::vector<Int3> cell_;
  std::vector<Vec4f> radiance_;
  QueryBatch batch_;
  // Accumulation.
  std::vector<Vec4f> accum_;
  std::vector<std::uint32_t> sampleCount_;
  std::vector<float> residual_;
  int frameIndex_ = 0;
  std::uint32_t ghostFrame_ = 0;
  double pendingUpdateMs_ = 0.0;  // time/TF update work, reported with the next frame
};

}  // namespace inr
