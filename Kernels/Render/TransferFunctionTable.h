#pragma once
// The transfer function as the per-ray code sees it: a table of colour and opacity sampled
// uniformly over [lo, hi] and interpolated linearly (the way VTK's volume mappers sample their
// transfer functions into a texture), plus a range-max table (sparse table of opacity maxima) so
// that the maximum extinction over any scalar interval is O(1) — which is what majorants need.
//
// Optical model (VTK semantics): the table holds opacity alpha "per scalar opacity unit
// distance" u; the extinction coefficient is sigma = -ln(1 - alpha) / u, so a slab of thickness
// u has opacity alpha, exactly VTK's opacity correction 1 - (1 - alpha)^(ds / u) in the limit.
// Emission is the colour: L = integral T(s) sigma(s) c(s) ds + T_total * background.
// Scalars outside [lo, hi] clamp to the end entries (VTK's default clamping).
#include <cstdint>

#include "Render/RenderMath.h"

namespace inr {

// Opacity 1 would make sigma infinite; VTK shows it as "opaque at the first sample". We clamp
// alpha to this, i.e. sigma <= 11.5 / u: the medium is 99.999% opaque after one unit distance.
constexpr float kMaxTableOpacity = 0.99999f;

struct TransferFunctionView {
  const Vec4f* rgba = nullptr;      // size entries: colour (x,y,z) and opacity (w)
  const float* opacityMax = nullptr;  // levels * size: level L, entry i = max opacity of [i, i + 2^L)
  int size = 0;
  int levels = 0;
  float lo = 0.f, hi = 1.f;          // scalar range the table spans
  float invUnitDistance = 1.f;       // 1 / u
  // Gradient opacity (TransferFunction::gradientOpacity): the factor gradientOpacity[k] at gradient
  // magnitude gradientOpacityX[k] (strictly increasing, gradientOpacitySize points: the function's
  // nodes, and samples between nodes with a midpoint or sharpness), interpolated linearly, clamped
  // to the end points. Null: off (the factor is 1 and no sample needs a gradient).
  const float* gradientOpacity = nullptr;
  const float* gradientOpacityX = nullptr;
  int gradientOpacitySize = 0;
  // Pre-integration (Render/PreintegratedMarch.h), size entries each, built with the table: the
  // extinction of each entry's opacity, and the running integrals from entry 0 to entry i, in
  // table-entry units, of the control extinction (the renderer's own: opacity interpolated
  // linearly, then converted: w) and of that extinction times the colour (xyz).
  const float* entryExtinction = nullptr;
  const Vec4f* extinctionIntegral = nullptr;
};

INR_HD float opacityToExtinction(float alpha, float invUnitDistance) {
  const float a = clampf(alpha, 0.f, kMaxTableOpacity);
  return -log1pf(-a) * invUnitDistance;
}

// Continuous table coordinate of scalar s, clamped to [0, size - 1].
INR_HD float tableCoordinate(const TransferFunctionView& tf, float s) {
  const float x = (s - tf.lo) / (tf.hi - tf.lo) * float(tf.size - 1);
  if (!(x > 0.f)) return 0.f;  // also maps NaN to the low end rather than into the index math
  return minf(x, float(tf.size - 1));
}

INR_HD Vec4f lookupTransferFunction(const TransferFunctionView& tf, float s) {
  const float x = tableCoordinate(tf, s);
  int i = int(x);
  if (i > tf.size - 2) i = tf.size - 2;
  if (i < 0) i = 0;
  const float f = x - float(i);
  const Vec4f a = tf.rgba[i], b = tf.rgba[i + 1];
  return Vec4f{a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f, a.z + (b.z - a.z) * f,
               a.w + (b.w - a.w) * f};
}

// The gradient opacity factor in [0, 1] for gradient magnitude g (model space); 1 when the TF has
// none. A non-finite magnitude (a network that overflowed) takes the last point's factor when
// infinite and the first's when NaN, as the scalar table maps NaN to its low end.
INR_HD float gradientOpacityAt(const TransferFunctionView& tf, float g) {
  if (!tf.gradientOpacity) return 1.f;
  const float* x = tf.gradientOpacityX;
  const float* y = tf.gradientOpacity;
  const int n = tf.gradientOpacitySize;
  if (!(g > x[0])) return y[0];
  if (!(g < x[n - 1])) return y[n - 1];
  int lo = 0, hi = n - 1;  // x[lo] <= g < x[hi]: a few steps (the points are few)
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (x[mid] <= g)
      lo = mid;
    else
      hi = mid;
  }
  return y[lo] + (y[hi] - y[lo]) * ((g - x[lo]) / (x[hi] - x[lo]));
}

// A sample's opacity: the scalar opacity alpha times the gradient opacity factor the evaluation
// stage stored beside its value (`opacityScale`, Render/Evaluate.h). Without a gradient opacity
// the factor is not read (it is never written then) and alpha is returned as it is.
INR_HD float sampleOpacity(const TransferFunctionView& tf, float alpha, const float* opacityScale, int slot) {
  return tf.gradientOpacity ? alpha * opacityScale[slot] : alpha;
}

INR_HD float extinctionAt(const TransferFunctionView& tf, float s) {
  return opacityToExtinction(lookupTransferFunction(tf, s).w, tf.invUnitDistance);
}

// Whether a sample of value s has any extinction under the scalar opacity (a non-finite value is
// empty space).
INR_HD bool sampleHasExtinction(const TransferFunctionView& tf, float s) {
  return isFiniteValue(s) && extinctionAt(tf, s) > 0.f;
}

INR_HD int floorLog2(unsigned v) {
  int r = 0;
  while (v >>= 1) ++r;
  return r;
}

// Maximum extinction the TF assigns to any scalar in [sMin, sMax]. Conservative: the table is
// linear between entries, so the maximum over the covering entries bounds it exactly.
INR_HD float maxExtinctionOver(const TransferFunctionView& tf, float sMin, float sMax) {
  if (!(sMin <= sMax)) return 0.f;  // empty (or NaN) range: nothing to bound
  int i0 = int(floorf(tableCoordinate(tf, sMin)));
  int i1 = int(ceilf(tableCoordinate(tf, sMax)));
  i0 = clampi(i0, 0, tf.size - 1);
  i1 = clampi(i1, i0, tf.size - 1);
  const int level = floorLog2(unsigned(i1 - i0 + 1));
  const float* row = tf.opacityMax + level * tf.size;
  const float alpha = maxf(row[i0], row[i1 - (1 << level) + 1]);
  return opacityToExtinction(alpha, tf.invUnitDistance);
}

}  // namespace inr
