// One frame accounting for every estimator and method (FrameStats::closeTiming): a frame's
// totalMs holds the scene update it waited for and its buffer setup, and every millisecond of it
// is in a named stage or in otherMs. Benchmarks compare estimators by summed totalMs, so an
// estimator whose first frame left its update out would look faster than it is.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "Backends/RenderSession.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/ModelBox.h"

namespace inr {
namespace {

void expectAccounted(const FrameStats& st, const std::string& what) {
  EXPECT_GE(st.updateMs, 0.0) << what;
  EXPECT_GE(st.setupMs, 0.0) << what;
  EXPECT_GE(st.otherMs, 0.0) << what;
  // Every part inside the total, and the total made of its parts.
  EXPECT_GE(st.totalMs + 1e-9, st.updateMs + st.setupMs) << what;
  EXPECT_NEAR(st.totalMs, st.namedStagesMs() + st.otherMs, 1e-6 * (1.0 + st.totalMs)) << what;
}

TEST(FrameAccounting, FirstFrameHoldsItsUpdateForEveryEstimator) {
  const InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr");
  const Box3f box = modelWorldBox(model);
  for (const char* name : {"delta", "ratio", "march"}) {
    for (bool naive : {false, true}) {
      if (naive && std::string(name) != "delta") continue;  // the naive baseline runs one estimator
      RenderSessionOptions o;
      o.backend = RenderBackend::Cpu;
      o.macrocells.dims = Int3{12, 12, 12};
      o.macrocells.temporalSlices = 2;
      o.tracking = TrackingOptions::recommended();
      o.tracking.estimator = parsePrimaryEstimator(name);
      auto session = RenderSession::create(model, o);
      RenderSettings s;
      s.width = 32;
      s.height = 24;
      session->setSettings(s);
      RenderScene scene;
      scene.camera = Camera::framing(box);
      const auto range = valueRangeFor(model, session->evaluator());
      scene.transferFunction = TransferFunction::preset(range[0], range[1], 0.8);
      scene.transferFunction.unitDistance = length(box.hi - box.lo) / 16.0;
      scene.time = model.domain.timeBegin;
      session->setScene(scene);
      const std::string what = std::string(name) + (naive ? " (naive)" : "");
      const FrameStats first = naive ? session->renderFrameNaive() : session->renderFrame();
      // The scene's first update (working grid and majorants) is the first frame's, on every path.
      EXPECT_GT(first.updateMs, 0.0) << what;
      expectAccounted(first, what + ", first frame");
      // A time change: the next frame waits for the working-grid update and reports it.
      scene.time = model.domain.timeEnd;
      session->setScene(scene);
      const FrameStats moved = naive ? session->renderFrameNaive() : session->renderFrame();
      EXPECT_GT(moved.updateMs, 0.0) << what;
      expectAccounted(moved, what + ", after a time change");
      const FrameStats still = naive ? session->renderFrameNaive() : session->renderFrame();
      expectAccounted(still, what + ", unchanged scene");
    }
  }
}

}  // namespace
}  // namespace inr
