#pragma once
// Stage II for unbiased ray marching with a pre-integrated control (PrimaryEstimator::
// Preintegrated), written once for the CPU and CUDA backends.
//
// Why: the first unbiased march (PrimaryEstimator::March, UnbiasedMarch.h) takes the extinction
// at the last comb point as its control, constant until the next one. The shipped transfer
// functions have sharp opacity edges, so that control is poor exactly where the opacity changes
// and its residual correction is noisy there. Here the control follows the network between comb
// points: its value is taken as linear from one comb point's value to the next one's, and the
// transfer function is integrated exactly over that (pre-integration, Engel, Kraus and Ertl 2001).
// What the residual points must correct is then only the network's curvature between comb
// points, not the transfer function's edges. The correction's frame is Kettunen et al. 2021
// (unbiased ray marching): a deterministic control plus an unbiased estimate of the rest.
//
// The estimator. Along the ray (in its non-empty macrocells) comb points x_0 < x_1 < ... come at
// k points per unit of majorant optical depth (k = FrameConstants::majorantScale, a random phase
// per frame), and residual
// points y_j from a Poisson process of rate mu = k_r x the majorant (k_r = residualScale), drawn
// independently of the comb. Between comb points x_k and x_{k+1}, with network values s_f and s_b
// and length d, the control scalar goes linearly from s_f to s_b; its extinction
// sigma~ is the transfer function's extinction there, read from the table's entries interpolated
// linearly, so that its integral over the segment is exact from running integrals over the table
// (TransferFunctionView::extinctionIntegral): tau~ = d x (mean of sigma~ over [s_f, s_b]). Before
// a macrocell's first comb point (and after its last) the control scalar is constant: the value
// at that comb point; in a cell with no comb point, the ray's last comb value, its extinction
// capped at the cell's majorant (resolvePreintegratedPoints). The control's colour over a segment
// is one constant, c-bar (the extinction-weighted mean colour over [s_f, s_b]), so its emission
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
// Segments never cross a macrocell boundary: where the ray leaves a cell that had comb points, a
// marker (kPointCellExit, no query) closes the cell's last segment, and in the next cell the first
// segment runs from the entry to its first comb point. So the control's values stay in each cell's
// value range and the control never exceeds the cell's majorant (a segment reaching from a dense
// cell into a thin one made the residual factors 1 - (sigma - sigma~) / mu, with mu the thin cell's
// rate, far larger than 1).
//
// Batches: a residual point needs its segment's closing point, so a ray's batch of points (up to
// FrameConstants::pointsPerIteration) ends where the walk's state was committed to the ray state:
// after a comb point or at a macrocell's start. When a batch fills first, the points after the
// last commit are dropped and drawn again, the same, next iteration. Points between two commits
// that fill a batch alone (a segment holds Poisson(k_r / k) residual points: rare) cut the ray off
// as the per-frame work cap does (kRayCapped). The image does not depend on the batch size
// otherwise. Russian roulette at each segment's end, below FrameConstants::rouletteThreshold as in
// ratio tracking, keeps the estimate unbiased.
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

// Comb points per unit length in a macrocell of majorant m (> 0), for both marches: majorantScale
// per unit of majorant optical depth, at least the floor; with combFloorDepth > 0 the floor only
// up to m / combFloorDepth, so a faint cell (majorant optical depth below combFloorDepth per floor
// interval) keeps combFloorDepth of it per interval (TrackingOptions::combFloorDepth says why).
INR_HD float combDensity(const FrameConstants& fc, float m) {
  float floorDensity = fc.combMinimumDensity;
  if (fc.combFloorDepth > 0.f) floorDensity = minf(floorDensity, m / fc.combFloorDepth);
  return maxf(m * fc.majorantScale, floorDensity);
}

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

// The table's opacity at table coordinate x: the entries' opacities interpolated linearly, the
// end entries' beyond the table (lookupTransferFunction's, unclamped coordinate).
INR_HD float controlOpacityAt(const TransferFunctionView& tf, float x) {
  float f;
  const int i = controlInterval(tf, x, f);
  const float a = tf.rgba[i].w, b = tf.rgba[i + 1].w;
  return a + (b - a) * f;
}

