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
// Shading (Shading.h) picks one point the same way, with or without shadows: its lit colour needs
// the network's gradient there, one query per ray rather than one per point.
//
// Unbiased ray marching (PrimaryEstimator::March) uses the same point machinery with two kinds of
// points per macrocell segment of majorant m: a jittered comb of spacing 1 / (k m) (one uniform
// offset per segment) for the emission integral, and residual ratio-tracking points at rate
// mu_r = k_r m (FrameConstants::residualScale) for the transmittance. The control extinction
// sigma~ is piecewise constant: the extinction at the last comb point (half the majorant before
// the first one; 0 in empty space), so
//     T(t) = exp(-int_0^t sigma~) * prod over residual points y < t of (1 - (sigma(y) - sigma~(y)) / mu_r)
// is unbiased for exp(-int sigma) for any sigma~ fixed before the residual points are drawn (the
// Poisson generating functional; the residual process is independent of the comb), and
//     L = sum over comb points x of T(x) sigma(x) c(x) / (k m)
// is unbiased for int T sigma c because a jittered comb is an unbiased quadrature of any fixed
// integrand. Where the field is smooth the control is close to sigma, the residual factors stay
// near 1 and the comb's error falls like a marcher's: ray-marching efficiency per query without
// a bias floor. Factors can leave [0, 1] where the control is poor; the estimate stays unbiased
// (roulette works on |T|, the shadow reservoir on |weights|). Under gradient opacity (with k_r >=
// 1) the control is 0 throughout (marchUsesControl below): sigma~ = 0 is as valid a choice, and
// every factor then lies in [0, 1].
//
// Majorants from lattice samples can underestimate sigma (refinement widens them as samples
// arrive); the weight sigma / mu is then clamped at 1 (the only bias, as Falcor's ratio tracker
// clamps; shared with delta tracking, whose acceptance probability clamps the same way).
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

