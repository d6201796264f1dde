// Wall-clock timing of host work (stage times, render budgets): one clock and one conversion for
// the engine, the CUDA pipeline's host side and the plugin.
#pragma once

#include <chrono>

namespace inr {

using Clock = std::chrono::steady_clock;

// Milliseconds from t0 to now.
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace inr
