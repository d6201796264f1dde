#pragma once
// Stage II for the debiased ray march (PrimaryEstimator::Debiased), written once for the CPU and
// CUDA backends.
//
// Why: a ray march's error falls like a quadrature's (the step squared where the field is
// smooth), so one march frame is cleaner than many frames of any tracking estimator at the same
// number of queries; but it is biased. A biased estimator whose bias vanishes as its step halves
// can be made unbiased by random refinement (Rhee and Glynn 2015; Misso, Bitterli, Novak and
// Jarosz 2022, "Unbiased and consistent rendering using biased estimators"): with L_k the march at
// 2^-k of the step and a random level K with P(K >= k) = p_k,
//     L_0 + sum over k = 1..K of (L_k - L_{k-1}) / p_k
// has expectation lim L_k, the exact integral. Its error is the march's own error amplified by
// the roulette, so it is small exactly where the march is accurate, with no bias floor.
//
// Refinement per comb interval, not per ray: every interval of the comb draws its own level, so a
// ray's work is the sum of many small independent draws (no ray runs 2^K times longer than its
// neighbours, which would lengthen the wavefront's tail), and the errors of the intervals are
// independent (they add like noise rather than coherently as a march's do). Interval j's estimates
// of its transmittance t_j and emission e_j are unbiased given the comb; the frame estimate
//     L = sum over j of (prod over i < j of t_i) e_j,   T = prod over j of t_j
// is then unbiased because the intervals' levels are independent.
//
// The comb. Along the ray's non-empty macrocells comb points come at k points per unit of
// majorant optical depth (k = FrameConstants::majorantScale, at least combMinimumDensity per
// unit length where the cell is not faint: combDensity), a random phase per frame: the comb
// coordinate tau advances at the cell's density (empty cells do not advance it, their extinction
// is 0). Interval j runs from comb point j - 1
// to comb point j (the first from where the ray enters its first non-empty cell); at level K it
// holds 2^K - 1 interior points at even steps of tau, and level k < K uses those of them whose
// index is a multiple of 2^(K-k): the levels are nested, level K's points serve all of them.
// Each level marches its points with the trapezoid rule in ray distance (the extinction linear
// between neighbouring points over the non-empty length between them; the colour the
// extinction-weighted mean of the two ends): its error falls with the square of its step across
// macrocell boundaries too, where the comb's density jumps but the extinction does not. The ray's
// two ends have no comb point: the extinction there is taken as that of the nearest point (only
// the rate of convergence depends on it).
//
// The levels. K = min(maxLevel, floor(ln v / ln r)) for a uniform v: P(K >= k) = r^k (r =
// FrameConstants::levelRatio). An interval's estimate is sum over k of C_k x (level k's march),
// C_k = r^-k - r^-(k+1) for k < K and r^-K for k = K (the telescoping sum above, regrouped); the
// expected number of points per interval is (1 - r) / (1 - 2 r) for r < 1/2 (2 at r = 1/3). The
// cap makes the expectation the level-maxLevel march (the step / 2^maxLevel), not the exact
// integral: a bias below that march's error, which the tests measure as converged to delta
// tracking's image.
//
// Batches end after a comb point (where the walk commits its state) or at the ray's end; an
// interval (at most 2^maxLevel points) fits in a batch (the renderer hands this estimator at
// least that many points per iteration), so a full batch drops the points after its last commit
// and draws them again, the same, next iteration. Russian roulette at each interval's end.
//
// Shadows and gradient shading: the renderer runs ratio tracking instead (WavefrontRenderer.cpp),
// as for the pre-integrated march: an interval's emission has no single point for a shadow ray or
// a lit colour. Gradient opacity scales each point's extinction, as in every estimator.
#include <cmath>
#include <cstdint>

#include "Render/CounterRng.h"
#include "Render/PreintegratedMarch.h"  // kPointCellExit, traverseBatchedRay
#include "Render/Pruning.h"
#include "Render/RatioTracking.h"
#include "Render/RayState.h"
#include "Render/Traverse.h"

