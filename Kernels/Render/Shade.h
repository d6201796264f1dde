#pragma once
// The shading stage (gradient lighting, Shading.h), after the primary and shadow loops: every ray
// whose frame estimate took a colour (kRayHit: delta tracking's real collision, or ratio
// tracking's picked point) asks the evaluator for the value and gradient at that point, one
// query per ray, in a batch of its own; the colour is then lit there with the shadow ray's
// visibility. Finalisation then leaves the colour as it is (Finalize.h).
#include "Evaluator/FieldEvaluator.h"
#include "Render/Finalize.h"
#include "Render/RayState.h"

namespace inr {

// Whether ray i's colour is to be lit this frame.
INR_HD bool needsShading(const FrameConstants& fc, const RayStateView& rs, int i) {
  return fc.shading.enabled && (rs.flags[i] & kRayHit);
}

// The point whose gradient lights ray i.
INR_HD QueryPoint shadingQuery(const FrameConstants& fc, const RayStateView& rs, int i) {
  const Vec3f p = primaryHitPoint(rs, i);
  return QueryPoint{p.x, p.y, p.z, fc.time};
}

// Lights ray i's colour with the gradient the evaluator returned at shadingQuery (a non-finite
// gradient gives no normal: ambient only). The colour is weighted by the ray's hitWeight (1 for
// delta tracking; the picked point's signed weight for ratio tracking) after lighting, as VTK
// lights and clamps a sample's colour before compositing it.
INR_HD void shadeRay(const FrameConstants& fc, const RayStateView& rs, int i, Vec3f gradient) {
  const Vec4f c = rs.radiance[i];
  const Vec3f p = primaryHitPoint(rs, i);
  const SampleLight light = sampleLightAt(fc.camera, fc.shading, fc.toLight, p, gradient);
  const Vec3f lit = litColour(Vec3f{c.x, c.y, c.z}, fc.ambient, light, fc.shadows ? rs.visibility[i] : 1.f);
  const float w = rs.hitWeight[i];
  rs.radiance[i] = Vec4f{lit.x * w, lit.y * w, lit.z * w, c.w};
}

}  // namespace inr
