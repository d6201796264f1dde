#include "Evaluator/ValueRange.h"

#include <algorithm>
#include <vector>

namespace inr {

SampledRange sampleValueRange(const FieldEvaluator& evaluator, const Domain& domain, int n, int timeSamples) {
  n = std::max(n, 2);
  timeSamples = domain.usesTime() ? std::max(timeSamples, 1) : 1;
  std::vector<QueryPoint> pts;
  pts.reserve(std::size_t(n) * n * n * timeSamples);
  for (int ti = 0; ti < timeSamples; ++ti) {
    const double f = timeSamples == 1 ? 0.5 : double(ti) / (timeSamples - 1);
    const float t = float(domain.timeBegin + f * (domain.timeEnd - domain.timeBegin));
    for (int k = 0; k < n; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          auto at = [&](int axis, int idx) {
            return float(domain.bounds[2 * axis] + (domain.bounds[2 * axis + 1] - domain.bounds[2 * axis]) * idx / (n - 1));
          };
          pts.push_back({at(0, i), at(1, j), at(2, k), t});
        }
  }
  std::vector<float> values(pts.size());
  evaluator.evaluate(pts.data(), pts.size(), values.data());
  SampledRange r;
  r.samples = values.size();
  const auto mm = std::minmax_element(values.begin(), values.end());
  r.min = *mm.first;
  r.max = *mm.second;
  return r;
}

std::array<float, 2> valueRangeFor(const InrModel& model, const FieldEvaluator& evaluator) {
  if (model.valueRange) return *model.valueRange;
  const SampledRange r = sampleValueRange(evaluator, model.domain, 16, 5);
  if (r.max > r.min) return {r.min, r.max};
  return {r.min - 0.5f, r.min + 0.5f};  // constant field: any non-empty range around it
}

}  // namespace inr
