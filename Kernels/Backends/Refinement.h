#pragma once
// Progressive refinement, written once for every host (the ParaView mapper, `inr render
// --converge`): how many frames one request adds, and when the image counts as converged.
//
// The convergence estimate is an estimated PSNR, in dB, of the displayed image against the
// converged one, over the pixels the volume covers (accumulated alpha > 0): background and rays
// that never met the volume do not dilute it. Each pixel's frames fall in two independent halves
// (Finalize.h); the halves' difference estimates the variance of the pixel's running mean, the
// expected squared error of what is shown. Their mean over the covered pixels is the estimated
// MSE (RGB in [0, 1]), and the PSNR is -10 log10(MSE). The renderers reduce the sums where the
// pixels live (FrameStats::varianceSum, coveredPixels), so nothing per pixel leaves the GPU for
// this. 40 dB means an RMS error of 1% of full scale per channel.
#include <functional>
#include <limits>

#include "Backends/RenderSession.h"

namespace inr {

struct RefinementOptions {
  // Accumulation stops here even when not converged. High enough for sparse scenes, which
  // cover few pixels and need several hundred frames for the default target (a 256-frame cap
  // stopped one short of it; figures: Benchmarks/RESULTS.md, "Figures moved out of code comments").
  int maximumFrames = 2048;
  // Stop when the estimated PSNR over the volume's pixels reaches this (dB); 0 = off. The
  // default leaves a margin for the estimate's own noise: against 1024-frame references on the
  // shipped models it gives at least 40 dB (Benchmarks/RESULTS.md).
  double convergenceTarget = 41.0;
  int minimumFrames = 8;           // never converged on fewer frames (the variance is unknown)
  int framesPerRender = 1;         // one request accumulates until the image holds this many
  // Refinement by time: after the frames framesPerRender asks for (at least one), a request keeps
  // adding frames while the next one is expected to end within this many milliseconds of the
  // request's start (expected: the request's slowest frame so far), never beyond maximumFrames
  // or past convergence. 0 = off (frame count only). The time is wall time around
  // RenderSession::renderFrame, which returns the frame's statistics read back from the device
  // (on CUDA a synchronising copy): the GPU's work is inside it.
  double timeBudgetMs = 0.0;
};

// The estimated PSNR (dB) after a frame whose statistics are `last`: +inf when no pixel is
// covered (nothing to converge) or the variance is 0, -inf while some covered pixel has a single
// sample.
double convergenceEstimate(const FrameStats& last);

class RefinementDriver {
public:
  explicit RefinementDriver(const RefinementOptions& options = {});
  // Throws std::invalid_argument on a non-positive frame count or a negative target.
  void setOptions(const RefinementOptions& options);
  const RefinementOptions& options() const { return options_; }

  struct Step {
    int framesRendered = 0;
    FrameStats total;  // the rendered frames' statistics, summed
  };
  // One request: after the host's setScene, adds at least one frame while not converged, until
  // the image holds framesPerRender frames, then more while timeBudgetMs allows, never beyond
  // maximumFrames or past convergence.
  // Notices when the session's accumulation was reset since the last request (the estimate then
  // starts over). `naive` renders with the session's naive baseline.
  Step advance(RenderSession& session, bool naive = false);
  // Whether the image needs no more frames, re-evaluated for `frames` under the current options
  // (they may have changed since the last request).
  bool converged(int frames) const;
  bool converged() const { return converged_; }
  double estimate() const { return estimate_; }
  // Forget the estimate (the host reset the accumulation).
  void restart();
  // The clock the time budget reads (milliseconds, any origin); default: std::chrono's steady
  // clock. Tests pass a fake one.
  void setClock(std::function<double()> nowMs);

private:
  RefinementOptions options_;
  double estimate_ = -std::numeric_limits<double>::infinity();
  bool converged_ = false;
  int lastFrames_ = 0;
  int lastEpoch_ = -1;  // accumulation resets + reprojections the session had at the last request
  std::function<double()> nowMs_;
};

}  // namespace inr
