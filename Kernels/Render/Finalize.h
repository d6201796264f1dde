#pragma once
// Stage IV — finalisation: turn the ray's result into this frame's premultiplied colour, fold it
// into the accumulation buffer (running mean) and compute the convergence residual r_i (paper
// Eq. divergence): the mean absolute RGB difference between the new displayed colour and the
// previous running average, both composited over the background as the user sees them. It also
// keeps each pixel's sample variance (Welford), from which the variance of the displayed mean —
// the pixel's expected squared error — follows; the convergence estimate aggregates it over the
// pixels the volume covers (Backends/Refinement.h).
#include <cstdint>

#include "Render/RayState.h"

namespace inr {

// A pixel's accumulation after a reset: nothing accumulated, residual 1 ("maximally unstable").
INR_HD void resetPixel(const AccumulationView& acc, int i) {
  acc.accum[i] = Vec4f{0.f, 0.f, 0.f, 0.f};
  acc.sampleCount[i] = 0u;
  acc.residual[i] = 1.f;
  acc.m2[i] = 0.f;
  acc.skip[i] = -1;
  acc.hitPoint[i] = Vec3f{0.f, 0.f, 0.f};
}

// What a pixel adds to the frame's convergence sums.
struct PixelConvergence {
  float residual;      // r_i
  float meanVariance;  // estimated variance of the displayed mean (RGB average); 0 when not covered
  int covered;         // the volume has covered the pixel in some frame (accumulated alpha > 0)
  int residualBin;     // histogram bin of r_i when the pixel was rendered and its ray entered the
                       // volume (the histogram scheme ranks those), else -1
};

// What pixel i adds to the convergence sums in its current state.
INR_HD PixelConvergence pixelConvergence(const AccumulationView& acc, int i) {
  PixelConvergence pc{acc.residual[i], 0.f, acc.accum[i].w > 0.f ? 1 : 0, -1};
  if (pc.covered) {
    // Unknown after one sample: infinite until a second arrives.
    const std::uint32_t count = acc.sampleCount[i];
    pc.meanVariance = count > 1 ? acc.m2[i] / (3.f * float(count) * float(count - 1)) : INFINITY;
  }
  return pc;
}

// World position of the primary ray's real collision (valid when kRayHit): a shadow ray starts
// there; without one the primary ray stopped at t.
INR_HD Vec3f primaryHitPoint(const RayStateView& rs, int i) {
  return (rs.flags[i] & kRayShadow) ? rs.origin[i] : rs.origin[i] + rs.direction[i] * rs.t[i];
}

// This frame's estimate for pixel i: premultiplied emission of the real collision, shaded by the
// light's visibility when shadows are on; (0,0,0,0) when the ray escaped. With gradient shading
// the shading stage (Shade.h) has lit the colour, visibility included.
INR_HD Vec4f frameEstimate(const FrameConstants& fc, const RayStateView& rs, int i) {
  Vec4f c = rs.radiance[i];
  if ((rs.flags[i] & kRayHit) && fc.shadows && !fc.shading.enabled) {
    const float shade = fc.ambient + (1.f - fc.ambient) * rs.visibility[i];
    c.x *= shade;
    c.y *= shade;
    c.z *= shade;
  }
  return c;
}

INR_HD Vec3f overBackground(const Vec4f& c, const Vec3f& bg) {
  return Vec3f{c.x + (1.f - c.w) * bg.x, c.y + (1.f - c.w) * bg.y, c.z + (1.f - c.w) * bg.z};
}

// Returns what the pixel adds to the convergence sums (the backends reduce them).
// Pixels that ray budgeting skipped keep their accumulation and add their current state.
INR_HD PixelConvergence finalizePixel(const FrameConstants& fc, const RayStateView& rs,
                                      const AccumulationView& acc, int i) {
  const std::uint8_t flags = rs.flags[i];
  if (flags & kRayBudgetSkipped) return pixelConvergence(acc, i);
  const Vec4f c = frameEstimate(fc, rs, i);
  const std::uint32_t n = acc.sampleCount[i];
  const Vec4f prev = acc.accum[i];
  if (n == 0) {
    acc.residual[i] = 1.f;  // nothing to compare with: maximally unstable
    acc.accum[i] = c;
  } else {
    const Vec3f a = overBackground(c, fc.background), b = overBackground(prev, fc.background);
    const float r = (fabsf(a.x - b.x) + fabsf(a.y - b.y) + fabsf(a.z - b.z)) * (1.f / 3.f);
    acc.residual[i] = clampf(r, 0.f, 1.f);
    const float w = 1.f / float(n + 1);
    acc.accum[i] = Vec4f{prev.x + (c.x - prev.x) * w, prev.y + (c.y - prev.y) * w,
                         prev.z + (c.z - prev.z) * w, prev.w + (c.w - prev.w) * w};
    // Welford: the displayed colour is affine in the premultiplied one, so its new mean is
    // b + (a - b) w and the update (a - b)(a - mean') = (a - b)^2 (1 - w).
    const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
    acc.m2[i] += (dx * dx + dy * dy + dz * dz) * (1.f - w);
  }
  const std::uint32_t count = n + 1;
  acc.sampleCount[i] = count;
  acc.skip[i] = -1;  // rendered: the histogram scheme decides afresh at the next initialisation
  if (flags & kRayHit) {
    // Running mean over the frames that hit: their count is the accumulated coverage times the
    // frame count (exact up to rounding; only the weights of a mean position depend on it).
    const float hits = maxf(1.f, acc.accum[i].w * float(count) + 0.5f);
    const Vec3f p = primaryHitPoint(rs, i), h = acc.hitPoint[i];
    const float w = 1.f / floorf(hits);
    acc.hitPoint[i] = Vec3f{h.x + (p.x - h.x) * w, h.y + (p.y - h.y) * w, h.z + (p.z - h.z) * w};
  }
  PixelConvergence pc = pixelConvergence(acc, i);
  if (flags & (kRayEntered | kRayHit)) pc.residualBin = residualBin(pc.residual);
  return pc;
}

}  // namespace inr
