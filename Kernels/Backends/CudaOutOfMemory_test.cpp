// Out of GPU memory, nothing lost (issue 52, item 2): every device allocation that a user's
// request makes (a session, a larger image, ratio tracking's query slots, gradient shading, a
// macrocell slice of a new time, reprojection's history) is made to fail in turn through the
// allocation fault hook (cuda::setDeviceAllocationFault), and once for real (an image larger
// than the device). Each failure must
//  - throw DeviceOutOfMemory whose message says "out of GPU memory", the bytes asked and what to
//    lower or turn off, with no CUDA error left pending;
//  - leave the session as it was: its image, accumulated frames and settings, rendering on;
//  - give back what the failed request had allocated (device memory in use back to its level).
// Label cuda, SERIAL (it reads the device's memory in use); skipped without a usable GPU.
#include <gtest/gtest.h>

#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Common/DeviceMemory.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/TestModelBuilder.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {


// Faults are injected at most this far into one request: a request with more allocations than
// this is not fully covered (the loop stops with a failure saying so).
constexpr int kMaxFaultPosition = 400;
// Device memory in use may differ by allocator rounding after a failed request; a leaked buffer
// of the large requests below is at least a 1024x1024 float array (4 MiB). Each test first makes
// its requests once on a throwaway session, so that loading kernels on first use (CUDA's lazy
// module loading) is no part of what is measured.
constexpr std::size_t kMemoryTolerance = std::size_t(2) << 20;

std::size_t deviceBytesInUse() {
  std::size_t freeB = 0, totalB = 0;
  cudaDeviceSynchronize();
  cudaMemGetInfo(&freeB, &totalB);
  return totalB - freeB;
}

InrModel sineModel() { return test::randomSineNetwork(5, {-1, 1, -1, 1, -1, 1}, 0.0, 10.0, "oom.inr"); }

std::array<float, 2> valueRange(const InrModel& model) {
  const CpuInrEvaluator e(model, CpuEvaluatorOptions{256, 1});
  std::vector<QueryPoint> pts;
  for (int i = 0; i < 2000; ++i) {
    const float a = float(i) / 2000.f;
    pts.push_back({-1.f + 2.f * a, std::sin(7.f * a), -1.f + 2.f * std::fmod(3.f * a, 1.f), 10.f * a});
  }
  std::vector<float> v(pts.size());
  e.evaluate(pts.data(), pts.size(), v.data());
  const auto mm = std::minmax_element(v.begin(), v.end());
  return {*mm.first, *mm.second};
}

RenderSessionOptions gpuOptions() {
  RenderSessionOptions o;
  o.backend = RenderBackend::Cuda;
  o.allowFallback = false;
  o.macrocells.dims = Int3{16, 16, 16};
  o.macrocells.temporalSlices = 8;
  o.tracking = TrackingOptions::recommended();  // ratio tracking: query slots per point
  return o;
}

RenderSettings settingsOf(int w, int h) {
  RenderSettings s;
  s.width = w;
  s.height = h;
  s.seed = 11;
  return s;
}

class CudaOutOfMemory : public ::testing::Test {
protected:
  void SetUp() override { REQUIRE_GPU(); }
  void TearDown() override { cuda::setDeviceAllocationFault(0); }
};

// What a caught DeviceOutOfMemory must say; `words` name the request's purpose and advice.
void expectMessage(const DeviceOutOfMemory& e, const std::vector<std::string>& words, const std::string& what) {
  const std::string m = e.what();
  EXPECT_NE(m.find("out of GPU memory"), std::string::npos) << what << ": " << m;
  EXPECT_GT(e.bytesAsked(), 0u) << what << ": " << m;
  const bool advises = m.find("lower") != std::string::npos || m.find("turn") != std::string::npos ||
                       m.find("free GPU memory") != std::string::npos;
  EXPECT_TRUE(advises) << what << ": the message says what to lower: " << m;
  for (const std::string& w : words) EXPECT_NE(m.find(w), std::string::npos) << what << ": '" << w << "' in " << m;
  EXPECT_EQ(cudaGetLastError(), cudaSuccess) << what << ": a CUDA error was left pending";
}

