// Gradient shading (Render/Shading.h, Render/Shade.h): the lighting formula on hand-computable
// cases, and the CPU renderers: shading changes the volume's colours the way the normals say and
// nothing else (coverage and background untouched), costs one gradient query per lit ray, and the
// wavefront estimators converge to the shaded ray-marched reference.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/RayMarcher.h"
#include "Render/SceneChange.h"
#include "Render/Shading.h"
#include "TestSupport/BlobRenders.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

Vec3f grey(float v) { return Vec3f{v, v, v}; }

ShadingConstants shadingOf(float diffuse, float specular, float power) {
  ShadingConstants s;
  s.enabled = 1;
  s.diffuse = diffuse;
  s.specular = specular;
  s.specularPower = power;
  return s;
}

const Vec3f kUp{0.f, 0.f, 1.f};

// The gradient points to rising values, the normal against it: a field falling along +z has
// the normal +z.
TEST(Shading, LightAlongTheNormalGivesAmbientPlusDiffusePlusSpecular) {
  const ShadingConstants s = shadingOf(0.6f, 0.25f, 10.f);
  const SampleLight l = phongLight(s, Vec3f{0.f, 0.f, -3.f}, kUp, kUp);
  EXPECT_FLOAT_EQ(l.diffuse.x, 0.6f);
  EXPECT_FLOAT_EQ(l.specular.x, 0.25f);
  const Vec3f c = litColour(Vec3f{0.5f, 0.25f, 0.f}, 0.1f, l, 1.f);
  EXPECT_FLOAT_EQ(c.x, 0.5f * 0.7f + 0.25f);
  EXPECT_FLOAT_EQ(c.y, 0.25f * 0.7f + 0.25f);
  EXPECT_FLOAT_EQ(c.z, 0.25f);
}

TEST(Shading, BackFacingSamplesAreLitTwoSided) {
  // VTK's volume lighting is two-sided: the same light whichever way the gradient points.
  const ShadingConstants s = shadingOf(0.6f, 0.25f, 10.f);
  const SampleLight front = phongLight(s, Vec3f{0.f, 0.f, -3.f}, kUp, kUp);
  const SampleLight back = phongLight(s, Vec3f{0.f, 0.f, 3.f}, kUp, kUp);
  EXPECT_FLOAT_EQ(back.diffuse.x, front.diffuse.x);
  EXPECT_FLOAT_EQ(back.specular.x, front.specular.x);
}

TEST(Shading, ObliqueLightFollowsCosineAndMirrorDirection) {
  // Light 60 degrees off the normal, eye along the normal: N.L = 1/2, the mirror direction
  // R = 2 (N.L) N - L is 60 degrees off the eye too, R.E = 1/2.
  const ShadingConstants s = shadingOf(0.8f, 0.5f, 3.f);
  const float sin60 = std::sqrt(3.f) / 2.f;
  const SampleLight l = phongLight(s, Vec3f{0.f, 0.f, -1.f}, Vec3f{sin60, 0.f, 0.5f}, kUp);
  EXPECT_NEAR(l.diffuse.x, 0.8f * 0.5f, 1e-6f);
  EXPECT_NEAR(l.specular.x, 0.5f * 0.125f, 1e-6f);
  // The eye on the mirror side gets the full highlight.
  const SampleLight m = phongLight(s, Vec3f{0.f, 0.f, -1.f}, Vec3f{sin60, 0.f, 0.5f}, Vec3f{-sin60, 0.f, 0.5f});
  EXPECT_NEAR(m.specular.x, 0.5f, 1e-6f);
  // Grazing light: nothing but ambient.
  const SampleLight g = phongLight(s, Vec3f{0.f, 0.f, -1.f}, Vec3f{1.f, 0.f, 0.f}, kUp);
  EXPECT_EQ(g.diffuse.x, 0.f);
  EXPECT_EQ(g.specular.x, 0.f);
}

