#pragma once
// Where a model's gradient magnitudes lie, so a test can place a gradient-opacity ramp where it
// changes the picture (TransferFunction::gradientOpacity's |grad f| is in model space).
#include <algorithm>
#include <cmath>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"
#include "Render/ModelBox.h"

namespace inr::test {

// The median |grad f| over a 16^3 lattice of points through the model's world box at `time`
// (the evaluator's own gradient; it must provide one).
inline double medianGradientNorm(const FieldEvaluator& eval, const InrModel& model, float time) {
  const Box3f box = modelWorldBox(model);
  std::vector<QueryPoint> points;
  const int n = 16;
  for (int k = 0; k < n * n * n; ++k) {
    const float u[3] = {(k % n + 0.5f) / n, (k / n % n + 0.5f) / n, (k / (n * n) + 0.5f) / n};
    points.push_back(QueryPoint{box.lo.x + u[0] * (box.hi.x - box.lo.x), box.lo.y + u[1] * (box.hi.y - box.lo.y),
                                box.lo.z + u[2] * (box.hi.z - box.lo.z), time});
  }
  std::vector<float> values(points.size()), gradients(3 * points.size());
  eval.evaluateWithGradient(points.data(), points.size(), values.data(), gradients.data());
  std::vector<double> norms;
  for (std::size_t k = 0; k < points.size(); ++k)
    norms.push_back(std::hypot(gradients[3 * k], gradients[3 * k + 1], gradients[3 * k + 2]));
  std::nth_element(norms.begin(), norms.begin() + norms.size() / 2, norms.end());
  return norms[norms.size() / 2];
}

}  // namespace inr::test
