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

}  // namespace inr
