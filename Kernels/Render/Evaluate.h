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

// Gradient opacity (TransferFunctionView::gradientOpacity): with it, every query is answered with
// the network's value and model-space gradient g, and the factor stored beside the value (the
// ray's or the point's opacityScale) is the function at |g|. The stage code multiplies the
// sample's scalar opacity by it (sampleOpacity, Render/TransferFunctionTable.h), so the extinction
// never exceeds the scalar opacity's: the majorants hold as they are.
INR_HD float gradientOpacityOf(const TransferFunctionView& tf, Vec3f g) { return gradientOpacityAt(tf, length(g)); }

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
