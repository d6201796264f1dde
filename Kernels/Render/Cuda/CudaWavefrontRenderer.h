#pragma once
// The CUDA backend of the four-stage wavefront pipeline (paper §4.1): the same per-ray code as the
// CPU backend (the INR_HD stage functions of Render/RayInit.h, Traverse.h, Evaluate.h, Shadows.h
// and Finalize.h compiled into the kernels) and the same host policy (WavefrontRenderer: scene
// changes, accumulation, ghost passes). Everything per ray or per pixel stays in device memory
// between stages and frames: struct-of-arrays ray and pixel state (Render/RayStateArrays.h), two
// query buffers (float4 points + ray indices) filled by warp-aggregated atomic append, the
// transfer-function table and the majorant grid (CudaMacrocellGrid: lattice sampling, working
// grid, majorants with their coarse empty-space-skipping level, and refinement on the GPU).
//
// Loop control: after ray initialisation a dense traverse pass runs over all rays; every later
// traverse pass runs only over the rays that queued a query in the previous pass (read from the
// previous query buffer: after traversal a ray is active iff it is pending), so late iterations
// cost what their few rays cost. Traversal is a DeviceTraversal (DeviceTraversal.h; the DDA by
// default). Per iteration the host reads back one counter (pinned memory) to size the evaluation
// launch and to stop when it is zero. Work is bounded as on the CPU (TrackingOptions:
// maxCollisionsPerRay in the stage code, maxIterations here: rays still pending then are
// terminated as escaped and the frame is counted in counters().truncatedFrames). Each frame leaves the GPU as a few bytes
// of statistics (counts, the residual sum of the convergence estimate).
//
// Also hosts the naive GPU baseline (renderFrameNaive, CudaNaiveTracker.cu): one thread per ray
// running init, tracking with a per-thread fp32 network evaluation inside its loop, shadows and
// finalisation.
#include <cuda_runtime.h>

#include <memory>
#include <string>
#include <vector>

#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/TraversalOptions.h"
#include "Render/WavefrontRenderer.h"

namespace inr {

class DeviceFieldEvaluator;
class CudaPerThreadMlp;
class DeviceTraversal;

struct CudaPipelineOptions {
  bool stageTiming = true;      // CUDA events around every stage (per-stage milliseconds)
  int naiveRaysPerLaunch = 1 << 16;  // naive baseline: rays per kernel launch (bounded launches)
};

using CudaPipelineCounters = RendererCounters;

class CudaWavefrontRenderer final : public WavefrontRenderer {
public:
  // `macrocells` (and the evaluator) must outlive the renderer; all work runs on the grid's stream.
  CudaWavefrontRenderer(const DeviceFieldEvaluator& evaluator, CudaMacrocellGrid& macrocells,
                            TrackingOptions options = {}, CudaPipelineOptions pipeline = {});
  ~CudaWavefrontRenderer() override;

  // Baseline: per-thread delta tracking with the network evaluated inside each thread's loop.
  FrameStats renderFrameNaive(const CudaPerThreadMlp& network);

  std::vector<float> residual() const override;
  std::vector<float> majorants() const override;
  std::vector<float> blockMajorants() const override;
  const CudaMacrocellGrid& macrocells() const { return macrocells_; }
  const DeviceTraversal& traversal() const;
  // Replaces the traversal (the DDA until called): TraversalOptions::kind, with auto deciding
  // here. Throws (std::invalid_argument for a bad option, std::runtime_error saying why OptiX
  // cannot run) and keeps the old traversal. Structures over the majorants are built before the
  // next frame.
  void setTraversal(const TraversalOptions& options);
  // The traversal running and why it was chosen, e.g. "dda (auto: the GPU has no RT cores; ...)".
  const std::string& traversalChoice() const { return traversalChoice_; }

  struct Impl;  // device state (CudaWavefrontRendererImpl.cuh)

  // Allocates the per-pixel device state of a width x height image beside the current one, so
  // that a later setSettings to that size only swaps it in. Throws DeviceOutOfMemory (naming the
  // bytes, the image size and what to lower) with nothing changed when it does not fit: the
  // current image, its accumulation and the settings stay. setSettings to a new size calls it
  // too, but by then the settings have changed; a caller that must keep the old image calls this
  // first (RenderSession does).
  void reservePixels(int width, int height);
  // A warning about work left out for lack of GPU memory since the last call (reprojection
  // skipped: the image restarted instead), "" when none; cleared by the call.
  std::string takeMemoryNote();

  // The accumulated image (accumulation()'s layout: width x height float RGBA) into a CUDA array
  // of that size, device to device; returns when the copy is done.
  void copyAccumulation(cudaArray* target) const;

private:
  void resizePixels(std::size_t pixels) override;
  void stagePixels(std::size_t pixels, const std::string& imageSize);
  void clearAccumulation() override;
  std::vector<Vec4f> accumulation() const override;
  double macrocellTime() const override { return macrocells_.time(); }
  void setMacrocellTime(double t) override { macrocells_.setTime(t); }
  void transferFunctionChanged() override;
  void recomputeMajorants() override;
  void depthLimitChanged(const std::vector<float>& depthLimit) override;
  void sceneUpdateDone() override;
  const Box3f& volumeBox() const override { return macrocells_.box(); }
  std::array<float, 2> workingValueRange() const override { return macrocells_.workingValueRange(); }
  Vec3f cellSize() const override { return macrocells_.cellSize(); }
  bool fieldHasGradient() const override;
  // The frame's stages (WavefrontRenderer::renderFrame runs them), as kernels on the grid's stream;
  // finalizePixels reads the frame's statistics and stage times back.
  FrameConstants prepareFrame(FrameStats& st) override;
  void initRays(const FrameConstants& fc, FrameStats& st) override;
  std::unique_ptr<TrackingLoopSteps> legSteps(const FrameConstants& fc, Leg leg, FrameStats& st) override;
  void spawnShadowRays(const FrameConstants& fc, FrameStats& st) override;
  // Gradient shading's stage (Render/Shade.h) after the tracking loops: the lit rays' value +
  // gradient batch on the evaluator's per-thread forward mode, then the lighting.
  void shadeHits(const FrameConstants& fc, FrameStats& st) override;
  const std::uint32_t* finalizePixels(const FrameConstants& fc, FrameStats& st) override;
  void beginGhostPasses() override;
  void traceGhostPass(const TransferFunctionTable& table, const FrameConstants& fc, int stride,
                      FrameStats& total) override;
  void endGhostPasses(FrameStats& total) override;
  BlueNoiseMaskView blueNoiseMask() override;
  void reprojectAccumulation(const CameraView& oldView, const CameraView& newView, std::uint32_t maxHistory,
                             const Vec3f& background) override;
  // What every frame's launches read: constants, medium, refinement view (counting into the
  // frame's statistics), ray state. Callers bring the majorants up to date first.
  struct FrameSetup {
    FrameConstants fc;
    TrackingMedium medium;
    DeviceRefineView refine;
    RayStateView rs;
  };
  FrameSetup frameSetup(int frame);
  FrameSetup frame_{};  // the frame under way (prepareFrame)
  void readFrameStats(FrameStats& st);
  // Rebuilds what the traversal keeps over the displayed majorants (the OptiX GAS) after they
  // changed; its time goes into the next frame's statistics.
  void rebuildTraversal();

  const DeviceFieldEvaluator& evaluator_;
  CudaMacrocellGrid& macrocells_;
  CudaPipelineOptions pipeline_;
  std::unique_ptr<Impl> impl_;
  std::string traversalChoice_ = "dda (default)";
};

}  // namespace inr
