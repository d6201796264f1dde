#pragma once
// Gradient shading, written once for every backend and both methods (delta / ratio tracking and
// the ray marcher): the transfer function's colour at a sample is lit by the light as ParaView's
// Volume representation lights it with Shade on (vtkVolumeProperty's Ambient, Diffuse, Specular,
// SpecularPower; the lighting of VTK's GPU ray-cast mapper):
//     lit = ambient * c + V * (diffuse * |N.L| * c + specular * max(0, R.E)^power),
// clamped to [0, 1] per channel as VTK clamps its lit colour. N is the unit normal of the scalar
// field (minus the normalised gradient: the outward side of a blob whose values rise inwards),
// L the unit vector towards the light, E the unit vector towards the eye, R = 2 (N.L) N - L the
// mirror direction of the light (VTK's Phong term; the half vector of Blinn-Phong gives other
// highlights), V the light's visibility (1 without shadows). Lighting is two-sided as VTK's
// default (the renderer's TwoSidedLighting): a sample lit from behind its normal takes |N.L|; the
// mirror direction is the same for N and -N. Where the gradient vanishes there is no normal and
// VTK takes the ambient term alone: so do we (a flat region neither faces nor turns from the
// light).
//
// That is VTK's "default lighting" for one headlight of intensity 1 (here also the one direction
// of RenderScene::toLight), with the light's colour multiplying the diffuse and specular terms
// (white by default). With any other set of lights (ParaView's light kit, several lights, coloured
// or dimmed ones) VTK's shader takes its light-list branch instead, and so do we when the scene
// carries a list of lights (ShadingOptions::lights):
//     lit = ambient * sum_i a_i + sum_i (diffuse * f_i * d_i * c + specular * max(0, R_i.E)^p * s_i),
// where a_i, d_i, s_i are light i's ambient, diffuse and specular colours times its intensity,
// f_i = |N.L_i| (two-sided) and R_i = normalize(2 f_i N - L_i) (the two-sided flip applied to the
// cosine only, as VTK's shader has it: for a light behind the normal this is not the mirror
// direction). The ambient term is not multiplied by the colour there, and VTK's lights have black
// ambient colours by default: ParaView's light kit gives no ambient term at all.
//
// One Ambient serves shading and shadows (as vtkVolumeProperty has one): the share of the colour
// every sample gets whatever its orientation and visibility. With shadows and without shading the
// light's factor is (1 - ambient) * V, which is this model for a normal facing the light with
// diffuse = 1 - ambient and no specular term (Finalize.h, RayMarch.h).
//
// The network's gradient is d value / d model coordinate (the evaluators' forward mode through the
// domain mapping). Under an actor transform the normal is a covector: its world form is the
// transposed model-from-world map applied to it, and lighting happens in world space, where the
// light and the eye are.
#include "Render/CameraView.h"
#include "Render/RenderMath.h"

