#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/RayMarcher.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::meanCoverage;

const Box3f kBox = test::kCubeBox;

MacrocellOptions cells(int n) {
  MacrocellOptions o;
  o.dims = Int3{n, n, n};
  o.temporalSlices = 4;
  return o;
}

TransferFunction flatOpacity(double alpha, double unitDistance) {
  TransferFunction tf;
  tf.color = {{0, 0.2, 0.6, 1.0}, {1, 0.2, 0.6, 1.0}};
  tf.opacity = {{0, alpha}, {1, alpha}};
  tf.unitDistance = unitDistance;
  return tf;
}

// Orthographic view down -z through the cube: every ray crosses exactly 2 units of medium.
Camera topDown() {
  Camera c = Camera::framing(kBox);
  c.parallelProjection = true;
  c.parallelScale = 0.9;
  return c;
}

// The analytic-medium tests' renderer: field f over 8^3 macrocells, 48 x 48 pixels, viewed
// topDown(); each test sets the transfer function.
struct TopDownRender {
  explicit TopDownRender(const FieldEvaluator& f, std::uint32_t seed = RenderSettings{}.seed)
      : grid(f, kBox, 0, 1, cells(8)), renderer(f, grid) {
    settings.width = settings.height = 48;
    settings.seed = seed;
    renderer.setSettings(settings);
    scene.camera = topDown();
  }
  MacrocellGrid grid;
  CpuWavefrontRenderer renderer;
  RenderSettings settings;
  RenderScene scene;
};

TEST(DeltaTracking, HomogeneousMediumTransmittance) {
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  TopDownRender t(f, 11);
  CpuWavefrontRenderer& r = t.renderer;
  t.scene.transferFunction = flatOpacity(0.3, 0.5);
  r.setScene(t.scene);
  const int frames = 20;
  for (int k = 0; k < frames; ++k) r.renderFrame();
  const double sigma = -std::log(1.0 - 0.3) / 0.5;
  const double p = 1.0 - std::exp(-sigma * 2.0);  // probability of a real collision
  const double n = 48.0 * 48.0 * frames;
  const double bound = 4.0 * std::sqrt(p * (1 - p) / n);
  const ImageRGBA img = r.premultipliedImage();
  EXPECT_NEAR(meanCoverage(img), p, bound);
  EXPECT_NEAR(img.data[4 * 100 + 2] / img.data[4 * 100 + 3], 1.0f, 1e-5);  // emission = colour
}

TEST(DeltaTracking, PiecewiseMediumUsesLocalMajorants) {
  // Two slabs with different extinction, cell faces on the interface: transmittance is
  // exp(-sigma1 - sigma2) for the unit thickness of each.
  test::FunctionField f([](const QueryPoint& p) { return p.z > 0.f ? 1.0f : 0.25f; });
  TopDownRender t(f, 5);
  CpuWavefrontRenderer& r = t.renderer;
  t.scene.transferFunction = TransferFunction::preset(0.0, 1.0, 0.8);
  t.scene.transferFunction.unitDistance = 1.0;
  r.setScene(t.scene);
  const int frames = 20;
  FrameStats total;
  for (int k = 0; k < frames; ++k) total += r.renderFrame();
  const double s1 = -std::log(1 - 0.8), s2 = -std::log(1 - 0.2);
  const double p = 1.0 - std::exp(-s1 - s2);
  const double n = 48.0 * 48.0 * frames;
  EXPECT_NEAR(meanCoverage(r.premultipliedImage()), p, 4.0 * std::sqrt(p * (1 - p) / n));
  // The lattice bounds of each slab are exact, so every candidate is a real collision: at most
  // one query per ray, one traverse-evaluate iteration per frame.
  EXPECT_EQ(total.iterations, frames);
  EXPECT_LE(total.queries, total.rays);
  EXPECT_GT(total.queries, total.rays / 2);
  EXPECT_EQ(total.rays, std::size_t(48 * 48 * frames));
}

using test::SceneSetup;

SceneSetup smoothScene(int size, bool shadows) {
  SceneSetup s = test::obliqueCubeScene(size, 3);
  s.settings.pixelJitter = false;  // compare the integral per pixel centre
  s.scene.transferFunction = TransferFunction::preset(0.2, 0.9, 0.5);
  s.scene.transferFunction.unitDistance = 0.25;
  test::lightScene(s.scene, shadows);
  return s;
}

