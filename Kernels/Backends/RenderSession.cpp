#include "Backends/RenderSession.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <stdexcept>

#include "Common/DeviceMemory.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Render/ModelBox.h"

#ifdef INR_HAVE_CUDA
#include "Common/Cuda/CudaDevice.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#endif

namespace inr {
namespace {

// The parts every backend shares: it holds evaluator -> macrocell grid -> renderer (in that
// construction order; the evaluator with shared ownership, possibly another session's) and
// forwards the session interface to the renderer.
template <typename Evaluator, typename Grid, typename Renderer>
class BackendSession : public RenderSession {
public:
  BackendSession(const InrModel& model, std::shared_ptr<const Evaluator> evaluator, const RenderSessionOptions& o)
      : options_(o),
        evaluator_(std::move(evaluator)),
        grid_(*evaluator_, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, lazy(o.macrocells)),
        renderer_(*evaluator_, grid_, o.tracking) {
    options_.evaluator = SharedEvaluator{};  // sharedEvaluator() says what this session runs
    // The grid is created lazy so that an eager build happens here, once the progress handler
    // is in place (a grid builds eager slices in its constructor).
    grid_.setProgressHandler(o.progress);
    if (!o.macrocells.lazySlices) grid_.buildAllSlices();
  }
  const FieldEvaluator& evaluator() const override { return *evaluator_; }
  const RenderSessionOptions& options() const override { return options_; }
  void setSettings(const RenderSettings& s) override { renderer_.setSettings(s); }
  void setScene(const RenderScene& s) override { renderer_.setScene(s); }
  void setQueryReduction(const QueryReductionSettings& q) override { renderer_.setQueryReduction(q); }
  const QueryReductionSettings& queryReduction() const override { return renderer_.queryReduction(); }
  FrameStats renderFrame() override { return renderer_.renderFrame(); }
  FrameStats runGhostPasses(int count) override { return renderer_.runGhostPasses(count); }
  void setTrackingOptions(const TrackingOptions& t) override { renderer_.setTrackingOptions(t); }
  const TrackingOptions& trackingOptions() const override { return renderer_.trackingOptions(); }
  void resetAccumulation() override { renderer_.resetAccumulation(); }
  void setStopRequest(const std::atomic<bool>* stop) override { renderer_.setStopRequest(stop); }
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
  RenderSessionOptions options_;
  std::shared_ptr<const Evaluator> evaluator_;
  Grid grid_;
  Renderer renderer_;
};

// Runs any host FieldEvaluator: its own CpuInrEvaluator, another session's, or a stand-in of the
// network (a GridField: RenderSession::workingMeanField).
class CpuRenderSession final : public BackendSession<FieldEvaluator, MacrocellGrid, CpuWavefrontRenderer> {
public:
  CpuRenderSession(const InrModel& model, std::shared_ptr<const FieldEvaluator> evaluator,
                   const RenderSessionOptions& o, std::string note)
      : BackendSession(model, std::move(evaluator), o), note_(std::move(note)) {}
  RenderBackend backend() const override { return RenderBackend::Cpu; }
  std::string description() const override {
    return "cpu: " + evaluator_->name() + (note_.empty() ? "" : " (" + note_ + ")");
  }
  SharedEvaluator sharedEvaluator() const override { return SharedEvaluator{evaluator_, RenderBackend::Cpu, 0}; }
  FrameStats renderFrameNaive() override { return renderer_.renderFrameNaive(); }
  std::shared_ptr<const GridField> workingMeanField(double time) const override {
    if (!grid_.hasWorkingGrid() || grid_.time() != time) return nullptr;
    return std::make_shared<const GridField>(grid_.box(), grid_.dims(), grid_.workingMean(),
                                             "macrocell means at t=" + std::to_string(grid_.time()));
  }

private:
  std::string note_;
};

#ifdef INR_HAVE_CUDA
// GPU slice builds report progress per slice (their lattice batches run asynchronously).
class CudaRenderSession final
    : public BackendSession<CudaInrEvaluator, CudaMacrocellGrid, CudaWavefrontRenderer> {
public:
  CudaRenderSession(const InrModel& model, std::shared_ptr<const CudaInrEvaluator> evaluator,
                    const RenderSessionOptions& o)
      : BackendSession(model, std::move(evaluator), o), model_(model), device_(o.cudaDevice) {
    renderer_.setTraversal(o.traversal);
  }
  RenderBackend backend() const override { return RenderBackend::Cuda; }
  std::string description() const override {
    return "cuda: " + evaluator_->name() + "; traversal " + renderer_.traversalChoice();
  }
  SharedEvaluator sharedEvaluator() const override {
    return SharedEvaluator{evaluator_, RenderBackend::Cuda, device_};
  }
  bool copyPremultipliedImage(cudaArray* target) const override {
    renderer_.copyAccumulation(target);
    return true;
  }
  // A new image size is allocated beside the current one before anything changes: if it does not
  // fit, DeviceOutOfMemory leaves the settings, the image and its accumulation as they were.
  void setSettings(const RenderSettings& s) override {
    const RenderSettings& now = renderer_.settings();
    if (s.width > 0 && s.height > 0 && (s.width != now.width || s.height != now.height))
      renderer_.reservePixels(s.width, s.height);
    renderer_.setSettings(s);
  }
  void setScene(const RenderScene& s) override {
    renderer_.setScene(s);
    passOnMemoryNote();
  }
  FrameStats renderFrame() override {
    FrameStats st = renderer_.renderFrame();
    passOnMemoryNote();
    return st;
  }
  void setWarningHandler(std::function<void(const std::string&)> handler) override {
    warn_ = handler;
    renderer_.setWarningHandler(std::move(handler));
  }
  FrameStats renderFrameNaive() override {
    if (!perThread_) perThread_ = std::make_unique<CudaPerThreadMlp>(model_);
    return renderer_.renderFrameNaive(*perThread_);
  }

private:
  // Work the renderer left out for lack of GPU memory (reprojection) goes where its warnings go.
  void passOnMemoryNote() {
    const std::string note = renderer_.takeMemoryNote();
    if (note.empty()) return;
    if (warn_)
      warn_(note);
    else
      std::fprintf(stderr, "INR Volume: warning: %s\n", note.c_str());
  }
  std::function<void(const std::string&)> warn_;
  InrModel model_;  // for the naive baseline's per-thread network, built on first use
  std::unique_ptr<CudaPerThreadMlp> perThread_;
  int device_ = 0;
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

namespace {
// A session on another session's evaluator (RenderSessionOptions::evaluator): its backend and
// device are the evaluator's.
std::unique_ptr<RenderSession> createOnShared(const InrModel& model, const RenderSessionOptions& options) {
  const SharedEvaluator& shared = options.evaluator;
  if (options.backend != RenderBackend::Auto && options.backend != shared.backend)
    throw std::invalid_argument(std::string("a shared evaluator of the ") + renderBackendName(shared.backend) +
                                " backend cannot run a " + renderBackendName(options.backend) + " session");
  if (shared.backend == RenderBackend::Cpu) return std::make_unique<CpuRenderSession>(model, shared.evaluator, options, "");
#ifdef INR_HAVE_CUDA
  if (options.cudaDevice != shared.cudaDevice)
    throw std::invalid_argument("the shared evaluator runs on CUDA device " + std::to_string(shared.cudaDevice) +
                                ", not on device " + std::to_string(options.cudaDevice));
  auto cuda = std::dynamic_pointer_cast<const CudaInrEvaluator>(shared.evaluator);
  if (!cuda) throw std::invalid_argument("the shared evaluator is not a CUDA INR evaluator");
  return std::make_unique<CudaRenderSession>(model, std::move(cuda), options);
#else
  throw std::invalid_argument("a shared CUDA evaluator in a build without the CUDA backend");
#endif
}
}  // namespace

std::unique_ptr<RenderSession> RenderSession::create(const InrModel& model, const RenderSessionOptions& options) {
  if (options.evaluator) return createOnShared(model, options);
  auto cpuEvaluator = [&] {
    return std::make_shared<const CpuInrEvaluator>(model, CpuEvaluatorOptions{256, options.cpuThreads});
  };
  std::string why;
  if (options.backend == RenderBackend::Cpu) return std::make_unique<CpuRenderSession>(model, cpuEvaluator(), options, "");
  const bool cuda = cudaBackendAvailable(&why);
  if (cuda) {
#ifdef INR_HAVE_CUDA
    try {
      return std::make_unique<CudaRenderSession>(
          model, std::make_shared<const CudaInrEvaluator>(model, CudaEvaluatorOptions{options.cudaDevice}), options);
    } catch (const DeviceOutOfMemory& e) {
      // Everything the attempt allocated is freed by now (RAII). CUDA asked for without fallback:
      // the caller gets the message; else (auto, or fallback allowed) the CPU renders and
      // description() says why.
      if (options.backend == RenderBackend::Cuda && !options.allowFallback) throw;
      return std::make_unique<CpuRenderSession>(model, cpuEvaluator(), options,
                                                std::string("the GPU is out of memory, rendering on the CPU: ") +
                                                    e.what());
    }
#endif
  }
  if (options.backend == RenderBackend::Cuda && !options.allowFallback)
    throw std::runtime_error("CUDA backend requested but unavailable: " + why);
  return std::make_unique<CpuRenderSession>(
      model, cpuEvaluator(), options,
      (options.backend == RenderBackend::Cuda ? "CUDA requested but unavailable: " : "CUDA unavailable: ") + why);
}

}  // namespace inr
