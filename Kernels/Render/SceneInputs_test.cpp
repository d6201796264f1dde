#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>

#include "Render/SceneChange.h"
#include "Render/SceneInputs.h"

namespace inr {
namespace {

TEST(TransferFunctionJson, ReadsParaViewExportAsIs) {
  const char* text = R"([{"ColorSpace": "RGB", "Name": "mine", "NanColor": [1, 0, 0],
    "RGBPoints": [0.0, 0.0, 0.0, 1.0,  2.0, 1.0, 1.0, 1.0,  4.0, 1.0, 0.0, 0.0],
    "Points": [0.0, 0.0, 0.5, 0.0,  4.0, 0.8, 0.5, 0.0]}])";
  const TransferFunction tf = TransferFunction::fromParaViewJson(text, "test.json");
  ASSERT_EQ(tf.color.size(), 3u);
  ASSERT_EQ(tf.opacity.size(), 2u);
  EXPECT_EQ(tf.color[1].x, 2.0);
  EXPECT_EQ(tf.color[2].r, 1.0);
  EXPECT_EQ(tf.opacity[1].alpha, 0.8);
  EXPECT_DOUBLE_EQ(tf.opacityAt(2.0), 0.4);
  EXPECT_DOUBLE_EQ(tf.opacityAt(-5.0), 0.0);  // clamped below
  EXPECT_DOUBLE_EQ(tf.opacityAt(9.0), 0.8);   // clamped above
  const auto c = tf.colorAt(1.0);
  EXPECT_DOUBLE_EQ(c[0], 0.5);
  EXPECT_DOUBLE_EQ(c[2], 1.0);
  EXPECT_TRUE(tf.colorSpaceWarning().empty());
}

TEST(TransferFunctionJson, MissingPointsGivesRampAndErrorsAreClear) {
  const TransferFunction tf = TransferFunction::fromParaViewJson(
      R"({"ColorSpace": "Diverging", "RGBPoints": [10, 0, 0, 0, 20, 1, 1, 1]})", "x");
  EXPECT_DOUBLE_EQ(tf.opacityAt(15.0), 0.5);
  EXPECT_FALSE(tf.colorSpaceWarning().empty());
  EXPECT_THROW(TransferFunction::fromParaViewJson("{", "bad.json"), std::runtime_error);
  EXPECT_THROW(TransferFunction::fromParaViewJson(R"({"RGBPoints": [1, 2, 3]})", "x"), std::runtime_error);
  EXPECT_THROW(TransferFunction::fromParaViewJson(R"({"Points": [0, 0, 0.5, 0]})", "x"), std::runtime_error);
  EXPECT_THROW(TransferFunction::fromParaViewJson(
                   R"({"RGBPoints": [0, 0, 0, 0], "Points": [0, 1.5, 0.5, 0]})", "x"),
               std::runtime_error);
  try {
    TransferFunction::fromParaViewJsonFile("/nonexistent/tf.json");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/tf.json"), std::string::npos);
  }
}

TEST(TransferFunctionJson, MidpointAndSharpnessFollowVtk) {
  TransferFunction tf;
  tf.color = {{0, 1, 1, 1}, {1, 1, 1, 1}};
  tf.opacity = {{0.0, 0.0, 0.25, 0.0}, {1.0, 1.0}};
  EXPECT_NEAR(tf.opacityAt(0.25), 0.5, 1e-12);  // midpoint: half value at 1/4 of the segment
  tf.opacity = {{0.0, 0.0, 0.5, 1.0}, {1.0, 1.0}};
  EXPECT_EQ(tf.opacityAt(0.49), 0.0);  // sharpness 1: a step at the midpoint
  EXPECT_EQ(tf.opacityAt(0.51), 1.0);
  tf.opacity = {{0.0, 0.0, 0.5, 0.5}, {1.0, 1.0}};
  EXPECT_NEAR(tf.opacityAt(0.5), 0.5, 1e-12);  // symmetric curve passes the midpoint
  EXPECT_LT(tf.opacityAt(0.25), 0.25);          // flatter than linear near the ends
}

