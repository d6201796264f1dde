#pragma once
// Progressive refinement, written once for every host (the ParaView mapper, `inr render
// --converge`): how many frames one request adds, and when the image counts as converged.
//
// The convergence estimate is the estimated standard error of the displayed image in RGB units
// ([0, 1] per channel): the mean over all pixels of the convergence residual r_i (Finalize.h)
// divided by sqrt(frames). The renderers reduce the residual where the pixels live and report
// the sum in FrameStats::residualSum, so nothing per pixel leaves the GPU for this.
#include <limits>

#include "Backends/RenderSession.h"

namespace inr {

struct RefinementOptions {
  int maximumFrames = 256;           // accumulation stops here
  double convergenceTarget = 0.002;  // stop when the estimate falls below this; 0 = off
  int minimumFrames = 4;             // never converged on fewer frames (the estimate is noisy)
  int framesPerRender = 1;           // one request accumulates until the image holds this many
};

// The estimate after a frame whose statistics are `last`, with `frames` accumulated.
double convergenceEstimate(const FrameStats& last, int frames);

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
  // the image holds framesPerRender frames, never beyond maximumFrames or past convergence.
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

private:
  RefinementOptions options_;
  double estimate_ = std::numeric_limits<double>::infinity();
  bool converged_ = false;
  int lastFrames_ = 0;
};

}  // namespace inr
