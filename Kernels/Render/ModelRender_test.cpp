// Converged delta tracking against fine-step ray marching on real networks through the CPU INR
// evaluator: the shipped models in Testing/Data/models/ (and the loader corpus' valid control
// model, so a real network is exercised even before models ship).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/ModelBox.h"
#include "Render/RayMarcher.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

namespace fs = std::filesystem;

struct Comparison {
  double psnr = 0;
  std::size_t queriesPerFrame = 0;
  double volumeVisibility = 0;  // PSNR of the reference against a background-only image
};

Comparison convergedVsRayMarched(const std::string& path, bool shadows, int size, int frames) {
  const InrModel model = InrModel::loadFile(path);
  const CpuInrEvaluator evaluator(model);
  const Box3f box = modelWorldBox(model);
  const float diagonal = length(box.hi - box.lo);
  const auto range = valueRangeFor(model, evaluator);

  RenderSettings settings;
  settings.width = settings.height = size;
  settings.seed = 9;
  settings.pixelJitter = false;  // compare the per-pixel integral, not edge antialiasing
  // Ratio-tracked shadows (the default of testScene): 1000 frames reach the 40 dB bar with margin
  // on networks; delta shadows are covered analytically.
  const RenderScene scene = test::testScene(model, range, shadows);

  MacrocellGrid grid(evaluator, box, model.domain.timeBegin, model.domain.timeEnd, test::testMacrocells());
  CpuWavefrontRenderer dt(evaluator, grid);
  const FrameStats total = test::renderFrames(dt, settings, scene, frames);

  RayMarchOptions ropts;
  ropts.step = diagonal / 512.f;
  ropts.shadowStep = diagonal / 96.f;
  RayMarchRenderer rm(evaluator, box, ropts);
  test::renderFrames(rm, settings, scene, 1);
  // The comparison only means something if the volume is visible: a background-only image must
  // be far from the reference (a renderer that drew nothing would otherwise pass).
  ImageRGBA empty(size, size);
  for (int i = 0; i < size * size; ++i)
    for (int c = 0; c < 3; ++c) empty.data[4 * i + c] = scene.background[c];
  return {psnrRgb(dt.image(), rm.image()), total.totalQueries() / std::size_t(frames), psnrRgb(empty, rm.image())};
}

TEST(ModelRender, ControlModelConvergesToRayMarching) {
  const std::string path = std::string(INR_TEST_DATA_DIR) + "/malformed/valid_control.inr";
  ASSERT_TRUE(fs::exists(path)) << path << " not found";
  for (bool shadows : {false, true}) {
    const Comparison c = convergedVsRayMarched(path, shadows, shadows ? 24 : 32, 1000);
    std::printf("%s%s: PSNR %.2f dB, %zu queries/frame (background-only image: %.2f dB)\n", path.c_str(),
                shadows ? " (shadows)" : "", c.psnr, c.queriesPerFrame, c.volumeVisibility);
    EXPECT_GE(c.psnr, 40.0) << path << (shadows ? " with shadows" : "");
    EXPECT_LT(c.volumeVisibility, 30.0) << path << ": the volume is barely visible; the comparison is vacuous";
  }
}

TEST(ModelRender, ShippedModelsConvergeToRayMarching) {
  for (const auto& path : test::shippedModels()) {
    for (bool shadows : {false, true}) {
      const Comparison c = convergedVsRayMarched(path, shadows, shadows ? 24 : 32, 1000);
      std::printf("%s%s: PSNR %.2f dB, %zu queries/frame (background-only image: %.2f dB)\n",
                  fs::path(path).filename().c_str(), shadows ? " (shadows)" : "", c.psnr, c.queriesPerFrame,
                  c.volumeVisibility);
      EXPECT_GE(c.psnr, 40.0) << path << (shadows ? " with shadows" : "");
      EXPECT_LT(c.volumeVisibility, 30.0) << path << ": the volume is barely visible; the comparison is vacuous";
    }
  }
}

}  // namespace
}  // namespace inr
