#pragma once
// The paper-size architectures the benchmarks compare on, built in memory with properly
// initialised random weights (values matter little for speed, but keep activations in range):
//   SIREN    4 -> 256 x 5 sine(30) -> 1
//   FFN      256 Fourier features (B ~ N(0, 10^2)), 5 x 256 SiLU, -> 1
//   CoordNet init 48: ResBlocks 4->48->96->192, 6 x 192, 192->1 (sine 30, 0.5-weighted)
#include <random>
#include <string>
#include <vector>

#include "Model/InrModel.h"
#include "TestSupport/TestModelBuilder.h"

namespace inr::bench {

class ArchitectureBuilder {
public:
  explicit ArchitectureBuilder(unsigned seed) : rng_(seed) {}

  nlohmann::json linear(int in, int out, float bound) {
    const std::string n = "l" + std::to_string(tensors_.size());
    add(n + ".weight", {out, in}, bound);
    add(n + ".bias", {out}, 1.f / std::sqrt(float(in)));
    return {{"type", "linear"}, {"weight", n + ".weight"}, {"bias", n + ".bias"}};
  }
  nlohmann::json sirenLinear(int in, int out, bool first) {
    return linear(in, out, first ? 1.f / in : std::sqrt(6.f / in) / 30.f);
  }
  nlohmann::json fourier(int in, int features, float sigma) {
    std::normal_distribution<float> d(0.f, sigma);
    std::vector<float> v(std::size_t(features) * in);
    for (auto& x : v) x = d(rng_);
    tensors_.push_back({"B", {features, in}, v});
    return {{"type", "fourier"}, {"B", "B"}};
  }
  InrModel finish(const nlohmann::json& layers, const std::string& label) {
    nlohmann::json arch = {{"input_dim", 4}, {"layers", layers}};
    bytes_ = test::buildSafeTensors(tensors_, test::modelMetadata(arch));
    return InrModel::loadBytes(bytes_.data(), bytes_.size(), label);
  }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

private:
  void add(const std::string& name, std::vector<std::int64_t> shape, float bound) {
    std::uniform_real_distribution<float> d(-bound, bound);
    std::size_t n = 1;
    for (auto s : shape) n *= std::size_t(s);
    std::vector<float> v(n);
    for (auto& x : v) x = d(rng_);
    tensors_.push_back({name, shape, v});
  }
  std::mt19937 rng_;
  std::vector<test::TensorSpec> tensors_;
  std::vector<std::uint8_t> bytes_;
};

// The paper's SIREN (4->256 x depth->1, sine w0 30); other depths show how costs grow with it.
inline InrModel sirenOfDepth(int depth, unsigned seed = 1, std::vector<std::uint8_t>* file = nullptr) {
  ArchitectureBuilder b(seed);
  nlohmann::json layers = nlohmann::json::array();
  int in = 4;
  for (int i = 0; i < depth; ++i) {
    layers.push_back(b.sirenLinear(in, 256, i == 0));
    layers.push_back({{"type", "sine"}, {"w0", 30}});
    in = 256;
  }
  layers.push_back(b.sirenLinear(256, 1, false));
  InrModel m = b.finish(layers, "SIREN 4->256x" + std::to_string(depth) + "->1");
  if (file) *file = b.bytes();
  return m;
}

inline InrModel sirenPaper(unsigned seed = 1, std::vector<std::uint8_t>* file = nullptr) {
  return sirenOfDepth(5, seed, file);
}

inline InrModel ffnPaper(unsigned seed = 2, std::vector<std::uint8_t>* file = nullptr) {
  ArchitectureBuilder b(seed);
  nlohmann::json layers = nlohmann::json::array();
  layers.push_back(b.fourier(4, 256, 10.f));
  int in = 512;
  for (int i = 0; i < 5; ++i) {
    layers.push_back(b.linear(in, 256, std::sqrt(6.f / in)));
    layers.push_back({{"type", "silu"}});
    in = 256;
  }
  layers.push_back(b.linear(256, 1, std::sqrt(6.f / 256)));
  InrModel m = b.finish(layers, "FFN 256ff 5x256 SiLU");
  if (file) *file = b.bytes();
  return m;
}

inline InrModel coordNetPaper(unsigned seed = 3, std::vector<std::uint8_t>* file = nullptr, int init = 48,
                              int residualBlocks = 6) {
  ArchitectureBuilder b(seed);
  auto block = [&](int in, int out) {
    nlohmann::json body = {b.sirenLinear(in, out, in == 4), {{"type", "sine"}, {"w0", 30}},
                           b.sirenLinear(out, out, false), {{"type", "sine"}, {"w0", 30}}};
    nlohmann::json r = {{"type", "residual"}, {"scale", 0.5}, {"body", body}};
    if (in != out) r["shortcut"] = {b.sirenLinear(in, out, in == 4), {{"type", "sine"}, {"w0", 30}}};
    return r;
  };
  nlohmann::json layers = nlohmann::json::array();
  layers.push_back(block(4, init));
  layers.push_back(block(init, 2 * init));
  layers.push_back(block(2 * init, 4 * init));
  for (int i = 0; i < residualBlocks; ++i) layers.push_back(block(4 * init, 4 * init));
  layers.push_back(block(4 * init, 1));
  InrModel m = b.finish(layers, "CoordNet init48 6res");
  if (file) *file = b.bytes();
  return m;
}

}  // namespace inr::bench
