#pragma once
// Ray budgeting (paper §4.2.1): the per-frame constants of the budgeting decision that Stage I
// takes per pixel (budgetPixel in Render/RayInit.h) and the residual histogram that Stage IV
// fills for the histogram scheme. Device-facing: plain data and INR_HD helpers.
#include <cstdint>

#include "Render/BlueNoiseMask.h"
#include "Render/RenderMath.h"

namespace inr {

constexpr int kResidualBins = 256;

// Histogram bin of a residual r in [0, 1].
INR_HD int residualBin(float r) { return clampi(int(r * float(kResidualBins)), 0, kResidualBins - 1); }

struct BudgetConstants {
  int scheme = 0;             // BudgetScheme (QueryReduction.h); 0 = every pixel
  float rho = 1.f;            // render fraction
  float alpha = 0.f;          // residual steering (weighted STBN)
  int maxSkip = 0;            // S_max = min(K, floor(n / 4)) for this frame (histogram scheme)
  float tau = 0.f;            // residual threshold from the last frame's histogram
  std::uint32_t noiseFrame = 0;  // slice index of the blue-noise mask (continues across reprojection)
  BlueNoiseMaskView mask;     // STBN schemes
};

}  // namespace inr
