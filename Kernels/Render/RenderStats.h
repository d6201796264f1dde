#pragma once
// Per-frame statistics every renderer reports (CLI, benchmarks, plugin status line).
#include <cstddef>
#include <string>

namespace inr {

struct FrameStats {
  std::string method;          // "delta", "naive", "raymarch", "ghost"
  int frame = 0;               // accumulation index of this frame (0 = first)
  // The frame was stopped before it was accumulated (WavefrontRenderer::setStopRequest): nothing
  // of it is in the image and it counts as no frame; its counts and times are what it spent.
  bool stopped = false;
  std::size_t pixels = 0;
  std::size_t rays = 0;        // primary rays that entered the volume
  std::size_t queries = 0;     // primary-ray INR queries
  int iterations = 0;          // primary traverse-evaluate iterations (evaluation batches)
  std::size_t shadowRays = 0;
  std::size_t shadowQueries = 0;
  int shadowIterations = 0;
  std::size_t shadingQueries = 0;  // value + gradient queries of gradient shading (one per lit ray)
  // Gradient opacity: the tracking loops' queries (primary and shadow, counted in queries and
  // shadowQueries) that were asked for their gradient too (Render/Evaluate.h).
  std::size_t gradientOpacityQueries = 0;
  std::size_t refinements = 0;  // macrocell bounds widened by this frame's samples
  std::size_t cappedRays = 0;   // rays cut off by the per-ray collision cap (bounded work)
  std::size_t budgetSkipped = 0;  // pixels ray budgeting left out this frame (no ray cast)
  std::size_t pruned = 0;         // candidate collisions answered by homogeneity pruning (no query)
  // Sum over all pixels of the convergence residual r_i after this frame (reduced where the
  // pixels live: a few bytes per frame leave the GPU). State, not a count: += keeps the later.
  double residualSum = 0;
  // The convergence estimate's sums after this frame (state too): the estimated variance of the
  // displayed mean over the pixels the volume covers, and how many pixels it covers.
  double varianceSum = 0;
  std::size_t coveredPixels = 0;
  // Milliseconds per stage: the same parts for every estimator, method and backend, and every
  // millisecond of totalMs in one of them (closeTiming).
  // - updateMs: majorant / working-grid updates the frame waited for, whether done when the scene
  //   changed (reported with the next frame) or at the frame's start;
  // - setupMs: the frame's buffers (re)allocated for a new image size or batch shape (a first
  //   frame's cost, like the update: benchmarks report both on the first frame's line);
  // - init ... finalize: the pipeline's stages (GPU: device time of each stage's kernels);
  // - otherMs: the rest of the frame's wall time, which no stage names (launches and syncs on the
  //   GPU, bookkeeping). Large values say a stage is missing its timer.
  double updateMs = 0, setupMs = 0, initMs = 0, traverseMs = 0, evaluateMs = 0, shadowTraverseMs = 0,
         shadowEvaluateMs = 0, shadingMs = 0, finalizeMs = 0, otherMs = 0, totalMs = 0;

  // The traversal's structure over the majorants (OptiX GAS; zero for the DDA): wall time of the
  // rebuilds since the previous frame (scene updates, refinements), and its primitives (non-empty
  // macrocells) and device bytes now.
  double traversalBuildMs = 0;
  std::size_t traversalPrimitives = 0, traversalBytes = 0;

  std::size_t totalQueries() const { return queries + shadowQueries + shadingQueries; }
  // The named stages' sum (every part of totalMs but otherMs).
  double namedStagesMs() const {
    return updateMs + setupMs + initMs + traverseMs + evaluateMs + shadowTraverseMs + shadowEvaluateMs + shadingMs +
           finalizeMs;
  }
  // Ends a frame's accounting: totalMs = the update done before the frame started (already in
  // updateMs) + the frame's own wall time; otherMs = what no stage names (never negative: GPU
  // stage times are device times that can overlap the host's).
  void closeTiming(double updateBeforeFrameMs, double frameWallMs) {
    totalMs = updateBeforeFrameMs + frameWallMs;
    otherMs = totalMs > namedStagesMs() ? totalMs - namedStagesMs() : 0.0;
  }
  // Sums counts and times (for run totals); keeps the later frame index.
  FrameStats& operator+=(const FrameStats& o);
};

}  // namespace inr
