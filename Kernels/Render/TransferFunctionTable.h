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
  // 2D transfer function (TransferFunction::transfer2D): colour and opacity over (scalar, gradient
  // magnitude |grad f|), size x gradientSize entries, entry (i, j) at rgba2D[j * size + i]: column i
  // at the scalar of the 1D table's entry i, row j at gradientLo + j (gradientHi - gradientLo) /
  // (gradientSize - 1), interpolated bilinearly and clamped at the edges (a texture's lookup).
  // Null: off. On, it replaces colour, scalar opacity and gradient opacity (gradientOpacity is
  // null), and the 1D table (rgba) holds each column's largest opacity with that entry's colour:
  // bilinear interpolation never exceeds the columns' maxima interpolated linearly, so every bound
  // the stage code takes from the scalar alone (majorants, maxExtinctionOver, which candidates need
  // a gradient) holds whatever the gradient.
  const Vec4f* rgba2D = nullptr;
  int gradientSize = 0;
  float gradientLo = 0.f, gradientHi = 1.f;
};

// Whether a sample's colour or opacity depends on the network's gradient there (gradient opacity
// or a 2D transfer function): every sample the renderers take then needs its gradient term
// (Render/Evaluate.h) as well as its value.
INR_HD bool usesGradient(const TransferFunctionView& tf) { return tf.gradientOpacity != nullptr || tf.rgba2D != nullptr; }

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

INR_HD Vec4f lerp4(const Vec4f& a, const Vec4f& b, float f) {
  return Vec4f{a.x + (b.x - a.x) * f, a.y + (b.y - a.y) * f, a.z + (b.z - a.z) * f, a.w + (b.w - a.w) * f};
}

INR_HD Vec4f lookupTransferFunction(const TransferFunctionView& tf, float s) {
  const float x = tableCoordinate(tf, s);
  int i = int(x);
  if (i > tf.size - 2) i = tf.size - 2;
  if (i < 0) i = 0;
  const float f = x - float(i);
  return lerp4(tf.rgba[i], tf.rgba[i + 1], f);
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

// The 2D transfer function's colour and opacity at scalar s and gradient magnitude g (tf.rgba2D
// must be set). Both coordinates clamp to the table's edges; NaN maps to the low end, as in the
// scalar table.
INR_HD Vec4f lookupTransferFunction2D(const TransferFunctionView& tf, float s, float g) {
  const float x = tableCoordinate(tf, s);
  int i = int(x);
  if (i > tf.size - 2) i = tf.size - 2;
  if (i < 0) i = 0;
  const float fx = x - float(i);
  float y = (g - tf.gradientLo) / (tf.gradientHi - tf.gradientLo) * float(tf.gradientSize - 1);
  if (!(y > 0.f)) y = 0.f;
  y = minf(y, float(tf.gradientSize - 1));
  int j = int(y);
  if (j > tf.gradientSize - 2) j = tf.gradientSize - 2;
  if (j < 0) j = 0;
  const float fy = y - float(j);
  const Vec4f* row0 = tf.rgba2D + j * tf.size;
  const Vec4f* row1 = row0 + tf.size;
  return lerp4(lerp4(row0[i], row0[i + 1], fx), lerp4(row1[i], row1[i + 1], fx), fy);
}

// The gradient term the evaluation stage stores beside a sample's value (`opacityScale`,
// Render/Evaluate.h) for gradient magnitude g: the gradient opacity factor, or with a 2D transfer
// function the magnitude itself (the table is looked up with the value, sampleColourOpacity).
INR_HD float gradientTermAt(const TransferFunctionView& tf, float g) {
  return tf.rgba2D ? g : gradientOpacityAt(tf, g);
}

// The term stored for a sample whose outcome no gradient can change (Render/Evaluate.h): one that
// makes it empty (factor 0; with a 2D TF a negative magnitude).
INR_HD float emptyGradientTerm(const TransferFunctionView& tf) { return tf.rgba2D ? -1.f : 0.f; }

// A sample's colour and opacity, the one transfer-function lookup of the stage code: value s
// (finite) and gradient term `term` (gradientTermAt). Without a gradient dependence the 1D table
// (the term is not read); with gradient opacity its scalar opacity times the factor; with a 2D
// transfer function the 2D table at (s, |grad f|), empty for the empty term.
INR_HD Vec4f sampleColourOpacity(const TransferFunctionView& tf, float s, float term) {
  if (tf.rgba2D) return term < 0.f ? Vec4f{0.f, 0.f, 0.f, 0.f} : lookupTransferFunction2D(tf, s, term);
  Vec4f c = lookupTransferFunction(tf, s);
  if (tf.gradientOpacity) c.w *= term;
  return c;
}

// The same with the term read from terms[slot] (the ray's or the point's opacityScale), only when
// the TF depends on the gradient (the stage code writes the terms only then).
INR_HD Vec4f sampleColourOpacity(const TransferFunctionView& tf, float s, const float* terms, int slot) {
  return sampleColourOpacity(tf, s, usesGradient(tf) ? terms[slot] : 1.f);
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
