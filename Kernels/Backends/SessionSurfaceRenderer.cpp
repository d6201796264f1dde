#include "Backends/SessionSurfaceRenderer.h"

#include <utility>

#ifdef INR_HAVE_CUDA
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Render/Cuda/CudaSurfaceRenderer.h"
#endif

namespace inr {

namespace {

// The host-driven renderer over the session's evaluator (CPU, or the CUDA evaluator's host
// interface).
class HostSurfaceRenderer final : public SessionSurfaceRenderer {
public:
  HostSurfaceRenderer(std::string description, const FieldEvaluator& evaluator, const Box3f& box, double timeBegin,
                      double timeEnd, const SurfaceOptions& options)
      : description_(std::move(description)), renderer_(evaluator, box, timeBegin, timeEnd, options) {}
  std::string description() const override { return description_; }
  bool onGpu() const override { return false; }
  void setSettings(const RenderSettings& settings) override { renderer_.setSettings(settings); }
  void setScene(const RenderScene& scene, const BlendScene& blend) override { renderer_.setScene(scene, blend); }
  FrameStats renderFrame() override { return renderer_.renderFrame(); }
  bool renderFramePart(double budgetMs, FrameStats* stats) override { return renderer_.renderFramePart(budgetMs, stats); }
  double frameProgress() const override { return renderer_.frameProgress(); }
  bool macrocellsBuiltFor(double time) const override { return renderer_.macrocellsBuiltFor(time); }
  void buildMacrocellsFor(double time) override { renderer_.buildMacrocellsFor(time); }
  void resetAccumulation() override { renderer_.resetAccumulation(); }
  int accumulatedFrames() const override { return renderer_.accumulatedFrames(); }
  ImageRGBA image() const override { return renderer_.image(); }
  ImageRGBA premultipliedImage() const override { return renderer_.premultipliedImage(); }
  std::vector<float> surfaceDepth() const override { return renderer_.surfaceDepth(); }
  float step() const override { return renderer_.step(); }
  float tolerance() const override { return renderer_.tolerance(); }
  MacrocellBuildStats macrocellBuildStats() const override {
    return renderer_.macrocells() ? renderer_.macrocells()->buildStats() : MacrocellBuildStats{};
  }

private:
  std::string description_;
  SurfaceRenderer renderer_;
};

#ifdef INR_HAVE_CUDA
// The GPU renderer (Render/Cuda/CudaSurfaceRenderer.h).
class GpuSurfaceRenderer final : public SessionSurfaceRenderer {
public:
  GpuSurfaceRenderer(const CudaInrEvaluator& evaluator, const Box3f& box, double timeBegin, double timeEnd,
                     const SurfaceOptions& options)
      : renderer_(evaluator, box, timeBegin, timeEnd, options) {}
  std::string description() const override { return "GPU surface renderer"; }
  bool onGpu() const override { return true; }
  void setSettings(const RenderSettings& settings) override { renderer_.setSettings(settings); }
  void setScene(const RenderScene& scene, const BlendScene& blend) override { renderer_.setScene(scene, blend); }
  FrameStats renderFrame() override { return renderer_.renderFrame(); }
  bool renderFramePart(double, FrameStats* stats) override {
    const FrameStats st = renderer_.renderFrame();
    if (stats) *stats = st;
    return true;
  }
  double frameProgress() const override { return 0.0; }
  bool macrocellsBuiltFor(double time) const override { return renderer_.macrocellsBuiltFor(time); }
  void buildMacrocellsFor(double time) override { renderer_.buildMacrocellsFor(time); }
  void resetAccumulation() override { renderer_.resetAccumulation(); }
  int accumulatedFrames() const override { return renderer_.accumulatedFrames(); }
  ImageRGBA image() const override { return renderer_.image(); }
  ImageRGBA premultipliedImage() const override { return renderer_.premultipliedImage(); }
  std::vector<float> surfaceDepth() const override { return renderer_.surfaceDepth(); }
  float step() const override { return renderer_.step(); }
  float tolerance() const override { return renderer_.tolerance(); }
  MacrocellBuildStats macrocellBuildStats() const override {
    const MacrocellGrid* grid = renderer_.host().macrocells();
    return grid ? grid->buildStats() : MacrocellBuildStats{};
  }

private:
  CudaSurfaceRenderer renderer_;
};
#endif

}  // namespace

std::unique_ptr<SessionSurfaceRenderer> SessionSurfaceRenderer::create(const RenderSession& session, const Box3f& box,
                                                                       double timeBegin, double timeEnd,
                                                                       const SurfaceOptions& options) {
#ifdef INR_HAVE_CUDA
  if (session.backend() == RenderBackend::Cuda) {
    if (const auto* gpuEvaluator = dynamic_cast<const CudaInrEvaluator*>(&session.evaluator()))
      return std::make_unique<GpuSurfaceRenderer>(*gpuEvaluator, box, timeBegin, timeEnd, options);
  }
#endif
  const std::string where = session.backend() == RenderBackend::Cuda
                                ? "host-driven surface renderer, batches on the GPU evaluator"
                                : "CPU surface renderer";
  return std::make_unique<HostSurfaceRenderer>(where, session.evaluator(), box, timeBegin, timeEnd, options);
}

}  // namespace inr
