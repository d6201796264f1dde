#pragma once
// The model files the tests and benchmarks run on, and random query points in a model's domain.
// No GoogleTest here, so the benchmarks use it too. INR_TEST_DATA_DIR (Testing/Data) is defined
// for every test (inr_add_gtest) and benchmark target.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr::test {

// Sorted paths of the *.inr files shipped in Testing/Data/models (small trained networks of every
// family), or in another folder of Testing/Data such as "real" (networks trained on simulation and
// scan data). Throws, naming the folder, when it is missing or holds no model: a test over the
// shipped models must fail, not pass vacuously, without them.
inline std::vector<std::string> shippedModels(const std::string& folder = "models") {
  const std::filesystem::path dir = std::filesystem::path(INR_TEST_DATA_DIR) / folder;
  if (!std::filesystem::is_directory(dir)) throw std::runtime_error("shipped model folder missing: " + dir.string());
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".inr") out.push_back(e.path().string());
  if (out.empty()) throw std::runtime_error("no .inr models in " + dir.string());
  std::sort(out.begin(), out.end());
  return out;
}

// n points uniform in the model's world box, drawn point by point (x, y, z, then t); t uniform
// over the model's time range, or `time` when given (no draw for t then).
inline std::vector<QueryPoint> randomQueryPoints(const InrModel& m, std::size_t n, unsigned seed,
                                                 std::optional<float> time = std::nullopt) {
  std::mt19937 rng(seed);
  const auto& b = m.domain.bounds;
  auto u = [&](double lo, double hi) { return float(std::uniform_real_distribution<double>(lo, hi)(rng)); };
  std::vector<QueryPoint> pts(n);
  for (auto& p : pts)
    p = {u(b[0], b[1]), u(b[2], b[3]), u(b[4], b[5]), time ? *time : u(m.domain.timeBegin, m.domain.timeEnd)};
  return pts;
}

// n points in the order a frame's wavefront iteration asks for them, at world time `time`: the
// rays of a square image (side at most 1024) from a camera outside the box looking at its centre,
// pixel after pixel (those whose ray meets the box), each ray's point at a random depth within
// the iteration's share of its span in the box (iteration k of K = ceil(n / rays) takes
// [k/K, (k+1)/K) of it). Neighbouring queries are neighbouring pixels at nearby depths, as in a
// render; randomQueryPoints' neighbours share nothing (what a hash grid's table reads feel).
inline std::vector<QueryPoint> rayOrderedQueryPoints(const InrModel& m, std::size_t n, unsigned seed, float time) {
  const auto& b = m.domain.bounds;
  const double lo[3] = {b[0], b[2], b[4]}, hi[3] = {b[1], b[3], b[5]};
  double c[3], d = 0;
  for (int i = 0; i < 3; ++i) c[i] = 0.5 * (lo[i] + hi[i]), d += (hi[i] - lo[i]) * (hi[i] - lo[i]);
  d = std::sqrt(d);
  // eye 1.6 diagonals from the centre, off every axis; the box's bounding sphere fills the view
  const double dir[3] = {0.55, 0.45, 0.70};
  const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
  double eye[3], fwd[3];
  for (int i = 0; i < 3; ++i) fwd[i] = -dir[i] / len, eye[i] = c[i] - 1.6 * d * fwd[i];
  double right[3] = {-fwd[2], 0.0, fwd[0]};  // fwd x (0, 1, 0)
  const double rl = std::sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
  for (double& v : right) v /= rl;
  const double up[3] = {right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
                        right[0] * fwd[1] - right[1] * fwd[0]};
  const double halfTan = 0.5 / 1.6 * 1.05;
  const int side = int(std::min<double>(1024.0, std::ceil(std::sqrt(double(std::max<std::size_t>(n, 1))))));
  struct Span { double o[3], v[3], t0, t1; };
  std::vector<Span> rays;
  for (int py = 0; py < side; ++py)
    for (int px = 0; px < side; ++px) {
      Span r{};
      const double sx = (2.0 * (px + 0.5) / side - 1.0) * halfTan, sy = (2.0 * (py + 0.5) / side - 1.0) * halfTan;
      double t0 = 0, t1 = 1e30;
      for (int i = 0; i < 3; ++i) {
        r.o[i] = eye[i];
        r.v[i] = fwd[i] + sx * right[i] + sy * up[i];
        const double a = (lo[i] - eye[i]) / r.v[i], e = (hi[i] - eye[i]) / r.v[i];
        t0 = std::max(t0, std::min(a, e));
        t1 = std::min(t1, std::max(a, e));
      }
      if (t1 <= t0) continue;
      r.t0 = t0, r.t1 = t1;
      rays.push_back(r);
    }
  if (rays.empty()) throw std::logic_error("rayOrderedQueryPoints: no ray meets the box");
  const std::size_t iterations = (n + rays.size() - 1) / rays.size();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<QueryPoint> pts(n);
  for (std::size_t q = 0; q < n; ++q) {
    const Span& r = rays[q % rays.size()];
    const double t = r.t0 + (r.t1 - r.t0) * (double(q / rays.size()) + u01(rng)) / double(iterations);
    float x[3];
    for (int i = 0; i < 3; ++i) x[i] = float(std::clamp(r.o[i] + t * r.v[i], lo[i], hi[i]));
    pts[q] = {x[0], x[1], x[2], time};
  }
  return pts;
}

}  // namespace inr::test