TEST(Shading, NoGradientMeansAmbientOnly) {
  // A flat region has no normal; VTK then takes the ambient term alone, and so do we (neither
  // lit like a surface facing the light nor left unlit).
  const ShadingConstants s = shadingOf(0.8f, 0.5f, 3.f);
  for (const Vec3f g : {Vec3f{0.f, 0.f, 0.f}, Vec3f{NAN, 0.f, 1.f}, Vec3f{INFINITY, 0.f, 0.f}}) {
    const SampleLight l = phongLight(s, g, kUp, kUp);
    EXPECT_EQ(l.diffuse.x, 0.f);
    EXPECT_EQ(l.specular.x, 0.f);
    const Vec3f c = litColour(Vec3f{0.5f, 1.f, 0.2f}, 0.3f, l, 1.f);
    EXPECT_FLOAT_EQ(c.x, 0.15f);
    EXPECT_FLOAT_EQ(c.y, 0.3f);
  }
  // A gradient too large to square still has a direction.
  const SampleLight big = phongLight(s, Vec3f{0.f, 0.f, -1e30f}, kUp, kUp);
  EXPECT_FLOAT_EQ(big.diffuse.x, 0.8f);
}

TEST(Shading, VisibilityDimsOnlyTheDirectLightAndColourIsClamped) {
  SampleLight l;
  l.diffuse = grey(0.7f);
  l.specular = grey(0.4f);
  const Vec3f shadowed = litColour(Vec3f{0.5f, 0.5f, 0.5f}, 0.2f, l, 0.f);
  EXPECT_FLOAT_EQ(shadowed.x, 0.1f);
  const Vec3f half = litColour(Vec3f{0.5f, 0.5f, 0.5f}, 0.2f, l, 0.5f);
  EXPECT_FLOAT_EQ(half.x, 0.5f * (0.2f + 0.35f) + 0.2f);
  const Vec3f bright = litColour(Vec3f{1.f, 0.f, 1.f}, 0.2f, l, 1.f);
  EXPECT_EQ(bright.x, 1.f);  // 1.3 clamped, as VTK clamps the lit colour
  EXPECT_FLOAT_EQ(bright.y, 0.4f);
}

