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
#include "Render/ModelBox.h"
#include "Render/RenderMath.h"

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
  const Box3f box = modelWorldBox(m);
  const Vec3f centre = (box.lo + box.hi) * 0.5f;
  // eye 1.6 diagonals from the centre, off every axis; the box's bounding sphere fills the view
  const Vec3f fwd = normalize(Vec3f{-0.55f, -0.45f, -0.70f});
  const Vec3f eye = centre - fwd * (1.6f * length(box.hi - box.lo));
  const Vec3f right = normalize(cross(fwd, Vec3f{0.f, 1.f, 0.f}));
  const Vec3f up = cross(right, fwd);
  const float halfTan = 0.5f / 1.6f * 1.05f;
  const int side = int(std::min<double>(1024.0, std::ceil(std::sqrt(double(std::max<std::size_t>(n, 1))))));
  struct Span {
    Vec3f dir;
    float t0, t1;
  };
  std::vector<Span> rays;
  for (int py = 0; py < side; ++py)
    for (int px = 0; px < side; ++px) {
      const float sx = (2.f * (px + 0.5f) / side - 1.f) * halfTan, sy = (2.f * (py + 0.5f) / side - 1.f) * halfTan;
      Span r{fwd + right * sx + up * sy, 0.f, 0.f};
      if (intersectBox(box, eye, r.dir, r.t0, r.t1)) rays.push_back(r);
    }
  if (rays.empty()) throw std::logic_error("rayOrderedQueryPoints: no ray meets the box");
  const std::size_t iterations = (n + rays.size() - 1) / rays.size();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<QueryPoint> pts(n);
  for (std::size_t q = 0; q < n; ++q) {
    const Span& r = rays[q % rays.size()];
    const float t = float(r.t0 + (r.t1 - r.t0) * (double(q / rays.size()) + u01(rng)) / double(iterations));
    const Vec3f x = eye + r.dir * t;
    pts[q] = {std::clamp(x.x, box.lo.x, box.hi.x), std::clamp(x.y, box.lo.y, box.hi.y),
              std::clamp(x.z, box.lo.z, box.hi.z), time};
  }
  return pts;
}

}  // namespace inr::test
