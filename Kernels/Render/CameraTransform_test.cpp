// The generalised camera (CameraView.h): the volume's model-to-world matrix applied to the rays,
// VTK's window centre, and tiles keyed by their place in the full picture.
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/Reproject.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using Matrix = std::array<double, 16>;

Matrix multiply(const Matrix& a, const Matrix& b) {
  Matrix c{};
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k)
      for (int j = 0; j < 4; ++j) c[4 * r + j] += a[4 * r + k] * b[4 * k + j];
  return c;
}

// Rotation by `degrees` about the unit axis (x, y, z), then uniform scale s, then translation t.
Matrix similarity(double degrees, std::array<double, 3> axis, double s, std::array<double, 3> t) {
  const double a = degrees * M_PI / 180.0, c = std::cos(a), n = std::sin(a), C = 1.0 - c;
  const double x = axis[0], y = axis[1], z = axis[2];
  return Matrix{s * (c + x * x * C),     s * (x * y * C - z * n), s * (x * z * C + y * n), t[0],
                s * (y * x * C + z * n), s * (c + y * y * C),     s * (y * z * C - x * n), t[1],
                s * (z * x * C - y * n), s * (z * y * C + x * n), s * (c + z * z * C),     t[2],
                0,                       0,                       0,                       1};
}

std::array<double, 3> applyPoint(const Matrix& m, const std::array<double, 3>& p, double w = 1.0) {
  return {m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3] * w, m[4] * p[0] + m[5] * p[1] + m[6] * p[2] + m[7] * w,
          m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11] * w};
}

// Inverse of a similarity (rotation R, scale s, translation t): x = R^T (y - t) / s.
Matrix inverseSimilarity(const Matrix& m, double s) {
  Matrix inv{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) inv[4 * r + c] = m[4 * c + r] / (s * s);
  for (int r = 0; r < 3; ++r)
    inv[4 * r + 3] = -(inv[4 * r] * m[3] + inv[4 * r + 1] * m[7] + inv[4 * r + 2] * m[11]);
  inv[15] = 1.0;
  return inv;
}

// The model: a smooth field over [-1, 1]^3 with shadows, seen obliquely.
struct Fixture {
  test::FunctionField field{test::smoothField};
  MacrocellGrid grid{field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2)};
  CpuWavefrontRenderer renderer{field, grid};
  test::SceneSetup setup = test::obliqueCubeScene(40, 7);
  Fixture() {
    setup.settings.height = 30;
    setup.scene.transferFunction = TransferFunction::preset(0.2, 0.9, 0.7);
    setup.scene.transferFunction.unitDistance = 0.4;
    test::lightScene(setup.scene, true);
  }
  ImageRGBA render(const RenderSettings& settings, const RenderScene& scene, int frames) {
    test::renderFrames(renderer, settings, scene, frames);
    return renderer.premultipliedImage();
  }
};

// Model-space rays are the world rays mapped by the inverse model matrix, with ray parameters in
// model units; projecting a point of the ray gives back its pixel (reprojection's inverse).
TEST(GeneralCamera, RaysAreWorldRaysMappedToModelSpace) {
  Camera cam = Camera::framing(test::kCubeBox);
  cam.position = {2.0, 1.0, 3.5};
  cam.windowCenter = {0.3, -0.2};
  // Shear and non-uniform scale through a user matrix, after a rotation and a translation.
  const Matrix shear{1.5, 0.4, 0, 0, 0, 0.7, 0.2, 0, 0.1, 0, 2.0, 0, 0, 0, 0, 1};
  cam.modelToWorld = multiply(similarity(25, {0, 0.6, 0.8}, 1.0, {0.3, -0.4, 0.5}), shear);
  ASSERT_TRUE(cam.hasModelTransform());
  const CameraView v = cam.view(32, 24);
  Camera world = cam;
  world.modelToWorld = Matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const CameraView w = world.view(32, 24);
  for (const auto& px : {std::array<int, 2>{0, 0}, {31, 5}, {16, 12}, {7, 23}}) {
    Vec3f ow, dw, om, dm;
    cameraRayWorld(w, px[0], px[1], 0.25f, 0.75f, ow, dw);
    cameraRay(v, px[0], px[1], 0.25f, 0.75f, om, dm);
    EXPECT_NEAR(length(dm), 1.f, 1e-6f);
    // A world point at distance t along the world ray is the model point at t * modelPerWorld.
    Vec3f o2 = ow, d2 = dw;
    const float modelPerWorld = worldRayToModel(v, o2, d2);
    const float t = 2.5f;
    const Vec3f pm = om + dm * (t * modelPerWorld);
    const Vec3f back = modelToWorld(v, pm), expected = ow + dw * t;
    EXPECT_NEAR(back.x, expected.x, 1e-4f);
    EXPECT_NEAR(back.y, expected.y, 1e-4f);
    EXPECT_NEAR(back.z, expected.z, 1e-4f);
    float fx, fy, depth;
    ASSERT_TRUE(projectToImage(v, pm, fx, fy, depth));
    EXPECT_NEAR(fx, px[0] + 0.25f, 1e-3f);
    EXPECT_NEAR(fy, px[1] + 0.75f, 1e-3f);
    EXPECT_NEAR(depth, viewDepth(v, pm), 1e-5f);
  }
  Camera projective = cam;
  projective.modelToWorld[14] = 0.1;
  EXPECT_THROW(projective.view(8, 8), std::invalid_argument);
  Camera flat = cam;
  flat.modelToWorld = Matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
  EXPECT_THROW(flat.view(8, 8), std::invalid_argument);
}