TEST(TransferFunctionTable, OpticalModelMatchesVtk) {
  TransferFunction tf;
  tf.color = {{0, 0, 0, 1}, {1, 1, 0, 0}};
  tf.opacity = {{0, 0.0}, {1, 0.5}};
  tf.unitDistance = 0.25;
  const TransferFunctionTable table(tf, 1025);  // knots fall on entries
  const auto v = table.view();
  const Vec4f c = lookupTransferFunction(v, 0.5f);
  EXPECT_NEAR(c.x, 0.5f, 1e-6);
  EXPECT_NEAR(c.z, 0.5f, 1e-6);
  EXPECT_NEAR(c.w, 0.25f, 1e-6);
  // sigma = -ln(1 - alpha) / u: a slab of thickness u has opacity alpha.
  EXPECT_NEAR(extinctionAt(v, 1.f), -std::log(0.5) / 0.25, 1e-5);
  EXPECT_NEAR(1.0 - std::exp(-extinctionAt(v, 0.5f) * 0.25), 0.25, 1e-6);
  EXPECT_NEAR(extinctionAt(v, 7.f), extinctionAt(v, 1.f), 1e-6);  // clamped outside the range
  EXPECT_NEAR(extinctionAt(v, -3.f), 0.f, 1e-7);
  EXPECT_EQ(extinctionAt(v, NAN), 0.f);
  // Opacity 1 stays finite.
  tf.opacity = {{0, 1.0}, {1, 1.0}};
  const TransferFunctionTable opaque(tf);
  EXPECT_TRUE(std::isfinite(extinctionAt(opaque.view(), 0.5f)));
}

TEST(TransferFunctionTable, RangeMaxBoundsAndIsTight) {
  TransferFunction tf;
  tf.color = {{0, 1, 1, 1}, {1, 1, 1, 1}};
  tf.opacity = {{0, 0.0}, {0.3, 0.9}, {0.35, 0.05}, {0.7, 0.4}, {1.0, 0.0}};
  tf.unitDistance = 1.0;
  const TransferFunctionTable table(tf, 256);
  const auto v = table.view();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.2f, 1.2f);
  for (int k = 0; k < 2000; ++k) {
    float a = u(rng), b = u(rng);
    if (a > b) std::swap(a, b);
    float dense = 0.f;
    for (int j = 0; j <= 400; ++j) dense = std::max(dense, extinctionAt(v, a + (b - a) * j / 400.f));
    const float bound = maxExtinctionOver(v, a, b);
    ASSERT_GE(bound, dense * (1 - 1e-6f)) << a << " " << b;
    // Tight up to one table entry on each side.
    const float h = 1.f / 255.f;
    float wider = 0.f;  // the TF's maximum over [a - h, b + h]: at the table entries inside it
    for (int e = 0; e < 256; ++e) {
      const float x = e * h;
      if (x >= a - h && x <= b + h) wider = std::max(wider, extinctionAt(v, x));
    }
    wider = std::max({wider, extinctionAt(v, a - h), extinctionAt(v, b + h)});
    ASSERT_LE(bound, wider * (1 + 1e-5f) + 1e-6f) << a << " " << b;
  }
  EXPECT_EQ(maxExtinctionOver(v, 0.5f, 0.4f), 0.f);  // empty range
}

TEST(Camera, FollowsVtkConventions) {
  const Box3f box{{-1, -2, -3}, {1, 2, 3}};
  const Camera cam = Camera::framing(box);
  EXPECT_DOUBLE_EQ(cam.focalPoint[2], 0.0);
  const double r = std::sqrt(1.0 + 4.0 + 9.0);
  EXPECT_NEAR(cam.position[2], r / std::sin(15.0 * M_PI / 180.0), 1e-9);
  const CameraView v = cam.view(64, 32);
  Vec3f o, d;
  cameraRay(v, 32, 16, 0.f, 0.f, o, d);  // the image centre (top-left corner of pixel 32,16)
  EXPECT_NEAR(d.z, -1.f, 1e-6);
  cameraRay(v, 32, 0, 0.f, 0.f, o, d);  // top edge: half the vertical view angle upwards
  EXPECT_NEAR(std::atan2(d.y, -d.z) * 180.0 / M_PI, 15.0, 1e-4);
  cameraRay(v, 0, 16, 0.f, 0.f, o, d);  // left edge: -x, wider by the aspect ratio
  EXPECT_NEAR(d.x / -d.z, -2.0 * std::tan(15.0 * M_PI / 180.0), 1e-5);

  Camera par = cam;
  par.parallelProjection = true;
  par.parallelScale = 2.0;
  const CameraView pv = par.view(10, 10);
  cameraRay(pv, 0, 0, 0.f, 0.f, o, d);
  EXPECT_NEAR(d.z, -1.f, 1e-7);
  EXPECT_NEAR(o.x, -2.f, 1e-6);
  EXPECT_NEAR(o.y, 2.f, 1e-6);  // row 0 is the top

  Camera bad = cam;
  bad.viewUp = {0, 0, 1};
  EXPECT_THROW(bad.view(8, 8), std::invalid_argument);
}

}  // namespace
}  // namespace inr