// PSNR of delta tracking after `frames` frames against one ray-marched frame of smoothScene(32).
double psnrAgainstRayMarching(bool shadows, int frames, const RayMarchOptions& ro) {
  test::FunctionField f(test::smoothField);
  const SceneSetup setup = smoothScene(32, shadows);
  MacrocellGrid grid(f, kBox, 0, 1, cells(16));
  CpuWavefrontRenderer dt(f, grid);
  test::renderFrames(dt, setup.settings, setup.scene, frames);
  RayMarchRenderer rm(f, kBox, ro);
  test::renderFrames(rm, setup.settings, setup.scene, 1);
  return psnrRgb(dt.image(), rm.image());
}

void convergedVsRayMarch(bool shadows, int frames, double minPsnr) {
  RayMarchOptions ro;
  ro.step = 2.f / 512.f;
  ro.shadowStep = 2.f / 128.f;
  const double psnr = psnrAgainstRayMarching(shadows, frames, ro);
  std::printf("converged delta tracking (%d frames%s) vs ray marching: PSNR %.2f dB\n", frames,
              shadows ? ", shadows" : "", psnr);
  EXPECT_GE(psnr, minPsnr);
}

TEST(DeltaTracking, ConvergesToRayMarchingAnalytic) { convergedVsRayMarch(false, 1000, 40.0); }
TEST(DeltaTracking, ConvergesToRayMarchingAnalyticWithShadows) { convergedVsRayMarch(true, 1000, 40.0); }

TEST(DeltaTracking, NotConvergedAfterOneFrame) {
  // Guards the test above against a comparison that cannot fail.
  EXPECT_LT(psnrAgainstRayMarching(false, 1, RayMarchOptions{}), 30.0);
}

std::vector<float> renderWithThreads(int threads, bool naive) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  test::FunctionField f(test::smoothField);
  // 96^2 rays: above kParallelMinItems, so the stage loops really run on several threads.
  SceneSetup setup = smoothScene(96, true);
  setup.settings.pixelJitter = true;
  MacrocellGrid grid(f, kBox, 0, 1, cells(8));
  TrackingOptions topt;
  topt.ghostPassesOnUpdate = 2;
  CpuWavefrontRenderer r(f, grid, topt);
  r.setSettings(setup.settings);
  r.setScene(setup.scene);
  for (int k = 0; k < 3; ++k) naive ? r.renderFrameNaive() : r.renderFrame();
  omp_set_num_threads(saved);
  return r.image().data;
}

TEST(DeltaTracking, IdenticalImagesForOneAndManyThreads) {
  const auto one = renderWithThreads(1, false);
  const auto many = renderWithThreads(4, false);
  ASSERT_EQ(one.size(), many.size());
  EXPECT_TRUE(one == many);
}

TEST(DeltaTracking, NaiveTrackerIsTheSameEstimator) {
  // Same random streams, same majorants: the unbatched baseline reproduces the wavefront image.
  EXPECT_TRUE(renderWithThreads(2, false) == renderWithThreads(2, true));
}

TEST(DeltaTracking, EmptyTransferFunctionRendersBackgroundWithoutQueries) {
  test::FunctionField f(test::smoothField);
  MacrocellGrid grid(f, kBox, 0, 1, cells(8));
  CpuWavefrontRenderer r(f, grid);
  SceneSetup setup = smoothScene(32, true);
  setup.scene.transferFunction = TransferFunction::transparent(0.0, 1.0);
  r.setSettings(setup.settings);
  r.setScene(setup.scene);
  f.resetCounts();
  const FrameStats st = r.renderFrame();
  EXPECT_EQ(f.points(), 0u);
  EXPECT_EQ(st.totalQueries(), 0u);
  EXPECT_EQ(st.iterations, 0);
  const ImageRGBA img = r.image();
  for (int i = 0; i < img.width * img.height; ++i) {
    ASSERT_EQ(img.data[4 * i + 0], 0.1f);
    ASSERT_EQ(img.data[4 * i + 1], 0.2f);
    ASSERT_EQ(img.data[4 * i + 2], 0.3f);
  }
}

