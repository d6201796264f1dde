#pragma once
// Test-only: hash-grid models (tiny-cuda-nn's HashGrid, Docs/FORMAT.md "hashgrid") built in
// memory with random fp16-representable tables and a small MLP, for the evaluator, GPU and
// macrocell tests. The table size is computed here by the format's formula, independently of the
// loader, so a loader that sized levels differently rejects these models.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "Common/Half.h"
#include "TestSupport/TestModelBuilder.h"

namespace inr::test {

struct HashGridOptions {
  int dims = 3;  // 3: x, y, z; 4: x, y, z, t
  int levels = 8;
  int featuresPerLevel = 2;
  int log2TableSize = 12;
  int baseResolution = 4;
  double perLevelScale = 2.0;
  bool smoothstep = false;
  std::string includeInput = "none";
  int width = 32;       // hidden width of the MLP after the encoding
  int hiddenLayers = 1;  // linear + relu pairs before the final linear
  float tableScale = 0.5f;
  unsigned seed = 1;
};

// tiny-cuda-nn style: `levels` levels of 2 features over `dims` inputs into `hiddenLayers` x
// `width` ReLU.
inline HashGridOptions hashGridMlp(int dims, int levels, int log2TableSize, int baseResolution, double perLevelScale,
                                   int width, int hiddenLayers) {
  HashGridOptions o;
  o.dims = dims;
  o.levels = levels;
  o.log2TableSize = log2TableSize;
  o.baseResolution = baseResolution;
  o.perLevelScale = perLevelScale;
  o.width = width;
  o.hiddenLayers = hiddenLayers;
  return o;
}

// Entries of each level, by the format's formula (tiny-cuda-nn's): the dense grid rounded up to 8
// entries, or the hash table, whichever is smaller.
inline std::vector<std::uint64_t> hashGridLevelSizes(const HashGridOptions& o) {
  std::vector<std::uint64_t> sizes;
  const float log2Scale = std::log2(float(o.perLevelScale));
  for (int l = 0; l < o.levels; ++l) {
    const float scale = std::exp2(float(l) * log2Scale) * float(o.baseResolution) - 1.0f;
    const double res = std::ceil(scale) + 1.0;
    const double dense = std::min(std::pow(res, o.dims), 2147483647.0);
    sizes.push_back(std::min<std::uint64_t>((std::uint64_t(dense) + 7) / 8 * 8, std::uint64_t(1) << o.log2TableSize));
  }
  return sizes;
}

inline std::vector<std::uint8_t> hashGridModelBytes(const HashGridOptions& o) {
  std::mt19937 rng(o.seed);
  std::uint64_t entries = 0;
  for (std::uint64_t s : hashGridLevelSizes(o)) entries += s;
  std::vector<float> table = randomValues(entries * o.featuresPerLevel, rng, o.tableScale);
  for (float& v : table) v = halfBitsToFloat(floatToHalfBits(v));  // as stored in fp16
  std::vector<TensorSpec> tensors{{"enc.table", {std::int64_t(entries), o.featuresPerLevel}, table}};
  nlohmann::json layers = nlohmann::json::array();
  layers.push_back({{"type", "hashgrid"}, {"table", "enc.table"}, {"n_levels", o.levels},
                    {"n_features_per_level", o.featuresPerLevel}, {"log2_hashmap_size", o.log2TableSize},
                    {"base_resolution", o.baseResolution}, {"per_level_scale", o.perLevelScale},
                    {"interpolation", o.smoothstep ? "smoothstep" : "linear"}, {"include_input", o.includeInput}});
  int width = o.levels * o.featuresPerLevel + (o.includeInput == "none" ? 0 : o.dims);
  for (int h = 0; h <= o.hiddenLayers; ++h) {
    const bool last = h == o.hiddenLayers;
    const int out = last ? 1 : o.width;
    const std::string name = "l" + std::to_string(h);
    // Glorot-like scale keeps the field's range near 1 whatever the widths.
    tensors.push_back({name + ".weight", {out, width}, randomValues(std::size_t(out) * width, rng, 2.f / std::sqrt(float(width)))});
    tensors.push_back({name + ".bias", {out}, randomValues(out, rng, 0.1f)});
    layers.push_back({{"type", "linear"}, {"weight", name + ".weight"}, {"bias", name + ".bias"}});
    if (!last) layers.push_back({{"type", "relu"}});
    width = out;
  }
  const nlohmann::json arch{{"input_dim", o.dims}, {"layers", layers}};
  // tiny-cuda-nn's encodings take inputs in [0, 1]: the box and time range map there.
  nlohmann::json domain{{"bounds", {-1, 1, -1, 1, -1, 1}}, {"input_range", {0, 1}}, {"time_range", {0, 1}},
                        {"time_input_range", {0, 1}}};
  if (o.dims == 3) domain["input_order"] = {"x", "y", "z"};
  return buildSafeTensors(tensors, modelMetadata(arch, domain));
}

inline InrModel hashGridModel(const HashGridOptions& o = {}) { return load(hashGridModelBytes(o), "hashgrid-test.inr"); }

// A hash-grid layer on one query's inputs (in [0, 1]^D inside the grid) in double, written from
// the format's text, independently of the evaluators: per level, the cell of x * scale + 0.5, its
// vertices' entries (dense index while the grid fits the level, else the XOR-of-primes hash,
// modulo the level's size), d-linear or smoothstep weights. gridMargin, where given, gets the
// smallest distance (in input units) from x to a cell face of any level: the encoding has kinks
// there, where central differences do not estimate the derivative.
inline std::vector<double> hashGridInDouble(const Layer& L, const std::vector<double>& x, double* gridMargin = nullptr) {
  const HashGridSpec& g = L.hashGrid;
  const int D = L.inWidth, F = g.featuresPerLevel;
  std::vector<double> out;
  for (int l = 0; l < g.levels; ++l) {
    const double scale = g.levelScale[l];
    const std::uint64_t res = g.levelResolution[l], size = g.levelSize[l];
    std::vector<double> feature(F, 0.0);
    std::int64_t cell[4];
    double w[4];
    for (int d = 0; d < D; ++d) {
      const double p = scale * x[d] + 0.5;
      cell[d] = std::int64_t(std::floor(p));
      const double t = p - std::floor(p);
      if (gridMargin && scale > 0) *gridMargin = std::min(*gridMargin, std::min(t, 1 - t) / scale);
      w[d] = g.smoothstep ? t * t * (3 - 2 * t) : t;
    }
    for (int c = 0; c < (1 << D); ++c) {
      double weight = 1;
      std::uint64_t v[4];
      for (int d = 0; d < D; ++d) {
        const bool up = (c >> d) & 1;
        v[d] = std::uint64_t(cell[d] + up) & 0xffffffffu;
        weight *= up ? w[d] : 1 - w[d];
      }
      std::uint64_t dense = 1;
      for (int d = 0; d < D; ++d) dense *= res;
      std::uint64_t index = 0;
      if (dense <= size) {
        std::uint64_t stride = 1;  // uint32 arithmetic, as tiny-cuda-nn's (wrapped vertices wrap the index)
        for (int d = 0; d < D; ++d, stride *= res) index = (index + v[d] * stride) & 0xffffffffu;
      } else {
        const std::uint64_t primes[4] = {1, 2654435761u, 805459861u, 3674653429u};
        for (int d = 0; d < D; ++d) index ^= (v[d] * primes[d]) & 0xffffffffu;
      }
      index %= size;
      for (int f = 0; f < F; ++f) feature[f] += weight * L.weight[(g.levelOffset[l] + index) * F + f];
    }
    out.insert(out.end(), feature.begin(), feature.end());
  }
  if (L.includeInput == IncludeInput::First) out.insert(out.begin(), x.begin(), x.end());
  if (L.includeInput == IncludeInput::Last) out.insert(out.end(), x.begin(), x.end());
  return out;
}


}  // namespace inr::test
