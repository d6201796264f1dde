#pragma once
// Stage III — evaluation, per-query part: what a query is (the pending candidate's world point at
// the frame's time) and how its result lands in the ray state (scatter by ray index, no gather
// pass afterwards). The batching itself is backend-specific: QueryBatch (CPU) compacts pending
// rays in ray order; the CUDA backend appends with an atomic counter.
#include <cmath>

#include "Evaluator/FieldEvaluator.h"
#include "Render/RayState.h"

namespace inr {

INR_HD QueryPoint pendingQuery(const RayStateView& rs, int ray, float time) {
  const Vec3f p = rs.origin[ray] + rs.direction[ray] * rs.t[ray];
  return QueryPoint{p.x, p.y, p.z, time};
}

INR_HD void storeQueryResult(const RayStateView& rs, int ray, float value) {
  rs.sample[ray] = value;
  if (!isFiniteValue(value)) rs.flags[ray] |= kRayBadSample;
}

// Gradient opacity and 2D transfer functions (usesGradient): the term stored beside a query's
// value (the ray's or the point's opacityScale) is gradientTermAt |g|, g the network's model-space
// gradient there: the gradient opacity factor, which the stage code multiplies the sample's scalar
// opacity by, or |g| itself, with which it looks the 2D table up (sampleColourOpacity,
// Render/TransferFunctionTable.h). Either way the extinction never exceeds the 1D table's (the
// scalar opacity; a 2D table's column maxima): the majorants hold as they are.
INR_HD float gradientTermOf(const TransferFunctionView& tf, Vec3f g) { return gradientTermAt(tf, length(g)); }

// Gradients cost several values, so the evaluation stage asks for them in a second pass only for
// the queries whose outcome the factor can change, once their values are back. A sample the scalar
// opacity leaves empty (alpha = 0, or a non-finite value: empty space) is empty whatever the
// factor. A delta-tracking candidate the scalar opacity already rejects (collisionProduct =
// xi * majorant >= sigma(alpha)) is rejected for any factor <= 1, since sigma(alpha * A) <=
// sigma(alpha): only the candidates it accepts need A (thinning: those are then accepted with the
// probability sigma(alpha A) / sigma(alpha), as the exact test collisionProduct < sigma(alpha A)
// does). Ratio-tracked shadow rays use every sample's sigma. The others get the empty term
// (emptyGradientTerm: factor 0), which gives them the outcome they have for any gradient (empty,
// rejected) however sigma rounds where the stage code recomputes it. With a 2D transfer function
// alpha is its column maximum at the value (the 1D table), which bounds the opacity at every
// gradient magnitude: the same reasoning holds.
INR_HD bool sampleNeedsOpacityScale(const TransferFunctionView& tf, float value) {
  return sampleHasExtinction(tf, value);
}

// The same for ray i's pending candidate (delta tracking, primary or shadow ray) of value `value`.
INR_HD bool candidateNeedsOpacityScale(const FrameConstants& fc, const TransferFunctionView& tf, const RayStateView& rs,
                                       int i, float value) {
  if (!isFiniteValue(value)) return false;
  const float sigma = extinctionAt(tf, value);
  if (!(sigma > 0.f)) return false;
  const bool ratioShadow = (rs.flags[i] & kRayShadow) && fc.shadowEstimator == ShadowEstimator::Ratio;
  return ratioShadow || rs.collisionProduct[i] < sigma;
}

// The naive trackers' form of that second pass, one candidate at a time: ray i's gradient term for
// its candidate of value `value`, asking gradientAt(g) for the model-space gradient only where the
// term can change the outcome (the empty term elsewhere, as the batches give). Returns whether it
// asked.
template <typename GradientAt>
INR_HD bool storeCandidateOpacityScale(const FrameConstants& fc, const TransferFunctionView& tf, const RayStateView& rs,
                                       int i, float value, GradientAt&& gradientAt) {
  rs.opacityScale[i] = emptyGradientTerm(tf);
  if (!candidateNeedsOpacityScale(fc, tf, rs, i, value)) return false;
  float g[3];
  gradientAt(g);
  rs.opacityScale[i] = gradientTermOf(tf, Vec3f{g[0], g[1], g[2]});
  return true;
}

// Expected-value refinement of homogeneity pruning (Eq. ev_ema, Render/Pruning.h): the evaluated
// `value` of ray `ray`'s pending query moves the expected scalar of the query's macrocell
// (rs.cell, the cell the candidate was emitted in), weighted by how central the query point is.
// Returns false for a non-finite value (nothing to learn); else the cell's linear index and its
// new estimate, which the caller stores (serially on the CPU, racily on the GPU).
INR_HD bool expectedAfterQuery(const TrackingMedium& medium, const RayStateView& rs, int ray, float value,
                               int& cell, float& estimate) {
  if (!isFiniteValue(value)) return false;
  const Int3 c = rs.cell[ray];
  const Vec3f p = rs.origin[ray] + rs.direction[ray] * rs.t[ray];
  cell = linearCellIndex(medium.grid.dims, c);
  estimate = emaExpected(medium.prune.expected[cell], value, cellCentreWeight(medium.grid, c, p));
  return true;
}

}  // namespace inr