TEST(DeltaTracking, DepthLimitStopsRays) {
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  TopDownRender t(f);
  CpuWavefrontRenderer& r = t.renderer;
  RenderScene& scene = t.scene;
  scene.transferFunction = flatOpacity(0.3, 0.5);
  const float tEnter = float(scene.camera.position[2]) - 1.f;  // parallel rays start at the eye plane
  scene.depthLimit.assign(48 * 48, tEnter + 1.f);               // opaque surface at z = 0
  for (int i = 0; i < 48 * 24; ++i) scene.depthLimit[i] = tEnter - 0.5f;  // top half: in front of the box
  r.setScene(scene);
  FrameStats total;
  const int frames = 20;
  for (int k = 0; k < frames; ++k) total += r.renderFrame();
  EXPECT_EQ(total.rays, std::size_t(48 * 24 * frames));  // top-half rays never start
  const ImageRGBA img = r.premultipliedImage();
  double top = 0, bottom = 0;
  for (int i = 0; i < 48 * 24; ++i) top += img.data[4 * i + 3];
  for (int i = 48 * 24; i < 48 * 48; ++i) bottom += img.data[4 * i + 3];
  EXPECT_EQ(top, 0.0);
  const double p = 1.0 - std::exp(-(-std::log(0.7) / 0.5) * 1.0);  // one unit of medium
  const double n = 48.0 * 24 * frames;
  EXPECT_NEAR(bottom / (48 * 24), p, 4 * std::sqrt(p * (1 - p) / n));
  // The ray marcher honours the same limit.
  RayMarchRenderer rm(f, kBox);
  rm.setSettings(t.settings);
  rm.setScene(scene);
  rm.renderFrame();
  EXPECT_NEAR(rm.premultipliedImage().data[4 * (48 * 40 + 10) + 3], p, 1e-3);
  EXPECT_EQ(rm.premultipliedImage().data[4 * 10 + 3], 0.f);
}

TEST(DeltaTracking, ResidualAndAccumulation) {
  test::FunctionField f(test::smoothField);
  MacrocellGrid grid(f, kBox, 0, 1, cells(8));
  CpuWavefrontRenderer r(f, grid);
  const SceneSetup setup = smoothScene(24, false);
  r.setSettings(setup.settings);
  r.setScene(setup.scene);
  r.renderFrame();
  for (float v : r.residual()) ASSERT_EQ(v, 1.f);
  const ImageRGBA first = r.image();
  r.renderFrame();
  const ImageRGBA mean2 = r.image();
  // r_i = mean |C2 - C1| and the accumulation is the mean of both: C2 = 2 * mean2 - C1.
  for (int i = 0; i < 24 * 24; i += 7) {
    double rr = 0;
    for (int c = 0; c < 3; ++c) rr += std::fabs(2.0 * (mean2.data[4 * i + c] - first.data[4 * i + c]));
    ASSERT_NEAR(r.residual()[i], rr / 3.0, 1e-5);
  }
  EXPECT_EQ(r.accumulatedFrames(), 2);
  r.setScene(setup.scene);  // identical scene: keeps accumulating
  EXPECT_EQ(r.accumulatedFrames(), 2);
  RenderScene moved = setup.scene;
  moved.camera.position[0] += 0.1;
  r.setScene(moved);  // reprojection (on by default) keeps the frames, up to its history
  EXPECT_EQ(r.accumulatedFrames(), 2);
  EXPECT_EQ(r.counters().reprojections, 1);
  QueryReductionSettings exact;
  exact.reproject = false;
  r.setQueryReduction(exact);
  moved.camera.position[0] += 0.1;
  r.setScene(moved);  // without it a camera move starts over
  EXPECT_EQ(r.accumulatedFrames(), 0);
}

TEST(DeltaTracking, RatioTrackedShadowsAgreeWithDeltaShadows) {
  test::FunctionField f(test::smoothField);
  SceneSetup setup = smoothScene(24, true);
  MacrocellGrid grid(f, kBox, 0, 1, cells(8));
  CpuWavefrontRenderer a(f, grid), b(f, grid);
  a.setSettings(setup.settings);
  b.setSettings(setup.settings);
  a.setScene(setup.scene);
  setup.scene.shadowEstimator = ShadowEstimator::Ratio;
  b.setScene(setup.scene);
  FrameStats sa, sb;
  for (int k = 0; k < 400; ++k) sa += a.renderFrame(), sb += b.renderFrame();
  EXPECT_GT(psnrRgb(a.image(), b.image()), 35.0);
  EXPECT_GT(sb.shadowQueries, sa.shadowQueries);  // ratio tracking never stops early
}

}  // namespace
}  // namespace inr
