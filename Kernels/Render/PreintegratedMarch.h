#pragma once
// Stage II for unbiased ray marching with a pre-integrated control (PrimaryEstimator::
// Preintegrated), written once for the CPU and CUDA backends.
//
// Why: the first unbiased march (PrimaryEstimator::March, RatioTracking.h) takes the extinction
// at the last comb point as its control, constant until the next one. The shipped transfer
// functions have sharp opacity edges, so that control is poor exactly where the opacity changes
// and its residual correction is noisy there. Here the control follows the network between comb
// points: its value is taken as linear from one comb point's value to the next one's, and the
// transfer function is integrated exactly over that (pre-integration, Engel, Kraus and Ertl 2001).
// What the residual points must correct is then only the network's curvature between comb
// points, not the transfer function's edges. The correction's frame is Kettunen et al. 2021
// (unbiased ray marching): a deterministic control plus an unbiased estimate of the rest.
//
// The estimator. Along the ray (the non-empty macrocells only: length u counts where the majorant
// is > 0) comb points x_0 < x_1 < ... come at k points per unit of majorant optical depth (k =
// FrameConstants::majorantScale, a random phase per frame as in the first march), and residual
// points y_j from a Poisson process of rate mu = k_r x the majorant (k_r = residualScale), drawn
// independently of the comb. Between comb points x_k and x_{k+1}, with network values s_f and s_b
// and non-empty length d, the control scalar goes linearly from s_f to s_b; its extinction
// sigma~ is the transfer function's extinction there, read from the table's entries interpolated
// linearly, so that its integral over the segment is exact from running integrals over the table
// (TransferFunctionView::extinctionIntegral): tau~ = d x (mean of sigma~ over [s_f, s_b]). Before
// the first comb point (and after the last) the control scalar is constant: the value at that
// comb point; a ray with no comb point has control 0. The control's colour over a segment is one
// constant, c-bar (the extinction-weighted mean colour over [s_f, s_b]), so its emission
// integrates exactly too: int T~ sigma~ c-bar = c-bar (1 - exp(-tau~)). With T_k the estimate of
// the transmittance at x_k and, inside the segment, T~(v) = exp(-int_0^v sigma~) and P(v) the
// product of the residual factors (1 - (sigma - sigma~) / mu) before offset v:
//     T at y          T_k T~(y) P(y)                                   (residual ratio tracking)
//     emission        sum over segments of T_k (1 - exp(-tau~)) c-bar                (the control)
//                     + sum over residual points y of T_k T~(y) (P(y) sigma(y) c(y) - sigma~(y) c-bar) / mu
// The first line is unbiased for exp(-int sigma) given the comb (the Poisson generating
// functional: the control is fixed by the comb before the residual points are drawn); the second
// is the control's exact integral plus an unbiased (Campbell-Mecke) estimate of the integral of
// T sigma c minus the control's integrand, whose weights use only the residual points before y.
// So the frame estimate is unbiased for every comb, whatever the phase: it converges to delta
// tracking's image. Where the network is linear between comb points, sigma = sigma~ and the
// residual terms vanish but for the colour's variation inside a segment: the marcher's error with
// the edges integrated exactly. Coverage (radiance.w) is the same sum with c = 1.
//
// Batches: a residual point needs its segment's closing comb point, so a ray's batch of points
// (up to FrameConstants::pointsPerIteration) ends at a comb point: when it fills first, the walk
// goes back to the last comb point of the batch (its state is committed to the ray state there;
// the points after it are drawn again, the same, next iteration). Only the ray's last batch ends
// with the residual points after its last comb point (then tailLength closes it). A segment whose
// points alone fill a batch (rare: a segment holds Poisson(k_r / k) residual points) cuts the ray
// off as the per-frame work cap does (kRayCapped). The image does not depend on the batch size
// otherwise. Under Russian roulette (at each segment's end, below FrameConstants::
// rouletteThreshold, as ratio tracking) the estimate stays unbiased.
//
// Shadows, gradient shading and gradient opacity: the renderer runs ratio tracking instead
// (frameConstants, WavefrontRenderer.cpp): a shadow ray or a lit colour needs one emission point,
// and the segments' control emission has none; gradient opacity scales each sample's extinction by
// a factor the control cannot know.
#include <cmath>
#include <cstdint>

