// The isosurface and slice blend modes on the GPU (Render/Cuda/CudaSurfaceRenderer.h; ctest label
// `cuda`, skipped with the reason without a usable GPU): the same per-ray code as the CPU
// renderer, so on an analytic field both images agree up to the device's sinf / expf rounding,
// and on a shipped network up to the fp16 evaluation error. The controls render another plane or
// isovalue on the GPU.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Model/InrModel.h"
#include "Render/Cuda/AnalyticDeviceField.h"
#include "Render/Cuda/CudaSurfaceRenderer.h"
#include "Render/ModelBox.h"
#include "Render/SurfaceRenderer.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::kCubeBox;

// PSNR (dB, peak 1) of b against a over the pixels either covers (alpha > 0), RGB of the
// premultiplied images; `covered` counts them.
double psnrOverCovered(const ImageRGBA& a, const ImageRGBA& b, int& covered) {
  double se = 0.0;
  covered = 0;
  for (std::size_t i = 0; i < a.data.size() / 4; ++i) {
    if (!(a.data[4 * i + 3] > 0.f) && !(b.data[4 * i + 3] > 0.f)) continue;
    ++covered;
    for (int k = 0; k < 3; ++k) {
      const double d = double(a.data[4 * i + k]) - double(b.data[4 * i + k]);
      se += d * d;
    }
  }
  if (covered == 0) return 0.0;
  const double mse = se / (3.0 * covered);
  return mse > 0.0 ? 10.0 * std::log10(1.0 / mse) : 200.0;
}

struct Views {
  RenderScene scene;
  RenderSettings settings;
  Views(const Box3f& box, int size) {
    scene.camera = Camera::framing(box);
    const auto& f = scene.camera.focalPoint;
    const double d = scene.camera.position[2] - f[2];
    scene.camera.position = {f[0] + 0.45 * d, f[1] + 0.35 * d, f[2] + 0.8 * d};
    settings.width = settings.height = size;
    settings.pixelJitter = false;
  }
};

template <typename Renderer>
ImageRGBA renderWith(Renderer& r, const Views& v, const BlendScene& blend) {
  r.setSettings(v.settings);
  r.setScene(v.scene, blend);
  r.renderFrame();
  return r.premultipliedImage();
}

TEST(CudaSurface, AnalyticFieldMatchesTheCpuRenderer) {
  REQUIRE_GPU();
  test::AnalyticDeviceField field;
  Views v(kCubeBox, 96);
  v.scene.transferFunction = TransferFunction::preset(0.0, 1.0, 0.8);
  for (BlendMode mode : {BlendMode::Slice, BlendMode::Isosurface}) {
    BlendScene blend;
    blend.mode = mode;
    blend.isovalues = {0.55, 0.7};
    blend.sliceNormal = {0.2, 0.3, 1.0};
    SurfaceRenderer cpu(field, kCubeBox, 0.0, 1.0);
    CudaSurfaceRenderer gpu(field, field, kCubeBox, 0.0, 1.0);
    const ImageRGBA a = renderWith(cpu, v, blend), b = renderWith(gpu, v, blend);
    int covered = 0;
    const double psnr = psnrOverCovered(a, b, covered);
    // Control: the GPU image of a moved plane / another isovalue.
    BlendScene other = blend;
    other.sliceOrigin = {0.0, 0.0, 0.1};
    other.isovalues = {0.6, 0.7};
    CudaSurfaceRenderer gpuOther(field, field, kCubeBox, 0.0, 1.0);
    int coveredOther = 0;
    const double control = psnrOverCovered(a, renderWith(gpuOther, v, other), coveredOther);
    std::printf("%s: GPU vs CPU %.1f dB over %d pixels; control %.1f dB\n", blendModeName(mode), psnr, covered, control);
    EXPECT_GT(covered, 1000);
    EXPECT_GE(psnr, 50.0);
    EXPECT_LT(control, 40.0);
  }
}

