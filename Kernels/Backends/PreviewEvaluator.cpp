#include "Backends/PreviewEvaluator.h"

#include <algorithm>
#include <stdexcept>
#include <thread>

#include "Common/DeviceMemory.h"
#include "Evaluator/CpuInrEvaluator.h"
#ifdef INR_HAVE_CUDA
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#endif

namespace inr {

namespace {
// The CPU evaluator's GEMM chunk for n points: halved from its default while there are fewer
// than two chunks per core (a default 8^3 preview is two 256-point chunks, which run on one core,
// and every time step of an animation evaluates it).
std::size_t cpuChunkFor(std::size_t n) {
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  std::size_t chunk = std::size_t(CpuEvaluatorOptions{}.chunkSize);
  while (chunk > 16 && n / chunk < 2 * cores) chunk /= 2;
  return chunk;
}
}  // namespace

PreviewEvaluator::PreviewEvaluator(const InrModel& model, PreviewEvaluatorOptions options)
    : model_(model), options_(options) {
  std::string why;
  if (options.backend != RenderBackend::Cpu && cudaBackendAvailable(&why)) {
#ifdef INR_HAVE_CUDA
    try {
      evaluator_ = std::make_unique<CudaInrEvaluator>(model, CudaEvaluatorOptions{options.cudaDevice});
      backend_ = RenderBackend::Cuda;
      description_ = "CUDA: " + evaluator_->name();
      return;
    } catch (const DeviceOutOfMemory& e) {
      if (options.backend == RenderBackend::Cuda) throw;
      why = std::string("the GPU is out of memory: ") + e.what();
    }
#endif
  }
  if (options.backend == RenderBackend::Cuda)
    throw std::runtime_error("preview on the GPU requested but CUDA is unavailable: " + why);
  backend_ = RenderBackend::Cpu;
  description_ = "CPU" + (options.backend == RenderBackend::Cpu ? std::string() : " (CUDA unavailable: " + why + ")");
}

PreviewEvaluator::~PreviewEvaluator() = default;

std::size_t PreviewEvaluator::chunkPoints(std::size_t n) {
  const std::size_t wanted = std::max<std::size_t>(std::size_t(1) << 16, (n + 31) / 32);
  if (backend_ == RenderBackend::Cuda) return wanted;
  const std::size_t chunk = cpuChunkFor(n);
  if (!evaluator_ || cpuChunk_ != chunk) {
    CpuEvaluatorOptions o;
    o.chunkSize = int(chunk);
    o.threads = options_.cpuThreads;
    evaluator_ = std::make_unique<CpuInrEvaluator>(model_, o);
    cpuChunk_ = chunk;
  }
  return (wanted + chunk - 1) / chunk * chunk;
}

void PreviewEvaluator::evaluate(const QueryPoint* points, std::size_t count, float* out) const {
  if (!evaluator_) throw std::logic_error("PreviewEvaluator::evaluate before chunkPoints");
  evaluator_->evaluate(points, count, out);
}

}  // namespace inr