#include "Render/CounterRng.h"
#include "Render/Pruning.h"
#include "Render/RatioTracking.h"
#include "Render/RayState.h"
#include "Render/Traverse.h"

namespace inr {

// ---- the pre-integrated control

// Table coordinate (entry units, not clamped: the control is constant beyond the table's ends)
// of scalar s; NaN for a non-finite s.
INR_HD float controlCoordinate(const TransferFunctionView& tf, float s) {
  return (s - tf.lo) / (tf.hi - tf.lo) * float(tf.size - 1);
}

// The table interval holding table coordinate x (clamped to the table) and the fraction into it.
INR_HD int controlInterval(const TransferFunctionView& tf, float x, float& f) {
  const float xc = x > 0.f ? minf(x, float(tf.size - 1)) : 0.f;
  int i = int(xc);
  if (i > tf.size - 2) i = tf.size - 2;
  f = xc - float(i);
  return i;
}

// The control extinction at table coordinate x: the entries' extinctions interpolated linearly,
// the end entries' beyond the table.
INR_HD float controlExtinctionAt(const TransferFunctionView& tf, float x) {
  float f;
  const int i = controlInterval(tf, x, f);
  const float a = tf.entryExtinction[i], b = tf.entryExtinction[i + 1];
  return a + (b - a) * f;
}

// The table's colour at table coordinate x (linear between entries, the ends' beyond).
INR_HD Vec3f controlColourAt(const TransferFunctionView& tf, float x) {
  float f;
  const int i = controlInterval(tf, x, f);
  const Vec4f c0 = tf.rgba[i], c1 = tf.rgba[i + 1];
  return Vec3f{c0.x + (c1.x - c0.x) * f, c0.y + (c1.y - c0.y) * f, c0.z + (c1.z - c0.z) * f};
}

// Integral over [a, b] (a <= b, both inside one table interval or both beyond one end) of the
// control extinction (w) and of it times the colour (xyz): the midpoint rule, exact for the
// extinction (linear there), close for the colour.
INR_HD Vec4f controlPiece(const TransferFunctionView& tf, float a, float b) {
  const float m = 0.5f * (a + b);
  const float w = (b - a) * controlExtinctionAt(tf, m);
  const Vec3f c = controlColourAt(tf, m);
  return Vec4f{w * c.x, w * c.y, w * c.z, w};
}

INR_HD Vec4f add4(const Vec4f& a, const Vec4f& b) { return Vec4f{a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w}; }

// Integral over [a, b] (a <= b, table coordinates) of the control extinction (w, exact) and of it
// times the colour (xyz): partial intervals at the ends, the running integrals between, so a short
// span never takes the difference of two large running integrals.
INR_HD Vec4f controlIntegral(const TransferFunctionView& tf, float a, float b) {
  const float last = float(tf.size - 1);
  Vec4f sum{0.f, 0.f, 0.f, 0.f};
  if (a < 0.f) {  // below the table: the first entry's extinction
    const float e = minf(b, 0.f);
    sum = controlPiece(tf, a, e);
    if (!(b > 0.f)) return sum;
    a = 0.f;
  }
  float inside = b;
  if (b > last) {  // above the table: the last entry's
    const float s = maxf(a, last);
    sum = add4(sum, controlPiece(tf, s, b));
    if (!(a < last)) return sum;
    inside = last;
  }
  const int ia = int(a), ib = int(inside);
  if (ib <= ia + 1) {
    if (ib == ia) return add4(sum, controlPiece(tf, a, inside));
    return add4(add4(sum, controlPiece(tf, a, float(ib))), controlPiece(tf, float(ib), inside));
  }
  const Vec4f lo = tf.extinctionIntegral[ia + 1], hi = tf.extinctionIntegral[ib];
  sum = add4(sum, controlPiece(tf, a, float(ia + 1)));
  sum = add4(sum, Vec4f{hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, hi.w - lo.w});
  if (inside > float(ib)) sum = add4(sum, controlPiece(tf, float(ib), inside));
  return sum;
}

// The control over a segment whose scalar goes linearly between table coordinates xf and xb: its
// mean extinction (exact) and its extinction-weighted mean colour. Equal ends: the value there.
struct ControlSegment {
  Vec3f colour;
  float extinction;
};
INR_HD ControlSegment controlSegment(const TransferFunctionView& tf, float xf, float xb) {
  const float a = minf(xf, xb), b = maxf(xf, xb);
  if (!(b > a)) return ControlSegment{controlColourAt(tf, a), controlExtinctionAt(tf, a)};
  const Vec4f in = controlIntegral(tf, a, b);
  const float inv = in.w > 0.f ? 1.f / in.w : 0.f;
  return ControlSegment{Vec3f{in.x * inv, in.y * inv, in.z * inv}, in.w / (b - a)};
}

// Mean control extinction between table coordinates xf and x (either order).
INR_HD float meanControlExtinction(const TransferFunctionView& tf, float xf, float x) {
  const float a = minf(xf, x), b = maxf(xf, x);
  if (!(b > a)) return controlExtinctionAt(tf, a);
  return controlIntegral(tf, a, b).w / (b - a);
}

// ---- drawing the points

// Draws ray i's next batch of points from rs.t on (PointStateView, slots 0..), resuming the
// walker, and returns their number; the batch ends at a comb point (the walk's state there is
// committed to the ray state) unless the ray reached its end (`left`, rs.t = tEnd, tailLength
// written). Points pruning answers get their sample at once; none is handed to the evaluator here
// (the caller emits the batch's queries).
template <typename Walker, bool kPruning>
INR_HD int drawPreintegratedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                   const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, bool& left) {
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  float combNext = rs.combNext[i], residualNext = rs.residualNext[i], combPhase = rs.combPhase[i];
  float sinceComb = 0.f;  // every batch starts at a comb point or at the ray's start
  int count = 0, committed = 0;
  std::uint32_t committedCounter = rng.counter;
  bool capped = false;
  left = false;
  Walker walker(medium.grid, rs, i);
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (m > 0.f) {
      // As the first march: the comb is regular in majorant optical depth and its phase carries
      // over from macrocell to macrocell; residual points restart at each cell (memoryless).
      const float density = m * fc.majorantScale, spacing = 1.f / density, mu = m * fc.residualScale;
      if (combNext != combNext) {
        if (drawCapReached(fc, rng, flags, left)) {
          capped = true;
          break;
        }
        if (combPhase != combPhase) combPhase = combOffset(fc, rng);  // the ray's first comb point
        combNext = t + combPhase * spacing;
        residualNext = mu > 0.f ? candidateDistance(rng, mu, t) : INFINITY;
      }
      bool full = false;
      for (;;) {
        const bool comb = combNext <= residualNext;
        const float next = comb ? combNext : residualNext;
        if (!(next < segmentEnd)) break;
        if (drawCapReached(fc, rng, flags, left)) {  // bounded work per frame
          capped = true;
          break;
        }
        if (count == fc.pointsPerIteration) {
          full = true;
          break;
        }
        sinceComb += next - t;
        t = next;
        const int slot = pointSlot(rs.count, i, count);
        const int cell = walker.cellIndex();
        pts.t[slot] = t;
        pts.majorant[slot] = comb ? spacing : mu;
        pts.sinceComb[slot] = sinceComb;
        pts.cell[slot] = cell;
        float estimate = NAN;
        const bool pruned =
            kPruning && prunes(medium.prune, cell, rng) && isFiniteValue(estimate = medium.prune.expected[cell]);
        pts.kind[slot] = std::uint8_t((comb ? kPointComb : 0) | (pruned ? kPointPruned : 0));
        pts.sample[slot] = estimate;
        ++count;
        if (comb) {
          combNext += spacing;
          sinceComb = 0.f;
          walker.store(rs, i);  // commit: the next batch resumes here
          rs.t[i] = t;
          rs.combNext[i] = combNext;
          rs.residualNext[i] = residualNext;
          rs.combPhase[i] = combPhase;
          committed = count;
          committedCounter = rng.counter;
        } else {
          residualNext = candidateDistance(rng, mu, t);
        }
      }
      if (full) {
        if (committed > 0) {  // back to the batch's last comb point
          rng.counter = committedCounter;
          return committed;
        }
        flags |= kRayCapped;  // one segment's points fill a batch: cut off (see the header)
        capped = true;
      }
      if (capped) break;
      sinceComb += segmentEnd - t;
      combPhase = (combNext - segmentEnd) * density;  // what is left of the comb interval
    }
    combNext = NAN;
    if (!walker.advance(segmentEnd, tEnd)) break;
    t = segmentEnd;
  }
  if (capped) count = committed;  // the ray stops at its last comb point
  left = true;
  rs.t[i] = tEnd;
  rs.tailLength[i] = capped ? 0.f : sinceComb;
  return count;
}