// One isosurface frame of the analytic field (two isovalues, 160²) with `options` (a) and with
// the GPU's defaults (b).
struct DefaultsAgainst {
  test::AnalyticDeviceField field;
  CudaSurfaceRenderer a, b;
  FrameStats sa, sb;
  explicit DefaultsAgainst(const SurfaceOptions& options)
      : a(field, field, kCubeBox, 0.0, 1.0, options), b(field, field, kCubeBox, 0.0, 1.0) {
    Views v(kCubeBox, 160);
    v.scene.transferFunction = TransferFunction::preset(0.0, 1.0, 0.8);
    BlendScene blend;
    blend.mode = BlendMode::Isosurface;
    blend.isovalues = {0.55, 0.7};
    for (CudaSurfaceRenderer* r : {&a, &b}) {
      r->setSettings(v.settings);
      r->setScene(v.scene, blend);
    }
    sa = a.renderFrame();
    sb = b.renderFrame();
  }
};

// The GPU's isosurface batches: the active rays only, with more march samples each as rays finish
// (SurfaceOptions::maxMarchSamples, by default 32 on the GPU). The image and depth are those of
// the frame without the growth, bit for bit (each ray's march is the same), in fewer iterations.
TEST(CudaSurface, GrowingMarchBatchesKeepTheImage) {
  REQUIRE_GPU();
  SurfaceOptions fixed;
  fixed.maxMarchSamples = fixed.samplesPerIteration;
  const DefaultsAgainst f(fixed);
  std::printf("iterations %d (growth off: %d), queries %zu (%zu), rays %zu (%zu)\n", f.sb.iterations, f.sa.iterations,
              f.sb.queries, f.sa.queries, f.sb.rays, f.sa.rays);
  EXPECT_LT(f.sb.iterations, f.sa.iterations);
  EXPECT_EQ(f.sb.rays, f.sa.rays);
  EXPECT_GT(f.sa.rays, 1000u);
  EXPECT_EQ(f.b.premultipliedImage().data, f.a.premultipliedImage().data);
  EXPECT_EQ(f.b.surfaceDepth(), f.a.surfaceDepth());
}

// The GPU refines a hit with 32 points a round by default (SurfaceOptions::refinePoints): two
// rounds from one step to the tolerance where 8 points take four, so a frame takes fewer
// iterations; the hits move within the tolerance only.
TEST(CudaSurface, WideRefinementRoundsTakeFewerIterations) {
  REQUIRE_GPU();
  SurfaceOptions narrow;
  narrow.refinePoints = narrow.samplesPerIteration;
  const DefaultsAgainst f(narrow);
  int covered = 0;
  const double psnr = psnrOverCovered(f.a.premultipliedImage(), f.b.premultipliedImage(), covered);
  std::printf("iterations %d (8 refinement points: %d), queries %zu (%zu), %.1f dB apart over %d pixels\n",
              f.sb.iterations, f.sa.iterations, f.sb.queries, f.sa.queries, psnr, covered);
  EXPECT_LT(f.sb.iterations, f.sa.iterations);
  EXPECT_EQ(f.sb.rays, f.sa.rays);
  EXPECT_GT(covered, 1000);
  EXPECT_GE(psnr, 50.0);
}

TEST(CudaSurface, ShippedNetworkMatchesTheCpuRenderer) {
  REQUIRE_GPU();
  const InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/real/siren_cylinder_vorticity_small.inr");
  const Box3f box = modelWorldBox(model);
  CpuInrEvaluator cpuField(model);
  CudaInrEvaluator gpuField(model);
  Views v(box, 256);
  v.scene.time = model.domain.timeBegin;
  v.scene.transferFunction = TransferFunction::preset(0.0, 30.0, 1.0);
  v.scene.shading.enabled = true;
  v.scene.shading.headlight = true;
  for (BlendMode mode : {BlendMode::Slice, BlendMode::Isosurface}) {
    BlendScene blend;
    blend.mode = mode;
    blend.isovalues = {8.0, 14.0};
    const Vec3f c = (box.lo + box.hi) * 0.5f;
    blend.sliceOrigin = {c.x, c.y, c.z};
    SurfaceRenderer cpu(cpuField, box, model.domain.timeBegin, model.domain.timeEnd);
    CudaSurfaceRenderer gpu(gpuField, box, model.domain.timeBegin, model.domain.timeEnd);
    int covered = 0;
    const double psnr = psnrOverCovered(renderWith(cpu, v, blend), renderWith(gpu, v, blend), covered);
    std::printf("%s on %s: GPU vs CPU %.1f dB over %d pixels\n", blendModeName(mode), gpuField.name().c_str(), psnr,
                covered);
    EXPECT_GT(covered, 500);
    EXPECT_GE(psnr, 40.0);
  }
}

}  // namespace
}  // namespace inr
