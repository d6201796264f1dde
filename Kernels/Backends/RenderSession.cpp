#include "Backends/RenderSession.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

#include "Evaluator/CpuInrEvaluator.h"
#include "Render/ModelBox.h"

#ifdef INR_HAVE_CUDA
#include "Cuda/CudaDevice.h"
#include "Cuda/CudaInrEvaluator.h"
#include "Cuda/Pipeline/CudaDeltaTrackingRenderer.h"
#include "Cuda/Pipeline/CudaMacrocellGrid.h"
#include "Cuda/Pipeline/CudaPerThreadMlp.h"
#endif

namespace inr {
namespace {

// The parts every backend shares: it owns evaluator -> macrocell grid -> renderer (in that
// construction order) and forwards the session interface to the renderer.
template <typename Evaluator, typename Grid, typename Renderer>
class BackendSession : public RenderSession {
public:
  template <typename EvaluatorOptions>
  BackendSession(const InrModel& model, const EvaluatorOptions& eo, const RenderSessionOptions& o)
      : evaluator_(model, eo),
        grid_(evaluator_, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, lazy(o.macrocells)),
        renderer_(evaluator_, grid_, o.tracking) {
    // The grid is created lazy so that an eager build happens here, once the progress handler
    // is in place (a grid builds eager slices in its constructor).
    grid_.setProgressHandler(o.progress);
    if (!o.macrocells.lazySlices) grid_.buildAllSlices();
  }
  const FieldEvaluator& evaluator() const override { return evaluator_; }
  void setSettings(const RenderSettings& s) override { renderer_.setSettings(s); }
  void setScene(const RenderScene& s) override { renderer_.setScene(s); }
  void setQueryReduction(const QueryReductionSettings& q) override { renderer_.setQueryReduction(q); }
  const QueryReductionSettings& queryReduction() const override { return renderer_.queryReduction(); }
  FrameStats renderFrame() override { return renderer_.renderFrame(); }
  FrameStats runGhostPasses(int count) override { return renderer_.runGhostPasses(count); }
  void setTrackingOptions(const TrackingOptions& t) override { renderer_.setTrackingOptions(t); }
  const TrackingOptions& trackingOptions() const override { return renderer_.trackingOptions(); }
  void resetAccumulation() override { renderer_.resetAccumulation(); }
  int accumulatedFrames() const override { return renderer_.accumulatedFrames(); }
  ImageRGBA image() const override { return renderer_.image(); }
  ImageRGBA premultipliedImage() const override { return renderer_.premultipliedImage(); }
  std::vector<float> residual() const override { return renderer_.residual(); }
  const RendererCounters& counters() const override { return renderer_.counters(); }
  void setWarningHandler(std::function<void(const std::string&)> handler) override {
    renderer_.setWarningHandler(std::move(handler));
  }
  void setProgressHandler(MacrocellProgress handler) override { grid_.setProgressHandler(std::move(handler)); }
  void buildAllSlices() override { grid_.buildAllSlices(); }
  void buildSlicesFor(double time) override { grid_.buildSlicesFor(time); }
  MacrocellInfo macrocellInfo() const override {
    MacrocellInfo i;
    i.dims = grid_.options().dims;
    i.temporalSlices = grid_.temporalSlices();
    i.skipBlockCells = grid_.options().skipBlockCells;
    i.boundsPadding = grid_.options().boundsPadding;
    i.slicesBuilt = grid_.buildStats().slicesBuilt;
    i.buildSeconds = grid_.buildStats().seconds;
    i.latticeQueries = grid_.buildStats().evaluations;
    i.refinements = grid_.refinementCount();
    return i;
  }

protected:
  static MacrocellOptions lazy(MacrocellOptions o) {
    o.lazySlices = true;
    return o;
  }
  Evaluator evaluator_;
  Grid grid_;
  Renderer renderer_;
};

class CpuRenderSession final : public BackendSession<CpuInrEvaluator, MacrocellGrid, DeltaTrackingRenderer> {
public:
  CpuRenderSession(const InrModel& model, const RenderSessionOptions& o, std::string note)
      : BackendSession(model, CpuEvaluatorOptions{256, o.cpuThreads}, o), note_(std::move(note)) {}
  RenderBackend backend() const override { return RenderBackend::Cpu; }
  std::string description() const override {
    return "cpu: " + evaluator_.name() + (note_.empty() ? "" : " (" + note_ + ")");
  }
  FrameStats renderFrameNaive() override { return renderer_.renderFrameNaive(); }

private:
  std::string note_;
};

#ifdef INR_HAVE_CUDA
// GPU slice builds report progress per slice (their lattice batches run asynchronously).
class CudaRenderSession final
    : public BackendSession<CudaInrEvaluator, CudaMacrocellGrid, CudaDeltaTrackingRenderer> {
public:
  CudaRenderSession(const InrModel& model, const RenderSessionOptions& o)
      : BackendSession(model, CudaEvaluatorOptions{o.cudaDevice}, o), model_(model) {
    renderer_.setTraversal(o.traversal);
  }
  RenderBackend backend() const override { return RenderBackend::Cuda; }
  std::string description() const override {
    return "cuda: " + evaluator_.name() + "; traversal " + renderer_.traversalChoice();
  }
  bool copyPremultipliedImage(cudaArray* target) const override {
    renderer_.copyAccumulation(target);
    return true;
  }
  FrameStats renderFrameNaive() override {
    if (!perThread_) perThread_ = std::make_unique<CudaPerThreadMlp>(model_);
    return renderer_.renderFrameNaive(*perThread_);
  }

private:
  InrModel model_;  // for the naive baseline's per-thread network, built on first use
  std::unique_ptr<CudaPerThreadMlp> perThread_;
};
#endif

}  // namespace

RenderBackend parseRenderBackend(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
  if (n == "auto") return RenderBackend::Auto;
  if (n == "cpu") return RenderBackend::Cpu;
  if (n == "cuda" || n == "gpu") return RenderBackend::Cuda;
  throw std::invalid_argument("unknown backend '" + name + "' (choose auto, cpu or cuda)");
}

const char* renderBackendName(RenderBackend backend) {
  switch (backend) {
    case RenderBackend::Auto: return "auto";
    case RenderBackend::Cpu: return "cpu";
    case RenderBackend::Cuda: return "cuda";
  }
  return "?";
}

bool cudaBackendAvailable(std::string* reason) {
#ifdef INR_HAVE_CUDA
  const CudaDeviceInfo d = queryCudaDevice();
  if (reason) *reason = d.reason;
  return d.usable;
#else
  if (reason) *reason = "this build has no CUDA backend (configure with nvcc available, INR_ENABLE_CUDA)";
  return false;
#endif
}

int cudaDeviceCount() {
#ifdef INR_HAVE_CUDA
  return countCudaDevices();
#else
  return 0;
#endif
}

std::unique_ptr<RenderSession> RenderSession::create(const InrModel& model, const RenderSessionOptions& options) {
  std::string why;
  if (options.backend == RenderBackend::Cpu) return std::make_unique<CpuRenderSession>(model, options, "");
  const bool cuda = cudaBackendAvailable(&why);
  if (cuda) {
#ifdef INR_HAVE_CUDA
    return std::make_unique<CudaRenderSession>(model, options);
#endif
  }
  if (options.backend == RenderBackend::Cuda && !options.allowFallback)
    throw std::runtime_error("CUDA backend requested but unavailable: " + why);
  return std::make_unique<CpuRenderSession>(
      model, options, (options.backend == RenderBackend::Cuda ? "CUDA requested but unavailable: " : "CUDA unavailable: ") + why);
}

}  // namespace inr