// ---- folding the points in

// Folds ray i's batch (`count` points in slot order: each segment's residual points, then its
// closing comb point; after the last comb point, when `rayDrawn`, the tail's residual points) into
// its estimate: radiance (premultiplied colour, w = coverage), visibility = T at the last closed
// segment's end, collisionProduct = the sum of the emission weights' magnitudes (the hit point's
// reservoir), lastCombValue. With `rayDrawn` the tail is closed too. `onEvaluated(slot, value)` for
// each point the network answered. Returns true when roulette ended the ray.
template <typename OnEvaluated>
INR_HD bool resolvePreintegratedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                       const PointStateView& pts, int i, int count, bool rayDrawn, const RngStream& ray,
                                       OnEvaluated&& onEvaluated) {
  const TransferFunctionView& tf = medium.tf;
  for (int j = 0; j < count; ++j) {
    const int slot = pointSlot(rs.count, i, j);
    if (!(pts.kind[slot] & kPointPruned)) onEvaluated(slot, pts.sample[slot]);
  }
  float T = rs.visibility[i];
  Vec4f L = rs.radiance[i];
  float absSum = rs.collisionProduct[i];
  float hitT = rs.hitT[i];
  float lastValue = rs.lastCombValue[i];
  bool ended = false;
  int j = 0;
  for (;;) {
    int e = j;  // the segment's closing comb point
    while (e < count && !(pts.kind[pointSlot(rs.count, i, e)] & kPointComb)) ++e;
    const bool closes = e < count;
    if (!closes && !rayDrawn) break;  // (every batch but the last ends at a comb point)
    const int closeSlot = closes ? pointSlot(rs.count, i, e) : -1;
    const float sb = closes ? pts.sample[closeSlot] : lastValue;
    const float sf = lastValue == lastValue ? lastValue : sb;  // before the first comb point: constant
    const float length = closes ? pts.sinceComb[closeSlot] : rs.tailLength[i];
    const float xf = controlCoordinate(tf, sf), xb = controlCoordinate(tf, sb);
    const bool controlled = isFiniteValue(xf) && isFiniteValue(xb);  // else the control is 0
    const ControlSegment control =
        controlled ? controlSegment(tf, xf, xb) : ControlSegment{Vec3f{0.f, 0.f, 0.f}, 0.f};
    float product = 1.f;  // residual factors so far in this segment
    for (int r = j; r < e && r < count; ++r) {
      const int slot = pointSlot(rs.count, i, r);
      const float s = pts.sample[slot], mu = pts.majorant[slot], v = pts.sinceComb[slot];
      const Vec4f c = isFiniteValue(s) ? lookupTransferFunction(tf, s) : Vec4f{0.f, 0.f, 0.f, 0.f};
      const float sigma = opacityToExtinction(c.w, tf.invUnitDistance);
      float controlSigma = 0.f, controlT = 1.f;
      if (controlled) {
        const float x = length > 0.f ? xf + (xb - xf) * minf(1.f, v / length) : xb;
        controlSigma = controlExtinctionAt(tf, x);
        controlT = expf(-v * meanControlExtinction(tf, xf, x));
      }
      const float scale = T * controlT / mu;
      const float a = product * sigma, b = controlSigma;
      const float w = scale * (a - b);
      L = Vec4f{L.x + scale * (a * c.x - b * control.colour.x), L.y + scale * (a * c.y - b * control.colour.y),
                L.z + scale * (a * c.z - b * control.colour.z), L.w + w};
      product *= 1.f - (sigma - controlSigma) / mu;
      if (w != 0.f) {
        absSum += fabsf(w);
        RngStream pointRng = ratioPointStream(ray, pts.t[slot]);
        if (pointRng.next() * absSum < fabsf(w)) hitT = pts.t[slot];  // reservoir: the hit point
      }
    }
    // The segment's control emission and its end's transmittance.
    const float tau = length * control.extinction;
    const float opacity = -expm1f(-tau), w = T * opacity;
    L = Vec4f{L.x + w * control.colour.x, L.y + w * control.colour.y, L.z + w * control.colour.z, L.w + w};
    T *= expf(-tau) * product;
    RngStream segmentRng = ratioPointStream(ray, closes ? pts.t[closeSlot] : rs.tEnd[i]);
    if (w != 0.f && closes) {
      absSum += fabsf(w);
      if (segmentRng.next() * absSum < fabsf(w)) hitT = pts.t[closeSlot];
    }
    if (closes) lastValue = sb;
    const float magnitude = fabsf(T);
    if (magnitude < fc.rouletteThreshold) {  // survivors continue with |T| = threshold: unbiased
      if (segmentRng.next() * fc.rouletteThreshold < magnitude) {
        T = T < 0.f ? -fc.rouletteThreshold : fc.rouletteThreshold;
      } else {
        T = 0.f;
        ended = true;
      }
    }
    if (ended || !closes) break;
    j = e + 1;
  }
  rs.visibility[i] = T;
  rs.radiance[i] = L;
  rs.collisionProduct[i] = absSum;
  rs.hitT[i] = hitT;
  rs.lastCombValue[i] = lastValue;
  return ended;
}

