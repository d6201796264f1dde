#pragma once
// CPU side of stage III: gather the pending queries of all rays into one dense batch in ray order
// (deterministic for any thread count), evaluate it with one FieldEvaluator call, scatter the
// results back into the ray state.
#include <atomic>
#include <cstddef>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/TrackingPoints.h"
#include "Render/RayState.h"

namespace inr {

class QueryBatch {
public:
  // Collects the pending rays' queries; returns their number.
  std::size_t gather(const RayStateView& rs, float time);
  // One evaluator call; with a `stop` flag, sub-batches of kStoppableQueries instead, the flag
  // looked at before each: false when it was raised (the values are then incomplete: the caller
  // drops the frame). Sub-batches are a multiple of the CPU evaluator's GEMM chunk, which
  // evaluates every point as one call would.
  static constexpr std::size_t kStoppableQueries = std::size_t(1) << 16;
  bool evaluate(const FieldEvaluator& evaluator, const std::atomic<bool>* stop = nullptr);
  // Gradient opacity (Render/Evaluate.h), after evaluate: the factor of each query whose outcome
  // it can change (delta-tracking candidates: the entries are rays; points: point slots), their
  // gradients in one evaluator call; 0 for the others. The scatters then store it beside the value.
  void evaluateOpacityScales(const FieldEvaluator& evaluator, const FrameConstants& fc, const TransferFunctionView& tf,
                             const RayStateView& rs);
  void evaluatePointOpacityScales(const FieldEvaluator& evaluator, const TransferFunctionView& tf);
  // Queries the last evaluate*OpacityScales asked a gradient for.
  std::size_t gradientQueries() const { return gradientQueries_; }
  void scatter(const RayStateView& rs) const;
  // Ratio tracking and the marches (TrackingPoints.h): the pending points that need the network (majorant > 0),
  // in ray order, then point order; rayIndices() then holds their slots.
  std::size_t gatherPoints(const RayStateView& rs, const PointStateView& pts, float time);
  void scatterPoints(const PointStateView& pts) const;
  // Gradient shading (Render/Shade.h): the rays whose colour is to be lit, in ray order; then
  // their values and gradients in one evaluator call, and the lighting.
  std::size_t gatherShading(const FrameConstants& fc, const RayStateView& rs);
  void shade(const FieldEvaluator& evaluator, const FrameConstants& fc, const RayStateView& rs);

  std::size_t size() const { return count_; }
  const int* rayIndices() const { return rays_.data(); }
  const float* values() const { return values_.data(); }

private:
  // Compacts, in ray order, the queries `count(i)` says ray i has, written by write(i, k).
  template <typename Count, typename Write>
  std::size_t compact(int n, Count&& count, Write&& write);

  std::vector<QueryPoint> points_;
  std::vector<int> rays_;
  std::vector<float> values_;
  std::vector<float> gradients_;  // gradient shading and gradient opacity: 3 per query
  std::vector<float> opacityScales_;  // gradient opacity or 2D TF: the gradient term per query
  bool withOpacityScales_ = false;    // opacityScales_ holds this batch's factors
  std::size_t gradientQueries_ = 0;
  std::vector<std::size_t> needGradient_;  // gradient opacity: the queries that need their factor
  std::vector<QueryPoint> gradientPoints_;
  std::vector<float> gradientValues_;
  // Computes opacityScales_ for the queries `needs(k)` selects (the empty term for the others).
  template <typename Needs>
  void evaluateOpacityScalesWhere(const FieldEvaluator& evaluator, const TransferFunctionView& tf, Needs&& needs);
  std::vector<std::size_t> chunkOffsets_;
  std::size_t count_ = 0;
};

}  // namespace inr
