#pragma once
// The points a ray hands the evaluator in batches, for ratio tracking and the marches
// (RatioTracking.h, UnbiasedMarch.h, PreintegratedMarch.h, DebiasedMarch.h), written once for the
// CPU and CUDA backends: their fields and layout, storing a drawn point (or answering it by
// pruning), the query of a point, its resolve-time random stream and the per-frame work cap.
#include <cmath>
#include <cstdint>
#include <cstring>

#include "Evaluator/FieldEvaluator.h"
#include "Render/CounterRng.h"
#include "Render/Pruning.h"
#include "Render/RayState.h"
#include "Render/Traverse.h"

namespace inr {

// The per-point fields, declared once (storage in Render/RayStateArrays.h).
//   t         ray parameter of the point
//   majorant  ratio tracking and residual points: the rate mu it was drawn with; comb points:
//             their spacing
//   gap       march: length of non-empty macrocells between the previous point and this one
//             (where the control extinction applies)
//   sinceBreak  preintegrated (PreintegratedMarch.h): length from the macrocell's previous comb
//             point (or where the ray entered the cell) to this point
//   sample    the network's value there (or the pruned estimate); NaN while pending
//   opacityScale  the gradient term there (RayStateView::opacityScale)
//   cell      linear index of the macrocell the point was drawn in (refinement, pruning's EMA)
//   kind      PointKind bits
//   level, step  debiased (DebiasedMarch.h): the level of the point's comb interval and the point's
//             index in it (1 .. 2^level, 2^level the closing comb point)
#define INR_POINT_STATE_FIELDS(X) \
  X(float, t)                     \
  X(float, majorant)              \
  X(float, gap)                   \
  X(float, sinceBreak)            \
  X(float, sample)                \
  X(float, opacityScale)          \
  X(int, cell)                    \
  X(std::uint8_t, kind)           \
  X(std::uint8_t, level)          \
  X(std::uint8_t, step)

enum PointKind : std::uint8_t {
  kPointComb = 1u << 0,          // march: an emission (comb) point, else a transmittance point
  kPointPruned = 1u << 1,        // answered by pruning without a query (no refinement, no EMA)
};

#define INR_DECLARE_POINT_VIEW_FIELD(type, name) type* name = nullptr;
struct PointStateView {
  int count = 0;  // slots: rays x pointsPerIteration
  // The layout (pointSlot): 0, by point index (slot j x rays + i); > 0, by ray with this many
  // points per ray (slot i x perRay + j; what the renderers use).
  int perRay = 0;
  INR_POINT_STATE_FIELDS(INR_DECLARE_POINT_VIEW_FIELD)
};
#undef INR_DECLARE_POINT_VIEW_FIELD

// Slot of point j of ray i among `rays` rays. By point index, the lanes of a warp (consecutive
// rays) touch consecutive words at the same j; by ray, a ray's points share cache lines, which
// stay whole when the lanes' rays are scattered (the later passes' lists) or draw many points
// each (the debiased march). The renderers lay the points out by ray (Benchmarks/RESULTS-archive.md,
// "The debiased march's traversal", has both layouts side by side).
INR_HD int pointSlot(const PointStateView& pts, int rays, int i, int j) {
  return pts.perRay > 0 ? i * pts.perRay + j : j * rays + i;
}

INR_HD std::uint32_t floatBits(float f) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(f);
#else
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
#endif
}

// The resolve-time stream of the point at ray parameter t: keyed by the ray's stream and the
// position's bits (distinct for the distinct points of a ray), so it does not depend on how the
// points were batched.
INR_HD RngStream ratioPointStream(const RngStream& ray, float t) {
  return RngStream{ray.pixel, ray.frame, ray.seed ^ 0x85ebca6bu, floatBits(t)};
}

// Whether the estimate keeps one picked point's colour (weighted by the emission weights' total)
// instead of the weighted sum of all: when something is computed at that point alone, the
// shadow ray's visibility or the shading's gradient.
INR_HD bool pickOnePoint(const FrameConstants& fc) { return fc.shadows || fc.shading.enabled; }

// World point of slot `slot` (ray i) at the frame's time: what the evaluator is asked.
INR_HD QueryPoint ratioPointQuery(const RayStateView& rs, const PointStateView& pts, int i, int slot, float time) {
  const Vec3f p = rs.origin[i] + rs.direction[i] * pts.t[slot];
  return QueryPoint{p.x, p.y, p.z, time};
}

// Stores a drawn point in slot `count` of ray i: pruning may answer it at once (then it needs no
// query), else emitQuery(slot) is called. Returns whether it needs the network.
template <bool kPruning, typename EmitQuery>
INR_HD bool storeRatioPoint(const TrackingMedium& medium, const RayStateView& rs, const PointStateView& pts, int i,
                            int count, float t, float rate, float gap, std::uint8_t kind, int cell, RngStream& rng,
                            EmitQuery&& emitQuery) {
  const int slot = pointSlot(pts, rs.count, i, count);
  pts.t[slot] = t;
  pts.majorant[slot] = rate;
  pts.gap[slot] = gap;
  pts.cell[slot] = cell;
  float estimate = NAN;
  const bool pruned = kPruning && prunes(medium.prune, cell, rng) && isFiniteValue(estimate = medium.prune.expected[cell]);
  pts.kind[slot] = std::uint8_t(kind | (pruned ? kPointPruned : 0));
  pts.sample[slot] = estimate;
  if (pruned) {
    rs.pruned[i] += 1u;
    return false;
  }
  emitQuery(slot);
  return true;
}

// The per-frame work cap (FrameConstants::maxRngDraws): true when ray i may draw no more; then
// it is flagged capped and leaves its walk.
INR_HD bool drawCapReached(const FrameConstants& fc, const RngStream& rng, std::uint8_t& flags, bool& left) {
  if (rng.counter < fc.maxRngDraws) return false;
  flags |= kRayCapped;
  left = true;
  return true;
}

// Pruning's expected-scalar update (Eq. ev_ema) from an evaluated point: the point's cell and
// position, as expectedAfterQuery does for a delta-tracking query. False for a non-finite value.
INR_HD bool expectedAfterPoint(const TrackingMedium& medium, const RayStateView& rs, const PointStateView& pts,
                               int i, int slot, float value, int& cell, float& estimate) {
  if (!isFiniteValue(value)) return false;
  cell = pts.cell[slot];
  const Int3 c = cellCoordinates(medium.grid.dims, cell);
  const Vec3f p = rs.origin[i] + rs.direction[i] * pts.t[slot];
  estimate = emaExpected(medium.prune.expected[cell], value, cellCentreWeight(medium.grid, c, p));
  return true;
}

}  // namespace inr
