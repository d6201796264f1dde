#pragma once
// Test-only: the relative error of gradients (3 per point) against reference gradients, as the
// gradient tests of every evaluator measure it (CPU forward mode, the fused kernel's tangent
// rows and their CPU emulation).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace inr::test {

struct GradientError {
  double maxRelative = 0;  // max over points of |g - reference| / max(|reference|, floor)
  std::size_t worst = 0;
  double worstNormOverRms = 0;  // |reference| at the worst point over the points' RMS
  double median = 0, quantile90 = 0;  // over points
};

// Relative error of gradients (3 per point) against reference gradients, per point as vector
// norms. The denominator has a floor of 5% of the points' RMS reference norm: near a critical
// point of the field the gradient goes to zero, and a relative error there measures the fp32
// rounding of the forward pass (which the value carries too), not the derivative; shading
// normalises the gradient, and gradient opacity hides such points anyway.
inline GradientError relativeErrors(const std::vector<float>& gradients, const std::vector<double>& reference) {
  const std::size_t n = reference.size() / 3;
  double sumSquares = 0;
  for (double r : reference) sumSquares += r * r;
  const double floor = 0.05 * std::sqrt(sumSquares / n);
  GradientError err;
  std::vector<double> all(n);
  for (std::size_t i = 0; i < n; ++i) {
    double diff = 0, norm = 0;
    for (int a = 0; a < 3; ++a) {
      diff += std::pow(gradients[3 * i + a] - reference[3 * i + a], 2);
      norm += reference[3 * i + a] * reference[3 * i + a];
    }
    all[i] = std::sqrt(diff) / std::max(std::sqrt(norm), floor);
    if (all[i] > err.maxRelative) {
      err.maxRelative = all[i];
      err.worst = i;
      err.worstNormOverRms = std::sqrt(norm) / (20 * floor);
    }
  }
  std::sort(all.begin(), all.end());
  err.median = all[n / 2];
  err.quantile90 = all[(9 * n) / 10];
  return err;
}

}  // namespace inr::test
