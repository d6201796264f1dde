// RenderSession::workingMeanField: the fine macrocells' per-cell means as a stand-in field (the
// plugin's camera drags on the CPU), and a session run on it (SharedEvaluator of any host field).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

struct StandInFixture {
  InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr");
  RenderSettings settings;
  RenderScene scene;
  std::array<float, 2> range{0.f, 1.f};

  RenderSessionOptions options(SharedEvaluator on = {}) const {
    RenderSessionOptions o;
    o.backend = RenderBackend::Cpu;
    o.macrocells.dims = Int3{32, 32, 32};
    o.macrocells.temporalSlices = 4;
    o.evaluator = std::move(on);
    return o;
  }
  std::unique_ptr<RenderSession> open(SharedEvaluator on = {}) {
    auto session = RenderSession::create(model, options(std::move(on)));
    settings.width = 80;
    settings.height = 64;
    settings.seed = 7;
    session->setSettings(settings);
    range = valueRangeFor(model, session->evaluator());
    scene = test::testScene(model, range, false, ShadowEstimator::Ratio, 0.8);
    scene.time = model.domain.timeBegin + 0.3 * (model.domain.timeEnd - model.domain.timeBegin);
    session->setScene(scene);
    return session;
  }
};

TEST(WorkingMeanField, FollowsTheNetworkAtTheSceneTime) {
  StandInFixture f;
  auto session = RenderSession::create(f.model, f.options());
  EXPECT_EQ(session->workingMeanField(f.model.domain.timeBegin), nullptr) << "no scene set yet";
  session = f.open();  // the scene at f.scene.time
  EXPECT_EQ(session->workingMeanField(f.model.domain.timeBegin), nullptr) << "another time";
  const auto field = session->workingMeanField(f.scene.time);
  ASSERT_NE(field, nullptr);
  EXPECT_EQ(field->dims().x, 32);
  EXPECT_EQ(field->dims().z, 32);
  EXPECT_NE(field->name().find("macrocell means"), std::string::npos) << field->name();

  // At the cell centres the stand-in is the cell's mean: near the network's value there.
  const Box3f box = field->box();
  std::vector<QueryPoint> centres;
  for (int k = 1; k < 32; k += 3)
    for (int j = 1; j < 32; j += 3)
      for (int i = 1; i < 32; i += 3)
        centres.push_back(QueryPoint{box.lo.x + (i + 0.5f) * (box.hi.x - box.lo.x) / 32.f,
                                     box.lo.y + (j + 0.5f) * (box.hi.y - box.lo.y) / 32.f,
                                     box.lo.z + (k + 0.5f) * (box.hi.z - box.lo.z) / 32.f, float(f.scene.time)});
  std::vector<float> net(centres.size()), standIn(centres.size());
  session->evaluator().evaluate(centres.data(), centres.size(), net.data());
  field->evaluate(centres.data(), centres.size(), standIn.data());
  double err = 0.0;
  for (std::size_t i = 0; i < centres.size(); ++i) err += std::fabs(double(net[i]) - double(standIn[i]));
  err /= double(centres.size()) * double(f.range[1] - f.range[0]);
  EXPECT_LT(err, 0.02) << "mean |network - stand-in| at cell centres, fraction of the value range";

  // After a time change the working grid is the new time's.
  const double before = f.scene.time;
  f.scene.time = f.model.domain.timeEnd;
  session->setScene(f.scene);
  EXPECT_EQ(session->workingMeanField(before), nullptr);
  ASSERT_NE(session->workingMeanField(f.scene.time), nullptr);
  EXPECT_NE(session->workingMeanField(f.scene.time)->values(), field->values());
}

TEST(WorkingMeanField, ASessionOnTheStandInDrawsNearlyTheNetworksImage) {
  StandInFixture f;
  auto network = f.open();
  constexpr int kFrames = 64;
  for (int k = 0; k < kFrames; ++k) network->renderFrame();
  const auto field = network->workingMeanField(f.scene.time);
  ASSERT_NE(field, nullptr);

  auto standIn = f.open(SharedEvaluator{field, RenderBackend::Cpu, 0});
  EXPECT_EQ(&standIn->evaluator(), field.get());
  EXPECT_NE(standIn->description().find("grid 32x32x32"), std::string::npos) << standIn->description();
  for (int k = 0; k < kFrames; ++k) standIn->renderFrame();

  const ImageRGBA reference = network->image(), coverage = network->premultipliedImage();
  const double psnr = test::psnrOverCoverage(standIn->image(), reference, coverage);
  std::printf("stand-in vs network, %d frames each, 80x64: %.1f dB over the volume's pixels\n", kFrames, psnr);
  EXPECT_GT(psnr, 24.0);
}

}  // namespace
}  // namespace inr
