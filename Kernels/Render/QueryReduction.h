#pragma once
// Query reduction (paper §4.2): the user's settings. Ray budgeting decides which pixels get a
// ray this frame (Render/Budgeting.h); homogeneity pruning answers candidate collisions in
// near-uniform macrocells without an INR query (Render/Pruning.h); reprojection carries the
// accumulation across camera moves.
#include <string>

namespace inr {

enum class BudgetScheme : int {
  None = 0,          // every pixel every frame
  Histogram = 1,     // residual-histogram thresholding with skip countdowns (paper Eq. 6)
  Stbn = 2,          // spatiotemporal blue-noise thresholding at rho (Eq. 7)
  WeightedStbn = 3,  // blue noise at a per-pixel rho_eff steered by the residual (Eq. 8)
};

// "none", "histogram", "stbn", "weighted-stbn"; throws std::invalid_argument naming the choices.
BudgetScheme parseBudgetScheme(const std::string& name);
const char* budgetSchemeName(BudgetScheme scheme);

struct QueryReductionSettings {
  BudgetScheme budget = BudgetScheme::None;
  double budgetFraction = 0.75;  // rho: fraction of pixels re-rendered per frame
  int budgetMaxSkip = 8;         // K: longest skip countdown of the histogram scheme (frames)
  double budgetAlpha = 0.5;      // alpha: residual steering of weighted STBN (0 = plain STBN)
  bool reproject = true;         // camera moves reproject the accumulation instead of resetting it
  // Frames of history a reprojected pixel keeps at most: fewer let new samples replace the
  // reprojection's blur sooner, more keep more of the converged image through small moves.
  int reprojectHistory = 32;
  // Pruning thresholds as fractions of the field's value range: epsilon (cells whose scalar
  // range is below it are always pruned) and the falloff band delta above it. 0, 0 = off.
  double pruneEpsilon = 0.0;
  double pruneFalloff = 0.0;

  // Throws std::invalid_argument naming the parameter and its valid range.
  void validate() const;
  bool pruning() const { return pruneEpsilon > 0.0 || pruneFalloff > 0.0; }
};

}  // namespace inr