namespace inr {

// The level of a comb interval from a uniform u in [0, 1): P(level >= k) = r^k up to the cap.
INR_HD int debiasedLevel(const FrameConstants& fc, float u) {
  const float v = 1.f - u;  // in (0, 1]
  int k = 0;
  float p = fc.levelRatio;
  while (k < fc.maxLevel && v < p) {
    ++k;
    p *= fc.levelRatio;
  }
  return k;
}

// ---- drawing the points

// Stores point `count` of ray i (`gap`: the non-empty length from its interval's left end); pruning
// may answer it at once (no query is emitted here).
template <bool kPruning>
INR_HD void storeDebiasedPoint(const TrackingMedium& medium, const RayStateView& rs, const PointStateView& pts, int i,
                               int count, float t, float gap, std::uint8_t kind, int level, int step, int cell,
                               RngStream& rng) {
  const int slot = pointSlot(pts, rs.count, i, count);
  pts.t[slot] = t;
  pts.gap[slot] = gap;
  pts.cell[slot] = cell;
  pts.level[slot] = std::uint8_t(level);
  pts.step[slot] = std::uint8_t(step);
  float estimate = NAN;
  const bool pruned = kPruning && !(kind & kPointCellExit) && prunes(medium.prune, cell, rng) &&
                      isFiniteValue(estimate = medium.prune.expected[cell]);
  pts.kind[slot] = std::uint8_t(kind | (pruned ? kPointPruned : 0));
  pts.sample[slot] = estimate;
}

// Draws ray i's next batch from rs.t on (slots 0..) and returns its size; the walk's state is
// committed to the ray state after each comb point. At the ray's end a marker (kPointCellExit,
// no query) closes its last interval and `left` is set (rs.t = tEnd).
template <typename Walker, bool kPruning>
INR_HD int drawDebiasedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                              const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, bool& left) {
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  float phase = rs.combPhase[i];  // comb coordinate from t to the next point (NaN: the comb has not started)
  int level = rs.marchLevel[i], step = rs.marchStep[i];
  // Non-empty length from the open interval's left end (its comb point, or the ray's start: a batch
  // starts at one of them).
  float gap = 0.f;
  int count = 0, committed = 0;
  std::uint32_t committedCounter = rng.counter;
  bool capped = false, full = false;
  left = false;
  Walker walker(medium.grid, rs, i);
  auto commit = [&](float tHere) {
    walker.store(rs, i);
    rs.t[i] = tHere;
    rs.combPhase[i] = phase;
    rs.marchLevel[i] = std::uint8_t(level);
    rs.marchStep[i] = std::uint8_t(step);
    committed = count;
    committedCounter = rng.counter;
  };
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (m > 0.f) {
      const float density = combDensity(fc, m);  // comb points per unit length
      if (phase != phase) {
        // The ray's first non-empty cell: the comb's phase u, and the level of the interval that
        // ends at the first comb point (the interval [u - 1, u] of the comb coordinate, clipped
        // to where the ray enters: its first point is the first of its steps at or after 0).
        if (drawCapReached(fc, rng, flags, left)) {
          capped = true;
          break;
        }
        const float u = rng.next();
        level = debiasedLevel(fc, rng.next());
        const int n = 1 << level;
        step = int(ceilf((1.f - u) * float(n)));
        step = step < 1 ? 1 : step > n ? n : step;
        phase = maxf(0.f, u - 1.f + float(step) / float(n));
      }
      for (;;) {
        const float next = t + phase / density;
        if (!(next < segmentEnd)) break;
        if (drawCapReached(fc, rng, flags, left)) {  // bounded work per frame: one draw per point
          capped = true;
          break;
        }
        if (count == fc.pointsPerIteration) {
          full = true;
          break;
        }
        rng.counter += 1u;
        gap += next - t;
        t = next;
        const int n = 1 << level;
        const bool comb = step >= n;
        storeDebiasedPoint<kPruning>(medium, rs, pts, i, count, t, gap, comb ? kPointComb : 0, level, step,
                                     walker.cellIndex(), rng);
        ++count;
        if (comb) {  // the next interval
          gap = 0.f;
          level = debiasedLevel(fc, rng.next());
          step = 1;
          phase = 1.f / float(1 << level);
          commit(t);
        } else {
          ++step;
          phase = 1.f / float(n);
        }
      }
      if (full || capped) break;
      gap += segmentEnd - t;
      phase = maxf(0.f, phase - (segmentEnd - t) * density);
    }
    if (!walker.advance(segmentEnd, tEnd)) break;
    t = segmentEnd;
  }
  if (!full && !capped && phase == phase) {  // the marker that closes the ray's last interval
    if (count == fc.pointsPerIteration) {
      full = true;
    } else {
      storeDebiasedPoint<kPruning>(medium, rs, pts, i, count, tEnd, gap, std::uint8_t(kPointCellExit | kPointPruned),
                                   level, step, -1, rng);
      ++count;
    }
  }
  if (full) {
    if (committed > 0) {  // back to the batch's last commit
      rng.counter = committedCounter;
      return committed;
    }
    flags |= kRayCapped;  // (an interval fills a batch only when the renderer gave too few slots)
    capped = true;
  }
  if (capped) count = committed;  // the ray stops at its last commit
  left = true;
  rs.t[i] = tEnd;
  return count;
}

// ---- folding the points in

