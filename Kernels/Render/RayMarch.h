#pragma once
// The ray marcher's per-ray logic, written once for the CPU marcher (RayMarchRenderer) and the
// GPU one (CudaRayMarcher): the camera ray with the delta tracker's jitter draws, its cut into
// equal segments of at most `step` sampled at their (per-frame shifted) midpoints, the shadow
// ray's samples towards the light, and front-to-back compositing with alpha = 1 - exp(-sigma ds)
// (= VTK's 1 - (1 - alpha)^(ds / u)). The backends only batch the samples for the evaluator.
#include <cmath>
#include <cstdint>

#include "Common/HostDevice.h"
#include "Render/CameraView.h"
#include "Render/CounterRng.h"
#include "Render/RenderMath.h"
#include "Render/Shading.h"
#include "Render/TransferFunctionTable.h"

namespace inr {

// A primary ray cut for marching: `count` samples at t0 + j * ds (model space); count 0 when
// the ray misses the box or the opaque geometry hides it.
struct MarchRay {
  Vec3f o, d;
  float t0 = 0.f, ds = 0.f;
  int count = 0;
};

// The key of pixel i (row-major in a width-wide image) as the delta tracker keys its random
// streams: its index in the full image when the image is a window of it.
INR_HD std::uint32_t marchPixelKey(int i, int width, int windowX, int windowY, int fullWidth) {
  return fullWidth == 0 ? std::uint32_t(i)
                        : std::uint32_t(i / width + windowY) * std::uint32_t(fullWidth) + std::uint32_t(i % width + windowX);
}

// Pixel i's ray for `frame`: the delta tracker's jitter draws (u0, u1), then the segment shift;
// pixel centres and midpoints without jitter. depthWorld: the opaque geometry's depth (world
// distance along the ray), infinity for none.
INR_HD MarchRay marchCameraRay(const CameraView& cam, const Box3f& box, int i, std::uint32_t key, std::uint32_t frame,
                               std::uint32_t seed, bool jitter, float depthWorld, float step) {
  RngStream rng{key, frame, seed, 0u};
  const float u0 = rng.next(), u1 = rng.next();  // same draws as the delta tracker's jitter
  const float shift = jitter ? rng.next() : 0.5f;
  MarchRay s;
  cameraRayWorld(cam, i % cam.width, i / cam.width, jitter ? u0 : 0.5f, jitter ? u1 : 0.5f, s.o, s.d);
  const float modelPerWorld = worldRayToModel(cam, s.o, s.d);  // model space from here on
  float tEnter, tExit;
  if (!intersectBox(box, s.o, s.d, tEnter, tExit)) return s;
  if (depthWorld < INFINITY) tExit = minf(tExit, depthWorld * modelPerWorld);
  if (!(tEnter < tExit)) return s;
  const float len = tExit - tEnter;
  s.count = int(ceilf(len / step));
  if (s.count < 1) s.count = 1;
  s.ds = len / float(s.count);
  s.t0 = tEnter + shift * s.ds;
  return s;
}

INR_HD Vec3f marchSample(const MarchRay& s, int j) { return s.o + s.d * (s.t0 + float(j) * s.ds); }

// The shadow ray from p towards the light (unit, model space): `count` samples at the
// midpoints of equal segments of at most `step` up to the box; count 0 when it leaves at once.
struct MarchShadowRay {
  float ds = 0.f;
  int count = 0;
};

INR_HD MarchShadowRay marchShadowRay(const Box3f& box, Vec3f p, Vec3f toLight, float step) {
  MarchShadowRay r;
  float te, tx;
  if (!intersectBox(box, p, toLight, te, tx) || !(tx > 0.f)) return r;
  r.count = int(ceilf(tx / step));
  if (r.count < 1) r.count = 1;
  r.ds = tx / float(r.count);
  return r;
}

INR_HD Vec3f marchShadowSample(Vec3f p, Vec3f toLight, const MarchShadowRay& r, int q) {
  return p + toLight * ((float(q) + 0.5f) * r.ds);
}

// Whether a sample of value v with gradient term opacityScale (gradientTermAt; 1 when the TF does
// not use the gradient) can contribute (and so needs a shadow ray).
INR_HD bool marchSampleEmits(const TransferFunctionView& tf, float v, float opacityScale = 1.f) {
  if (tf.rgba2D) return isFiniteValue(v) && sampleColourOpacity(tf, v, opacityScale).w > 0.f;
  return opacityScale > 0.f && sampleHasExtinction(tf, v);
}

// The extinction of a shadow-ray sample of value v with gradient term opacityScale (0 for a NaN
// output: empty space).
INR_HD float marchExtinction(const TransferFunctionView& tf, float v, float opacityScale = 1.f) {
  if (!isFiniteValue(v)) return 0.f;
  return opacityToExtinction(sampleColourOpacity(tf, v, opacityScale).w, tf.invUnitDistance);
}

INR_HD float expm1Of(float x) { return expm1f(x); }
INR_HD double expm1Of(double x) { return expm1(x); }

// Front-to-back compositing of a ray's samples in precision Real (the CPU marcher composites in
// double, the GPU one in float).
template <typename Real>
struct MarchCompositor {
  Real T = 1, r = 0, g = 0, b = 0;