// A volume moved, rotated and uniformly scaled renders as the untransformed volume seen by the
// inverse-transformed camera, light and depth limit: the same rays in model space, the same
// optical depths (opacity per model unit, as VTK's GPU ray-cast mapper) and the same draws.
TEST(GeneralCamera, TransformedVolumeEqualsInverseTransformedCamera) {
  for (const bool parallel : {false, true}) {
    Fixture f;
    RenderScene moved = f.setup.scene;
    const double s = 1.7;
    const Matrix m = similarity(40, {0.48, 0.6, 0.64}, s, {0.5, -1.0, 0.25});
    moved.camera.modelToWorld = m;
    // Keep the moved volume in view: look at where its centre went, from the same offset, scaled.
    const auto c = applyPoint(m, {0, 0, 0});
    const auto off = applyPoint(m, {2.2, 1.6, 3.4}, 0.0);
    moved.camera.focalPoint = c;
    moved.camera.position = {c[0] + off[0], c[1] + off[1], c[2] + off[2]};
    moved.camera.viewUp = applyPoint(m, {0, 1, 0}, 0.0);
    moved.camera.parallelProjection = parallel;
    moved.camera.parallelScale = 1.6 * s;
    moved.toLight = {0.3, 0.9, -0.2};
    // An opaque plane through the volume's centre, perpendicular to the view (world distances).
    const int W = f.setup.settings.width, H = f.setup.settings.height;
    const CameraView mv = moved.camera.view(W, H);
    moved.depthLimit.assign(std::size_t(W) * H, 0.f);
    for (int i = 0; i < W * H; ++i) {
      Vec3f o, d;
      cameraRayWorld(mv, i % W, i / W, 0.5f, 0.5f, o, d);
      const Vec3f toCentre = Vec3f{float(c[0]), float(c[1]), float(c[2])} - o;
      moved.depthLimit[i] = (i % W) < W / 2 ? dot(toCentre, mv.forward) / dot(d, mv.forward) : 1e30f;
    }

    RenderScene inverse = moved;
    const Matrix inv = inverseSimilarity(m, s);
    inverse.camera.modelToWorld = Matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    inverse.camera.position = applyPoint(inv, moved.camera.position);
    inverse.camera.focalPoint = applyPoint(inv, moved.camera.focalPoint);
    inverse.camera.viewUp = applyPoint(inv, moved.camera.viewUp, 0.0);
    inverse.camera.parallelScale = moved.camera.parallelScale / s;
    inverse.toLight = applyPoint(inv, moved.toLight, 0.0);
    for (float& d : inverse.depthLimit) d = d < 1e29f ? float(d / s) : d;

    RenderSettings settings = f.setup.settings;
    settings.pixelJitter = false;  // the two views' centre rays agree to float rounding
    const ImageRGBA a = f.render(settings, moved, 6);
    const ImageRGBA b = f.render(settings, inverse, 6);
    const double psnr = test::psnrOverCoverage(a, b, b);
    std::printf("%s: transformed vs inverse-transformed camera, 6 frames: PSNR over covered pixels %.1f dB\n",
                parallel ? "parallel" : "perspective", psnr);
    EXPECT_GE(psnr, 40.0);
    std::size_t covered = 0;
    for (int i = 0; i < W * H; ++i) covered += b.data[4 * std::size_t(i) + 3] > 0.f ? 1 : 0;
    EXPECT_GT(covered, std::size_t(W * H / 8));  // the volume is in view (and left of the plane)
  }
}

