#pragma once
// Homogeneity-based query pruning (paper §4.2.2): a candidate collision in a macrocell whose
// scalar range is tiny is answered with the cell's expected scalar instead of an INR query.
// Device-facing view; the host grids own the arrays. Stage code lives here too (INR_HD: the
// same decisions and updates on CPU and GPU); traversal calls it from traverseRay (Traverse.h),
// the evaluation side feeds the expected scalars (expectedAfterQuery, Evaluate.h).
#include <cstdint>

#include "Common/HostDevice.h"
#include "Render/CounterRng.h"
#include "Render/MajorantGrid.h"

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

// Eq. homog_skip: the probability that a candidate in cell `cell` is pruned, from the cell's
// working range Delta_c = max - min: 1 below epsilon, a linear ramp down to 0 over
// [epsilon, epsilon + falloff), 0 above. Empty or invalid bounds (min > max, NaN, infinite
// range) are never pruned: nothing says the cell is uniform. falloff == 0 is a hard threshold
// (the ramp's test is never true, so there is no division by zero).
INR_HD float pruneProbability(const PruneView& v, int cell) {
  const float lo = v.cellMin[cell], hi = v.cellMax[cell];
  const float range = hi - lo;
  if (!(lo <= hi) || !isFiniteValue(range)) return 0.f;
  if (range < v.epsilon) return 1.f;
  if (range < v.epsilon + v.falloff) return 1.f - (range - v.epsilon) / v.falloff;
  return 0.f;
}

// The pruning decision for a candidate in cell `cell`. Draws from the ray's stream only inside
// the falloff band (0 < p < 1): with pruning off, or in every cell outside the band, the ray's
// draws, and so the image, are exactly those of a renderer without pruning.
INR_HD bool prunes(const PruneView& v, int cell, RngStream& rng) {
  if (!v.expected) return false;  // off: one test of a kernel parameter
  const float p = pruneProbability(v, cell);
  if (!(p > 0.f)) return false;
  return p >= 1.f || rng.next() < p;
}

// Centre weight w_c of Eq. ev_ema for a point p in cell `cell`: 1 at the cell centre, falling
// linearly to 0 on the faces, in the max norm of the cell-normalised offset:
//   w_c = 1 - max over axes of |2 (p - centre) / cellSize|, clamped to [0, 1].
// The max norm makes the level sets boxes like the cell itself, so a sample near any face counts
// little (a face is where a neighbouring, possibly different, cell's values bleed in), and the
// weight depends on the position only (not on the ray that brought the sample).
INR_HD float cellCentreWeight(const MajorantGridView& g, const Int3& cell, const Vec3f& p) {
  float d = 0.f;
  for (int a = 0; a < 3; ++a) {
    const float size = component(g.cellSize, a);
    const float centre = component(g.box.lo, a) + (float(component(cell, a)) + 0.5f) * size;
    const float u = fabsf(2.f * (component(p, a) - centre) / size);
    d = (u > d || u != u) ? u : d;  // a NaN offset sticks
  }
  return d < 1.f ? 1.f - d : 0.f;  // (NaN: 0)
}

// Eq. ev_ema: the expected scalar after a real evaluation `sample` with centre weight w:
// s^ + alpha (sample - s^), alpha = 0.1 max(w, 0.01). Callers skip non-finite samples; a
// non-finite estimate (never from the lattice mean, which skips NaN) restarts at the sample.
INR_HD float emaExpected(float current, float sample, float weight) {
  if (!isFiniteValue(current)) return sample;
  const float alpha = 0.1f * maxf(weight, 0.01f);
  return current + alpha * (sample - current);
}

}  // namespace inr
