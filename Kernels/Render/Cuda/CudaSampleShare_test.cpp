// The sample-space split (RenderSettings::sampleShare) on the GPU backend, the twin of
// Render/SampleShare_test.cpp (ctest label `cuda`; skipped, with the reason, without a usable
// GPU): share r of N renders the single renderer's frames r, r + N, ..., so the shares' frame-
// weighted mean equals one render over all their frames, on an analytic field and on a shipped
// network, and for the GPU ray marcher.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/AnalyticDeviceField.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/Cuda/CudaRayMarcher.h"
#include "Render/ModelBox.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/SampleShareCheck.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::SceneSetup;

// Fresh macrocells and renderer per render over one evaluator (its launch configurations are
// chosen once, so a query's value does not depend on which render asks), no refinement.
test::ShareRenderer gpuRenderer(const DeviceFieldEvaluator& field, const Box3f& box, double t0, double t1,
                                const MacrocellOptions& cells, const RenderScene& scene, TrackingOptions tracking) {
  tracking.refineMacrocells = false;
  return [&field, box, t0, t1, cells, scene, tracking](const RenderSettings& settings, int frames) {
    CudaMacrocellGrid grid(field, box, t0, t1, cells);
    CudaWavefrontRenderer r(field, grid, tracking);
    test::ShareRun run;
    run.frames = test::renderEachFrame(r, settings, scene, frames);
    run.image = r.premultipliedImage();
    return run;
  };
}

TEST(CudaSampleShare, SharesAverageToOneRendererOverTheirFrames) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  test::expectSharesEqualOneRendererForEveryEstimator(
      "GPU", 48,
      [&](const SceneSetup& s, const TrackingOptions& t) {
        return gpuRenderer(field, test::kCubeBox, 0, 1, test::cubeMacrocells(8, 2), s.scene, t);
      },
      {{2, 9}, {4, 18}});
}

// The same on a network (the fused evaluator's arithmetic) and the recommended estimator, and for
// the GPU ray marcher (its jitter keyed by the mapped frame).
TEST(CudaSampleShare, SharesOfANetworkAndOfTheRayMarcher) {
  REQUIRE_GPU();
  const std::string path = test::shippedModels().front();
  const InrModel model = InrModel::loadFile(path);
  const CudaInrEvaluator eval(model);
  const auto range = valueRangeFor(model, eval);
  const Box3f box = modelWorldBox(model);
  RenderSettings settings;
  settings.width = 40;
  settings.height = 32;
  const RenderScene scene = test::testScene(model, range, true);
  const test::ShareRenderer tracker = gpuRenderer(eval, box, model.domain.timeBegin, model.domain.timeEnd,
                                                  test::testMacrocells(), scene, TrackingOptions::recommended());
  const std::string name = std::filesystem::path(path).filename().string();
  test::expectSharesEqualOneRenderer(tracker, settings, 3, 10, "GPU ratio tracking on " + name);

  RayMarchOptions o;
  o.step = length(box.hi - box.lo) / 200.f;
  const test::ShareRenderer march = [&](const RenderSettings& s, int frames) {
    CudaRayMarcher r(eval, box, o);
    test::ShareRun run;
    run.frames = test::renderEachFrame(r, s, scene, frames);  // with shadows
    run.image = r.image();
    return run;
  };
  test::expectSharesEqualOneRenderer(march, settings, 2, 7, "GPU ray marcher on " + name);
}

}  // namespace
}  // namespace inr