namespace inr {

// The most lights a scene's list may hold (bounds the per-frame constants and the per-sample
// loop; ParaView's light kit has five, with its headlight).
constexpr int kMaxShadingLights = 8;

// One light of a list, in world space: the unit direction towards it and its colours times its
// intensity.
struct ShadingLight {
  Vec3f toLight{0.f, 0.f, 1.f};
  Vec3f diffuse{1.f, 1.f, 1.f}, specular{1.f, 1.f, 1.f};
};

// The shading options as the stages read them (RenderScene::shading on the host).
struct ShadingConstants {
  int enabled = 0;
  float diffuse = 0.8f, specular = 0.2f, specularPower = 10.f;
  int headlight = 0;  // the light sits at the eye (VTK's headlight): L = E at every sample
  Vec3f oneLightDiffuse{1.f, 1.f, 1.f}, oneLightSpecular{1.f, 1.f, 1.f};  // the one light's colours
  // VTK's light-list lighting over lights[0, numLights) (0 lights: only the ambient term), in
  // place of the one light; lightAmbient is the sum of the lights' ambient colours.
  int lightList = 0;
  int numLights = 0;
  Vec3f lightAmbient{0.f, 0.f, 0.f};
  ShadingLight lights[kMaxShadingLights];
};

// The lights' factors at a sample: lit = A + V (diffuse * c + specular), per channel, where the
// ambient part A is ambient * c with the one light and ambient * lightAmbient with a list.
struct SampleLight {
  Vec3f diffuse{0.f, 0.f, 0.f}, specular{0.f, 0.f, 0.f};
  int ambientFromLights = 0;
  Vec3f lightAmbient{0.f, 0.f, 0.f};
};

INR_HD Vec3f timesEach(Vec3f a, Vec3f b) { return Vec3f{a.x * b.x, a.y * b.y, a.z * b.z}; }

// The outward unit normal for gradient g (any length, any sign convention of the field), or
// false where there is none (a zero or non-finite gradient: VTK then takes the ambient term alone).
INR_HD bool unitNormal(Vec3f g, Vec3f& n) {
  float len = length(g);
  if (!isFiniteValue(len)) {  // components beyond float's square root: scale them down first
    const float big = maxf(fabsf(g.x), maxf(fabsf(g.y), fabsf(g.z)));
    if (!isFiniteValue(big)) return false;
    g = g * (1.f / big);
    len = length(g);
  }
  if (!(len > 0.f)) return false;
  n = g * (-1.f / len);
  return true;
}

// The Phong factors of VTK's volume shading for gradient g (any length, any sign convention of
// the field: the lighting is two-sided), unit toLight and toEye.
INR_HD SampleLight phongLight(const ShadingConstants& s, Vec3f g, Vec3f toLight, Vec3f toEye) {
  SampleLight out;
  Vec3f n;
  if (!unitNormal(g, n)) return out;  // no normal: ambient only (VTK)
  const float nDotL = dot(n, toLight);
  const float facing = fabsf(nDotL);
  if (!(facing > 0.f)) return out;
  out.diffuse = s.oneLightDiffuse * (s.diffuse * facing);
  const Vec3f r = n * (2.f * nDotL) - toLight;
  const float rDotE = maxf(0.f, dot(r, toEye));
  // pow(0, 0) is 1 in VTK's shader too: a power of 0 makes the highlight uniform.
  out.specular = s.oneLightSpecular * (s.specular * powf(rDotE, s.specularPower));
  return out;
}

// VTK's light-list lighting (the header's second formula) for gradient g, every light of s's list
// in world space, unit toEye.
INR_HD SampleLight lightListLight(const ShadingConstants& s, Vec3f g, Vec3f toEye) {
  SampleLight out;
  out.ambientFromLights = 1;
  out.lightAmbient = s.lightAmbient;
  Vec3f n;
  if (!unitNormal(g, n)) return out;
  for (int i = 0; i < s.numLights && i < kMaxShadingLights; ++i) {
    const ShadingLight& light = s.lights[i];
    const float facing = fabsf(dot(n, light.toLight));
    if (!(facing > 0.f)) continue;
    out.diffuse = out.diffuse + light.diffuse * (s.diffuse * facing);
    const float rDotE = dot(normalize(n * (2.f * facing) - light.toLight), toEye);
    if (rDotE > 0.f) out.specular = out.specular + light.specular * (s.specular * powf(rDotE, s.specularPower));
  }
  return out;
}

// The lit colour of TF colour c with the direct light's visibility V, clamped as VTK clamps.
INR_HD Vec3f litColour(Vec3f c, float ambient, const SampleLight& light, float visibility) {
  const Vec3f a = light.ambientFromLights ? light.lightAmbient * ambient : c * ambient;
  const Vec3f lit = a + (timesEach(light.diffuse, c) + light.specular) * visibility;
  return Vec3f{clampf(lit.x, 0.f, 1.f), clampf(lit.y, 0.f, 1.f), clampf(lit.z, 0.f, 1.f)};
}

// The world-space form of a model-space gradient (a covector): M^T g for world-to-model map M.
INR_HD Vec3f gradientToWorld(const CameraView& cam, Vec3f g) {
  if (!cam.transformed) return g;
  const Affine3f& m = cam.modelFromWorld;
  return m.row0 * g.x + m.row1 * g.y + m.row2 * g.z;
}

// The light at model point p with model-space gradient g, for the camera `cam` and the light
// towards unit model-space direction toLightModel (ignored with a headlight or a list of lights,
// whose directions are in world space): the eye direction is
// from p to the camera's position, with parallel projection too, as VTK's shader takes it (its
// eye is the camera position whatever the projection), so it needs no per-ray state.
INR_HD SampleLight sampleLightAt(const CameraView& cam, const ShadingConstants& s, Vec3f toLightModel, Vec3f p,
                                 Vec3f g) {
  const Vec3f pWorld = modelToWorld(cam, p);
  const Vec3f fromP = cam.position - pWorld;
  // (a point at the eye itself: the view direction)
  const Vec3f toEye = dot(fromP, fromP) > 0.f ? normalize(fromP) : cam.forward * -1.f;
  if (s.lightList) return lightListLight(s, gradientToWorld(cam, g), toEye);
  Vec3f toLight = toLightModel;
  if (s.headlight)
    toLight = toEye;
  else if (cam.transformed)
    toLight = normalize(applyLinear(cam.worldFromModel, toLightModel));
  return phongLight(s, gradientToWorld(cam, g), toLight, toEye);
}

}  // namespace inr
