#pragma once
// The reference evaluator: batched fp32 inference through Eigen GEMMs, multi-threaded with
// OpenMP over fixed-size chunks of queries (so a query's arithmetic does not depend on the thread
// count). Its semantics define the model; every other evaluator is tested against it.
#include <memory>

#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr {

struct CpuEvaluatorOptions {
  int chunkSize = 256;  // queries per GEMM batch; fixed, never derived from the thread count
  int threads = 0;      // 0 = OpenMP default
};

class CpuInrEvaluator final : public FieldEvaluator {
public:
  explicit CpuInrEvaluator(const InrModel& model, CpuEvaluatorOptions options = {});
  ~CpuInrEvaluator() override;
  void evaluate(const QueryPoint* points, std::size_t n, float* out) const override;
  std::string name() const override { return "cpu-eigen-fp32"; }

  // Values and their gradients with respect to world x, y, z in one pass (forward-mode
  // derivatives through the layer graph, the domain's input mapping and the output mapping):
  // values[i] as evaluate gives it (the same bits), gradients[3 i + k] = d values[i] / d world
  // axis k (x, y, z); the time derivative is not computed. Chunked and threaded as evaluate.
  // Throws std::runtime_error, naming the layer, when the graph holds a layer kind without a
  // derivative (before any output is written).
  void evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values, float* gradients) const override;
  bool providesGradient() const override { return true; }

  // Network output before the output mapping, for inputs already in network coordinates
  // (inputDim floats per query, network input order). For tests and tools.
  void evaluateNetwork(const float* inputs, std::size_t n, float* out) const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
