#pragma once
// An implicit neural representation loaded from an INR Volume file (Docs/FORMAT.md):
// architecture (a layer graph with fp32 weights), domain (world box, time range, and how world
// coordinates map to network inputs) and the output mapping. Host-only; evaluators turn it into
// whatever layout they run.
#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace inr {

// Every problem with a model file is reported as a ModelError whose message names the file and
// says what is wrong (and, where it helps, how to fix it).
class ModelError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

enum class LayerKind { Fourier, Linear, Sine, SiLU, ReLU, Sigmoid, Tanh, Identity, Scale, Residual, HashGrid };
enum class IncludeInput { None, First, Last };

const char* layerKindName(LayerKind kind);

// A multiresolution hash encoding (Müller et al. 2022, tiny-cuda-nn's HashGrid) of the layer's
// inputs (3 or 4 coordinates), with tiny-cuda-nn's conventions (Docs/FORMAT.md, "hashgrid").
// The per-level figures are derived once, on load, by tiny-cuda-nn's formulas in fp32, and every
// evaluator uses these very numbers, so no two evaluators can disagree on a level's resolution.
struct HashGridSpec {
  // Documented bounds (Docs/FORMAT.md), so the tables and the per-query work stay bounded.
  static constexpr int kMaxLevels = 32;            // tiny-cuda-nn's offset table
  static constexpr int kMaxLog2TableSize = 24;     // 16 M entries per level
  static constexpr int kMaxBaseResolution = 1 << 16;
  static constexpr double kMaxFinestScale = 16777216.0;  // 2^24: cells still resolved in fp32

  int levels = 0;
  int featuresPerLevel = 0;  // 1, 2, 4 or 8
  int log2TableSize = 0;
  int baseResolution = 0;
  float perLevelScale = 0.f;
  bool smoothstep = false;  // interpolation weights t^2 (3 - 2t) instead of t
  // Per level: position scale (pos = x * scale + 0.5), grid resolution ceil(scale) + 1, and the
  // level's entries [offset, offset + size) of the table (dense where resolution^D fits, else hashed).
  std::vector<float> levelScale;
  std::vector<std::uint32_t> levelResolution, levelOffset, levelSize;
  std::uint64_t entries() const { return levelOffset.empty() ? 0 : std::uint64_t(levelOffset.back()) + levelSize.back(); }
};

struct Layer {
  LayerKind kind = LayerKind::Identity;
  int inWidth = 0;
  int outWidth = 0;
  // Linear: weight [outWidth x inWidth] row-major (PyTorch layout), bias [outWidth] or empty.
  // Fourier: weight holds B [m x inWidth] row-major, outWidth = 2m (+ inWidth if included).
  // HashGrid: weight holds the table [entries x featuresPerLevel] (tiny-cuda-nn's layout: level
  // by level, entry by entry), outWidth = levels * featuresPerLevel (+ inWidth if included).
  std::vector<float> weight;
  std::vector<float> bias;
  std::string weightName, biasName;  // tensor names in the file, for messages
  float param = 0.f;                 // Sine: w0; Scale: factor; Fourier: frequency scale
  IncludeInput includeInput = IncludeInput::None;  // Fourier and HashGrid
  HashGridSpec hashGrid;                           // HashGrid only
  // Residual: out = residualScale * (body(x) + shortcut(x)); empty shortcut = identity.
  std::vector<Layer> body;
  std::vector<Layer> shortcut;
  float residualScale = 1.f;
};

struct Architecture {
  int inputDim = 0;
  std::vector<Layer> layers;
  std::size_t parameterCount() const;
  int maxWidth() const;  // widest activation vector anywhere in the graph
  std::string summary() const;  // one line, e.g. "fourier(4->512) linear(512->256) silu ..."
};

// network_input = scale * world + offset
struct AxisMap {
  double scale = 1.0;
  double offset = 0.0;
  double apply(double w) const { return scale * w + offset; }
};

enum WorldCoord : int { kX = 0, kY = 1, kZ = 2, kT = 3 };

struct Domain {
  std::array<double, 6> bounds{};  // xmin xmax ymin ymax zmin zmax (world)
  double timeBegin = 0.0, timeEnd = 1.0;  // world time range
  std::array<AxisMap, 4> toNetwork{};  // x, y, z, t
  std::vector<int> inputOrder;  // network input i reads world coordinate inputOrder[i] (WorldCoord)
  std::vector<double> timeSteps;  // optional animation hints (world times)
  bool usesTime() const;
};

struct OutputMapping {
  float scale = 1.f, offset = 0.f;
  struct PerTime {
    std::vector<double> times, min, max;
    double networkLo = -1.0, networkHi = 1.0;
  };
  std::optional<PerTime> perTime;
  // Affine map value = a * net + b at world time t.
  void affineAt(double t, float& a, float& b) const;
};

struct InrModel {
  std::string path;  // where it was loaded from (for messages)
  std::string name, description, provenance;
  Architecture architecture;
  Domain domain;
  OutputMapping output;
  std::optional<std::array<float, 2>> valueRange;  // hint for the transfer function

  static InrModel loadFile(const std::string& path);
  // `label` names the source in error messages.
  static InrModel loadBytes(const std::uint8_t* data, std::size_t size, const std::string& label);
};

}  // namespace inr