// Runs `request` with the fault at allocation 1, 2, ... until it succeeds. After each failure
// `checkKept` checks the state and device memory is back to its level. Returns the messages.
std::vector<std::string> failEachAllocation(const std::string& what, const std::function<void()>& request,
                                            const std::function<void(const std::string&)>& checkKept) {
  std::vector<std::string> messages;
  for (int n = 1; n <= kMaxFaultPosition; ++n) {
    const std::size_t before = deviceBytesInUse();
    cuda::setDeviceAllocationFault(n);
    try {
      request();
      cuda::setDeviceAllocationFault(0);
      EXPECT_GT(n, 1) << what << ": the fault hook made no allocation fail (the request allocates nothing?)";
      return messages;
    } catch (const DeviceOutOfMemory& e) {
      cuda::setDeviceAllocationFault(0);
      const std::string label = what + ", allocation " + std::to_string(n) + " failing";
      expectMessage(e, {"[injected"}, label);
      messages.push_back(e.what());
      const std::size_t after = deviceBytesInUse();
      EXPECT_LE(after, before + kMemoryTolerance) << label << ": device memory not given back ("
                                                  << formatBytes(after - std::min(after, before)) << " more)";
      checkKept(label);
    }
  }
  ADD_FAILURE() << what << ": still failing with the fault at allocation " << kMaxFaultPosition;
  return messages;
}

bool anyContains(const std::vector<std::string>& messages, const std::string& word) {
  return std::any_of(messages.begin(), messages.end(),
                     [&](const std::string& m) { return m.find(word) != std::string::npos; });
}

// The session's state a failed request must leave as it was.
struct Kept {
  int frames = 0;
  int width = 0, height = 0;
  std::vector<float> image;
  static Kept of(const RenderSession& s) {
    Kept k;
    const ImageRGBA img = s.premultipliedImage();
    k.frames = s.accumulatedFrames();
    k.width = img.width;
    k.height = img.height;
    k.image = img.data;
    return k;
  }
  void expectSame(const RenderSession& s, const std::string& what) const {
    const ImageRGBA img = s.premultipliedImage();
    EXPECT_EQ(s.accumulatedFrames(), frames) << what << ": the accumulation restarted or moved";
    EXPECT_EQ(img.width, width) << what;
    EXPECT_EQ(img.height, height) << what;
    EXPECT_TRUE(img.data == image) << what << ": the image changed";
  }
};

// A GPU session rendered `frames` frames of `scene` at w x h; on `evaluator` when given (a warm-up
// session's: the evaluator's own lazily allocated buffers and autotuning are then done).
std::unique_ptr<RenderSession> renderedSession(const InrModel& model, const RenderScene& scene, int w, int h,
                                               int frames, SharedEvaluator evaluator = {}) {
  RenderSessionOptions o = gpuOptions();
  o.evaluator = evaluator;
  auto s = RenderSession::create(model, o);
  EXPECT_EQ(s->backend(), RenderBackend::Cuda) << s->description();
  // The generated kernels' code (loaded when their background compilation ends) is not what a
  // test here measures: waited for first.
  if (const auto* gpu = dynamic_cast<const CudaInrEvaluator*>(&s->evaluator())) gpu->waitForGeneratedKernels();
  s->setSettings(settingsOf(w, h));
  s->setScene(scene);
  for (int f = 0; f < frames; ++f) s->renderFrame();
  return s;
}

TEST_F(CudaOutOfMemory, LargerImageKeepsThePreviousImage) {
  const InrModel model = sineModel();
  const RenderScene scene = test::testScene(model, valueRange(model), true);
  SharedEvaluator evaluator;
  {
    auto warm = renderedSession(model, scene, 64, 48, 1);
    warm->setSettings(settingsOf(1024, 1024));
    warm->renderFrame();
    evaluator = warm->sharedEvaluator();
  }
  auto s = renderedSession(model, scene, 64, 48, 3, evaluator);
  // One failure, then the session renders on at its old size.
  Kept kept = Kept::of(*s);
  cuda::setDeviceAllocationFault(1);
  EXPECT_THROW(s->setSettings(settingsOf(1024, 1024)), DeviceOutOfMemory);
  cuda::setDeviceAllocationFault(0);
  kept.expectSame(*s, "1024x1024 refused");
  s->renderFrame();
  EXPECT_EQ(s->accumulatedFrames(), kept.frames + 1);
  // Every allocation of the request failing in turn.
  kept = Kept::of(*s);
  const auto messages = failEachAllocation(
      "setSettings 64x48 -> 1024x1024", [&] { s->setSettings(settingsOf(1024, 1024)); },
      [&](const std::string& label) { kept.expectSame(*s, label); });
  ASSERT_FALSE(messages.empty());
  EXPECT_TRUE(anyContains(messages, "1024x1024 image")) << messages.front();
  EXPECT_TRUE(anyContains(messages, "image resolution")) << messages.front();
  // The request succeeded after the faults: the new size renders.
  s->renderFrame();
  EXPECT_EQ(s->premultipliedImage().width, 1024);
  EXPECT_EQ(s->accumulatedFrames(), 1);
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);
}