// The control extinction at table coordinate x: the renderer's own extinction there (the opacity
// interpolated linearly, then -ln(1 - alpha) / u: extinctionAt), so where the network is linear
// between comb points the control is the medium exactly and the residual points see nothing.
// (Interpolating the entries' extinctions instead differs most at the table's sharp edges, by up
// to the edge's height in the middle of an interval: exactly where the residual was noisy.)
INR_HD float controlExtinctionAt(const TransferFunctionView& tf, float x) {
  return opacityToExtinction(controlOpacityAt(tf, x), tf.invUnitDistance);
}

// The mean of -ln(1 - alpha) over a span where alpha goes linearly from a0 to a1, both in
// [0, kMaxTableOpacity]: with beta = 1 - alpha and e = (beta1 - beta0) / beta0, the mean of -ln beta
// is -ln beta0 + 1 - (1 + e) ln(1 + e) / e (a series for small e, where that ratio cancels).
INR_HD float meanNegLogTransmittance(float a0, float a1) {
  const float b0 = 1.f - a0, e = (a0 - a1) / b0;
  const float r = fabsf(e) < 1e-3f ? 1.f + e * (0.5f - e * (1.f / 6.f - e * (1.f / 12.f))) : (1.f + e) * log1pf(e) / e;
  return maxf(0.f, -logf(b0) + 1.f - r);
}

// The table's colour at table coordinate x (linear between entries, the ends' beyond).
INR_HD Vec3f controlColourAt(const TransferFunctionView& tf, float x) {
  float f;
  const int i = controlInterval(tf, x, f);
  const Vec4f c0 = tf.rgba[i], c1 = tf.rgba[i + 1];
  return Vec3f{c0.x + (c1.x - c0.x) * f, c0.y + (c1.y - c0.y) * f, c0.z + (c1.z - c0.z) * f};
}

