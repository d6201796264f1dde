#pragma once
// Stage II for the ratio-tracking primary estimator (PrimaryEstimator::Ratio), written once for
// the CPU and CUDA backends.
//
// Why: delta tracking's collision estimator buys one binary event per ray (the pixel's frame
// estimate is a colour or nothing), and on the GPU every event costs a wavefront iteration.
// Ratio tracking used as an emission estimator (the "expected value" estimator; Novak, Georgiev,
// Hanika and Jarosz, "Monte Carlo methods for volumetric light transport simulation", Eurographics
// 2018 STAR, surveys both) keeps every tentative collision: along the ray, tentative points
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
// Shading (Shading.h) picks one point the same way, with or without shadows: its lit colour needs
// the network's gradient there, one query per ray rather than one per point.
//
// The unbiased ray march (PrimaryEstimator::March, UnbiasedMarch.h) draws its own points and
// weighs them its own way; folding them in, the reservoir, roulette and the traversal pass are
// shared with ratio tracking here. The points themselves: TrackingPoints.h.
//
// Majorants from lattice samples can underestimate sigma (refinement widens them as samples
// arrive); the weight sigma / mu is then clamped at 1 (the only bias, as Falcor's ratio tracker
// clamps; shared with delta tracking, whose acceptance probability clamps the same way).
#include <cmath>
#include <cstdint>

#include "Render/CounterRng.h"
#include "Render/TrackingPoints.h"
#include "Render/UnbiasedMarch.h"

namespace inr {

// Folds ray i's `count` pending points, in order, into its estimate: radiance (colour sum or,
// with shadows, the picked colour with its sign), radiance.w = W (the emission weights' sum,
// coverage), collisionProduct = the weights' absolute sum (the shadow reservoir's total),
// visibility = T, lastExtinction = the march's control (UnbiasedMarch.h), hitT. `onEvaluated(slot, value)` is called
// for each point the network answered (refinement, pruning's EMA on the GPU; the CPU does that in
// its batch loop). Returns true when roulette ended the ray.
template <typename OnEvaluated>
INR_HD bool resolveRatioPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                               const PointStateView& pts, int i, int count, const RngStream& ray,
                               OnEvaluated&& onEvaluated) {
  const bool march = fc.estimator == PrimaryEstimator::March;
  float T = rs.visibility[i];
  Vec4f L = rs.radiance[i];
  float absSum = rs.collisionProduct[i];
  float control = rs.lastExtinction[i];
  float hitT = rs.hitT[i];
  float pickedSign = rs.hitWeight[i];  // of the picked point's weight (one picked point: pickOnePoint)
  const bool pickOne = pickOnePoint(fc);
  bool ended = false;
  for (int j = 0; j < count; ++j) {
    const int slot = pointSlot(pts, rs.count, i, j);
    const float s = pts.sample[slot], mu = pts.majorant[slot];
    const std::uint8_t kind = pts.kind[slot];
    if (!(kind & kPointPruned)) onEvaluated(slot, s);
    if (ended) continue;  // (the remaining points still refine)
    const float t = pts.t[slot];
    const Vec4f c = isFiniteValue(s) ? sampleColourOpacity(medium.tf, s, pts.opacityScale, slot) : Vec4f{0.f, 0.f, 0.f, 0.f};
    const float sigma = opacityToExtinction(c.w, medium.tf.invUnitDistance);
    RngStream pointRng = ratioPointStream(ray, t);
    const float pick = pointRng.next();
    float w = 0.f;  // this point's emission weight
    if (march) {
      w = foldMarchPoint(fc, medium.tf, kind, sigma, mu, pts.gap[slot], T, control);
    } else {
      const float r = minf(1.f, sigma / mu);
      w = T * r;
      T *= 1.f - r;
    }
    if (w != 0.f) {
      L.w += w;
      absSum += fabsf(w);
      const bool picked = pick * absSum < fabsf(w);  // reservoir: point j with probability |w| / sum |w|
      if (pickOne) {
        if (picked) {
          L = Vec4f{c.x, c.y, c.z, L.w};
          pickedSign = w > 0.f ? 1.f : -1.f;
        }
      } else {
        L = Vec4f{L.x + w * c.x, L.y + w * c.y, L.z + w * c.z, L.w};
      }
      if (picked) hitT = t;
    }
    const float a = fabsf(T);
    if (a < fc.rouletteThreshold) {  // survivors continue with |T| = threshold: unbiased
      if (pointRng.next() * fc.rouletteThreshold < a) {
        T = T < 0.f ? -fc.rouletteThreshold : fc.rouletteThreshold;
      } else {
        T = 0.f;
        ended = true;
      }
    }
  }
  rs.visibility[i] = T;
  rs.radiance[i] = L;
  rs.collisionProduct[i] = absSum;
  rs.lastExtinction[i] = control;
  rs.hitT[i] = hitT;
  rs.hitWeight[i] = pickedSign;
  return ended;
}

// Draws ray i's next tentative points from rs.t on (at most fc.pointsPerIteration), resuming the
// walker: ratio tracking's, at rate majorantScale x the cell majorant (the march's:
// drawMarchPoints). Points pruning answers get their sample at once; the others call
// emitQuery(slot) and are counted in `queries`. Sets `left` when the ray reached its segment's end
// or its draw cap (rs.t is then tEnd). Returns the number of points drawn.
template <typename Walker, bool kPruning, typename EmitQuery>
INR_HD int drawRatioPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                           const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, int& queries,
                           bool& left, EmitQuery&& emitQuery) {
  if (fc.estimator == PrimaryEstimator::March)
    return drawMarchPoints<Walker, kPruning>(fc, medium, rs, pts, i, flags, rng, queries, left, emitQuery);
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  int count = 0;
  left = false;
  Walker walker(medium.grid, rs, i);
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (m > 0.f) {
      const float mu = m * fc.majorantScale;
      for (;;) {
        if (drawCapReached(fc, rng, flags, left)) break;  // bounded work per frame
        const float tc = candidateDistance(rng, mu, t);
        if (!(tc < segmentEnd)) break;
        t = tc;
        if (storeRatioPoint<kPruning>(medium, rs, pts, i, count, t, mu, 0.f, 0, walker.cellIndex(), rng, emitQuery))
          ++queries;
        if (++count == fc.pointsPerIteration) {
          walker.store(rs, i);
          rs.t[i] = t;
          return count;
        }
      }
      if (left) break;
    }
    if (!walker.advance(segmentEnd, tEnd)) break;
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
    const Vec4f L = rs.radiance[i];
    const float absSum = rs.collisionProduct[i];
    if (absSum > 0.f) {
      flags |= kRayHit;
      if (pickOnePoint(fc)) {  // the estimate is +-sum|w| c_I
        const float weight = rs.hitWeight[i] * absSum;
        if (fc.shading.enabled)
          rs.hitWeight[i] = weight;  // the shading stage lights c_I first (Shading.h)
        else
          rs.radiance[i] = Vec4f{L.x * weight, L.y * weight, L.z * weight, L.w};
      }
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

}  // namespace inr
