#pragma once
// The evaluator behind the reader's output grid (the preview ParaView's own filters see: Slice,
// Contour, Volume on the reader's output): the model's network on the GPU where a usable one is
// (backend Auto or Cuda), else on the CPU. A grid of n points is evaluated in chunks (progress,
// abort between them) whose values are those of one call over all n points.
#include <cstddef>
#include <memory>
#include <string>

#include "Backends/RenderSession.h"
#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr {

struct PreviewEvaluatorOptions {
  RenderBackend backend = RenderBackend::Auto;
  int cudaDevice = 0;
  int cpuThreads = 0;  // 0: OpenMP's default
};

class PreviewEvaluator {
public:
  // Backend Cuda without a usable GPU throws std::runtime_error naming why; Auto falls back to the
  // CPU and says why in description(). The model must outlive the evaluator.
  PreviewEvaluator(const InrModel& model, PreviewEvaluatorOptions options = {});
  ~PreviewEvaluator();
  PreviewEvaluator(const PreviewEvaluator&) = delete;
  PreviewEvaluator& operator=(const PreviewEvaluator&) = delete;

  RenderBackend backend() const { return backend_; }  // Cpu or Cuda: where the grid is evaluated
  // "CUDA: <evaluator>", "CPU", or "CPU (CUDA unavailable: <why>)" where Auto found no usable GPU.
  const std::string& description() const { return description_; }

  // Points per chunk for a grid of n points: about 1/32 of them, at least 64 Ki (a small grid is
  // one chunk); on the CPU a multiple of the evaluator's GEMM chunk, which is chosen for n (small
  // enough that every core has two), so chunks give the values of one call.
  std::size_t chunkPoints(std::size_t n);
  // Values of points[0, count) of a grid of n points (chunkPoints(n) called for it first).
  void evaluate(const QueryPoint* points, std::size_t count, float* out) const;

private:
  const InrModel& model_;
  PreviewEvaluatorOptions options_;
  RenderBackend backend_ = RenderBackend::Cpu;
  std::string description_;
  std::unique_ptr<FieldEvaluator> evaluator_;
  std::size_t cpuChunk_ = 0;  // the CPU evaluator's GEMM chunk (0: not built yet)
};

}  // namespace inr
