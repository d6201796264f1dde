#pragma once
// Test-only: builds INR Volume files in memory (safetensors bytes) so unit tests can construct
// exact models and damaged variants without files on disk.
#include <cstdint>
#include <array>
#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "Model/InrModel.h"

namespace inr::test {

struct TensorSpec {
  std::string name;
  std::vector<std::int64_t> shape;
  std::vector<float> values;
};

inline std::vector<std::uint8_t> buildSafeTensors(const std::vector<TensorSpec>& tensors,
                                                  const std::map<std::string, std::string>& metadata) {
  nlohmann::ordered_json header;
  std::uint64_t offset = 0;
  for (const auto& t : tensors) {
    const std::uint64_t bytes = t.values.size() * 4;
    header[t.name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {offset, offset + bytes}}};
    offset += bytes;
  }
  header["__metadata__"] = metadata;
  std::string h = header.dump();
  while (h.size() % 8) h += ' ';
  std::vector<std::uint8_t> out(8 + h.size() + offset);
  std::uint64_t len = h.size();
  for (int i = 0; i < 8; ++i) out[i] = std::uint8_t(len >> (8 * i));
  std::memcpy(out.data() + 8, h.data(), h.size());
  std::uint8_t* p = out.data() + 8 + h.size();
  for (const auto& t : tensors) {
    std::memcpy(p, t.values.data(), t.values.size() * 4);
    p += t.values.size() * 4;
  }
  return out;
}

// Metadata for a model with the given architecture JSON and a default unit-box domain.
inline std::map<std::string, std::string> modelMetadata(const nlohmann::json& architecture,
                                                        const nlohmann::json& domain = nlohmann::json(),
                                                        const nlohmann::json& output = nlohmann::json()) {
  std::map<std::string, std::string> m;
  m["format"] = "inr-volume";
  m["format_version"] = "1";
  m["architecture"] = architecture.dump();
  m["domain"] = (domain.is_null() ? nlohmann::json{{"bounds", {-1, 1, -1, 1, -1, 1}}, {"time_range", {-1, 1}}}
                                  : domain).dump();
  if (!output.is_null()) m["output"] = output.dump();
  return m;
}

// A model from bytes built here; `label` names it in the loader's errors.
inline InrModel load(const std::vector<std::uint8_t>& bytes, const std::string& label = "m.inr") {
  return InrModel::loadBytes(bytes.data(), bytes.size(), label);
}

// n weights drawn uniformly from [-scale, scale].
inline std::vector<float> randomValues(std::size_t n, std::mt19937& rng, float scale = 0.5f) {
  std::uniform_real_distribution<float> d(-scale, scale);
  std::vector<float> v(n);
  for (auto& x : v) x = d(rng);
  return v;
}

// A small time-varying SIREN-like network, 4 -> 16 (sine, w0 2) -> 16 (sine, w0 1) -> 1 with the
// given weights and output bias 0.5, on `bounds` (the network sees [-1, 1]^4 whatever the box):
// cheap on the CPU, the fused fp16 kernel on the GPU.
inline InrModel sineNetwork(const std::vector<float>& w0, const std::vector<float>& b0, const std::vector<float>& w1,
                            const std::vector<float>& b1, const std::vector<float>& w2,
                            const std::array<double, 6>& bounds = {-1, 1, -1, 1, -1, 1}, double t0 = 0.0,
                            double t1 = 10.0, const std::string& label = "m.inr") {
  const int h = 16;
  const nlohmann::json arch = {{"input_dim", 4},
                               {"layers",
                                {{{"type", "linear"}, {"weight", "w0"}, {"bias", "b0"}},
                                 {{"type", "sine"}, {"w0", 2.0}},
                                 {{"type", "linear"}, {"weight", "w1"}, {"bias", "b1"}},
                                 {{"type", "sine"}, {"w0", 1.0}},
                                 {{"type", "linear"}, {"weight", "w2"}, {"bias", "b2"}}}}};
  const nlohmann::json domain = {{"bounds", bounds}, {"time_range", {t0, t1}}};
  return load(buildSafeTensors({{"w0", {h, 4}, w0}, {"b0", {h}, b0}, {"w1", {h, h}, w1}, {"b1", {h}, b1},
                                {"w2", {1, h}, w2}, {"b2", {1}, {0.5f}}},
                               modelMetadata(arch, domain)),
              label);
}

// sineNetwork with random weights from `seed` (smooth: first-layer scale 1.5, hidden 0.4).
inline InrModel randomSineNetwork(unsigned seed, const std::array<double, 6>& bounds = {-1, 1, -1, 1, -1, 1},
                                  double t0 = 0.0, double t1 = 10.0, const std::string& label = "m.inr") {
  std::mt19937 rng(seed);
  const int h = 16;
  const std::vector<float> w0 = randomValues(h * 4, rng, 1.5f), b0 = randomValues(h, rng, 1.f),
                           w1 = randomValues(h * h, rng, 0.4f), b1 = randomValues(h, rng, 0.5f),
                           w2 = randomValues(h, rng, 0.3f);
  return sineNetwork(w0, b0, w1, b1, w2, bounds, t0, t1, label);
}

}  // namespace inr::test