namespace inr {
namespace {

TEST(TransferFunctionJson, ReadsShippedParaViewFile) {
  const TransferFunction tf =
      TransferFunction::fromParaViewJsonFile(std::string(INR_TEST_DATA_DIR) + "/render/paraview-colormap.json");
  ASSERT_EQ(tf.color.size(), 3u);
  ASSERT_EQ(tf.opacity.size(), 3u);
  EXPECT_DOUBLE_EQ(tf.opacityAt(0.75), 0.35);
  EXPECT_DOUBLE_EQ(tf.colorAt(0.5)[0], 0.865);
  EXPECT_EQ(tf.range()[1], 1.0);
}

}  // namespace
}  // namespace inr

namespace inr {
namespace {

// A camera handed back with float round-off (vtkWindowToImageFilter's re-render turns a view
// angle of 30 into 30.000000834826057) is the same camera: a screenshot must not restart or
// reproject a converged image. A real move, however small on screen, is a change.
TEST(SceneChange, CameraRoundOffIsNoChangeButAMoveIs) {
  RenderScene a;
  a.camera.position = {3.1211623972205644, 2.8977774788672055, 5.0488474403641463};
  a.camera.focalPoint = {1, 0, 0.5};
  RenderScene b = a;
  b.camera.viewAngle = 30.000000834826057;
  EXPECT_FALSE(diffScenes(&a, b).camera);
  EXPECT_FALSE(diffScenes(&a, b).any());
  b = a;
  b.camera.viewAngle = 30.01;
  EXPECT_TRUE(diffScenes(&a, b).camera);
  b = a;
  b.camera.position[0] += 1e-4;  // about a hundredth of a pixel at 1000 pixels across this view
  EXPECT_TRUE(diffScenes(&a, b).camera);
}

// The light only matters with shadows on (ParaView's light follows the camera: a camera move
// must stay a camera-only change, which reprojection keeps).
TEST(SceneChange, LightMattersOnlyWithShadows) {
  RenderScene a;
  RenderScene b = a;
  b.toLight = {0.3, 0.4, 0.8};
  b.ambient = 0.5f;
  EXPECT_FALSE(diffScenes(&a, b).light);
  a.shadows = b.shadows = true;
  EXPECT_TRUE(diffScenes(&a, b).light);
  b = a;
  b.shadows = false;
  EXPECT_TRUE(diffScenes(&a, b).light);
}

// A network that overflows leaves +-inf in the working value range (seen on the GPU's fp16 path:
// relu activations ~1e10): the ghost sweep's transfer functions must still be valid ones, with
// the same sweep as before over a finite range.
TEST(GhostSweep, OverflowedWorkingRangeGivesValidTransferFunctions) {
  const Vec3f cell{0.1f, 0.1f, 0.1f};
  const float inf = std::numeric_limits<float>::infinity();
  for (const std::array<float, 2> range : {std::array<float, 2>{-inf, inf}, std::array<float, 2>{0.f, inf},
                                           std::array<float, 2>{-inf, 2.f}, std::array<float, 2>{NAN, NAN}}) {
    const GhostSweep sweep(range, cell, 3);
    for (int g = 0; g < 3; ++g) {
      const TransferFunction tf = sweep.transferFunction(g);
      EXPECT_NO_THROW(TransferFunctionTable table(tf)) << range[0] << ".." << range[1] << ", pass " << g;
    }
  }
  // A finite range sweeps as it did: pass 1 of 2 over [1, 3] is the bump at 2.5, half-width 1.
  const TransferFunction finite = GhostSweep({1.f, 3.f}, cell, 2).transferFunction(1);
  const TransferFunction expected = TransferFunction::cosineBump(1.0, 3.0, 2.5, 1.0, 0.5);
  EXPECT_EQ(finite.range(), expected.range());
  EXPECT_EQ(finite.opacity.size(), expected.opacity.size());
}

}  // namespace
}  // namespace inr