// A point as a level's march sees it: its extinction and colour (0 for empty space).
struct MarchPoint {
  float sigma = 0.f;
  Vec3f colour{0.f, 0.f, 0.f};
};

// Point `slot` (a non-finite value: empty space).
INR_HD MarchPoint debiasedPoint(const TransferFunctionView& tf, const PointStateView& pts, int slot) {
  MarchPoint p;
  const float s = pts.sample[slot];
  if (!isFiniteValue(s)) return p;
  const Vec4f c = sampleColourOpacity(tf, s, pts.opacityScale, slot);  // (1D or 2D transfer function)
  p.sigma = opacityToExtinction(c.w, tf.invUnitDistance);
  p.colour = Vec3f{c.x, c.y, c.z};
  return p;
}

// The optical depth and the mean colour of the span between neighbouring points a and b over a
// non-empty length `length`: the extinction linear between them (the trapezoid rule), the colour
// their extinction-weighted mean. (Integrating the transfer function exactly over a linear scalar
// between them, as the pre-integrated march's control does, changed one frame's error on the
// shipped models by a fraction of a dB at several times the cost of a span on the GPU.)
INR_HD float marchSpan(const MarchPoint& a, const MarchPoint& b, float length, Vec3f& colour) {
  const float both = a.sigma + b.sigma;
  const float inv = both > 0.f ? 1.f / both : 0.f;
  colour = Vec3f{(a.sigma * a.colour.x + b.sigma * b.colour.x) * inv, (a.sigma * a.colour.y + b.sigma * b.colour.y) * inv,
                 (a.sigma * a.colour.z + b.sigma * b.colour.z) * inv};
  return 0.5f * length * both;
}

// One level's march over an interval: its points are the left end (when known) and those of the
// interval's points (slots j..e of ray i, at steps s0, s0 + 1, ... from slot j on) whose step is a
// multiple of `stride`; only they are read (the points' lengths from the interval's left end give
// each span's length), so the levels of an interval of n points read about 2 n points in all,
// not n per level. The marker closing the ray stands for the level's last point, a missing left
// end for its first (the medium at the ray's ends taken as at the nearest point). Returns the
// emission (xyz colour, w coverage) and sets the transmittance.
INR_HD Vec4f marchInterval(const TransferFunctionView& tf, const RayStateView& rs, const PointStateView& pts, int i,
                           int j, int e, int s0, int stride, bool leftKnown, const MarchPoint& leftEnd,
                           float& transmittance) {
  Vec4f emission{0.f, 0.f, 0.f, 0.f};
  float T = 1.f;
  auto span = [&](const MarchPoint& a, const MarchPoint& b, float length) {
    Vec3f colour;
    const float depth = marchSpan(a, b, length, colour);
    if (depth > 0.f) {
      const float opacity = -expm1f(-depth), w = T * opacity;
      emission = Vec4f{emission.x + w * colour.x, emission.y + w * colour.y, emission.z + w * colour.z, emission.w + w};
      T *= 1.f - opacity;
    }
  };
  bool havePrevious = leftKnown;
  MarchPoint previous = leftEnd;
  float previousAt = 0.f;  // the previous point's length from the left end
  const int closeSlot = pointSlot(pts, rs.count, i, e);
  const bool markerEnd = (pts.kind[closeSlot] & kPointCellExit) != 0;
  const int first = (s0 + stride - 1) / stride * stride;  // the level's first step in the interval
  for (int p = j + (first - s0); p <= e; p += stride) {
    if (p == e && markerEnd) break;
    const int slot = pointSlot(pts, rs.count, i, p);
    const MarchPoint here = debiasedPoint(tf, pts, slot);
    const float at = pts.gap[slot];
    if (!havePrevious) previous = here;  // (a copy: `havePrevious ? previous : here` selected between
    havePrevious = true;                 // two objects' addresses and put both on the stack)
    span(previous, here, at - previousAt);
    previous = here;
    previousAt = at;
  }
  if (markerEnd && havePrevious) span(previous, previous, pts.gap[closeSlot] - previousAt);
  transmittance = T;
  return emission;
}

