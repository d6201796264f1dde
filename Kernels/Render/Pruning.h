#pragma once
// Homogeneity-based query pruning (paper §4.2.2): a candidate collision in a macrocell whose
// scalar range is tiny is answered with the cell's expected scalar instead of an INR query.
// Device-facing view; the host grids own the arrays. Stage code lives here too.
#include <cstdint>

#include "Common/HostDevice.h"

namespace inr {

// Off unless `expected` is set and epsilon + falloff > 0. Thresholds are absolute (scalar units):
// the renderer converts the user's fractions of the field's value range.
struct PruneView {
  float epsilon = 0.f;             // Delta_c < epsilon: always pruned
  float falloff = 0.f;             // epsilon <= Delta_c < epsilon + falloff: pruned with falling probability
  const float* cellMin = nullptr;  // working bounds per cell (Delta_c = max - min)
  const float* cellMax = nullptr;
  float* expected = nullptr;       // s^_c per cell
};

}  // namespace inr