  // A sample of value v over ds; lightFactor: the share of its emission that reaches the eye's
  // side of the light (1 without shadows); opacityScale: its gradient term (gradientTermAt; 1
  // when the TF does not use the gradient, Render/Evaluate.h). NaN outputs are empty space, as in
  // the delta tracker.
  INR_HD void add(const TransferFunctionView& tf, float v, float ds, Real lightFactor, float opacityScale = 1.f) {
    if (!isFiniteValue(v)) return;
    const Vec4f c = sampleColourOpacity(tf, v, opacityScale);
    emit(c, tf, ds, lightFactor, Vec3f{c.x, c.y, c.z});
  }

  // The same with gradient shading (Shading.h): the sample's colour lit by `light` with the
  // light's visibility lightT (1 without shadows).
  INR_HD void addLit(const TransferFunctionView& tf, float v, float ds, float ambient, const SampleLight& light,
                     float lightT, float opacityScale = 1.f) {
    if (!isFiniteValue(v)) return;
    const Vec4f c = sampleColourOpacity(tf, v, opacityScale);
    emit(c, tf, ds, Real(1), litColour(Vec3f{c.x, c.y, c.z}, ambient, light, lightT));
  }

  INR_HD void emit(const Vec4f& c, const TransferFunctionView& tf, float ds, Real lightFactor, const Vec3f& colour) {
    const Real sigma = opacityToExtinction(c.w, tf.invUnitDistance);
    const Real alpha = -expm1Of(-sigma * ds);
    const Real w = T * alpha * lightFactor;
    r += w * colour.x;
    g += w * colour.y;
    b += w * colour.z;
    T *= Real(1) - alpha;
  }

  // Premultiplied RGBA: alpha is 1 - the transmittance.
  INR_HD Vec4f estimate() const { return Vec4f{float(r), float(g), float(b), float(Real(1) - T)}; }
};

// The light factor of a sample whose light transmittance is lightT, with an unshadowed share
// `ambient` of the emission.
template <typename Real>
INR_HD Real marchLightFactor(float ambient, float lightT) {
  return ambient + (Real(1) - ambient) * lightT;
}

// The running mean over frames: the new estimate weighs 1 / (frameIndex + 1).
INR_HD Vec4f accumulateMean(Vec4f prev, Vec4f est, int frameIndex) {
  const float wgt = 1.f / float(frameIndex + 1);
  return Vec4f{prev.x + (est.x - prev.x) * wgt, prev.y + (est.y - prev.y) * wgt, prev.z + (est.z - prev.z) * wgt,
               prev.w + (est.w - prev.w) * wgt};
}

}  // namespace inr