// Folds ray i's batch (`count` points in slot order) into its estimate: radiance (premultiplied
// colour, w = coverage), visibility = T, collisionProduct = the sum of the intervals' |emission
// weights| (kRayHit), hitT (the reprojection hit point: an interval's closing point picked in
// proportion to its weight), and the left end (lastCombValue, leftScale, leftKnown).
// `onEvaluated(slot, value)` for each point the network answered. Returns true when roulette
// ended the ray.
template <typename OnEvaluated>
INR_HD bool resolveDebiasedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                  const PointStateView& pts, int i, int count, const RngStream& ray,
                                  OnEvaluated&& onEvaluated) {
  const TransferFunctionView& tf = medium.tf;
  for (int j = 0; j < count; ++j) {
    const int slot = pointSlot(pts, rs.count, i, j);
    if (!(pts.kind[slot] & kPointPruned)) onEvaluated(slot, pts.sample[slot]);
  }
  float T = rs.visibility[i];
  Vec4f L = rs.radiance[i];
  float absSum = rs.collisionProduct[i];
  float hitT = rs.hitT[i];
  bool leftKnown = rs.leftKnown[i] != 0;
  MarchPoint leftEnd;
  if (leftKnown) {
    const float s = rs.lastCombValue[i];
    if (isFiniteValue(s)) {
      const Vec4f c = sampleColourOpacity(tf, s, usesGradient(tf) ? rs.leftScale[i] : 1.f);
      leftEnd.sigma = opacityToExtinction(c.w, tf.invUnitDistance);
      leftEnd.colour = Vec3f{c.x, c.y, c.z};
    }
  }
  const float inverseRatio = 1.f / fc.levelRatio;
  bool ended = false;
  for (int j = 0; j < count && !ended;) {
    // The interval: points j..e-1 inside, closed by point e: its comb point at step 2^level, or
    // the ray's marker, the batch's last point (every batch ends at one of them).
    const int firstSlot = pointSlot(pts, rs.count, i, j);
    const int level = pts.level[firstSlot], s0 = pts.step[firstSlot];
    const int e = j + (1 << level) - s0 < count ? j + (1 << level) - s0 : count - 1;
    const int closeSlot = pointSlot(pts, rs.count, i, e);
    Vec4f emission{0.f, 0.f, 0.f, 0.f};
    float transmittance = 0.f;
    float weight = 1.f;  // r^-k
    for (int k = 0; k <= level; ++k) {
      float tk;
      const Vec4f ek = marchInterval(tf, rs, pts, i, j, e, s0, 1 << (level - k), leftKnown, leftEnd, tk);
      const float c = k < level ? weight * (1.f - inverseRatio) : weight;
      emission = Vec4f{emission.x + c * ek.x, emission.y + c * ek.y, emission.z + c * ek.z, emission.w + c * ek.w};
      transmittance += c * tk;
      weight *= inverseRatio;
    }
    const float w = T * emission.w;
    L = Vec4f{L.x + T * emission.x, L.y + T * emission.y, L.z + T * emission.z, L.w + w};
    T *= transmittance;
    const float tClose = pts.t[closeSlot];
    RngStream intervalRng = ratioPointStream(ray, tClose);
    intervalRng.seed ^= 0x3c6ef372u;
    if (w != 0.f) {
      absSum += fabsf(w);
      if (intervalRng.next() * absSum < fabsf(w)) hitT = tClose;  // reservoir: the hit point
    }
    if (pts.kind[closeSlot] & kPointComb) {
      leftKnown = true;
      rs.lastCombValue[i] = pts.sample[closeSlot];
      rs.leftScale[i] = usesGradient(tf) ? pts.opacityScale[closeSlot] : 1.f;
      leftEnd = debiasedPoint(tf, pts, closeSlot);
    } else {
      leftKnown = false;
    }
    const float magnitude = fabsf(T);
    if (magnitude < fc.rouletteThreshold) {  // survivors continue with |T| = threshold: unbiased
      if (intervalRng.next() * fc.rouletteThreshold < magnitude) {
        T = T < 0.f ? -fc.rouletteThreshold : fc.rouletteThreshold;
      } else {
        T = 0.f;
        ended = true;
      }
    }
    j = e + 1;
  }
  rs.visibility[i] = T;
  rs.radiance[i] = L;
  rs.collisionProduct[i] = absSum;
  rs.hitT[i] = hitT;
  rs.leftKnown[i] = leftKnown ? 1 : 0;
  return ended;
}

// ---- one traversal pass

// The debiased march's pass (traverseBatchedRay, PreintegratedMarch.h); onEvaluated(slot, value)
// for each point the network answered.
template <typename Walker, bool kPruning, typename OnEvaluated, typename EmitQuery>
INR_HD void traverseDebiasedRayWith(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                    const PointStateView& pts, int i, OnEvaluated&& onEvaluated, EmitQuery&& emitQuery) {
  traverseBatchedRay(
      fc, rs, pts, i,
      [&](int count, const RngStream& rng) {
        return resolveDebiasedPoints(fc, medium, rs, pts, i, count, rng, onEvaluated);
      },
      [&](std::uint8_t& flags, RngStream& rng, bool& left) {
        return drawDebiasedPoints<Walker, kPruning>(fc, medium, rs, pts, i, flags, rng, left);
      },
      emitQuery);
}

}  // namespace inr