TEST_F(CudaOutOfMemory, ImageLargerThanTheDeviceFailsForReal) {
  const InrModel model = sineModel();
  const RenderScene scene = test::testScene(model, valueRange(model), false);
  auto s = renderedSession(model, scene, 64, 48, 2);
  const Kept kept = Kept::of(*s);
  const std::size_t before = deviceBytesInUse();
  std::size_t freeB = 0, totalB = 0;
  cudaMemGetInfo(&freeB, &totalB);
  const int side = 32768;  // 2^30 pixels, the pipeline's largest image: far above 100 bytes each
  if (std::size_t(side) * side * 100 < freeB) GTEST_SKIP() << "this device has room for a " << side << "^2 image";
  try {
    s->setSettings(settingsOf(side, side));
    FAIL() << "a " << side << "x" << side << " image fit in " << formatBytes(freeB) << " free";
  } catch (const DeviceOutOfMemory& e) {
    expectMessage(e, {"32768x32768 image", "image resolution", "free of"}, "real out of memory");
    EXPECT_EQ(std::string(e.what()).find("[injected"), std::string::npos);
  }
  EXPECT_LE(deviceBytesInUse(), before + kMemoryTolerance) << "device memory not given back";
  kept.expectSame(*s, "real out of memory");
  s->renderFrame();
  EXPECT_EQ(s->accumulatedFrames(), kept.frames + 1);
}

TEST_F(CudaOutOfMemory, SessionCreationFailsCleanlyOrFallsBackToTheCpu) {
  const InrModel model = sineModel();
  const RenderScene scene = test::testScene(model, valueRange(model), false);
  renderedSession(model, scene, 16, 12, 1);  // warm-up
  std::unique_ptr<RenderSession> s;
  const auto messages = failEachAllocation(
      "RenderSession::create", [&] { s = RenderSession::create(model, gpuOptions()); },
      [&](const std::string& label) { EXPECT_EQ(s, nullptr) << label; });
  ASSERT_TRUE(s);
  EXPECT_EQ(s->backend(), RenderBackend::Cuda);
  EXPECT_TRUE(anyContains(messages, "network's weights")) << messages.front();
  EXPECT_TRUE(anyContains(messages, "macrocell")) << messages.front();
  s.reset();
  // With fallback (the plugin's and the CLI's auto): the CPU renders, and says why.
  RenderSessionOptions o = gpuOptions();
  o.allowFallback = true;
  cuda::setDeviceAllocationFault(1);
  auto cpu = RenderSession::create(model, o);
  cuda::setDeviceAllocationFault(0);
  EXPECT_EQ(cpu->backend(), RenderBackend::Cpu);
  EXPECT_NE(cpu->description().find("out of GPU memory"), std::string::npos) << cpu->description();
  EXPECT_NE(cpu->description().find("rendering on the CPU"), std::string::npos) << cpu->description();
  cpu->setSettings(settingsOf(16, 12));
  cpu->setScene(scene);
  cpu->renderFrame();
  EXPECT_EQ(cpu->accumulatedFrames(), 1);
}

