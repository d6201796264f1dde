#pragma once
// The CUDA backend of the four-stage wavefront pipeline (paper §4.1), with the CPU backend's
// API (DeltaTrackingRenderer) and the same per-ray code: the INR_HD stage functions of
// Render/RayInit.h, Traverse.h, Evaluate.h, Shadows.h and Finalize.h are compiled into the
// kernels here. Everything per ray or per pixel stays in device memory between stages and
// frames: struct-of-arrays ray state, two query buffers (float4 points + ray indices) filled by
// warp-aggregated atomic append, the accumulation buffer and residual, the transfer-function
// table and the majorant grid (CudaMacrocellGrid: lattice sampling, working grid, majorants with
// their coarse empty-space-skipping level, and refinement on the GPU).
//
// Loop control: after ray initialisation a dense traverse pass runs over all rays; every later
// traverse pass runs only over the rays that queued a query in the previous pass (read from the
// previous query buffer: after traversal a ray is active iff it is pending), so late iterations
// cost what their few rays cost. Per iteration the host reads back one counter (pinned memory)
// to size the evaluation launch and to stop when it is zero. The iteration count is capped
// (CudaPipelineOptions::maxIterations): rays still pending then are terminated as escaped and
// the frame is counted in counters().truncatedFrames.
//
// Also hosts the naive GPU baseline (renderFrameNaive): one thread per ray running init,
// tracking with a per-thread fp32 network evaluation inside its loop, shadows and finalisation.
#include <cuda_runtime.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Cuda/Pipeline/CudaMacrocellGrid.h"
#include "Render/DeltaTrackingRenderer.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"

namespace inr {

class CudaInrEvaluator;
class CudaPerThreadMlp;

struct CudaPipelineOptions {
  int maxIterations = 1 << 14;  // traverse-evaluate iterations per loop before rays are cut off
  bool stageTiming = true;      // CUDA events around every stage (per-stage milliseconds)
  int naiveRaysPerLaunch = 1 << 16;  // naive baseline: rays per kernel launch (bounded launches)
};

// Work the scene-change detection did (what tests and benchmarks check).
struct CudaPipelineCounters {
  int workingGridUpdates = 0;   // time changes
  int majorantUpdates = 0;      // full majorant recomputations (time or TF changes)
  int transferFunctionUploads = 0;
  int accumulationResets = 0;
  int truncatedFrames = 0;      // frames where maxIterations cut rays off
};

class CudaDeltaTrackingRenderer {
public:
  // `macrocells` (and the evaluator) must outlive the renderer; all work runs on the grid's stream.
  CudaDeltaTrackingRenderer(const CudaInrEvaluator& evaluator, CudaMacrocellGrid& macrocells,
                            TrackingOptions options = {}, CudaPipelineOptions pipeline = {});
  ~CudaDeltaTrackingRenderer();
  CudaDeltaTrackingRenderer(const CudaDeltaTrackingRenderer&) = delete;
  CudaDeltaTrackingRenderer& operator=(const CudaDeltaTrackingRenderer&) = delete;

  void setSettings(const RenderSettings& settings);
  // Applies a scene doing only the work its changes need: time -> working grid + majorants;
  // TF -> table upload + majorants; camera/light/background/depth/shadow settings ->
  // accumulation reset; nothing -> nothing (keeps accumulating).
  void setScene(const RenderScene& scene);

  FrameStats renderFrame();
  // Baseline: per-thread delta tracking with the network evaluated inside each thread's loop.
  FrameStats renderFrameNaive(const CudaPerThreadMlp& network);
  FrameStats runGhostPasses(int count);

  void resetAccumulation();
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;               // composited over the background, alpha = coverage
  ImageRGBA premultipliedImage() const;  // volume only
  std::vector<float> residual() const;
  std::vector<float> majorants() const;
  std::vector<float> blockMajorants() const;  // the coarse skip level; empty when skipping is off
  const CudaMacrocellGrid& macrocells() const { return macrocells_; }
  double lastUpdateMs() const { return pendingUpdateMs_; }
  const CudaPipelineCounters& counters() const { return counters_; }

private:
  struct Impl;
  void resize();

  const CudaInrEvaluator& evaluator_;
  CudaMacrocellGrid& macrocells_;
  TrackingOptions options_;
  CudaPipelineOptions pipeline_;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  int frameIndex_ = 0;
  std::uint32_t ghostFrame_ = 0;
  double pendingUpdateMs_ = 0.0;
  CudaPipelineCounters counters_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
