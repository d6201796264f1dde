// What RenderSession offers the ParaView panel beyond rendering: progress of macrocell builds
// (setProgressHandler, RenderSessionOptions::progress) and tracking options changed on a live
// session (setTrackingOptions), with the grid's options read back (macrocellInfo).
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Common/DeviceMemory.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/ModelBox.h"

namespace inr {
namespace {

struct ProgressLog {
  std::vector<double> fractions;
  std::vector<std::string> phases;
  MacrocellProgress handler() {
    return [this](double f, const std::string& phase) {
      fractions.push_back(f);
      phases.push_back(phase);
    };
  }
  void clear() {
    fractions.clear();
    phases.clear();
  }
  // One build: starts at 0, never goes back, ends at 1, every phase names the macrocells.
  void expectOneBuild(std::size_t minEvents, const char* what) const {
    SCOPED_TRACE(what);
    ASSERT_GE(fractions.size(), minEvents);
    EXPECT_DOUBLE_EQ(fractions.front(), 0.0);
    EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
    EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
    for (const std::string& p : phases) EXPECT_NE(p.find("building macrocells"), std::string::npos) << p;
  }
};

struct SessionFixture {
  InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr");
  RenderScene scene;

  RenderSessionOptions options(int cells, int slices) const {
    RenderSessionOptions o;
    o.backend = RenderBackend::Cpu;
    o.macrocells.dims = Int3{cells, cells, cells};
    o.macrocells.temporalSlices = slices;
    // Batches of 10 lattice planes of a 16^3 grid (4 cell layers; one layer of a 32^3 grid), so a
    // slice reports in several steps (as a large grid does by default).
    o.macrocells.maxBatch = 10 * 33 * 33;
    return o;
  }
  std::unique_ptr<RenderSession> open(const RenderSessionOptions& o) {
    auto session = RenderSession::create(model, o);
    RenderSettings s;
    s.width = 64;
    s.height = 48;
    session->setSettings(s);
    const Box3f box = modelWorldBox(model);
    scene.camera = Camera::framing(box);
    const auto range = valueRangeFor(model, session->evaluator());
    scene.transferFunction = TransferFunction::preset(range[0], range[1], 0.8);
    scene.transferFunction.unitDistance = length(box.hi - box.lo) / 16.0;
    scene.time = model.domain.timeBegin;
    return session;
  }
  // A time a fraction `u` through the model's time range.
  double timeAt(double u) const { return model.domain.timeBegin + u * (model.domain.timeEnd - model.domain.timeBegin); }
};

TEST(RenderSessionProgress, FirstSceneAndUnbuiltTimesReportOneBuildEach) {
  SessionFixture f;
  ASSERT_TRUE(f.model.domain.usesTime());
  auto session = f.open(f.options(32, 5));  // 32^3 cells: 32 batches (one layer each) per slice
  ProgressLog log;
  session->setProgressHandler(log.handler());
  session->setScene(f.scene);  // the first time: slice 0
  log.expectOneBuild(8, "first scene");
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 1);
  EXPECT_EQ(log.phases.back(), "building macrocells: 1 of 5 time slices, 32x32x32 cells");

  log.clear();
  f.scene.time = f.timeAt(0.6);  // between slices 2 and 3, neither built: one build of two
  session->setScene(f.scene);
  log.expectOneBuild(16, "time change to unbuilt slices");
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 3);
  EXPECT_NE(log.phases.back().find("2 of 5"), std::string::npos);

  log.clear();
  f.scene.time = f.timeAt(0.55);  // the same two slices: no build, no progress
  session->setScene(f.scene);
  EXPECT_TRUE(log.fractions.empty());
  session->renderFrame();  // frames never report progress
  EXPECT_TRUE(log.fractions.empty());

  session->setProgressHandler({});  // removed: builds go on silently
  f.scene.time = f.timeAt(1.0);
  session->setScene(f.scene);
  EXPECT_TRUE(log.fractions.empty());
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 4);
}

TEST(RenderSessionProgress, EagerBuildReportsFromTheStart) {
  SessionFixture f;
  RenderSessionOptions o = f.options(16, 4);
  o.macrocells.lazySlices = false;
  ProgressLog log;
  o.progress = log.handler();
  auto session = f.open(o);  // every slice built while the session is created
  log.expectOneBuild(4 * 4 + 1, "eager build");  // 16^3 cells: 4 batches per slice, 4 slices
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 4);
  EXPECT_EQ(log.phases.front(), "building macrocells: 4 of 4 time slices, 16x16x16 cells");
  log.clear();
  session->setScene(f.scene);
  EXPECT_TRUE(log.fractions.empty());
}