// Whether unbiased ray marching uses its control extinction (the extinction at the last comb
// point). Under gradient opacity the factor switches the extinction on and off from one sample to
// the next wherever |grad f| crosses the function's ramp, so a piecewise-constant control is
// poor there and its residual factors 1 - (sigma - control) / mu leave [0, 1] by far: a product
// of them now and then weighs a pixel many times over (fireflies that set the image back by
// several dB). Without the control (0) the residual points are plain ratio tracking of the
// transmittance at rate mu = residualScale x the majorant >= sigma: every factor in [0, 1], still
// unbiased. That needs residualScale >= 1: below it the residual points are too sparse to carry
// the transmittance alone (none at all at 0, the plain jittered marcher), so the control stays.
// A 2D transfer function switches it the same way (its opacity follows |grad f| too).
INR_HD bool marchUsesControl(const FrameConstants& fc, const TransferFunctionView& tf) {
  return !usesGradient(tf) || fc.residualScale < 1.f;
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

// Folds ray i's `count` pending points, in order, into its estimate: radiance (colour sum or,
// with shadows, the picked colour with its sign), radiance.w = W (the emission weights' sum,
// coverage), collisionProduct = the weights' absolute sum (the shadow reservoir's total),
// visibility = T, lastExtinction = march's control, hitT. `onEvaluated(slot, value)` is called
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
      // Until the ray's first comb point the control is half the macrocell majorant (`gap` then
      // holds the majorant optical depth since the last point); from then on the extinction at
      // the last comb point (`gap` a length).
      const bool known = control == control;
      if (marchUsesControl(fc, medium.tf)) {
        T *= expf(-(known ? control * pts.gap[slot] : 0.5f * pts.gap[slot]));
        if (kind & kPointComb) {
          w = T * sigma * mu;  // mu: the comb's spacing
          control = sigma;
        } else {
          const float controlHere = known ? control : 0.5f * mu / maxf(fc.residualScale, fc.majorantScale);
          T *= 1.f - (sigma - controlHere) / mu;
        }
      } else if (kind & kPointComb) {
        w = T * sigma * mu;
      } else {
        T *= 1.f - minf(1.f, sigma / mu);
      }
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

// The phase of a march ray's comb in this frame: uniform in [0, 1) for every pixel and frame
// (so each frame's estimate is unbiased), and a golden-ratio sequence over the frames of each
// half of the accumulation (frameHalf, CounterRng.h; a random start per pixel and half,
// Cranley-Patterson rotated), so successive frames place their combs evenly between each other's
// and the error falls faster than 1 / sqrt(frames) where the integrand is smooth, while the two
// halves stay independent (the convergence estimate, Finalize.h). Drawn from the ray's stream for
// the count only (bounded work).
INR_HD float combOffset(const FrameConstants& fc, RngStream& rng) {
  rng.next();
  const float start = counterUniform(rng.pixel, frameHalf(fc.frame), fc.seed ^ 0x68e31da4u, 0u);
  const float u = start + float((fc.frame >> 1) % 16777216u) * 0.61803398875f;
  return u - floorf(u);
}

// The per-frame work cap (FrameConstants::maxRngDraws): true when ray i may draw no more; then
// it is flagged capped and leaves its walk.
INR_HD bool drawCapReached(const FrameConstants& fc, const RngStream& rng, std::uint8_t& flags, bool& left) {
  if (rng.counter < fc.maxRngDraws) return false;
  flags |= kRayCapped;
  left = true;
  return true;
}

// Draws ray i's next tentative points from rs.t on (at most fc.pointsPerIteration), resuming the
// walker. Points pruning answers get their sample at once; the others call emitQuery(slot) and
// are counted in `queries`. Sets `left` when the ray reached its segment's end or its draw cap
// (rs.t is then tEnd). Returns the number of points drawn.
template <typename Walker, bool kPruning, typename EmitQuery>
INR_HD int drawRatioPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                           const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, int& queries,
                           bool& left, EmitQuery&& emitQuery) {
  const bool march = fc.estimator == PrimaryEstimator::March;
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  // March: the next comb and residual points of the current segment (NaN: the walk is at a
  // segment's start and draws them afresh).
  float combNext = rs.combNext[i], residualNext = rs.residualNext[i], combPhase = rs.combPhase[i];
  float gap = 0.f;          // non-empty length since the last point
  bool controlKnown = rs.controlKnown[i] != 0;  // march: the ray has had a comb point
  int count = 0;
  left = false;
  Walker walker(medium.grid, rs, i);
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (march && m > 0.f) {
      // The comb is regular in majorant optical depth (k points per unit), continuous along the
      // ray across macrocells: its phase (the fraction of a comb interval still to go) carries
      // over from segment to segment, so cells shorter than the spacing keep the stratification.
      // Until the ray's first comb point the control is half the majorant, and the residual
      // points there come at the comb's density (at least), so their factors
      // 1 - (sigma - m / 2) / mu stay near 1. The control then carries over empty space (where
      // it does not apply: gaps count non-empty length only) to the next comb point.
      const float density = m * fc.majorantScale, spacing = 1.f / density;
      const float muKnown = m * fc.residualScale, muUnknown = m * maxf(fc.residualScale, fc.majorantScale);
      bool& known = controlKnown;
      if (combNext != combNext) {  // a segment's start: its first comb and residual points
        if (drawCapReached(fc, rng, flags, left)) break;
        if (combPhase != combPhase) combPhase = combOffset(fc, rng);  // the ray's first comb point
        combNext = t + combPhase * spacing;
        const float mu = known ? muKnown : muUnknown;
        residualNext = mu > 0.f ? candidateDistance(rng, mu, t) : INFINITY;
      }
      for (;;) {
        const bool comb = combNext <= residualNext;
        const float next = comb ? combNext : residualNext;
        if (!(next < segmentEnd)) break;
        if (drawCapReached(fc, rng, flags, left)) break;  // bounded work per frame
        gap += (next - t) * (known ? 1.f : m);
        t = next;
        const float muNow = known ? muKnown : muUnknown;
        const std::uint8_t kind = comb ? kPointComb : 0;
        if (storeRatioPoint<kPruning>(medium, rs, pts, i, count, t, comb ? spacing : muNow, gap, kind,
                                      walker.cellIndex(), rng, emitQuery))
          ++queries;
        gap = 0.f;
        if (comb) {
          combNext += spacing;
          if (!known) {  // the control is known from here on: the residual process at its own rate
            known = true;
            residualNext = muKnown > 0.f ? candidateDistance(rng, muKnown, t) : INFINITY;
          }
        } else {
          residualNext = candidateDistance(rng, muNow, t);
        }
        if (++count == fc.pointsPerIteration) {  // the batch is full: resume here next iteration
          walker.store(rs, i);
          rs.t[i] = t;
          rs.combNext[i] = combNext;
          rs.residualNext[i] = residualNext;
          rs.combPhase[i] = combPhase;
          rs.controlKnown[i] = controlKnown ? 1 : 0;
          return count;
        }
      }
      if (left) break;
      gap += (segmentEnd - t) * (known ? 1.f : m);
      combPhase = (combNext - segmentEnd) * density;  // what is left of the comb interval
    } else if (m > 0.f) {
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
    combNext = NAN;
    if (!walker.advance(segmentEnd, tEnd)) break;
    t = segmentEnd;
  }
  left = true;
  rs.t[i] = tEnd;
  rs.controlKnown[i] = controlKnown ? 1 : 0;
  rs.combPhase[i] = combPhase;
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
