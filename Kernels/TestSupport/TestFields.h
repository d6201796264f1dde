#pragma once
// Analytic FieldEvaluators for the render tests (no network needed), and a counting wrapper.
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/MajorantGrid.h"

namespace inr::test {

// An analytic field, optionally with its analytic gradient (d f / d x, y, z) for shading.
class FunctionField : public FieldEvaluator {
public:
  using Gradient = std::function<std::array<float, 3>(const QueryPoint&)>;
  explicit FunctionField(std::function<float(const QueryPoint&)> f, std::string name = "analytic",
                         Gradient gradient = nullptr)
      : f_(std::move(f)), gradient_(std::move(gradient)), name_(std::move(name)) {}
  void evaluate(const QueryPoint* p, std::size_t n, float* out) const override {
    calls_ += 1;
    points_ += n;
    for (std::size_t i = 0; i < n; ++i) out[i] = f_(p[i]);
  }
  bool providesGradient() const override { return gradient_ != nullptr; }
  void evaluateWithGradient(const QueryPoint* p, std::size_t n, float* values, float* gradients) const override {
    if (!gradient_) FieldEvaluator::evaluateWithGradient(p, n, values, gradients);
    gradientCalls_ += 1;
    gradientPoints_ += n;
    for (std::size_t i = 0; i < n; ++i) {
      values[i] = f_(p[i]);
      const std::array<float, 3> g = gradient_(p[i]);
      for (int k = 0; k < 3; ++k) gradients[3 * i + k] = g[k];
    }
  }
  std::string name() const override { return name_; }
  std::size_t points() const { return points_; }
  std::size_t calls() const { return calls_; }
  std::size_t gradientPoints() const { return gradientPoints_; }
  std::size_t gradientCalls() const { return gradientCalls_; }
  void resetCounts() { points_ = 0, calls_ = 0, gradientPoints_ = 0, gradientCalls_ = 0; }

private:
  std::function<float(const QueryPoint&)> f_;
  Gradient gradient_;
  std::string name_;
  mutable std::size_t points_ = 0, calls_ = 0, gradientPoints_ = 0, gradientCalls_ = 0;
};

// A Gaussian blob exp(-|p - centre|^2 / w^2) at the centre of [-1,1]^3 shifted by (0.1, -0.05, 0)
// (not time-varying) and its gradient: level sets are spheres, so the outward normal at p is
// the unit vector from the centre, which the shading tests predict the light from.
constexpr float kBlobCentre[3] = {0.1f, -0.05f, 0.f};
constexpr float kBlobWidth = 0.6f;
inline float blobField(const QueryPoint& p) {
  const float dx = p.x - kBlobCentre[0], dy = p.y - kBlobCentre[1], dz = p.z - kBlobCentre[2];
  return std::exp(-(dx * dx + dy * dy + dz * dz) / (kBlobWidth * kBlobWidth));
}
inline std::array<float, 3> blobGradient(const QueryPoint& p) {
  const float k = -2.f * blobField(p) / (kBlobWidth * kBlobWidth);
  return {k * (p.x - kBlobCentre[0]), k * (p.y - kBlobCentre[1]), k * (p.z - kBlobCentre[2])};
}

// Smooth time-varying field on [-1,1]^3 with values in about [0, 1].
inline float smoothField(const QueryPoint& p) {
  return 0.5f + 0.35f * std::sin(2.2f * p.x + 0.7f * p.t) * std::cos(1.7f * p.y - 0.4f * p.t) *
                    std::sin(1.9f * p.z + 1.1f) +
         0.15f * std::exp(-4.f * ((p.x - 0.3f) * (p.x - 0.3f) + p.y * p.y + (p.z + 0.2f) * (p.z + 0.2f)));
}

// Sparse time-varying field on [-1,1]^3 with values in [0, 1]: a few compact blobs, exactly 0
// outside their radii. Under a TF with zero opacity at 0 most macrocells (and most blocks of
// them) are empty: the scene empty-space skipping is for.
inline float sparseField(const QueryPoint& p) {
  struct Blob {
    float x, y, z, r;
  };
  const Blob blobs[] = {{-0.45f, 0.3f, 0.2f, 0.3f}, {0.5f, -0.35f, -0.4f, 0.22f}, {0.1f, 0.55f, -0.6f, 0.16f},
                        {0.62f, 0.6f, 0.58f, 0.12f}};
  float v = 0.f;
  for (const Blob& b : blobs) {
    const float dx = p.x - b.x - 0.1f * p.t, dy = p.y - b.y, dz = p.z - b.z + 0.05f * p.t;
    const float q = 1.f - (dx * dx + dy * dy + dz * dz) / (b.r * b.r);
    if (q > 0.f) v = std::max(v, q * q);
  }
  return v;
}

// Brute-force coarse skip level (the CPU and GPU skipping tests' reference): block value =
// max(0, max of the cell majorants it covers), blocks of B^3 cells over a grid of dims d.
inline std::vector<float> bruteBlocks(const Int3& d, int B, const std::vector<float>& cells) {
  const Int3 bd{(d.x + B - 1) / B, (d.y + B - 1) / B, (d.z + B - 1) / B};
  std::vector<float> out(std::size_t(bd.x) * bd.y * bd.z, 0.f);
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        float& b = out[std::size_t((z / B * bd.y + y / B) * bd.x + x / B)];
        b = std::max(b, cells[std::size_t(linearCellIndex(d, Int3{x, y, z}))]);
      }
  return out;
}

}  // namespace inr::test
