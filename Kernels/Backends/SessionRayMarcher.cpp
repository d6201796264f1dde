#include "Backends/SessionRayMarcher.h"

#include <type_traits>
#include <utility>

#ifdef INR_HAVE_CUDA
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Render/Cuda/CudaRayMarcher.h"
#endif

namespace inr {

namespace {

// Forwards to a marcher class that has the interface's members but no base class.
template <typename Marcher>
class MarcherAdapter final : public SessionRayMarcher {
public:
  template <typename Evaluator>
  MarcherAdapter(std::string description, const Evaluator& evaluator, const Box3f& box, const RayMarchOptions& options,
                 bool gpu)
      : description_(std::move(description)), marcher_(evaluator, box, options), gpu_(gpu) {}
  std::string description() const override { return description_; }
  bool onGpu() const override { return gpu_; }
  void setSettings(const RenderSettings& settings) override { marcher_.setSettings(settings); }
  void setScene(const RenderScene& scene) override { marcher_.setScene(scene); }
  FrameStats renderFrame() override { return marcher_.renderFrame(); }
  ImageRGBA image() const override { return marcher_.image(); }
  float step() const override { return marcher_.step(); }
  float shadowStep() const override { return marcher_.shadowStep(); }

private:
  std::string description_;
  Marcher marcher_;
  bool gpu_;
};

}  // namespace

std::unique_ptr<SessionRayMarcher> SessionRayMarcher::create(const RenderSession& session, const Box3f& box,
                                                             const RayMarchOptions& options) {
#ifdef INR_HAVE_CUDA
  if (session.backend() == RenderBackend::Cuda) {
    if (const auto* gpuEvaluator = dynamic_cast<const CudaInrEvaluator*>(&session.evaluator()))
      return std::make_unique<MarcherAdapter<CudaRayMarcher>>("GPU ray marcher", *gpuEvaluator, box, options, true);
  }
#endif
  return std::make_unique<MarcherAdapter<RayMarchRenderer>>("CPU ray marcher", session.evaluator(), box, options,
                                                            false);
}

}  // namespace inr
