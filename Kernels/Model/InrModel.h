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

enum class LayerKind { Fourier, Linear, Sine, SiLU, ReLU, Sigmoid, Tanh, Identity, Scale, Residual };
enum class IncludeInput { None, First, Last };

const char* layerKindName(LayerKind kind);

struct Layer {
  LayerKind kind = LayerKind::Identity;
  int inWidth = 0;
  int outWidth = 0;
  // Linear: weight [outWidth x inWidth] row-major (PyTorch layout), bias [outWidth] or empty.
  // Fourier: weight holds B [m x inWidth] row-major, outWidth = 2m (+ inWidth if included).
  std::vector<float> weight;
  std::vector<float> bias;
  std::string weightName, biasName;  // tensor names in the file, for messages
  float param = 0.f;                 // Sine: w0; Scale: factor; Fourier: frequency scale
  IncludeInput includeInput = IncludeInput::None;  // Fourier only
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
