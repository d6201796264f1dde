#pragma once
// The CPU backend of the four-stage wavefront pipeline (paper §4.1): it owns the persistent ray
// state, the query batch, the accumulation buffer and the majorant grids, and runs the stages over
// all rays with OpenMP, frame after frame. The per-ray work is the INR_HD stage code in
// RayInit.h / Traverse.h / Evaluate.h / Shadows.h / Finalize.h — the same functions the CUDA
// backend compiles; settings, scene changes, accumulation rules and ghost passes are
// WavefrontRenderer's, shared with it.
//
// It also hosts the naive baseline (renderFrameNaive): the same estimator and random streams,
// but each ray evaluates the network inside its own loop, one point per call, no batching.
#include <array>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/MacrocellGrid.h"
#include "Render/QueryBatch.h"
#include "Render/RayStateArrays.h"
#include "Render/WavefrontRenderer.h"

namespace inr {

class CpuWavefrontRenderer final : public WavefrontRenderer {
public:
  // `macrocells` must outlive the renderer; it is shared so a session keeps its built slices.
  CpuWavefrontRenderer(const FieldEvaluator& evaluator, MacrocellGrid& macrocells,
                        TrackingOptions options = {});

  FrameStats renderFrameNaive();  // baseline: per-ray, one query per evaluator call

  std::vector<float> residual() const override { return pixels_.residual; }
  std::vector<float> majorants() const override { return majorants_.cell; }
  std::vector<float> blockMajorants() const override { return majorants_.block; }
  const MacrocellGrid& macrocells() const { return macrocells_; }

private:
  void resizePixels(std::size_t pixels) override;
  void clearAccumulation() override;
  std::vector<Vec4f> accumulation() const override { return pixels_.accum; }
  double macrocellTime() const override { return macrocells_.time(); }
  void setMacrocellTime(double t) override { macrocells_.setTime(t); }
  void recomputeMajorants() override { macrocells_.computeMajorants(tfTable_->view(), majorants_); }
  const Box3f& volumeBox() const override { return macrocells_.box(); }
  std::array<float, 2> workingValueRange() const override { return macrocells_.workingValueRange(); }
  Vec3f cellSize() const override { return macrocells_.cellSize(); }
  bool fieldHasGradient() const override { return evaluator_.providesGradient(); }
  void beginGhostPasses() override { applyDirtyMajorants(); }
  void traceGhostPass(const TransferFunctionTable& table, const FrameConstants& fc, int stride,
                      FrameStats& total) override;
  void endGhostPasses(FrameStats& total) override { total.updateMs = applyDirtyMajorants(); }

  BlueNoiseMaskView blueNoiseMask() override;
  void reprojectAccumulation(const CameraView& oldView, const CameraView& newView, std::uint32_t maxHistory,
                             const Vec3f& background) override;

  // The frame's stages (WavefrontRenderer::renderFrame runs them).
  FrameConstants prepareFrame(FrameStats& st) override;
  void initRays(const FrameConstants& fc, FrameStats& st) override;
  std::unique_ptr<TrackingLoopSteps> legSteps(const FrameConstants& fc, Leg leg, FrameStats& st) override;
  void spawnShadowRays(const FrameConstants& fc, FrameStats& st) override;
  bool stopsMidFrame() const override { return true; }
  void dropFrame() override;
  void keepFrame(FrameStats& st) override;
  void shadeHits(const FrameConstants& fc, FrameStats& st) override;
  const std::uint32_t* finalizePixels(const FrameConstants& fc, FrameStats& st) override;
  class TrackingSteps;  // a leg's traverse-evaluate loop steps (CpuWavefrontRenderer.cpp)

  FrameConstants frameConstants(std::uint32_t frame) {
    return WavefrontRenderer::frameConstants(frame, scene_.depthLimit.data());
  }
  double applyDirtyMajorants();
  // Applies pendingRefinements_ (and empties it); returns how many widened a cell.
  std::size_t applyPendingRefinements();

  const FieldEvaluator& evaluator_;
  MacrocellGrid& macrocells_;
  MajorantArrays majorants_;
  RayStateArrays<HostArray> rays_;
  PointStateArrays<HostScratchArray> points_;  // ratio tracking: rays x pointsPerIteration (sized on use)
  PixelStateArrays<HostArray> pixels_;
  PixelStateArrays<HostArray> history_;       // reprojection's copy of the old accumulation
  std::vector<std::uint64_t> reprojectKeys_;  // reprojection's per-pixel minimum offer
  QueryBatch batch_;
  // The macrocell widenings (cell, value) of the frame under way, applied in batch order when it
  // completes: a stopped frame leaves the macrocells as they were, so the frames after it are a
  // never-stopped session's. (Majorants change only between frames, so a completed frame's image
  // is the same as with widenings applied as they come.)
  std::vector<std::pair<int, float>> pendingRefinements_;
  std::vector<float> expectedBeforeFrame_;  // pruning's expected scalars before a stoppable frame
  TrackingMedium medium_{};  // the frame under way's (prepareFrame)
  std::array<std::uint32_t, kResidualBins> residualHistogram_{};  // the last frame's (finalizePixels)
};

}  // namespace inr
