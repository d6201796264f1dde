#pragma once
// Stage II for the ratio-tracking primary estimator (PrimaryEstimator::Ratio), written once for
// the CPU and CUDA backends.
//
// Why: delta tracking's collision estimator buys one binary event per ray (the pixel's frame
// estimate is a colour or nothing), and on the GPU every event costs a wavefront iteration.
// Ratio tracking used as an emission estimator (the "expected value" estimator of
// ../shared/notes/estimators.md) keeps every tentative collision: along the ray, tentative points
// x_1 < x_2 < ... come from a Poisson process of rate mu = k * (cell majorant) (k =
// FrameConstants::majorantScale), and at each one
//     L += T * (sigma_j / mu_j) * c_j,      T <- T * (1 - sigma_j / mu_j),
// until the ray leaves the volume; L (premultiplied colour) and W = sum of the weights (coverage)
// are unbiased for the emission-absorption integral and 1 - transmittance, because T at x_j is
// the ratio-tracking estimate over the points before x_j, and for a Poisson process those are
// independent of where x_j lies. Any mu >= sigma keeps it unbiased; k > 1 trades queries for
// variance. Russian roulette below FrameConstants::rouletteThreshold (survivors continue with
// T = threshold, so the estimate stays unbiased) ends rays behind opaque matter.
//
// Batching: a ray hands the evaluator up to FrameConstants::pointsPerIteration points per
// wavefront iteration (its next points along the ray, all of which are used), so a frame needs
// about (points per ray) / K iterations instead of one per point. Points live in a separate
// struct-of-arrays (PointStateView), slot j of ray i at j * rays + i.
//
// Determinism: the point positions come from the ray's stream (one draw per point, in order);
// the resolve-time draws (reservoir and roulette) from a per-point stream keyed by the point's
// position. So the image does not depend on K (or on thread counts): tests compare K = 1 and
// K = 16 bit for bit.
//
// Shadows: the shaded emission sum_j w_j c_j V(x_j) is estimated with one shadow ray from a
// point I picked with probability w_I / W (weighted reservoir sampling, one uniform per point):
// E[W c_I V(x_I)] = sum_j w_j c_j V(x_j). Without shadows the colour is the full weighted sum;
// the picked point still gives the reprojection hit point.
//
// Majorants from lattice samples can underestimate sigma (refinement widens them as samples
// arrive); the weight sigma / mu is then clamped at 1 (the only bias, as Falcor's ratio tracker
// clamps; shared with delta tracking, whose acceptance probability clamps the same way).
#include <cmath>
#include <cstdint>
#include <cstring>

#include "Render/CounterRng.h"
#include "Render/Pruning.h"
#include "Render/RayState.h"
#include "Render/Traverse.h"

namespace inr {

// The per-point fields, declared once (storage in Render/RayStateArrays.h).
//   t         ray parameter of the tentative collision
//   majorant  the rate mu it was drawn with; negative (-mu) when pruning answered it without a
//             query (it then feeds neither refinement nor pruning's expected scalars)
//   sample    the network's value there (or the pruned estimate); NaN while pending
//   cell      linear index of the macrocell the point was drawn in (refinement, pruning's EMA)
#define INR_POINT_STATE_FIELDS(X) \
  X(float, t)                     \
  X(float, majorant)              \
  X(float, sample)                \
  X(int, cell)

#define INR_DECLARE_POINT_VIEW_FIELD(type, name) type* name = nullptr;
struct PointStateView {
  int count = 0;  // slots: rays x pointsPerIteration
  INR_POINT_STATE_FIELDS(INR_DECLARE_POINT_VIEW_FIELD)
};
#undef INR_DECLARE_POINT_VIEW_FIELD

// Slot of point j of ray i among `rays` rays (struct-of-arrays by point index: on the GPU the
// lanes of a warp, consecutive rays, touch consecutive words).
INR_HD int pointSlot(int rays, int i, int j) { return j * rays + i; }

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

// World point of slot `slot` (ray i) at the frame's time: what the evaluator is asked.
INR_HD QueryPoint ratioPointQuery(const RayStateView& rs, const PointStateView& pts, int i, int slot, float time) {
  const Vec3f p = rs.origin[i] + rs.direction[i] * pts.t[slot];
  return QueryPoint{p.x, p.y, p.z, time};
}

// Folds ray i's `count` pending points, in order, into its estimate (radiance: colour sum or,
// with shadows, the picked colour; radiance.w = W; visibility = T; hitT). `onEvaluated(slot,
// value)` is called for each point the network answered (refinement, pruning's EMA on the GPU;
// the CPU does that in its batch loop). Returns true when roulette ended the ray.
template <typename OnEvaluated>
INR_HD bool resolveRatioPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                               const PointStateView& pts, int i, int count, const RngStream& ray,
                               OnEvaluated&& onEvaluated) {
  float T = rs.visibility[i];
  Vec4f L = rs.radiance[i];
  float hitT = rs.hitT[i];
  bool ended = false;
  for (int j = 0; j < count; ++j) {
    const int slot = pointSlot(rs.count, i, j);
    const float s = pts.sample[slot], mu = pts.majorant[slot];
    if (mu > 0.f) onEvaluated(slot, s);
    if (ended) continue;  // (the remaining points still refine)
    const float t = pts.t[slot];
    const Vec4f c = isFiniteValue(s) ? lookupTransferFunction(medium.tf, s) : Vec4f{0.f, 0.f, 0.f, 0.f};
    const float sigma = opacityToExtinction(c.w, medium.tf.invUnitDistance);
    const float r = minf(1.f, sigma / fabsf(mu));
    RngStream pointRng = ratioPointStream(ray, t);
    const float pick = pointRng.next();
    if (r > 0.f) {
      const float w = T * r;
      L.w += w;
      const bool picked = pick * L.w < w;  // reservoir: point j with probability w / W
      if (fc.shadows) {
        if (picked) L = Vec4f{c.x, c.y, c.z, L.w};
      } else {
        L = Vec4f{L.x + w * c.x, L.y + w * c.y, L.z + w * c.z, L.w};
      }
      if (picked) hitT = t;
      T *= 1.f - r;
    }
    if (T < fc.rouletteThreshold) {
      if (pointRng.next() * fc.rouletteThreshold < T) {
        T = fc.rouletteThreshold;
      } else {
        T = 0.f;
        ended = true;
      }
    }
  }
  rs.visibility[i] = T;
  rs.radiance[i] = L;
  rs.hitT[i] = hitT;
  return ended;
}