// Integral over [a, b] (a <= b, both inside one table interval or both beyond one end) of the
// control extinction (w: exact, the opacity being linear there; split where it crosses the
// opacity clamp) and of it times the colour (xyz: the colour at the midpoint, close).
INR_HD Vec4f controlPiece(const TransferFunctionView& tf, float a, float b) {
  const float len = b - a;
  if (!(len > 0.f)) return Vec4f{0.f, 0.f, 0.f, 0.f};
  const float aa = controlOpacityAt(tf, a), ab = controlOpacityAt(tf, b);
  const float cap = kMaxTableOpacity;
  float depth;  // in units of 1 / u
  if (aa <= cap && ab <= cap) {
    depth = len * meanNegLogTransmittance(maxf(aa, 0.f), maxf(ab, 0.f));
  } else if (aa >= cap && ab >= cap) {
    depth = len * -logf(1.f - cap);
  } else {  // the clamp inside: the clamped part is constant
    const float lo = minf(aa, ab), fraction = (cap - lo) / fabsf(ab - aa);  // unclamped share
    depth = len * (fraction * meanNegLogTransmittance(maxf(lo, 0.f), cap) + (1.f - fraction) * -logf(1.f - cap));
  }
  const float w = depth * tf.invUnitDistance;
  const Vec3f c = controlColourAt(tf, 0.5f * (a + b));
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

// A cell-exit marker, where the ray leaves a non-empty macrocell (or ends in it): no query; its
// `sinceBreak` is the length from the cell's last comb point (or its entry) to there, its
// `majorant` the cell's majorant. Skipped by the evaluator's gather as a pruned point is.
constexpr std::uint8_t kPointCellExit = 1u << 2;

// Stores point `count` of ray i (no query is emitted here; pruning may answer it at once).
template <bool kPruning>
INR_HD void storePreintegratedPoint(const TrackingMedium& medium, const RayStateView& rs, const PointStateView& pts,
                                    int i, int count, float t, float rate, float sinceBreak, std::uint8_t kind,
                                    int cell, RngStream& rng) {
  const int slot = pointSlot(pts, rs.count, i, count);
  pts.t[slot] = t;
  pts.majorant[slot] = rate;
  pts.sinceBreak[slot] = sinceBreak;
  pts.cell[slot] = cell;
  float estimate = NAN;
  const bool pruned = kPruning && !(kind & kPointCellExit) && prunes(medium.prune, cell, rng) &&
                      isFiniteValue(estimate = medium.prune.expected[cell]);
  pts.kind[slot] = std::uint8_t(kind | (pruned ? kPointPruned : 0));
  pts.sample[slot] = estimate;
}

// Draws ray i's next batch of points from rs.t on (PointStateView, slots 0..), resuming the
// walker, and returns their number. The walk's state is committed to the ray state after each comb
// point and at each macrocell exit, and the batch ends at such a commit (when it fills first, the
// points after the last commit are dropped and drawn again, the same, next time) or at the ray's
// end (`left`, rs.t = tEnd). Points pruning answers get their sample at once; no query is handed
// to the evaluator here (the caller emits the batch's).
template <typename Walker, bool kPruning>
INR_HD int drawPreintegratedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                   const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, bool& left) {
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  float combNext = rs.combNext[i], residualNext = rs.residualNext[i], combPhase = rs.combPhase[i];
  // A batch starts at a commit: after a comb point or at a cell's start.
  float sinceBreak = 0.f;  // length since the cell's last comb point or its entry
  int count = 0, committed = 0;
  std::uint32_t committedCounter = rng.counter;
  bool capped = false, full = false;
  left = false;
  Walker walker(medium.grid, rs, i);
  auto commit = [&](float tHere) {
    walker.store(rs, i);
    rs.t[i] = tHere;
    rs.combNext[i] = combNext;
    rs.residualNext[i] = residualNext;
    rs.combPhase[i] = combPhase;
    committed = count;
    committedCounter = rng.counter;
  };
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (m > 0.f) {
      // As the first march: the comb is regular in majorant optical depth and its phase carries
      // over from macrocell to macrocell; residual points restart at each cell (memoryless).
      const float density = combDensity(fc, m), spacing = 1.f / density;
      const float mu = m * fc.residualScale;
      if (combNext != combNext) {
        if (drawCapReached(fc, rng, flags, left)) {
          capped = true;
          break;
        }
        // The ray's first comb point: a phase drawn afresh each frame (not the first march's
        // golden-ratio sequence over each half's frames, combOffset), so the frames are
        // independent estimates. The convergence estimate no longer needs that (it compares the
        // accumulation's halves, Finalize.h); whether the sequence helps here is not measured.
        if (combPhase != combPhase) combPhase = rng.next();
        combNext = t + combPhase * spacing;
        residualNext = mu > 0.f ? candidateDistance(rng, mu, t) : INFINITY;
      }
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
        sinceBreak += next - t;
        t = next;
        storePreintegratedPoint<kPruning>(medium, rs, pts, i, count, t, comb ? spacing : mu, sinceBreak,
                                          comb ? kPointComb : 0, walker.cellIndex(), rng);
        ++count;
        if (comb) {
          combNext += spacing;
          sinceBreak = 0.f;
          commit(t);
        } else {
          residualNext = candidateDistance(rng, mu, t);
        }
      }
      if (full || capped) break;
      sinceBreak += segmentEnd - t;
      // The cell's last segment ends at a marker where the ray leaves the cell (or ends), with
      // the cell's majorant.
      if (count == fc.pointsPerIteration) {
        full = true;
        break;
      }
      storePreintegratedPoint<kPruning>(medium, rs, pts, i, count, segmentEnd, m, sinceBreak,
                                        std::uint8_t(kPointCellExit | kPointPruned), walker.cellIndex(), rng);
      ++count;
      combPhase = (combNext - segmentEnd) * density;  // what is left of the comb interval
    }
    combNext = NAN;
    residualNext = NAN;
    sinceBreak = 0.f;
    if (!walker.advance(segmentEnd, tEnd)) break;
    t = segmentEnd;
    if (count > committed) commit(t);  // the next cell's start
  }
  if (full) {
    if (committed > 0) {  // back to the batch's last commit
      rng.counter = committedCounter;
      return committed;
    }
    flags |= kRayCapped;  // the points between two commits fill a batch: cut off (see the header)
    capped = true;
  }
  if (capped) count = committed;  // the ray stops at its last commit
  left = true;
  rs.t[i] = tEnd;
  return count;
}

// ---- folding the points in

// The control over one segment: 0, a constant (extinction and colour), or linear in the network's
// value between table coordinates xf and xb (pre-integrated).
struct SegmentControl {
  int kind = 0;  // 0: none, 1: constant, 2: linear
  float xf = 0.f, xb = 0.f;
  float extinction = 0.f;  // constant: its extinction; linear: the mean over the segment
  Vec3f colour{0.f, 0.f, 0.f};
};