TEST(Shading, NormalIsACovectorUnderTheActorTransform) {
  // Actor scale 2 in x: model gradient (1, 1, 0) is world gradient (0.5, 1, 0).
  RenderScene scene;
  scene.camera = Camera::framing(test::kCubeBox);
  scene.camera.modelToWorld = {2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const CameraView cam = scene.camera.view(16, 16);
  const Vec3f g = gradientToWorld(cam, Vec3f{1.f, 1.f, 0.f});
  EXPECT_NEAR(g.x, 0.5f, 1e-6f);
  EXPECT_NEAR(g.y, 1.f, 1e-6f);
  EXPECT_NEAR(g.z, 0.f, 1e-6f);
}

TEST(Shading, HeadlightLightsFromTheEye) {
  RenderScene scene;
  scene.camera = Camera::framing(test::kCubeBox);  // on +z, looking down -z
  scene.camera.parallelProjection = true;
  const CameraView cam = scene.camera.view(16, 16);
  ShadingConstants s = shadingOf(1.f, 0.f, 1.f);
  s.headlight = 1;
  // The given light direction (+x, grazing for a +z normal) is ignored with the headlight.
  const SampleLight l = sampleLightAt(cam, s, Vec3f{1.f, 0.f, 0.f}, Vec3f{0.f, 0.f, 0.5f}, Vec3f{0.f, 0.f, -2.f});
  EXPECT_NEAR(l.diffuse.x, 1.f, 1e-6f);
  s.headlight = 0;
  EXPECT_EQ(sampleLightAt(cam, s, Vec3f{1.f, 0.f, 0.f}, Vec3f{0.f, 0.f, 0.5f}, Vec3f{0.f, 0.f, -2.f}).diffuse.x, 0.f);
}

// VTK's light-list lighting (any lights but one white headlight: ParaView's light kit): each
// light's colour times intensity weighs its diffuse and specular terms, and the ambient term is
// the lights' ambient colours, not the sample's colour.
ShadingConstants lightListOf(std::initializer_list<ShadingLight> lights, Vec3f ambient) {
  ShadingConstants s = shadingOf(0.8f, 0.2f, 4.f);
  s.lightList = 1;
  for (const ShadingLight& l : lights) s.lights[s.numLights++] = l;
  s.lightAmbient = ambient;
  return s;
}

TEST(Shading, LightListSumsTheLightsAsVtksShaderDoes) {
  const float sin60 = std::sqrt(3.f) / 2.f;
  const ShadingLight white{kUp, grey(0.75f), grey(0.75f)};
  const ShadingLight red{Vec3f{sin60, 0.f, 0.5f}, Vec3f{0.5f, 0.f, 0.f}, Vec3f{0.5f, 0.f, 0.f}};
  const ShadingConstants s = lightListOf({white, red}, grey(0.1f));
  RenderScene scene;
  scene.camera = Camera::framing(test::kCubeBox);  // on +z: the eye is straight above the point
  scene.camera.parallelProjection = true;
  const CameraView cam = scene.camera.view(16, 16);
  // Normal +z; the model's light direction (+x) is ignored with a list.
  const SampleLight l = sampleLightAt(cam, s, Vec3f{1.f, 0.f, 0.f}, Vec3f{0.f, 0.f, 0.5f}, Vec3f{0.f, 0.f, -2.f});
  // white: N.L 1, R = N, R.E 1; red: N.L 1/2, R 60 degrees off the eye, R.E 1/2.
  EXPECT_NEAR(l.diffuse.x, 0.8f * (0.75f + 0.5f * 0.5f), 1e-6f);
  EXPECT_NEAR(l.diffuse.y, 0.8f * 0.75f, 1e-6f);
  EXPECT_NEAR(l.specular.x, 0.2f * (0.75f + 0.5f * std::pow(0.5f, 4.f)), 1e-6f);
  EXPECT_NEAR(l.specular.z, 0.2f * 0.75f, 1e-6f);
  const Vec3f c = litColour(Vec3f{0.5f, 0.25f, 0.f}, 0.3f, l, 1.f);
  // ambient 0.3 x the lights' ambient 0.1, whatever the colour
  EXPECT_NEAR(c.z, 0.03f + l.specular.z, 1e-6f);
  EXPECT_NEAR(c.y, 0.03f + 0.25f * l.diffuse.y + l.specular.y, 1e-6f);
  // No lights: the ambient term alone (VTK's shader with Shade on and every light off gives black).
  const SampleLight none = lightListLight(lightListOf({}, grey(0.f)), Vec3f{0.f, 0.f, -1.f}, kUp);
  const Vec3f dark = litColour(Vec3f{0.5f, 0.25f, 1.f}, 0.3f, none, 1.f);
  EXPECT_EQ(dark.x, 0.f);
  EXPECT_EQ(dark.z, 0.f);
}

TEST(Shading, LightListHighlightOfALightBehindTheNormalIsVtks) {
  // VTK's light-list branch flips the cosine for two-sided lighting but not the normal, so its
  // "mirror" direction for a light behind the surface is normalize(2 |N.L| N - L): a light from
  // below at 60 degrees off -N still gives a highlight to an eye above. (The one-light branch
  // mirrors with the signed cosine and gives none: Shading.ObliqueLight... above.)
  const float sin60 = std::sqrt(3.f) / 2.f;
  const Vec3f below{sin60, 0.f, -0.5f};
  const ShadingConstants s = lightListOf({ShadingLight{below, grey(1.f), grey(1.f)}}, grey(0.f));
  const SampleLight l = lightListLight(s, Vec3f{0.f, 0.f, -1.f}, kUp);
  EXPECT_NEAR(l.diffuse.x, 0.8f * 0.5f, 1e-6f);
  const float rDotE = 1.5f / std::sqrt(3.f);  // normalize((-sin60, 0, 1.5)).z
  EXPECT_NEAR(l.specular.x, 0.2f * std::pow(rDotE, 4.f), 1e-5f);
  EXPECT_EQ(phongLight(s, Vec3f{0.f, 0.f, -1.f}, below, kUp).specular.x, 0.f);
}

TEST(Shading, TheOneLightsColourTintsDiffuseAndSpecular) {
  // VTK's default lighting multiplies both terms by the headlight's colour, not the ambient one.
  ShadingConstants s = shadingOf(0.6f, 0.25f, 10.f);
  s.oneLightDiffuse = Vec3f{1.f, 0.5f, 0.f};
  s.oneLightSpecular = Vec3f{0.f, 1.f, 1.f};
  const SampleLight l = phongLight(s, Vec3f{0.f, 0.f, -3.f}, kUp, kUp);
  EXPECT_FLOAT_EQ(l.diffuse.y, 0.3f);
  EXPECT_EQ(l.diffuse.z, 0.f);
  EXPECT_EQ(l.specular.x, 0.f);
  EXPECT_FLOAT_EQ(l.specular.z, 0.25f);
  EXPECT_FLOAT_EQ(litColour(Vec3f{0.5f, 0.5f, 0.5f}, 0.2f, l, 1.f).z, 0.1f + 0.25f);
}

TEST(Shading, CameraLightsTurnWithTheCamera) {
  Camera camera = Camera::framing(test::kCubeBox);
  ShadingOptions o;
  o.enabled = o.lightList = true;
  SceneLight towardsViewer;  // camera coordinates: +z points back at the viewer
  towardsViewer.cameraLight = true;
  towardsViewer.toLight = {0.0, 0.0, 2.0};
  SceneLight right = towardsViewer;
  right.toLight = {1.0, 0.0, 0.0};
  SceneLight world;
  world.toLight = {0.0, 3.0, 4.0};
  world.ambient = {0.1f, 0.2f, 0.3f};
  SceneLight above = towardsViewer;
  above.toLight = {0.0, 5.0, 0.0};
  o.lights = {towardsViewer, right, world, above};
  // Absolute: the framing camera looks down -z with +y up, so camera x is world +x and y is +y.
  {
    const ShadingConstants s = shadingConstants(o, camera.view(8, 8));
    EXPECT_NEAR(s.lights[1].toLight.x, 1.f, 1e-6f);
    EXPECT_NEAR(s.lights[3].toLight.y, 1.f, 1e-6f);
    EXPECT_NEAR(s.lights[0].toLight.z, 1.f, 1e-6f);
  }
  for (const std::array<double, 3>& eye : {std::array<double, 3>{0.0, 0.0, 4.0}, std::array<double, 3>{4.0, 0.0, 0.0}}) {
    camera.position = eye;
    const CameraView cam = camera.view(8, 8);
    const ShadingConstants s = shadingConstants(o, cam);
    ASSERT_EQ(s.numLights, 4);
    for (const auto& [got, want] : {std::pair<Vec3f, Vec3f>{s.lights[0].toLight, cam.forward * -1.f},
                                    std::pair<Vec3f, Vec3f>{s.lights[1].toLight, cam.right},
                                    std::pair<Vec3f, Vec3f>{s.lights[3].toLight, cam.up},
                                    std::pair<Vec3f, Vec3f>{s.lights[2].toLight, Vec3f{0.f, 0.6f, 0.8f}}}) {
      EXPECT_NEAR(got.x, want.x, 1e-6f);
      EXPECT_NEAR(got.y, want.y, 1e-6f);
      EXPECT_NEAR(got.z, want.z, 1e-6f);
    }
    EXPECT_FLOAT_EQ(s.lightAmbient.z, 0.3f);
  }
}

TEST(Shading, LightListsOutOfBoundsAreRefusedByName) {
  const auto message = [](const RenderScene& scene) -> std::string {
    try {
      validateLighting(scene);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  RenderScene scene;
  scene.shading.enabled = scene.shading.lightList = true;
  EXPECT_EQ(message(scene), "");  // no lights: valid (ambient only)
  scene.shading.lights.assign(kMaxShadingLights, SceneLight{});
  EXPECT_EQ(message(scene), "");
  scene.shading.lights.push_back(SceneLight{});
  EXPECT_NE(message(scene).find("at most 8 lights"), std::string::npos);
  scene.shading.lights.assign(2, SceneLight{});
  scene.shading.lights[1].toLight = {0.0, 0.0, 0.0};
  EXPECT_NE(message(scene).find("light 1's direction"), std::string::npos);
  scene.shading.lights[1].toLight = {0.0, 1.0, 0.0};
  scene.shading.lights[0].diffuse = {1.f, -0.5f, 1.f};
  EXPECT_NE(message(scene).find("light 0's colours"), std::string::npos);
  scene.shading.lights[0].diffuse = {1.f, 1e30f, 1.f};  // would overflow once summed
  EXPECT_NE(message(scene).find("light 0's colours"), std::string::npos);
  scene.shading.lights[0].diffuse = {1.f, 1.f, 1.f};
  scene.shadows = true;
  EXPECT_NE(message(scene).find("does not combine with shadows"), std::string::npos);
}

TEST(Shading, OptionsOutOfRangeAreRefusedByName) {
  const auto message = [](ShadingOptions o) -> std::string {
    try {
      o.validate();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  ShadingOptions o;
  EXPECT_EQ(message(o), "");
  o.diffuse = -0.1f;
  EXPECT_NE(message(o).find("diffuse"), std::string::npos);
  o = ShadingOptions{};
  o.specular = NAN;
  EXPECT_NE(message(o).find("specular"), std::string::npos);
  o = ShadingOptions{};
  o.specularPower = 200.f;
  EXPECT_NE(message(o).find("specular power"), std::string::npos);
}

TEST(SceneChange, ShadingOptionsRestartAccumulation) {
  RenderScene a;
  RenderScene b = a;
  b.shading.enabled = true;
  EXPECT_TRUE(diffScenes(&a, b).light);
  a = b;
  b.shading.specular = 0.7f;
  EXPECT_TRUE(diffScenes(&a, b).light);
  b = a;
  b.ambient = 0.4f;  // shading's ambient, even without shadows
  EXPECT_TRUE(diffScenes(&a, b).light);
  // A headlight does not use the direction: ParaView's light following the camera stays a
  // camera-only change.
  a.shading.headlight = b.shading.headlight = true;
  b = a;
  b.toLight = {0.3, 0.4, 0.8};
  EXPECT_FALSE(diffScenes(&a, b).light);
  a.shading.headlight = b.shading.headlight = false;
  EXPECT_TRUE(diffScenes(&a, b).light);
  // A list of lights: the scene's direction is unused; the lights are the change. Camera lights
  // turning with the camera are a camera change only.
  a.shading.lightList = b.shading.lightList = true;
  a.shading.lights = b.shading.lights = {SceneLight{{0.0, 0.0, 1.0}, true}};
  EXPECT_FALSE(diffScenes(&a, b).light);
  b.camera.position = {1.0, 2.0, 3.0};
  EXPECT_FALSE(diffScenes(&a, b).light);
  EXPECT_TRUE(diffScenes(&a, b).camera);
  b.shading.lights[0].diffuse = {0.5f, 0.5f, 0.5f};
  EXPECT_TRUE(diffScenes(&a, b).light);
  b.shading.lights = a.shading.lights;
  b.shading.lights[0].toLight = {0.0, 1.0, 1.0};
  EXPECT_TRUE(diffScenes(&a, b).light);
  b.shading.lights = a.shading.lights;
  b.shading.lights[0].cameraLight = false;
  EXPECT_TRUE(diffScenes(&a, b).light);
  b.shading.lights = a.shading.lights;
  b.shading.oneLightDiffuse = {1.f, 0.f, 0.f};
  EXPECT_TRUE(diffScenes(&a, b).light);
}

// ---- Renders of the Gaussian blob (TestFields.h: spherical level sets, analytic gradient).

constexpr float kAmbient = 0.2f, kDiffuse = 0.8f;

// Orthographic view down -z, an opaque shell around the blob's 0.45 level (radius ~0.54).
test::SceneSetup blobScene(int size, bool shade) {
  test::SceneSetup s = test::orthographicCubeView(size, 11);
  TransferFunction tf;
  tf.color = {{0.0, 0.9, 0.6, 0.3}, {1.0, 0.9, 0.6, 0.3}};
  tf.opacity = {{0.0, 0.0}, {0.3, 0.0}, {0.6, 1.0}, {1.0, 1.0}};
  tf.unitDistance = 0.05;
  s.scene.transferFunction = tf;
  s.scene.background = {0.1f, 0.2f, 0.3f};
  s.scene.ambient = kAmbient;
  s.scene.shading.enabled = shade;
  s.scene.shading.diffuse = kDiffuse;
  s.scene.shading.specular = 0.f;
  s.scene.shading.headlight = true;
  return s;
}

using test::BlobRender;

BlobRender renderBlob(const test::SceneSetup& setup, const TrackingOptions& options, int frames) {
  return test::trackedBlob(setup, options, frames);
}

// Distance of pixel i's centre from the blob's centre on the image plane (world units).
double pixelRadius(const test::SceneSetup& s, int i) {
  const int w = s.settings.width;
  const double scale = 2.0 * s.scene.camera.parallelScale / w;
  const double x = (i % w + 0.5 - 0.5 * w) * scale - test::kBlobCentre[0];
  const double y = (0.5 * w - (i / w + 0.5)) * scale - test::kBlobCentre[1];
  return std::sqrt(x * x + y * y);
}

TEST(ShadedRender, ShadingDimsTheRimAndLeavesCoverageAndBackground) {
  const int size = 40, frames = 24;
  const test::SceneSetup flat = blobScene(size, false), lit = blobScene(size, true);
  const BlobRender a = renderBlob(flat, TrackingOptions{}, frames);
  const BlobRender b = renderBlob(lit, TrackingOptions{}, frames);
  double centre = 0, centreN = 0, rim = 0, rimN = 0;
  std::size_t covered = 0;
  for (int i = 0; i < size * size; ++i) {
    // Delta tracking's collisions do not depend on shading (it draws nothing): same coverage.
    ASSERT_EQ(a.premultiplied.data[4 * i + 3], b.premultiplied.data[4 * i + 3]) << "pixel " << i;
    const float alpha = a.premultiplied.data[4 * i + 3];
    if (alpha == 0.f) {  // background: untouched
      for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image.data[4 * i + c], b.image.data[4 * i + c]);
      continue;
    }
    ++covered;
    // Each hit's colour is scaled by ambient + diffuse |N.L| (no specular): the mean factor lies
    // in [ambient, ambient + diffuse].
    const double ratio = b.premultiplied.data[4 * i] / a.premultiplied.data[4 * i];
    ASSERT_GE(ratio, kAmbient - 1e-5);
    ASSERT_LE(ratio, kAmbient + kDiffuse + 1e-5);
    const double r = pixelRadius(lit, i);
    if (r < 0.1) centre += ratio, ++centreN;
    if (r > 0.42 && r < 0.5) rim += ratio, ++rimN;
  }
  ASSERT_GT(covered, std::size_t(size * size / 8));
  ASSERT_GT(centreN, 0);
  ASSERT_GT(rimN, 0);
  // Facing the headlight: |N.L| near 1; at the rim the normals turn away.
  EXPECT_GT(centre / centreN, 0.9);
  EXPECT_LT(rim / rimN, 0.8);
  // One value + gradient query per hit, none without shading.
  EXPECT_EQ(a.total.shadingQueries, 0u);
  EXPECT_EQ(a.gradientPoints, 0u);
  EXPECT_EQ(b.gradientPoints, b.total.shadingQueries);
  double hits = 0;
  for (int i = 0; i < size * size; ++i) hits += a.premultiplied.data[4 * i + 3] * frames;
  EXPECT_NEAR(double(b.total.shadingQueries), hits, 0.5);
  EXPECT_EQ(a.total.queries, b.total.queries);
}

// A directional light with a highlight, so every term of the model is in the picture.
test::SceneSetup highlightScene(bool shadows) {
  test::SceneSetup s = blobScene(32, true);
  s.scene.shading.headlight = false;
  s.scene.shading.specular = 0.4f;
  s.scene.shading.specularPower = 8.f;
  s.scene.toLight = {0.5, 0.6, 0.8};
  s.scene.shadows = shadows;
  // A softer shell than blobScene's, so shadows fall across it rather than only behind it.
  s.scene.transferFunction.unitDistance = 0.2;
  return s;
}

void expectConvergesToMarcher(const test::SceneSetup& setup, TrackingOptions options, int frames, double minPsnr) {
  const BlobRender tracked = renderBlob(setup, options, frames);
  const ImageRGBA reference = test::marchedBlob(setup).image;
  test::SceneSetup flat = setup;
  flat.scene.shading.enabled = false;
  const ImageRGBA unshaded = test::marchedBlob(flat).image;
  const double psnr = test::psnrOverCoverage(tracked.image, reference, tracked.premultiplied);
  const double flatPsnr = test::psnrOverCoverage(unshaded, reference, tracked.premultiplied);
  std::printf("shaded %s (%d frames%s) vs shaded ray marching: %.2f dB over the volume; unshaded marcher %.2f dB\n",
              primaryEstimatorName(options.estimator), frames, setup.scene.shadows ? ", shadows" : "", psnr, flatPsnr);
  EXPECT_GE(psnr, minPsnr);
  // The comparison can fail: the unshaded picture is far from the shaded one, and so is the
  // shaded one without its shadows.
  EXPECT_LT(flatPsnr, minPsnr - 8.0);
  if (setup.scene.shadows) {
    test::SceneSetup unshadowed = setup;
    unshadowed.scene.shadows = false;
    const double unshadowedPsnr = test::psnrOverCoverage(test::marchedBlob(unshadowed).image, reference, tracked.premultiplied);
    std::printf("  shaded marcher without shadows: %.2f dB\n", unshadowedPsnr);
    EXPECT_LT(unshadowedPsnr, minPsnr - 8.0);
  }
  EXPECT_EQ(test::nonFinitePixels(tracked.image), 0u);
}

TEST(ShadedRender, DeltaTrackingConvergesToShadedRayMarching) {
  expectConvergesToMarcher(highlightScene(false), TrackingOptions{}, 400, 40.0);
}

TEST(ShadedRender, RatioTrackingConvergesToShadedRayMarching) {
  // Ratio tracking keeps one picked point per ray when shading (RatioTracking.h).
  expectConvergesToMarcher(highlightScene(false), test::ratioTracking(4.0), 100, 40.0);
}

TEST(ShadedRender, ShadowsMultiplyTheDirectLight) {
  expectConvergesToMarcher(highlightScene(true), test::ratioTracking(4.0), 150, 34.0);
}

TEST(ShadedRender, LightListReachesEveryRenderer) {
  // One light with a white ambient colour and no direct terms, ambient 1: every lit colour is
  // white whatever the transfer function's colour (the light list's ambient term, which the
  // one-light model cannot give), so each renderer's premultiplied colour equals its alpha.
  test::SceneSetup setup = blobScene(24, true);
  setup.scene.ambient = 1.f;
  setup.scene.shading.headlight = false;
  setup.scene.shading.lightList = true;
  SceneLight ambientOnly;
  ambientOnly.ambient = {1.f, 1.f, 1.f};
  ambientOnly.diffuse = ambientOnly.specular = {0.f, 0.f, 0.f};
  setup.scene.shading.lights = {ambientOnly};
  test::FunctionField f(test::blobField, "blob", test::blobGradient);
  RayMarchRenderer marcher(f, test::kCubeBox, RayMarchOptions{});
  test::renderFrames(marcher, setup.settings, setup.scene, 1);
  const std::vector<std::pair<const char*, ImageRGBA>> images = {
      {"delta tracking", renderBlob(setup, TrackingOptions{}, 4).premultiplied},
      {"ratio tracking", renderBlob(setup, test::ratioTracking(4.0), 4).premultiplied},
      {"ray marching", marcher.premultipliedImage()}};
  for (const auto& [name, image] : images) {
    std::size_t covered = 0;
    for (int i = 0; i < 24 * 24; ++i) {
      const float alpha = image.data[4 * i + 3];
      if (alpha > 0.f) ++covered;
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(image.data[4 * i + c], alpha, 2e-5f) << name << ", pixel " << i;
    }
    EXPECT_GT(covered, std::size_t(24 * 24 / 8)) << name;
  }
  // The TF colour (0.9, 0.6, 0.3) would show without the list: the check can fail.
  setup.scene.shading.lightList = false;
  const ImageRGBA unlisted = renderBlob(setup, TrackingOptions{}, 4).premultiplied;
  bool differs = false;
  for (int i = 0; i < 24 * 24; ++i) differs |= std::fabs(unlisted.data[4 * i + 2] - unlisted.data[4 * i + 3]) > 0.05f;
  EXPECT_TRUE(differs);
}

TEST(ShadedRender, NaiveTrackerShadesTheSame) {
  // Same streams, same lighting code: the unbatched baseline reproduces the wavefront image.
  const test::SceneSetup setup = highlightScene(true);
  const test::FunctionField f(test::blobField, "blob", test::blobGradient);
  EXPECT_TRUE(test::naiveImageEqualsWavefront(f, setup, test::cubeMacrocells(8, 2)));
}

TEST(ShadedRender, FieldWithoutGradientIsRefused) {
  test::expectRefusedWithoutGradient(blobScene(8, true), "shading");
}

}  // namespace
}  // namespace inr
