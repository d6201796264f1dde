#include "Render/WavefrontRenderer.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "Render/AccumulationImage.h"

namespace inr {

namespace {
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }
}  // namespace

void WavefrontRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  const bool sizeChanged = settings.width != settings_.width || settings.height != settings_.height;
  settings_ = settings;
  if (sizeChanged) {
    const std::size_t n = std::size_t(settings_.width) * settings_.height;
    resizePixels(n);
    if (haveScene_ && !scene_.depthLimit.empty() && scene_.depthLimit.size() != n) {
      scene_.depthLimit.clear();  // stale: the next setScene must bring one of the new size
      depthLimitChanged(scene_.depthLimit);
    }
  }
  if (haveScene_) cameraView_ = scene_.camera.view(settings_.width, settings_.height);
  resetAccumulation();
}

void WavefrontRenderer::setScene(const RenderScene& scene) {
  const CameraView view = validateScene(scene, settings_);
  SceneChange change = diffScenes(haveScene_ ? &scene_ : nullptr, scene);
  change.time = change.time || macrocellTime() != scene.time;  // the grid may be shared
  const auto t0 = Clock::now();
  if (change.first || change.transferFunction) {
    tfTable_ = std::make_unique<TransferFunctionTable>(scene.transferFunction);
    transferFunctionChanged();
    ++counters_.transferFunctionUploads;
  }
  if (change.time) {
    setMacrocellTime(scene.time);
    ++counters_.workingGridUpdates;
  }
  if (change.majorants()) {
    recomputeMajorants();
    ++counters_.majorantUpdates;
  }
  if (change.depthLimit) depthLimitChanged(scene.depthLimit);
  sceneUpdateDone();
  pendingUpdateMs_ += msSince(t0);
  scene_ = scene;
  cameraView_ = view;
  haveScene_ = true;
  if (change.resetsAccumulation()) resetAccumulation();
  if (change.majorants() && options_.ghostPassesOnUpdate > 0) runGhostPasses(options_.ghostPassesOnUpdate);
}

void WavefrontRenderer::allocatePixels() {
  resizePixels(std::size_t(settings_.width) * settings_.height);
  clearAccumulation();
}

void WavefrontRenderer::resetAccumulation() {
  clearAccumulation();
  frameIndex_ = 0;
  ++counters_.accumulationResets;
}

FrameConstants WavefrontRenderer::frameConstants(std::uint32_t frame, const float* depthLimit) const {
  return makeFrameConstants(cameraView_, volumeBox(), scene_, settings_, depthLimit, frame);
}

FrameStats WavefrontRenderer::beginFrame(const char* method, const char* caller) {
  if (!haveScene_) throw std::logic_error(std::string(caller) + ": setScene first");
  FrameStats st;
  st.method = method;
  st.frame = frameIndex_;
  st.pixels = std::size_t(settings_.width) * settings_.height;
  st.updateMs = pendingUpdateMs_;
  pendingUpdateMs_ = 0.0;
  return st;
}

FrameStats WavefrontRenderer::runGhostPasses(int count) {
  if (!haveScene_) throw std::logic_error("runGhostPasses: setScene first");
  FrameStats total;
  total.method = "ghost";
  if (count <= 0) return total;
  const auto tStart = Clock::now();
  beginGhostPasses();
  const GhostSweep sweep(workingValueRange(), cellSize(), count);
  const int stride = std::max(1, options_.ghostPixelStride);
  for (int g = 0; g < count; ++g) {
    const TransferFunctionTable table(sweep.transferFunction(g));
    FrameConstants fc = frameConstants(GhostSweep::frameNumber(ghostPasses_++), nullptr);
    fc.shadows = 0;
    fc.depthLimit = nullptr;  // refine what is hidden now too: it may show up after a camera move
    traceGhostPass(table, fc, stride, total);
  }
  endGhostPasses(total);
  total.totalMs = msSince(tStart);
  return total;
}

ImageRGBA WavefrontRenderer::premultipliedImage() const {
  return accumulationImage(accumulation(), settings_.width, settings_.height, nullptr);
}

ImageRGBA WavefrontRenderer::image() const {
  return accumulationImage(accumulation(), settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
