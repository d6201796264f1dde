#pragma once
// The Stage II steps around a ray's traversal that every DeviceTraversal runs the same way
// (DdaTraversal.cu, OptixPrograms.cu): complete the previous query, and write the next one.
#include "Render/Cuda/DeviceRefine.cuh"
#include "Render/Cuda/DeviceTraversal.h"
#include "Render/Evaluate.h"
#include "Render/DebiasedMarch.h"
#include "Render/PreintegratedMarch.h"
#include "Render/RatioTracking.h"

namespace inr::cuda {

// The evaluation stage answered ray i's previous query into rs.sample: complete it, refine its
// macrocell (when the launch says so) and feed pruning's expected scalar. kPruning = false
// leaves the pruning code out (the DDA kernel without pruning, DdaTraversal.cu).
template <bool kPruning = true>
__device__ __forceinline__ void completeListedQuery(const TraversalLaunch& p, int i) {
  const RayStateView& rs = p.rs;
  const float v = rs.sample[i];
  storeQueryResult(rs, i, v);
  if (p.refine) refineCell(p.refineView, linearCellIndex(p.medium.grid.dims, rs.cell[i]), v);
  int cell;
  float estimate;
  // Pruning's EMA (Eq. ev_ema). Threads of a pass update hot cells concurrently; a benign race
  // by design: read, then one atomic store of the new estimate. A lost update only drops a
  // sample (every stored value is still a convex mix of the mean and real samples); a CAS
  // loop would serialise the many rays in a hot cell for no visible gain.
  if (kPruning && p.medium.prune.expected && expectedAfterQuery(p.medium, rs, i, v, cell, estimate))
    atomicExch(&p.medium.prune.expected[cell], estimate);
}

// Writes ray i's pending query into the launch's output at `slot`.
__device__ __forceinline__ void writeListedQuery(const TraversalLaunch& p, int i, unsigned slot) {
  const QueryPoint q = pendingQuery(p.rs, i, p.fc.time);
  p.outPoints[slot] = make_float4(q.x, q.y, q.z, q.t);
  p.outRays[slot] = i;
}

// A ratio-tracked primary ray's traversal pass (Render/RatioTracking.h) for any walker: its
// evaluated points refine their macrocells and feed pruning's expected scalars as they are
// folded in; the points that need the network are appended to the launch's query output with
// their slots, and the ray to the next pass's list while it waits for them.
// kPass: kRatioPoints (ratio tracking and the first march), kPreintegratedPoints (the
// pre-integrated march's pass, Render/PreintegratedMarch.h) or kDebiasedPoints (the debiased
// march's, Render/DebiasedMarch.h), the same way.
constexpr int kRatioPoints = 1, kPreintegratedPoints = 2, kDebiasedPoints = 3;
template <typename Walker, bool kPruning, int kPass = kRatioPoints>
__device__ __forceinline__ void traverseRatioListedRay(const TraversalLaunch& p, int i) {
  const RayStateView& rs = p.rs;
  const PointStateView& pts = p.points;
  auto onEvaluated = [&](int slot, float v) {
    if (p.refine) refineCell(p.refineView, pts.cell[slot], v);
    int cell;
    float estimate;
    // The same benign race as completeListedQuery's.
    if (kPruning && p.medium.prune.expected && expectedAfterPoint(p.medium, rs, pts, i, slot, v, cell, estimate))
      atomicExch(&p.medium.prune.expected[cell], estimate);
  };
  auto emitQuery = [&](int slot) {
    const QueryPoint q = ratioPointQuery(rs, pts, i, slot, p.fc.time);
    const unsigned k = appendSlot(p.outCount);
    p.outPoints[k] = make_float4(q.x, q.y, q.z, q.t);
    p.outRays[k] = slot;
  };
  if (kPass == kDebiasedPoints)
    traverseDebiasedRayWith<Walker, kPruning>(p.fc, p.medium, rs, pts, i, onEvaluated, emitQuery);
  else if (kPass == kPreintegratedPoints)
    traversePreintegratedRayWith<Walker, kPruning>(p.fc, p.medium, rs, pts, i, onEvaluated, emitQuery);
  else
    traverseRatioRayWith<Walker, kPruning>(p.fc, p.medium, rs, pts, i, onEvaluated, emitQuery);
  if (rs.flags[i] & kRayPending) p.outRayList[appendSlot(p.outRayCount)] = i;
}

}  // namespace inr::cuda
