#pragma once
// Unbiased ray marching (PrimaryEstimator::March), written once for the CPU and CUDA backends: its
// points (a comb and residual ratio-tracking points) and how each is weighed. Ratio tracking's
// traversal pass (RatioTracking.h) folds them in.
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
#include <cmath>
#include <cstdint>

#include "Render/CounterRng.h"
#include "Render/TrackingPoints.h"
#include "Render/Traverse.h"

namespace inr {

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

// Folds one march point (extinction sigma; mu its comb spacing or residual rate; `gap` the
// non-empty length, or before the ray's first comb point the majorant optical depth, since the
// previous point) into the ray's transmittance T and control, and returns its emission weight.
// Until the ray's first comb point the control is half the macrocell majorant; from then on the
// extinction at the last comb point.
INR_HD float foldMarchPoint(const FrameConstants& fc, const TransferFunctionView& tf, std::uint8_t kind, float sigma,
                            float mu, float gap, float& T, float& control) {
  const bool known = control == control;
  float w = 0.f;
  if (marchUsesControl(fc, tf)) {
    T *= expf(-(known ? control * gap : 0.5f * gap));
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
  return w;
}

// The march's points (drawRatioPoints for PrimaryEstimator::March): from rs.t on, at most
// fc.pointsPerIteration of the comb and residual points, resuming the walker and the comb.
template <typename Walker, bool kPruning, typename EmitQuery>
INR_HD int drawMarchPoints(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs,
                           const PointStateView& pts, int i, std::uint8_t& flags, RngStream& rng, int& queries,
                           bool& left, EmitQuery&& emitQuery) {
  const float tEnd = rs.tEnd[i];
  float t = rs.t[i];
  // The next comb and residual points of the current segment (NaN: the walk is at a segment's
  // start and draws them afresh).
  float combNext = rs.combNext[i], residualNext = rs.residualNext[i], combPhase = rs.combPhase[i];
  float gap = 0.f;          // non-empty length since the last point
  bool controlKnown = rs.controlKnown[i] != 0;  // the ray has had a comb point
  int count = 0;
  left = false;
  Walker walker(medium.grid, rs, i);
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) break;
    if (m > 0.f) {
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

}  // namespace inr