// Tiles rendered one by one, each with the tile's own camera (vtkWindowToImageFilter's: window
// centre shifted, view angle or parallel scale narrowed) and its window in the full picture,
// equal the full picture rendered at once: same rays (to float rounding), same random streams.
TEST(GeneralCamera, TilesEqualTheFullPicture) {
  for (const bool parallel : {false, true}) {
    Fixture f;
    RenderScene scene = f.setup.scene;
    scene.camera.parallelProjection = parallel;
    scene.camera.parallelScale = 1.4;
    scene.camera.modelToWorld = similarity(30, {0, 0, 1}, 0.9, {0.1, 0.0, -0.2});
    const int W = 48, H = 36, frames = 4;
    RenderSettings full = f.setup.settings;
    full.width = W;
    full.height = H;
    const ImageRGBA whole = f.render(full, scene, frames);
    ImageRGBA tiled(W, H);
    const int tilesX = 3, tilesY = 2, tw = W / tilesX, th = H / tilesY;
    for (int ty = 0; ty < tilesY; ++ty) {
      for (int tx = 0; tx < tilesX; ++tx) {
        RenderScene tile = scene;
        // The tile's centre, in the tile's half-extents (x right, y up; tile rows go down).
        const double mag = 1.0 / tilesY;  // vertical fraction of the full view the tile shows
        tile.camera.windowCenter = {(-1.0 + (2.0 * tx + 1.0) / tilesX) * tilesX,
                                    (1.0 - (2.0 * ty + 1.0) / tilesY) * tilesY};
        tile.camera.viewAngle = 2.0 * std::atan(std::tan(scene.camera.viewAngle * M_PI / 360.0) * mag) * 180.0 / M_PI;
        tile.camera.parallelScale = scene.camera.parallelScale * mag;
        RenderSettings ts = full;
        ts.width = tw;
        ts.height = th;
        ts.window = ImageWindow{W, H, tx * tw, ty * th};
        const ImageRGBA part = f.render(ts, tile, frames);
        for (int y = 0; y < th; ++y)
          for (int x = 0; x < tw; ++x)
            for (int c = 0; c < 4; ++c)
              tiled.data[4 * (std::size_t(ty * th + y) * W + tx * tw + x) + c] = part.data[4 * (std::size_t(y) * tw + x) + c];
      }
    }
    const double psnr = test::psnrOverCoverage(tiled, whole, whole);
    std::printf("%s: %dx%d tiles vs the whole %dx%d picture, %d frames: PSNR over covered pixels %.1f dB\n",
                parallel ? "parallel" : "perspective", tilesX, tilesY, W, H, frames, psnr);
    EXPECT_GE(psnr, 40.0);
  }
  RenderSettings bad;
  bad.width = bad.height = 16;
  bad.window = ImageWindow{20, 20, 8, 0};
  EXPECT_THROW(validateImageWindow(bad.window, bad.width, bad.height), std::invalid_argument);
}

// The traversal's division-free stream key equals the full picture's pixel index.
TEST(GeneralCamera, StreamKeysAreFullPicturePixels) {
  for (const auto& t : {std::array<int, 6>{7, 5, 31, 17, 9, 4}, {1, 1, 1, 1, 0, 0}, {960, 540, 1920, 1080, 960, 540},
                        {4093, 37, 9000, 100, 4907, 63}, {48, 36, 48, 36, 0, 0}}) {
    const int w = t[0], h = t[1];
    RenderSettings settings;
    settings.width = w;
    settings.height = h;
    settings.window = ImageWindow{t[2], t[3], t[4], t[5]};
    if (t[2] == w && t[3] == h) settings.window = ImageWindow{};
    validateImageWindow(settings.window, w, h);
    RenderScene scene;
    const CameraView view = scene.camera.view(w, h);
    const FrameConstants fc = makeFrameConstants(view, test::kCubeBox, scene, settings, nullptr, 0);
    const int fullWidth = settings.window.fullWidth ? settings.window.fullWidth : w;
    for (int i = 0; i < w * h; ++i) {
      const std::uint32_t expected =
          std::uint32_t(i / w + settings.window.y) * std::uint32_t(fullWidth) + std::uint32_t(i % w + settings.window.x);
      ASSERT_EQ(pixelStreamKey(fc, i), expected) << w << "x" << h << " pixel " << i;
    }
  }
}

}  // namespace
}  // namespace inr
