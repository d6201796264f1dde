#pragma once
// The model files the tests and benchmarks run on, and random query points in a model's domain.
// No GoogleTest here, so the benchmarks use it too. INR_TEST_DATA_DIR (Testing/Data) is defined
// for every test (inr_add_gtest) and benchmark target.
#include <algorithm>
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

}  // namespace inr::test