TEST(RenderSessionProgress, BuildAllSlicesBuildsOnlyTheMissingOnesAhead) {
  SessionFixture f;
  auto session = f.open(f.options(16, 5));
  session->setScene(f.scene);  // slice 0, lazily
  ASSERT_EQ(session->macrocellInfo().slicesBuilt, 1);
  ProgressLog log;
  session->setProgressHandler(log.handler());
  session->buildAllSlices();  // the 4 others, as one build
  log.expectOneBuild(4 * 4 + 1, "build ahead");
  EXPECT_EQ(log.phases.front(), "building macrocells: 4 of 5 time slices, 16x16x16 cells");
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 5);
  log.clear();
  f.scene.time = f.timeAt(0.7);  // a first visit now finds its slices built
  session->setScene(f.scene);
  session->buildAllSlices();  // nothing left: no build, no progress
  EXPECT_TRUE(log.fractions.empty());
  EXPECT_EQ(session->macrocellInfo().slicesBuilt, 5);
}

TEST(RenderSessionProgress, ProgressDoesNotChangeTheImage) {
  SessionFixture f;
  auto quiet = f.open(f.options(16, 3));
  auto observed = f.open(f.options(16, 3));
  ProgressLog log;
  observed->setProgressHandler(log.handler());
  for (auto* s : {quiet.get(), observed.get()}) {
    s->setScene(f.scene);
    s->renderFrame();
    s->renderFrame();
  }
  EXPECT_FALSE(log.fractions.empty());
  EXPECT_EQ(quiet->image().data, observed->image().data);
}

TEST(RenderSessionOptions, MacrocellInfoReportsTheGridsOptions) {
  SessionFixture f;
  RenderSessionOptions o = f.options(16, 2);
  o.macrocells.skipBlockCells = 8;
  o.macrocells.boundsPadding = 0.125;
  auto session = f.open(o);
  const MacrocellInfo m = session->macrocellInfo();
  EXPECT_EQ(m.dims.x, 16);
  EXPECT_EQ(m.temporalSlices, 2);
  EXPECT_EQ(m.skipBlockCells, 8);
  EXPECT_DOUBLE_EQ(m.boundsPadding, 0.125);
  const MacrocellInfo d = f.open(f.options(16, 2))->macrocellInfo();
  EXPECT_EQ(d.skipBlockCells, MacrocellOptions{}.skipBlockCells);
  EXPECT_DOUBLE_EQ(d.boundsPadding, MacrocellOptions{}.boundsPadding);
}

TEST(RenderSessionOptions, TrackingOptionsChangeOnALiveSession) {
  SessionFixture f;
  auto session = f.open(f.options(8, 2));
  EXPECT_EQ(session->trackingOptions().ghostPassesOnUpdate, TrackingOptions{}.ghostPassesOnUpdate);
  EXPECT_EQ(session->trackingOptions().refineMacrocells, TrackingOptions{}.refineMacrocells);
  session->setScene(f.scene);
  session->renderFrame();
  session->renderFrame();
  const int framesBefore = session->accumulatedFrames();

  TrackingOptions t = session->trackingOptions();
  t.ghostPassesOnUpdate = 8;
  t.refineMacrocells = false;
  session->setTrackingOptions(t);
  EXPECT_EQ(session->trackingOptions().ghostPassesOnUpdate, 8);
  EXPECT_FALSE(session->trackingOptions().refineMacrocells);
  EXPECT_EQ(session->accumulatedFrames(), framesBefore);  // kept: the converged image is the same

  // Ghost passes run on the next time change: on a coarse grid (2^3 cells, whose 27 lattice
  // points per cell miss the network's extrema) they refine cells before any frame does.
  t.refineMacrocells = true;
  session->setTrackingOptions(t);
  auto coarse = f.open(f.options(2, 2));
  coarse->setScene(f.scene);
  coarse->setTrackingOptions(t);
  f.scene.time = f.timeAt(1.0);
  coarse->setScene(f.scene);
  auto plain = f.open(f.options(2, 2));  // the same without ghost passes
  plain->setScene(f.scene);
  EXPECT_GT(coarse->macrocellInfo().refinements, plain->macrocellInfo().refinements);
  EXPECT_EQ(plain->macrocellInfo().refinements, 0u);

  // Out of range: refused, naming the option; the previous options stay.
  for (int bad : {-1, TrackingOptions::kMaxGhostPasses + 1}) {
    TrackingOptions b = t;
    b.ghostPassesOnUpdate = bad;
    try {
      session->setTrackingOptions(b);
      ADD_FAILURE() << "ghost passes " << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("ghost passes"), std::string::npos) << e.what();
    }
    EXPECT_EQ(session->trackingOptions().ghostPassesOnUpdate, 8);
  }
}