// The control's extinction at offset v of a segment of length `length`, and its optical depth
// from the segment's start to there.
INR_HD void controlAlong(const TransferFunctionView& tf, const SegmentControl& control, float v, float length,
                         float& sigma, float& depth) {
  if (control.kind == 2) {
    const float x = length > 0.f ? control.xf + (control.xb - control.xf) * minf(1.f, v / length) : control.xb;
    sigma = controlExtinctionAt(tf, x);
    depth = v * meanControlExtinction(tf, control.xf, x);
  } else {
    sigma = control.extinction;
    depth = v * control.extinction;
  }
}

// A constant control at scalar s (non-finite: none), its extinction at most `cap`.
INR_HD SegmentControl constantControl(const TransferFunctionView& tf, float s, float cap) {
  SegmentControl c;
  const float x = controlCoordinate(tf, s);
  if (!isFiniteValue(x)) return c;
  c.kind = 1;
  c.extinction = minf(controlExtinctionAt(tf, x), cap);
  c.colour = controlColourAt(tf, x);
  return c;
}

// Folds ray i's batch (`count` points in slot order) into its estimate: radiance (premultiplied
// colour, w = coverage), visibility = T, collisionProduct = the sum of the emission weights'
// magnitudes (the hit point's reservoir), lastCombValue, combInCell. A segment runs from a
// breakpoint (a comb point, or where the ray entered the macrocell) to the next (a comb point or
// the cell's exit marker), inside one cell. Its control: linear between two comb points; the value
// of its comb point when the other end is the cell's entry or exit; in a cell without comb points,
// the ray's last comb value with its extinction capped at the cell's majorant (0 before the ray's
// first comb point). So the control never exceeds the cell's majorant (but where the majorant
// underestimates) and the residual factors stay within 1 +- 1 / residualScale.
// `onEvaluated(slot, value)` for each point the network answered. Returns true when roulette
// ended the ray.
template <typename OnEvaluated>
INR_HD bool resolvePreintegratedPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
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
  float lastValue = rs.lastCombValue[i];  // the ray's last comb point's value (NaN: none yet)
  bool inCell = rs.combInCell[i] != 0;   // that comb point is in the current cell
  bool ended = false;
  for (int j = 0; j < count && !ended;) {
    // The segment: residual points j..e-1, closed by point e (a comb point or the cell's marker).
    int e = j;
    while (e < count && !(pts.kind[pointSlot(pts, rs.count, i, e)] & (kPointComb | kPointCellExit))) ++e;
    if (e == count) break;  // (never: every batch ends at a comb point or a marker)
    const int closeSlot = pointSlot(pts, rs.count, i, e);
    const bool atComb = (pts.kind[closeSlot] & kPointComb) != 0;
    const float length = pts.sinceBreak[closeSlot];
    SegmentControl control;
    if (atComb) {
      const float sb = pts.sample[closeSlot];
      const float xf = controlCoordinate(tf, lastValue), xb = controlCoordinate(tf, sb);
      if (inCell && isFiniteValue(xf) && isFiniteValue(xb)) {
        const ControlSegment seg = controlSegment(tf, xf, xb);
        control.kind = 2;
        control.xf = xf;
        control.xb = xb;
        control.extinction = seg.extinction;
        control.colour = seg.colour;
      } else if (!inCell) {
        control = constantControl(tf, sb, INFINITY);  // (in the cell's range)
      }
    } else {  // the marker: its majorant field holds the cell's majorant
      // In a cell without comb points: the ray's last comb value, its extinction capped at the
      // cell's majorant (on siren_cylinder_vorticity_small a control of 0 there was noisier).
      control = constantControl(tf, lastValue, inCell ? INFINITY : pts.majorant[closeSlot]);
    }
    float product = 1.f;  // residual factors so far in this segment
    for (int r = j; r < e; ++r) {
      const int slot = pointSlot(pts, rs.count, i, r);
      const float s = pts.sample[slot], mu = pts.majorant[slot], v = pts.sinceBreak[slot];
      const Vec4f c = isFiniteValue(s) ? lookupTransferFunction(tf, s) : Vec4f{0.f, 0.f, 0.f, 0.f};
      const float sigma = opacityToExtinction(c.w, tf.invUnitDistance);
      float controlSigma, depth;
      controlAlong(tf, control, v, length, controlSigma, depth);
      const float scale = T * expf(-depth) / mu;
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
    // The segment's own stream (reservoir, roulette), keyed by its closing point.
    const float tClose = pts.t[closeSlot];
    RngStream segmentRng = ratioPointStream(ray, tClose);
    segmentRng.seed ^= 0x27d4eb2du;
    if (w != 0.f) {
      absSum += fabsf(w);
      if (segmentRng.next() * absSum < fabsf(w)) hitT = tClose;
    }
    if (atComb) {
      const float sb = pts.sample[closeSlot];
      lastValue = isFiniteValue(sb) ? sb : NAN;
      inCell = isFiniteValue(sb);
    } else {
      inCell = false;
    }
    const float magnitude = fabsf(T);
    if (magnitude < fc.rouletteThreshold) {  // survivors continue with |T| = threshold: unbiased
      if (segmentRng.next() * fc.rouletteThreshold < magnitude) {
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
  rs.lastCombValue[i] = lastValue;
  rs.combInCell[i] = inCell ? 1 : 0;
  return ended;
}

// ---- one traversal pass

// One traversal pass of a ray whose batches end where its walk commits its state (the
// pre-integrated march's and the debiased march's, DebiasedMarch.h): `resolve(count, rng)` folds
// the answered batch in (true when roulette ended the ray), `draw(flags, rng, left)` draws the next
// batch from rs.t on and returns its size (0 only at the ray's end, rs.t = tEnd). Its queries go to
// emitQuery(slot); points answered without a query (pruning, the ray's end marker) are folded in at
// once and the walk goes on. At the end of the walk the ray's frame estimate is complete (kRayHit
// when it gathered emission, rs.t = the reservoir's hit point for reprojection).
template <typename Resolve, typename Draw, typename EmitQuery>
INR_HD void traverseBatchedRay(const FrameConstants& fc, const RayStateView& rs, const PointStateView& pts, int i,
                               Resolve&& resolve, Draw&& draw, EmitQuery&& emitQuery) {
  std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayActive)) return;
  RngStream rng{pixelStreamKey(fc, i), fc.frame, fc.seed, rs.rngCounter[i]};
  int pending = (flags & kRayPending) ? int(rs.pointCount[i]) : 0;
  bool finished = false;
  for (;;) {
    if (pending > 0 && resolve(pending, rng)) {
      finished = true;
      break;
    }
    pending = 0;
    if (!(rs.t[i] < rs.tEnd[i])) {
      finished = true;
      break;
    }
    bool left = false;
    pending = draw(flags, rng, left);
    int queries = 0;
    for (int j = 0; j < pending; ++j) {
      const int slot = pointSlot(pts, rs.count, i, j);
      if (pts.kind[slot] & kPointCellExit) {
        // (no query)
      } else if (pts.kind[slot] & kPointPruned) {
        rs.pruned[i] += 1u;
      } else {
        emitQuery(slot);
        ++queries;
      }
    }
    if (queries > 0) break;  // wait for the evaluator
    if (pending == 0) {      // (left with nothing drawn)
      finished = true;
      break;
    }
    // else: all answered already (pruning, markers): fold them in and go on
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

// The pre-integrated march's pass (traverseBatchedRay); onEvaluated(slot, value) for each point the
// network answered.
template <typename Walker, bool kPruning, typename OnEvaluated, typename EmitQuery>
INR_HD void traversePreintegratedRayWith(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                                         const PointStateView& pts, int i, OnEvaluated&& onEvaluated,
                                         EmitQuery&& emitQuery) {
  traverseBatchedRay(
      fc, rs, pts, i,
      [&](int count, const RngStream& rng) {
        return resolvePreintegratedPoints(fc, medium, rs, pts, i, count, rng, onEvaluated);
      },
      [&](std::uint8_t& flags, RngStream& rng, bool& left) {
        return drawPreintegratedPoints<Walker, kPruning>(fc, medium, rs, pts, i, flags, rng, left);
      },
      emitQuery);
}

}  // namespace inr
