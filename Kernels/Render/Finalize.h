#pragma once
// Stage IV — finalisation: turn the ray's result into this frame's premultiplied colour, fold it
// into the accumulation buffer (running mean) and compute the convergence residual r_i (paper
// Eq. divergence): the mean absolute RGB difference between the new displayed colour and the
// previous running average, both composited over the background as the user sees them. It also
// keeps the mean of the pixel's frames in the accumulation's second half (frameHalf, CounterRng.h),
// from which the variance of the displayed mean — the pixel's expected squared error — follows;
// the convergence estimate aggregates it over the pixels the volume covers
// (Backends/Refinement.h).
#include <cstdint>

#include "Render/CounterRng.h"
#include "Render/RayInit.h"
#include "Render/RayState.h"

namespace inr {

// A pixel's accumulation after a reset: nothing accumulated, residual 1 ("maximally unstable").
INR_HD void resetPixel(const AccumulationView& acc, int i) {
  acc.accum[i] = Vec4f{0.f, 0.f, 0.f, 0.f};
  acc.sampleCount[i] = 0u;
  acc.residual[i] = 1.f;
  acc.halfMean[i] = Vec4f{0.f, 0.f, 0.f, 0.f};
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

INR_HD Vec3f overBackground(const Vec4f& c, const Vec3f& bg) {
  return Vec3f{c.x + (1.f - c.w) * bg.x, c.y + (1.f - c.w) * bg.y, c.z + (1.f - c.w) * bg.z};
}

// What pixel i adds to the convergence sums in its current state, its colours shown over
// `background`. The error of the displayed mean M of n frames comes from the means A and B of
// the accumulation's two halves (n_A + n_B = n frames): their frame estimates are independent of
// each other (each half's sub-pixel positions have their own random start), so
// E|A - B|^2 = Var A + Var B, and for frames of equal variance Var M = E|A - B|^2 n_A n_B / n^2.
// Unlike the frames' sample variance (Var M = s^2 / n), this holds when the frames within a half
// are not independent: the stratified jitter spreads them evenly over the pixel, which makes M
// better than s^2 / n says (RESULTS-archive, "Honest convergence estimate under the stratified
// jitter", has both side by side).
INR_HD PixelConvergence pixelConvergence(const AccumulationView& acc, int i, const Vec3f& background) {
  PixelConvergence pc{acc.residual[i], 0.f, acc.accum[i].w > 0.f ? 1 : 0, -1};
  if (pc.covered) {
    // Unknown until both halves hold a frame: infinite until then.
    const Vec4f h = acc.halfMean[i];
    const float n = float(acc.sampleCount[i]), nB = h.w, nA = n - nB;
    if (nA >= 1.f && nB >= 1.f) {
      const Vec3f m = overBackground(acc.accum[i], background);
      const float ax = (n * m.x - nB * h.x) / nA, ay = (n * m.y - nB * h.y) / nA, az = (n * m.z - nB * h.z) / nA;
      const float dx = ax - h.x, dy = ay - h.y, dz = az - h.z;
      pc.meanVariance = (dx * dx + dy * dy + dz * dz) * (1.f / 3.f) * (nA * nB / (n * n));
    } else {
      pc.meanVariance = INFINITY;
    }
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

// The sub-pixel jitter's control variate (FrameConstants::jitterControl). A frame samples pixel i
// at a random point x of the pixel, so its estimate c carries the image's variation across the
// pixel as noise: with the shipped transfer functions most of a first frame's error at 256²
// (RESULTS-archive, "Where a first frame's error comes from on the CPU"). With g a slope of the
// image at the pixel that does not depend on x, c - g . (x - centre) has c's expectation (x is
// uniform in the pixel: E[x - centre] = 0) and lacks the part of that noise that is linear across
// the pixel. g is the slope of the least-squares plane through this frame's estimates of the (up
// to) 8 neighbours at their own sampled positions, which are independent of pixel i's draws: no
// control where fewer than 3 neighbours have an estimate (a pixel budgeting skipped has none), where
// their positions do not span a plane, or where their estimates are all equal (the background's
// pixels, most of a frame, skip the positions' draws) — rules that do not look at pixel i's own
// sample. The plane's 8 neighbours carry less of their own Monte Carlo noise into g than central
// differences of 4 (RESULTS-archive, "A plane through the 8 neighbours"). Every frame stays
// unbiased; the frames of neighbouring pixels become correlated, which the convergence estimate
// (per pixel, from the two halves) does not assume otherwise. The finalize pass reads the
// neighbours' ray state and writes only the accumulation, so one pass over the pixels serves on
// either backend.
INR_HD Vec4f jitterControlled(const FrameConstants& fc, const RayStateView& rs, int i, const Vec4f& c) {
  const int width = fc.camera.width, height = fc.camera.height;
  const int px = i % width, py = i / width;
  float xs[8], ys[8];  // the neighbours' sampled positions relative to pixel i's centre
  Vec4f cs[8];
  int n = 0;
  bool differ = false;
  for (int oy = -1; oy <= 1; ++oy)
    for (int ox = -1; ox <= 1; ++ox) {
      if ((ox == 0 && oy == 0) || px + ox < 0 || px + ox >= width || py + oy < 0 || py + oy >= height) continue;
      const int j = i + oy * width + ox;
      if (rs.flags[j] & kRayBudgetSkipped) continue;
      cs[n] = frameEstimate(fc, rs, j);
      differ = differ || (n > 0 && (cs[n].x != cs[0].x || cs[n].y != cs[0].y || cs[n].z != cs[0].z ||
                                    cs[n].w != cs[0].w));
      xs[n] = float(ox);
      ys[n] = float(oy);
      ++n;
    }
  if (!differ || n < 3) return c;
  // Centred least squares: g = S^-1 sum (p - mean p)(c - mean c), S = sum (p - mean p)(p - mean p)^T.
  float mx = 0.f, my = 0.f;
  Vec4f mc{0.f, 0.f, 0.f, 0.f};
  for (int k = 0; k < n; ++k) {
    float a0, a1;
    RngStream unused;
    primaryJitter(fc, i + int(ys[k]) * width + int(xs[k]), unused, a0, a1);
    xs[k] += a0 - 0.5f;
    ys[k] += a1 - 0.5f;
    mx += xs[k];
    my += ys[k];
    mc = Vec4f{mc.x + cs[k].x, mc.y + cs[k].y, mc.z + cs[k].z, mc.w + cs[k].w};
  }
  const float inv = 1.f / float(n);
  mx *= inv;
  my *= inv;
  mc = Vec4f{mc.x * inv, mc.y * inv, mc.z * inv, mc.w * inv};
  float sxx = 0.f, sxy = 0.f, syy = 0.f;
  Vec4f sxc{0.f, 0.f, 0.f, 0.f}, syc{0.f, 0.f, 0.f, 0.f};
  for (int k = 0; k < n; ++k) {
    const float x = xs[k] - mx, y = ys[k] - my;
    const Vec4f d{cs[k].x - mc.x, cs[k].y - mc.y, cs[k].z - mc.z, cs[k].w - mc.w};
    sxx += x * x;
    sxy += x * y;
    syy += y * y;
    sxc = Vec4f{sxc.x + x * d.x, sxc.y + x * d.y, sxc.z + x * d.z, sxc.w + x * d.w};
    syc = Vec4f{syc.x + y * d.x, syc.y + y * d.y, syc.z + y * d.z, syc.w + y * d.w};
  }
  const float det = sxx * syy - sxy * sxy;
  if (!(det > 1e-3f * sxx * syy)) return c;  // the positions lie (nearly) on a line
  const float ixx = syy / det, ixy = -sxy / det, iyy = sxx / det;
  float u0, u1;
  RngStream rng;
  primaryJitter(fc, i, rng, u0, u1);
  const float dx = u0 - 0.5f, dy = u1 - 0.5f;
  // g . (x - centre) with g = S^-1 (sxc, syc): the weights of sxc and syc.
  const float wx = ixx * dx + ixy * dy, wy = ixy * dx + iyy * dy;
  return Vec4f{c.x - wx * sxc.x - wy * syc.x, c.y - wx * sxc.y - wy * syc.y, c.z - wx * sxc.z - wy * syc.z,
               c.w - wx * sxc.w - wy * syc.w};
}

// Returns what the pixel adds to the convergence sums (the backends reduce them).
// Pixels that ray budgeting skipped keep their accumulation and add their current state.
INR_HD PixelConvergence finalizePixel(const FrameConstants& fc, const RayStateView& rs,
                                      const AccumulationView& acc, int i) {
  const std::uint8_t flags = rs.flags[i];
  if (flags & kRayBudgetSkipped) return pixelConvergence(acc, i, fc.background);
  Vec4f c = frameEstimate(fc, rs, i);
  if (fc.jitterControl) c = jitterControlled(fc, rs, i, c);
  const std::uint32_t n = acc.sampleCount[i];
  const Vec4f prev = acc.accum[i];
  const Vec3f a = overBackground(c, fc.background);  // this frame's colour as shown
  if (n == 0) {
    acc.residual[i] = 1.f;  // nothing to compare with: maximally unstable
    acc.accum[i] = c;
  } else {
    const Vec3f b = overBackground(prev, fc.background);
    const float r = (fabsf(a.x - b.x) + fabsf(a.y - b.y) + fabsf(a.z - b.z)) * (1.f / 3.f);
    acc.residual[i] = clampf(r, 0.f, 1.f);
    const float w = 1.f / float(n + 1);
    acc.accum[i] = Vec4f{prev.x + (c.x - prev.x) * w, prev.y + (c.y - prev.y) * w,
                         prev.z + (c.z - prev.z) * w, prev.w + (c.w - prev.w) * w};
  }
  if (frameHalf(fc.frame)) {  // the second half's running mean, in the displayed colour
    const Vec4f h = acc.halfMean[i];
    const float count = h.w + 1.f, w = 1.f / count;
    acc.halfMean[i] = Vec4f{h.x + (a.x - h.x) * w, h.y + (a.y - h.y) * w, h.z + (a.z - h.z) * w, count};
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
  PixelConvergence pc = pixelConvergence(acc, i, fc.background);
  if (flags & (kRayEntered | kRayHit)) pc.residualBin = residualBin(pc.residual);
  return pc;
}

}  // namespace inr