// Draws ray i's next tentative points from rs.t on (at most fc.pointsPerIteration), resuming the
// walker. Points pruning answers get their sample at once; the others call emitQuery(slot) and
// are counted in `queries`. Sets `left` when the ray reached its segment's end or its draw cap
// (rs.t is then tEnd). Returns the number of points drawn.
template <typename Walker, bool kPruning, typename EmitQuery>
INR_HD int drawRatioPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                           const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, int& queries,
                           bool& left, EmitQuery&& emitQuery) {
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  int count = 0;
  left = false;
  Walker walker(medium.grid, rs, i);
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    const float mu = m * fc.majorantScale;
    while (mu > 0.f) {
      if (rng.counter >= fc.maxRngDraws) {  // bounded work per frame
        flags |= kRayCapped;
        left = true;
        break;
      }
      const float tc = candidateDistance(rng, mu, t);
      if (!(tc < segmentEnd)) break;
      t = tc;
      const int slot = pointSlot(rs.count, i, count);
      const int cell = walker.cellIndex();
      pts.t[slot] = tc;
      pts.cell[slot] = cell;
      float estimate = NAN;
      const bool pruned = kPruning && prunes(medium.prune, cell, rng) &&
                          isFiniteValue(estimate = medium.prune.expected[cell]);
      pts.majorant[slot] = pruned ? -mu : mu;
      pts.sample[slot] = pruned ? estimate : NAN;
      if (pruned) {
        rs.pruned[i] += 1u;
      } else {
        ++queries;
        emitQuery(slot);
      }
      if (++count == fc.pointsPerIteration) {  // the batch is full: resume here next iteration
        walker.store(rs, i);
        rs.t[i] = t;
        return count;
      }
    }
    if (left || !walker.advance(segmentEnd, tEnd)) break;
    t = segmentEnd;
  }
  left = true;
  rs.t[i] = tEnd;
  return count;
}

// One traversal pass of a ratio-tracked primary ray: fold in the points the evaluator answered,
// then draw the next batch. Points that pruning answered alone are folded in at once and the
// walk goes on, so a ray stays pending only while a query of it is out. At the end of the walk
// the ray's frame estimate is complete: kRayHit when it gathered emission, rs.t = the picked
// point (for the shadow ray and the reprojection hit point).
template <typename Walker, bool kPruning, typename OnEvaluated, typename EmitQuery>
INR_HD void traverseRatioRayWith(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                 const PointStateView& pts, int i, OnEvaluated&& onEvaluated, EmitQuery&& emitQuery) {
  std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayActive)) return;
  RngStream rng{pixelStreamKey(fc, i), fc.frame, fc.seed, rs.rngCounter[i]};
  int pending = (flags & kRayPending) ? int(rs.pointCount[i]) : 0;
  bool finished = false;
  for (;;) {
    if (pending > 0 && resolveRatioPoints(fc, medium, rs, pts, i, pending, rng, onEvaluated)) {
      finished = true;
      break;
    }
    pending = 0;
    if (!(rs.t[i] < rs.tEnd[i])) {
      finished = true;
      break;
    }
    int queries = 0;
    bool left = false;
    pending = drawRatioPoints<Walker, kPruning>(fc, medium, rs, pts, i, flags, rng, queries, left, emitQuery);
    if (queries > 0) break;  // wait for the evaluator
    if (pending == 0) {      // (left with nothing drawn)
      finished = true;
      break;
    }
  }
  if (finished) {
    flags &= std::uint8_t(~(kRayActive | kRayPending));
    Vec4f L = rs.radiance[i];
    if (L.w > 0.f) {
      flags |= kRayHit;
      if (fc.shadows) rs.radiance[i] = Vec4f{L.x * L.w, L.y * L.w, L.z * L.w, L.w};  // W c_I
      rs.t[i] = rs.hitT[i];
    }
    rs.pointCount[i] = 0;
  } else {
    flags |= kRayPending;
    rs.pointCount[i] = std::uint8_t(pending);
  }
  rs.flags[i] = flags;
  rs.rngCounter[i] = rng.counter;
}

// Pruning's expected-scalar update (Eq. ev_ema) from an evaluated point: the point's cell and
// position, as expectedAfterQuery does for a delta-tracking query. False for a non-finite value.
INR_HD bool expectedAfterPoint(const TrackingMedium& medium, const RayStateView& rs, const PointStateView& pts,
                               int i, int slot, float value, int& cell, float& estimate) {
  if (!isFiniteValue(value)) return false;
  cell = pts.cell[slot];
  const Int3& d = medium.grid.dims;
  const Int3 c{cell % d.x, (cell / d.x) % d.y, cell / (d.x * d.y)};
  const Vec3f p = rs.origin[i] + rs.direction[i] * pts.t[slot];
  estimate = emaExpected(medium.prune.expected[cell], value, cellCentreWeight(medium.grid, c, p));
  return true;
}

}  // namespace inr
