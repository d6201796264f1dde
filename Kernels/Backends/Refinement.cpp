#include "Backends/Refinement.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace inr {

double convergenceEstimate(const FrameStats& last) {
  if (last.coveredPixels == 0) return std::numeric_limits<double>::infinity();
  const double mse = last.varianceSum / double(last.coveredPixels);
  if (!(mse < std::numeric_limits<double>::infinity())) return -std::numeric_limits<double>::infinity();
  if (!(mse > 0.0)) return std::numeric_limits<double>::infinity();
  return -10.0 * std::log10(mse);
}

RefinementDriver::RefinementDriver(const RefinementOptions& options) {
  setOptions(options);
  setClock({});
}

void RefinementDriver::setClock(std::function<double()> nowMs) {
  if (!nowMs) {
    nowMs = [] {
      return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
    };
  }
  nowMs_ = std::move(nowMs);
}

void RefinementDriver::setOptions(const RefinementOptions& o) {
  if (o.maximumFrames < 1) throw std::invalid_argument("refinement: maximum frames must be >= 1");
  if (o.framesPerRender < 1) throw std::invalid_argument("refinement: frames per render must be >= 1");
  if (!(o.convergenceTarget >= 0.0 && o.convergenceTarget <= 200.0))
    throw std::invalid_argument("refinement: convergence target must be a PSNR in [0, 200] dB (0 = off)");
  if (o.minimumFrames < 1) throw std::invalid_argument("refinement: minimum frames must be >= 1");
  if (!(o.timeBudgetMs >= 0.0 && o.timeBudgetMs <= 3.6e6))
    throw std::invalid_argument("refinement: time budget must be in [0, 3600000] ms (0 = off)");
  options_ = o;
}

bool RefinementDriver::converged(int frames) const {
  return frames >= options_.maximumFrames ||
         (options_.convergenceTarget > 0.0 && frames >= options_.minimumFrames &&
          estimate_ >= options_.convergenceTarget);
}

void RefinementDriver::restart() {
  estimate_ = -std::numeric_limits<double>::infinity();
  converged_ = false;
  lastFrames_ = 0;
  lastEpoch_ = -1;
}

RefinementDriver::Step RefinementDriver::advance(RenderSession& session, bool naive) {
  Step step;
  int frames = session.accumulatedFrames();
  // A reset or a reprojection (which keeps some frames) since the last request: start over.
  const int epoch = session.counters().accumulationResets + session.counters().reprojections;
  if (frames == 0 || frames < lastFrames_ || epoch != lastEpoch_) estimate_ = -std::numeric_limits<double>::infinity();
  lastEpoch_ = epoch;
  converged_ = converged(frames);
  const int goal = std::min(options_.maximumFrames, std::max(frames + 1, options_.framesPerRender));
  const bool timed = options_.timeBudgetMs > 0.0;
  const double start = timed ? nowMs_() : 0.0;
  double before = start, slowest = 0.0;
  // The frames asked for by count, then more while the next one (expected to take as long as the
  // slowest so far) ends within the budget.
  auto wanted = [&] {
    if (frames < goal) return true;
    if (!timed || frames >= options_.maximumFrames) return false;
    return before - start + slowest <= options_.timeBudgetMs;
  };
  while (!converged_ && wanted()) {
    const FrameStats st = naive ? session.renderFrameNaive() : session.renderFrame();
    if (st.stopped) break;  // asked to stop (RenderSession::setStopRequest): no frame, the step ends
    step.total += st;
    ++step.framesRendered;
    frames = session.accumulatedFrames();
    estimate_ = convergenceEstimate(st);
    converged_ = converged(frames);
    if (timed) {
      const double now = nowMs_();
      slowest = std::max(slowest, now - before);
      before = now;
    }
  }
  lastFrames_ = frames;
  return step;
}

}  // namespace inr
