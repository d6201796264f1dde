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

// Weighted STBN's floor of rho_eff: the paper's 2/256, raised to one slice's share 1/D of a
// D-slice mask. A pixel's D thresholds hold one per 1/D-wide band (the mask's stratification,
// Docs/blue-noise.md), so rho_eff >= 1/D renders every pixel at least once per D frames whatever
// its residual; with 2/256 alone a 64-slice mask starves the pixels whose lowest threshold is
// 2/256 or 3/256 (about half of them) for ever.
INR_HD float budgetRhoFloor(int maskDepth) {
  const float share = maskDepth > 0 ? 1.f / float(maskDepth) : 0.f;
  return share > 2.f / 256.f ? share : 2.f / 256.f;
}

struct BudgetConstants {
  int scheme = 0;             // BudgetScheme (QueryReduction.h); 0 = every pixel
  float rho = 1.f;            // render fraction
  float alpha = 0.f;          // residual steering (weighted STBN)
  float rhoFloor = 2.f / 256.f;  // weighted STBN's floor of rho_eff (budgetRhoFloor)
  int maxSkip = 0;            // S_max = min(K, floor(n / 4)) for this frame (histogram scheme)
  float tau = 0.f;            // residual threshold from the last frame's histogram
  std::uint32_t noiseFrame = 0;  // slice index of the blue-noise mask (continues across reprojection)
  BlueNoiseMaskView mask;     // STBN schemes
};

}  // namespace inr
