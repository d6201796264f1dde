#pragma once
// CPU side of stage III: gather the pending queries of all rays into one dense batch in ray order
// (deterministic for any thread count), evaluate it with one FieldEvaluator call, scatter the
// results back into the ray state.
#include <cstddef>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/RayState.h"

namespace inr {

class QueryBatch {
public:
  // Collects the pending rays' queries; returns their number.
  std::size_t gather(const RayStateView& rs, float time);
  void evaluate(const FieldEvaluator& evaluator);
  void scatter(const RayStateView& rs) const;

  std::size_t size() const { return count_; }
  const int* rayIndices() const { return rays_.data(); }
  const float* values() const { return values_.data(); }

private:
  std::vector<QueryPoint> points_;
  std::vector<int> rays_;
  std::vector<float> values_;
  std::vector<std::size_t> chunkOffsets_;
  std::size_t count_ = 0;
};

}  // namespace inr
