#pragma once
// The scalar range a model actually produces, sampled on a lattice over its box and time range.
// Used when a model carries no value_range hint (default transfer function, `inr info`).
#include <array>

#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr {

struct SampledRange {
  float min = 0.f, max = 0.f;
  std::size_t samples = 0;
};

// n^3 node-centred points at each of `timeSamples` evenly spaced times in [t0, t1] (one at the
// middle when the model ignores time or timeSamples == 1).
SampledRange sampleValueRange(const FieldEvaluator& evaluator, const Domain& domain, int n, int timeSamples);

// The model's hint if it has one, otherwise the sampled range (never empty: lo < hi).
std::array<float, 2> valueRangeFor(const InrModel& model, const FieldEvaluator& evaluator);

}  // namespace inr