// Two sessions of one model at different macrocell resolutions (the mapper's fine and coarse
// level-of-detail sessions) run one evaluator: the second is created with the first's
// sharedEvaluator(), owns it jointly (it outlives the first), and renders what a session with an
// evaluator of its own renders.
TEST(RenderSessionSharedEvaluator, ASecondSessionRunsTheFirstsEvaluator) {
  SessionFixture f;
  auto fine = f.open(f.options(16, 2));
  const SharedEvaluator shared = fine->sharedEvaluator();
  ASSERT_TRUE(shared);
  EXPECT_EQ(shared.backend, RenderBackend::Cpu);
  EXPECT_EQ(shared.evaluator.get(), &fine->evaluator());

  RenderSessionOptions o = f.options(4, 2);
  o.evaluator = shared;
  auto coarse = f.open(o);
  EXPECT_EQ(&coarse->evaluator(), &fine->evaluator()) << "the coarse session built an evaluator of its own";
  EXPECT_EQ(coarse->backend(), RenderBackend::Cpu);
  EXPECT_EQ(coarse->macrocellInfo().dims.x, 4);
  EXPECT_FALSE(coarse->options().evaluator) << "options() keeps no second reference to the evaluator";

  auto own = f.open(f.options(4, 2));  // the same session with its own evaluator
  EXPECT_NE(&own->evaluator(), &fine->evaluator());
  fine.reset();  // the shared evaluator lives on in the coarse session
  for (auto* s : {coarse.get(), own.get()}) {
    s->setScene(f.scene);
    s->renderFrame();
    s->renderFrame();
  }
  EXPECT_GT(coarse->accumulatedFrames(), 0);
  EXPECT_EQ(coarse->image().data, own->image().data);
}

TEST(RenderSessionSharedEvaluator, RefusesAnotherBackend) {
  SessionFixture f;
  auto cpu = f.open(f.options(8, 2));
  RenderSessionOptions o = f.options(8, 2);
  o.backend = RenderBackend::Cuda;
  o.evaluator = cpu->sharedEvaluator();
  try {
    RenderSession::create(f.model, o);
    ADD_FAILURE() << "a CUDA session accepted a CPU evaluator";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("shared evaluator of the cpu backend"), std::string::npos) << e.what();
  }
}

// The out-of-GPU-memory message (built on the host, so it is checked here; the GPU paths that
// throw it are cuda_oom_tests): the bytes, the device's free memory, the innermost purpose and
// its advice; without a purpose a generic one.
TEST(DeviceOutOfMemoryMessage, NamesBytesPurposeAndWhatToLower) {
  {
    const DeviceAllocationPurpose outer("the working macrocell grid", "lower the macrocell resolution");
    {
      const DeviceAllocationPurpose inner("the per-pixel state of a 16384x16384 image", "lower the image resolution");
      const DeviceOutOfMemory e = deviceOutOfMemory(std::size_t(3) << 30, std::size_t(512) << 20,
                                                    std::size_t(80) << 30, false);
      const std::string m = e.what();
      EXPECT_NE(m.find("out of GPU memory: 3.00 GiB asked for the per-pixel state of a 16384x16384 image"),
                std::string::npos) << m;
      EXPECT_NE(m.find("512.0 MiB free of 80.00 GiB"), std::string::npos) << m;
      EXPECT_NE(m.find("lower the image resolution"), std::string::npos) << m;
      EXPECT_EQ(m.find("macrocell"), std::string::npos) << "the innermost purpose only: " << m;
      EXPECT_EQ(m.find("injected"), std::string::npos) << m;
      EXPECT_EQ(e.bytesAsked(), std::size_t(3) << 30);
      EXPECT_EQ(e.purpose(), "the per-pixel state of a 16384x16384 image");
    }
    const std::string m = deviceOutOfMemory(1000, 0, 0, true).what();
    EXPECT_NE(m.find("1000 bytes asked for the working macrocell grid"), std::string::npos) << m;
    EXPECT_EQ(m.find("free of"), std::string::npos) << "free memory unknown: not printed: " << m;
    EXPECT_NE(m.find("[injected"), std::string::npos) << m;
  }
  EXPECT_EQ(DeviceAllocationPurpose::current(), nullptr);
  const std::string generic = deviceOutOfMemory(64, 0, 0, false).what();
  EXPECT_NE(generic.find("a device buffer"), std::string::npos) << generic;
  EXPECT_NE(generic.find("lower the image resolution, the macrocell resolution"), std::string::npos) << generic;
  const std::string call = deviceOutOfMemoryIn("cudaStreamCreate").what();
  EXPECT_NE(call.find("out of GPU memory in cudaStreamCreate"), std::string::npos) << call;
  EXPECT_NE(call.find("free GPU memory"), std::string::npos) << call;
}

}  // namespace
}  // namespace inr