// ---- one traversal pass

// Fold in the points the evaluator answered, then draw the next batch and hand its queries to
// emitQuery(slot); points that pruning answered alone are folded in at once and the walk goes on.
// At the end of the walk the ray's frame estimate is complete (kRayHit when it gathered emission,
// rs.t = the reservoir's hit point for reprojection).
template <typename Walker, bool kPruning, typename OnEvaluated, typename EmitQuery>
INR_HD void traversePreintegratedRayWith(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                         const PointStateView& pts, int i, OnEvaluated&& onEvaluated,
                                         EmitQuery&& emitQuery) {
  std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayActive)) return;
  RngStream rng{pixelStreamKey(fc, i), fc.frame, fc.seed, rs.rngCounter[i]};
  int pending = (flags & kRayPending) ? int(rs.pointCount[i]) : 0;
  bool finished = false;
  for (;;) {
    const bool rayDrawn = !(rs.t[i] < rs.tEnd[i]);
    if (pending > 0 || rayDrawn) {
      if (resolvePreintegratedPoints(fc, medium, rs, pts, i, pending, rayDrawn, rng, onEvaluated) || rayDrawn) {
        finished = true;
        break;
      }
    }
    bool left = false;
    pending = drawPreintegratedPoints<Walker, kPruning>(fc, medium, rs, pts, i, flags, rng, left);
    int queries = 0;
    for (int j = 0; j < pending; ++j) {
      const int slot = pointSlot(rs.count, i, j);
      if (pts.kind[slot] & kPointPruned) {
        rs.pruned[i] += 1u;
      } else {
        emitQuery(slot);
        ++queries;
      }
    }
    if (queries > 0) break;  // wait for the evaluator
  }
  if (finished) {
    flags &= std::uint8_t(~(kRayActive | kRayPending));
    if (rs.collisionProduct[i] > 0.f) {
      flags |= kRayHit;
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