TEST_F(CudaOutOfMemory, FrameBuffersKeepTheAccumulation) {
  // More points per iteration (kept accumulation, larger query slots for the next frame), then
  // Shade on (gradient shading's results on the first shaded frame): each allocation of those
  // frames failing leaves the frame unrendered and the image as it was.
  const InrModel model = sineModel();
  const RenderScene scene = test::testScene(model, valueRange(model), false);
  RenderScene shaded = scene;
  shaded.shading.enabled = true;
  TrackingOptions fewer = gpuOptions().tracking, more = fewer;
  fewer.pointsPerIteration = 4;
  more.pointsPerIteration = 64;
  auto run = [&](RenderSession& s, const std::function<void()>& between) {
    s.setTrackingOptions(fewer);
    s.renderFrame();
    s.renderFrame();
    s.setTrackingOptions(more);
    between();
    s.setScene(shaded);
    between();
  };
  SharedEvaluator evaluator;
  {
    auto warm = renderedSession(model, scene, 96, 64, 0);
    run(*warm, [&] { warm->renderFrame(); });
    evaluator = warm->sharedEvaluator();
  }
  auto s = renderedSession(model, scene, 96, 64, 0, evaluator);
  std::vector<std::string> messages;
  run(*s, [&] {
    const Kept kept = Kept::of(*s);
    const auto m = failEachAllocation("a frame with new buffers", [&] { s->renderFrame(); },
                                      [&](const std::string& label) { kept.expectSame(*s, label); });
    messages.insert(messages.end(), m.begin(), m.end());
    EXPECT_EQ(s->accumulatedFrames(), kept.frames + 1);
  });
  EXPECT_TRUE(anyContains(messages, "Points Per Batch")) << (messages.empty() ? "" : messages.front());
  EXPECT_TRUE(anyContains(messages, "Shade off")) << (messages.empty() ? "" : messages.front());
}

TEST_F(CudaOutOfMemory, TimeChangeKeepsTheImageAndRetries) {
  // A time whose macrocell slices are not built yet (lazy slices): building them fails, the scene,
  // the working grid and the image stay at the old time, and asking again builds them.
  const InrModel model = sineModel();
  RenderScene scene = test::testScene(model, valueRange(model), false);
  scene.time = 0.0;
  RenderScene later = scene;
  later.time = 9.3;
  SharedEvaluator evaluator;
  {
    auto warm = renderedSession(model, scene, 48, 32, 1);
    warm->setScene(later);
    evaluator = warm->sharedEvaluator();
  }
  auto s = renderedSession(model, scene, 48, 32, 2, evaluator);
  const Kept kept = Kept::of(*s);
  const int slicesBefore = s->macrocellInfo().slicesBuilt;
  // (A slice built before the failing one stays built, as any built slice does.)
  const auto messages = failEachAllocation("setScene to a time with unbuilt slices", [&] { s->setScene(later); },
                                           [&](const std::string& label) { kept.expectSame(*s, label); });
  EXPECT_TRUE(anyContains(messages, "temporal macrocell slice")) << (messages.empty() ? "" : messages.front());
  EXPECT_TRUE(anyContains(messages, "Temporal Slices")) << (messages.empty() ? "" : messages.front());
  EXPECT_GT(s->macrocellInfo().slicesBuilt, slicesBefore);
  s->renderFrame();
  EXPECT_EQ(s->accumulatedFrames(), 1);  // the new time restarted the image
}

TEST_F(CudaOutOfMemory, ReprojectionWithoutRoomRestartsTheImageWithAWarning) {
  const InrModel model = sineModel();
  RenderScene scene = test::testScene(model, valueRange(model), false);
  auto s = renderedSession(model, scene, 48, 32, 3);
  QueryReductionSettings q = s->queryReduction();
  q.reproject = true;
  s->setQueryReduction(q);
  std::vector<std::string> warnings;
  s->setWarningHandler([&](const std::string& m) { warnings.push_back(m); });
  for (int f = 0; f < 3; ++f) s->renderFrame();
  RenderScene moved = scene;
  moved.camera.position[0] += 0.05 * (moved.camera.position[2] - moved.camera.focalPoint[2]);
  cuda::setDeviceAllocationFault(1);
  s->setScene(moved);  // no throw: the image restarts instead of being reprojected
  cuda::setDeviceAllocationFault(0);
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("reprojection skipped"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("Reproject off"), std::string::npos) << warnings[0];
  s->renderFrame();
  const ImageRGBA img = s->premultipliedImage();
  EXPECT_EQ(std::count_if(img.data.begin(), img.data.end(), [](float v) { return !std::isfinite(v); }), 0);
  // With room again, the next camera move reprojects.
  RenderScene back = scene;
  s->setScene(back);
  EXPECT_EQ(warnings.size(), 1u);
}

}  // namespace
}  // namespace inr
