#include "Model/InrModel.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "Model/SafeTensors.h"

namespace inr {
namespace {

using nlohmann::json;

constexpr const char* kFormatName = "inr-volume";
constexpr int kFormatVersion = 1;
// The renderer and the evaluators work in fp32: every number that reaches them must fit.
constexpr double kFloatMax = std::numeric_limits<float>::max();

bool fitsFp32(double v) { return std::fabs(v) <= kFloatMax; }  // false for NaN and infinities

std::string num(double v) {  // shortest text that reads back as v
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

// Parses the JSON metadata and builds the layer graph; every error names the file and the path
// inside the metadata ("architecture.layers[3].weight") where the problem is.
class Builder {
public:
  Builder(const std::string& label, SafeTensorFile& file) : label_(label), file_(file) {}

  [[noreturn]] void fail(const std::string& what) const { throw ModelError(label_ + ": " + what); }

  json parseJsonKey(const char* key, bool required) {
    auto it = file_.metadata.find(key);
    if (it == file_.metadata.end()) {
      if (required)
        fail(std::string("metadata key '") + key + "' is missing (see Docs/FORMAT.md; export with Tools/python/inr_export.py)");
      return json();
    }
    try {
      return json::parse(it->second);
    } catch (const json::out_of_range& e) {  // e.g. 406: number overflow parsing '1e999'
      fail(std::string("metadata '") + key + "' holds a number outside the double range: " + e.what());
    } catch (const json::exception& e) {
      fail(std::string("metadata '") + key + "' is not valid JSON: " + e.what());
    }
  }

  void checkKeys(const json& obj, const std::string& path, std::initializer_list<const char*> allowed) const {
    if (!obj.is_object()) fail(path + " must be a JSON object");
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      bool ok = false;
      for (const char* a : allowed) ok = ok || it.key() == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(path + " has unknown field '" + it.key() + "' (allowed: " + list + ")");
      }
    }
  }

  double number(const json& obj, const char* key, const std::string& path, std::optional<double> dflt) const {
    if (!obj.contains(key)) {
      if (dflt) return *dflt;
      fail(path + "." + key + " is required");
    }
    const json& v = obj[key];
    if (!v.is_number()) fail(path + "." + key + " must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(path + "." + key + " must be finite");
    return d;
  }

  // A number the evaluators use as an fp32 parameter (w0, scales, offsets).
  float floatNumber(const json& obj, const char* key, const std::string& path, std::optional<double> dflt) const {
    const double d = number(obj, key, path, dflt);
    if (!fitsFp32(d))
      fail(path + "." + key + " is " + num(d) + ", outside the fp32 range (|x| <= " + num(kFloatMax) + ")");
    return static_cast<float>(d);
  }

  std::string optionalString(const json& obj, const char* key, const std::string& path, const char* dflt) const {
    if (!obj.contains(key)) return dflt;
    if (!obj[key].is_string()) fail(path + "." + key + " must be a string");
    return obj[key].get<std::string>();
  }

  // Throws unless the interval [lo, hi] (`what`: "domain.bounds: the x extent") and its length are
  // finite in fp32, where the renderer works.
  void checkFp32Interval(double lo, double hi, const std::string& what) const {
    if (!fitsFp32(lo) || !fitsFp32(hi) || !fitsFp32(hi - lo))
      fail(what + " [" + num(lo) + ", " + num(hi) + "] is not finite in fp32 (the ends and the length must be at "
           "most " + num(kFloatMax) + " in magnitude)");
  }

  // Throws unless the world -> network map of `what` is finite and invertible.
  void checkAxisMap(const AxisMap& m, const std::string& what) const {
    if (!fitsFp32(m.scale) || !fitsFp32(m.offset) || m.scale == 0)
      fail("domain: the map of world " + what + " onto the network input (scale " + num(m.scale) + ", offset " +
           num(m.offset) + ") is not finite in fp32; check domain.bounds/time_range against input_range");
  }

  std::vector<double> numberArray(const json& v, const std::string& path, std::size_t n = 0) const {
    if (!v.is_array()) fail(path + " must be an array of numbers");
    if (n && v.size() != n) fail(path + " must have " + std::to_string(n) + " entries, has " + std::to_string(v.size()));
    std::vector<double> out;
    for (const json& e : v) {
      if (!e.is_number() || !std::isfinite(e.get<double>())) fail(path + " must contain finite numbers only");
      out.push_back(e.get<double>());
    }
    return out;
  }

  const SafeTensor& takeTensor(const json& layer, const char* key, const std::string& path, std::string& nameOut) {
    if (!layer.contains(key) || !layer[key].is_string()) fail(path + "." + key + " must name a tensor (string)");
    nameOut = layer[key].get<std::string>();
    auto it = file_.tensors.find(nameOut);
    if (it == file_.tensors.end())
      fail(path + "." + key + " names tensor '" + nameOut + "', which is not in the file");
    if (!used_.insert(nameOut).second)
      fail("tensor '" + nameOut + "' is used twice (" + path + "." + key + "); shared weights are not supported");
    return it->second;
  }

  void expectShape(const SafeTensor& t, const std::string& name, const std::vector<std::int64_t>& want,
                   const std::string& path) const {
    if (t.shape != want)
      fail("tensor '" + name + "' has shape " + shapeToString(t.shape) + " but " + path + " expects " +
           shapeToString(want));
  }

  std::vector<Layer> layerList(const json& list, int inWidth, const std::string& path, int& outWidth, int depth) {
    if (!list.is_array()) fail(path + " must be an array of layers");
    if (depth > 16) fail(path + ": residual blocks nested deeper than 16 levels");
    std::vector<Layer> layers;
    int width = inWidth;
    for (std::size_t i = 0; i < list.size(); ++i) {
      layers.push_back(layer(list[i], width, path + "[" + std::to_string(i) + "]", depth));
      width = layers.back().outWidth;
    }
    outWidth = width;
    return layers;
  }

  Layer layer(const json& j, int inWidth, const std::string& path, int depth) {
    if (!j.is_object() || !j.contains("type") || !j["type"].is_string())
      fail(path + " must be an object with a string 'type'");
    const std::string type = j["type"].get<std::string>();
    Layer L;
    L.inWidth = inWidth;
    L.outWidth = inWidth;
    if (type == "linear") {
      checkKeys(j, path, {"type", "weight", "bias"});
      L.kind = LayerKind::Linear;
      const SafeTensor& w = takeTensor(j, "weight", path, L.weightName);
      if (w.shape.size() != 2 || w.shape[1] != inWidth)
        fail("tensor '" + L.weightName + "' has shape " + shapeToString(w.shape) + " but " + path +
             " (linear) receives width " + std::to_string(inWidth) + ", so it must be [out, " +
             std::to_string(inWidth) + "]");
      if (w.shape[0] < 1 || w.shape[0] > 65536) fail(path + ": output width " + std::to_string(w.shape[0]) + " out of range");
      L.outWidth = static_cast<int>(w.shape[0]);
      L.weight = w.values;
      if (j.contains("bias") && !j["bias"].is_null()) {
        const SafeTensor& b = takeTensor(j, "bias", path, L.biasName);
        expectShape(b, L.biasName, {L.outWidth}, path + ".bias");
        L.bias = b.values;
      }
    } else if (type == "fourier") {
      checkKeys(j, path, {"type", "B", "frequency_scale", "include_input"});
      L.kind = LayerKind::Fourier;
      const SafeTensor& b = takeTensor(j, "B", path, L.weightName);
      if (b.shape.size() != 2 || b.shape[1] != inWidth || b.shape[0] < 1)
        fail("tensor '" + L.weightName + "' has shape " + shapeToString(b.shape) + " but " + path +
             " (fourier) receives width " + std::to_string(inWidth) + ", so B must be [m, " + std::to_string(inWidth) + "]");
      L.weight = b.values;
      L.param = floatNumber(j, "frequency_scale", path, 6.283185307179586);
      L.includeInput = includeInput(j, path);
      if (b.shape[0] > 32768) fail(path + ": " + std::to_string(b.shape[0]) + " frequencies out of range (at most 32768)");
      L.outWidth = static_cast<int>(2 * b.shape[0]) + (L.includeInput == IncludeInput::None ? 0 : inWidth);
    } else if (type == "hashgrid") {
      hashGridLayer(j, path, L);
    } else if (type == "sine") {
      checkKeys(j, path, {"type", "w0"});
      L.kind = LayerKind::Sine;
      L.param = floatNumber(j, "w0", path, 30.0);
    } else if (type == "scale") {
      checkKeys(j, path, {"type", "factor"});
      L.kind = LayerKind::Scale;
      L.param = floatNumber(j, "factor", path, std::nullopt);
    } else if (type == "silu" || type == "swish" || type == "relu" || type == "sigmoid" || type == "tanh" ||
               type == "identity") {
      checkKeys(j, path, {"type"});
      L.kind = type == "relu" ? LayerKind::ReLU
               : type == "sigmoid" ? LayerKind::Sigmoid
               : type == "tanh" ? LayerKind::Tanh
               : type == "identity" ? LayerKind::Identity
                                    : LayerKind::SiLU;
    } else if (type == "residual") {
      checkKeys(j, path, {"type", "body", "shortcut", "scale"});
      L.kind = LayerKind::Residual;
      if (!j.contains("body")) fail(path + ".body is required");
      int bodyOut = 0, shortOut = inWidth;
      L.body = layerList(j["body"], inWidth, path + ".body", bodyOut, depth + 1);
      if (L.body.empty()) fail(path + ".body must not be empty");
      if (j.contains("shortcut") && !j["shortcut"].is_null())
        L.shortcut = layerList(j["shortcut"], inWidth, path + ".shortcut", shortOut, depth + 1);
      if (bodyOut != shortOut)
        fail(path + ": body ends at width " + std::to_string(bodyOut) + " but the shortcut at width " +
             std::to_string(shortOut) + (L.shortcut.empty() ? " (identity; add a shortcut transform)" : ""));
      L.outWidth = bodyOut;
      L.residualScale = floatNumber(j, "scale", path, 1.0);
    } else {
      fail(path + " has unknown layer type '" + type +
           "' (known: fourier, hashgrid, linear, sine, silu, relu, sigmoid, tanh, identity, scale, residual)");
    }
    return L;
  }

  IncludeInput includeInput(const json& j, const std::string& path) const {
    const std::string inc = optionalString(j, "include_input", path, "none");
    if (inc == "none") return IncludeInput::None;
    if (inc == "first") return IncludeInput::First;
    if (inc == "last") return IncludeInput::Last;
    fail(path + ".include_input must be \"none\", \"first\" or \"last\", not \"" + inc + "\"");
  }

  // An integer field in [lo, hi] (`what` says what the bound protects, for the message).
  int boundedInteger(const json& j, const char* key, const std::string& path, std::optional<double> dflt, int lo,
                     int hi, const char* what) const {
    const double v = number(j, key, path, dflt);
    if (v != std::floor(v) || v < lo || v > hi)
      fail(path + "." + key + " is " + num(v) + "; it must be an integer in [" + std::to_string(lo) + ", " +
           std::to_string(hi) + "]" + what);
    return static_cast<int>(v);
  }

  // A hash-grid encoding (tiny-cuda-nn's HashGrid): parameters, the derived levels, the table.
  void hashGridLayer(const json& j, const std::string& path, Layer& L) {
    checkKeys(j, path, {"type", "table", "n_levels", "n_features_per_level", "log2_hashmap_size", "base_resolution",
                        "per_level_scale", "interpolation", "include_input"});
    L.kind = LayerKind::HashGrid;
    const int dims = L.inWidth;
    if (dims < 3 || dims > 4)
      fail(path + " (hashgrid) receives width " + std::to_string(dims) +
           "; a hash grid encodes 3 coordinates (x, y, z) or 4 (x, y, z, t): put it first in the layer list");
    HashGridSpec& g = L.hashGrid;
    g.levels = boundedInteger(j, "n_levels", path, 16.0, 1, HashGridSpec::kMaxLevels, " (tiny-cuda-nn's limit)");
    g.featuresPerLevel = boundedInteger(j, "n_features_per_level", path, 2.0, 1, 8, "");
    if (g.featuresPerLevel & (g.featuresPerLevel - 1))
      fail(path + ".n_features_per_level is " + std::to_string(g.featuresPerLevel) + "; it must be 1, 2, 4 or 8");
    g.log2TableSize = boundedInteger(j, "log2_hashmap_size", path, 19.0, 1, HashGridSpec::kMaxLog2TableSize,
                                     " (at most 2^24 entries per level)");
    g.baseResolution = boundedInteger(j, "base_resolution", path, 16.0, 1, HashGridSpec::kMaxBaseResolution, "");
    const double scale = number(j, "per_level_scale", path, 2.0);
    if (!(scale >= 1.0) || !fitsFp32(scale))
      fail(path + ".per_level_scale is " + num(scale) + "; it must be at least 1 (each level at least as fine as the last)");
    g.perLevelScale = static_cast<float>(scale);
    const std::string interp = optionalString(j, "interpolation", path, "linear");
    if (interp == "linear" || interp == "Linear") g.smoothstep = false;
    else if (interp == "smoothstep" || interp == "Smoothstep") g.smoothstep = true;
    else fail(path + ".interpolation must be \"linear\" or \"smoothstep\", not \"" + interp + "\"");
    L.includeInput = includeInput(j, path);

    // tiny-cuda-nn's levels: scale_l = 2^(l log2(per_level_scale)) * base - 1 (fp32), resolution
    // ceil(scale_l) + 1, and as many entries as the dense grid needs (rounded up to 8) or the
    // hash table holds, whichever is fewer.
    const float log2Scale = std::log2(g.perLevelScale);
    const std::uint64_t tableSize = std::uint64_t(1) << g.log2TableSize;
    constexpr std::uint64_t kMaxDenseParams = std::numeric_limits<std::uint32_t>::max() / 2;
    std::uint64_t offset = 0;
    for (int l = 0; l < g.levels; ++l) {
      const float s = std::exp2(float(l) * log2Scale) * float(g.baseResolution) - 1.0f;
      if (!(s <= HashGridSpec::kMaxFinestScale))
        fail(path + ": level " + std::to_string(l) + " has scale " + num(s) + " (base_resolution " +
             std::to_string(g.baseResolution) + " x per_level_scale " + num(scale) + "^" + std::to_string(l) +
             "); at most 2^24 is supported: lower n_levels or per_level_scale");
      const std::uint32_t res = static_cast<std::uint32_t>(std::ceil(s)) + 1;
      std::uint64_t dense = std::pow(double(res), dims) > double(kMaxDenseParams) ? kMaxDenseParams
                                                                                   : std::uint64_t(std::pow(double(res), dims));
      dense = (dense + 7) / 8 * 8;
      const std::uint64_t size = std::min(dense, tableSize);
      g.levelScale.push_back(s);
      g.levelResolution.push_back(res);
      g.levelOffset.push_back(static_cast<std::uint32_t>(offset));
      g.levelSize.push_back(static_cast<std::uint32_t>(size));
      offset += size;
    }
    const SafeTensor& t = takeTensor(j, "table", path, L.weightName);
    const std::vector<std::int64_t> want{std::int64_t(offset), g.featuresPerLevel};
    if (t.shape != want)
      fail("tensor '" + L.weightName + "' has shape " + shapeToString(t.shape) + " but " + path + ".table expects " +
           shapeToString(want) + ": " + std::to_string(g.levels) + " levels of " + std::to_string(g.featuresPerLevel) +
           " features with log2_hashmap_size " + std::to_string(g.log2TableSize) + ", base_resolution " +
           std::to_string(g.baseResolution) + " and per_level_scale " + num(scale) + " over " + std::to_string(dims) +
           " inputs need " + std::to_string(offset) +
           " entries (check these parameters against the training config; Docs/FORMAT.md gives the formula)");
    L.weight = t.values;
    L.outWidth = g.levels * g.featuresPerLevel + (L.includeInput == IncludeInput::None ? 0 : dims);
  }

  Architecture architecture() {
    const json a = parseJsonKey("architecture", true);
    checkKeys(a, "architecture", {"input_dim", "layers"});
    if (!a.contains("input_dim") || !a["input_dim"].is_number_integer()) fail("architecture.input_dim must be an integer");
    Architecture arch;
    const std::int64_t inputDim = a["input_dim"].get<std::int64_t>();
    if (inputDim < 3 || inputDim > 4)
      fail("architecture.input_dim is " + std::to_string(inputDim) + "; must be 3 (x,y,z) or 4 (x,y,z,t)");
    arch.inputDim = static_cast<int>(inputDim);
    if (!a.contains("layers")) fail("architecture.layers is required");
    int out = 0;
    arch.layers = layerList(a["layers"], arch.inputDim, "architecture.layers", out, 0);
    if (arch.layers.empty()) fail("architecture.layers is empty");
    if (out != 1) fail("the network ends at width " + std::to_string(out) + "; it must end at width 1 (one scalar)");
    for (const auto& kv : file_.tensors)
      if (!used_.count(kv.first))
        fail("tensor '" + kv.first + "' is not used by the architecture (extra tensor; remove it or reference it)");
    return arch;
  }

  AxisMap axisMap(double wmin, double wmax, double lo, double hi, bool cell, int n) {
    // node: wmin -> lo, wmax -> hi.  cell: first/last cell centre -> lo/hi.
    double a = wmin, b = wmax;
    if (cell) {
      const double h = (wmax - wmin) / n;
      a = wmin + 0.5 * h;
      b = wmax - 0.5 * h;
    }
    AxisMap m;
    m.scale = (hi - lo) / (b - a);
    m.offset = lo - m.scale * a;
    return m;
  }

  Domain domain(int inputDim) {
    const json d = parseJsonKey("domain", true);
    checkKeys(d, "domain", {"bounds", "input_range", "centering", "resolution", "time_range", "time_input_range",
                            "input_order", "time_steps"});
    Domain dom;
    if (!d.contains("bounds")) fail("domain.bounds is required ([xmin, xmax, ymin, ymax, zmin, zmax])");
    const auto bounds = numberArray(d["bounds"], "domain.bounds", 6);
    for (int i = 0; i < 6; ++i) dom.bounds[i] = bounds[i];
    const char* axis = "xyz";
    for (int i = 0; i < 3; ++i) {
      if (!(bounds[2 * i + 1] > bounds[2 * i]))
        fail(std::string("domain.bounds is an empty box: ") + axis[i] + "max (" + std::to_string(bounds[2 * i + 1]) +
             ") must exceed " + axis[i] + "min (" + std::to_string(bounds[2 * i]) + ")");
      checkFp32Interval(bounds[2 * i], bounds[2 * i + 1], std::string("domain.bounds: the ") + axis[i] + " extent");
    }

    std::array<std::array<double, 2>, 3> range{{{-1, 1}, {-1, 1}, {-1, 1}}};
    if (d.contains("input_range")) {
      const json& r = d["input_range"];
      if (r.is_array() && r.size() == 3 && r[0].is_array()) {
        for (int i = 0; i < 3; ++i) {
          auto p = numberArray(r[i], "domain.input_range[" + std::to_string(i) + "]", 2);
          range[i] = {p[0], p[1]};
        }
      } else {
        auto p = numberArray(r, "domain.input_range", 2);
        for (int i = 0; i < 3; ++i) range[i] = {p[0], p[1]};
      }
      for (int i = 0; i < 3; ++i)
        if (range[i][0] == range[i][1]) fail("domain.input_range is degenerate (lo == hi)");
    }
    const std::string centering = optionalString(d, "centering", "domain", "node");
    if (centering != "node" && centering != "cell")
      fail("domain.centering must be \"node\" or \"cell\", not \"" + centering + "\"");
    const bool cell = centering == "cell";
    std::vector<double> res;
    if (d.contains("resolution")) res = numberArray(d["resolution"], "domain.resolution", 3);
    if (cell) {
      if (res.empty()) fail("domain.centering \"cell\" needs domain.resolution [nx, ny, nz]");
      for (double r : res)
        if (r < 2 || r > std::numeric_limits<int>::max() || r != std::floor(r))
          fail("domain.resolution entries must be integers in [2, 2^31 - 1]");
    }
    for (int i = 0; i < 3; ++i) {
      dom.toNetwork[i] = axisMap(bounds[2 * i], bounds[2 * i + 1], range[i][0], range[i][1], cell,
                                 cell ? int(res[i]) : 0);
      checkAxisMap(dom.toNetwork[i], std::string(1, axis[i]));
    }

    if (!d.contains("time_range")) fail("domain.time_range is required ([t0, t1])");
    const auto tr = numberArray(d["time_range"], "domain.time_range", 2);
    if (!(tr[0] < tr[1]))
      fail("domain.time_range [" + std::to_string(tr[0]) + ", " + std::to_string(tr[1]) + "] must have t0 < t1");
    checkFp32Interval(tr[0], tr[1], "domain.time_range");
    dom.timeBegin = tr[0];
    dom.timeEnd = tr[1];
    std::vector<double> tir{-1, 1};
    if (d.contains("time_input_range")) tir = numberArray(d["time_input_range"], "domain.time_input_range", 2);
    if (tir[0] == tir[1]) fail("domain.time_input_range is degenerate (lo == hi)");
    dom.toNetwork[kT] = axisMap(tr[0], tr[1], tir[0], tir[1], false, 0);
    checkAxisMap(dom.toNetwork[kT], "time");

    std::vector<std::string> order{"x", "y", "z", "t"};
    if (d.contains("input_order")) {
      if (!d["input_order"].is_array()) fail("domain.input_order must be an array like [\"x\",\"y\",\"z\",\"t\"]");
      order.clear();
      for (const json& e : d["input_order"]) {
        if (!e.is_string()) fail("domain.input_order entries must be strings");
        order.push_back(e.get<std::string>());
      }
    } else if (inputDim == 3) {
      order = {"x", "y", "z"};
    }
    if (int(order.size()) != inputDim)
      fail("domain.input_order has " + std::to_string(order.size()) + " entries but architecture.input_dim is " +
           std::to_string(inputDim));
    int seen[4] = {0, 0, 0, 0};
    for (const auto& o : order) {
      int c = o == "x" ? kX : o == "y" ? kY : o == "z" ? kZ : o == "t" ? kT : -1;
      if (c < 0) fail("domain.input_order entry \"" + o + "\" is not one of x, y, z, t");
      if (seen[c]++) fail("domain.input_order names \"" + o + "\" twice");
      dom.inputOrder.push_back(c);
    }
    if (!seen[kX] || !seen[kY] || !seen[kZ]) fail("domain.input_order must contain x, y and z");
    if (d.contains("time_steps")) {
      dom.timeSteps = numberArray(d["time_steps"], "domain.time_steps");
      for (std::size_t i = 1; i < dom.timeSteps.size(); ++i)
        if (!(dom.timeSteps[i] > dom.timeSteps[i - 1])) fail("domain.time_steps must be strictly increasing");
    }
    return dom;
  }

  OutputMapping output() {
    OutputMapping out;
    const json o = parseJsonKey("output", false);
    if (o.is_null()) return out;
    checkKeys(o, "output", {"scale", "offset", "per_time"});
    if (o.contains("per_time")) {
      if (o.contains("scale") || o.contains("offset")) fail("output.per_time excludes output.scale/offset");
      const json& p = o["per_time"];
      checkKeys(p, "output.per_time", {"times", "min", "max", "network_range"});
      OutputMapping::PerTime pt;
      if (!p.contains("times") || !p.contains("min") || !p.contains("max"))
        fail("output.per_time needs times, min and max");
      pt.times = numberArray(p["times"], "output.per_time.times");
      pt.min = numberArray(p["min"], "output.per_time.min", pt.times.size());
      pt.max = numberArray(p["max"], "output.per_time.max", pt.times.size());
      if (pt.times.empty()) fail("output.per_time.times is empty");
      for (std::size_t i = 1; i < pt.times.size(); ++i)
        if (!(pt.times[i] > pt.times[i - 1])) fail("output.per_time.times must be strictly increasing");
      if (p.contains("network_range")) {
        auto r = numberArray(p["network_range"], "output.per_time.network_range", 2);
        if (r[0] == r[1]) fail("output.per_time.network_range is degenerate");
        pt.networkLo = r[0];
        pt.networkHi = r[1];
      }
      out.perTime = std::move(pt);
      // affineAt interpolates the tabulated min/max linearly, so a map that fits fp32 at every entry
      // fits everywhere.
      const auto& q = *out.perTime;
      for (std::size_t i = 0; i < q.times.size(); ++i) {
        const double a = (q.max[i] - q.min[i]) / (q.networkHi - q.networkLo), b = q.min[i] - a * q.networkLo;
        if (!fitsFp32(a) || !fitsFp32(b))
          fail("output.per_time: the value map at time " + num(q.times[i]) + " (scale " + num(a) + ", offset " +
               num(b) + ") is not finite in fp32; min/max or network_range too large");
      }
    } else {
      out.scale = floatNumber(o, "scale", "output", 1.0);
      out.offset = floatNumber(o, "offset", "output", 0.0);
    }
    return out;
  }

private:
  std::string label_;
  SafeTensorFile& file_;
  std::set<std::string> used_;
};

std::size_t countParams(const std::vector<Layer>& layers) {
  std::size_t n = 0;
  for (const Layer& L : layers) n += L.weight.size() + L.bias.size() + countParams(L.body) + countParams(L.shortcut);
  return n;
}

int maxWidthOf(const std::vector<Layer>& layers) {
  int w = 0;
  for (const Layer& L : layers)
    w = std::max({w, L.inWidth, L.outWidth, maxWidthOf(L.body), maxWidthOf(L.shortcut)});
  return w;
}

void summarise(const std::vector<Layer>& layers, std::ostringstream& s) {
  for (const Layer& L : layers) {
    if (s.tellp() > 0) s << ' ';
    s << layerKindName(L.kind);
    if (L.kind == LayerKind::Residual) {
      s << '{';
      std::ostringstream b;
      summarise(L.body, b);
      s << b.str();
      if (!L.shortcut.empty()) {
        std::ostringstream c;
        summarise(L.shortcut, c);
        s << " | " << c.str();
      }
      s << "}x" << L.residualScale;
    } else if (L.kind == LayerKind::Linear || L.kind == LayerKind::Fourier) {
      s << '(' << L.inWidth << "->" << L.outWidth << ')';
    } else if (L.kind == LayerKind::HashGrid) {
      const HashGridSpec& g = L.hashGrid;
      s << '(' << L.inWidth << "->" << L.outWidth << ": " << g.levels << "x" << g.featuresPerLevel << ", 2^"
        << g.log2TableSize << ", base " << g.baseResolution << ", x" << g.perLevelScale
        << (g.smoothstep ? ", smoothstep" : "") << ')';
    } else if (L.kind == LayerKind::Sine) {
      s << '(' << L.param << ')';
    }
  }
}

}  // namespace

const char* layerKindName(LayerKind kind) {
  switch (kind) {
    case LayerKind::Fourier: return "fourier";
    case LayerKind::Linear: return "linear";
    case LayerKind::Sine: return "sine";
    case LayerKind::SiLU: return "silu";
    case LayerKind::ReLU: return "relu";
    case LayerKind::Sigmoid: return "sigmoid";
    case LayerKind::Tanh: return "tanh";
    case LayerKind::Identity: return "identity";
    case LayerKind::Scale: return "scale";
    case LayerKind::Residual: return "residual";
    case LayerKind::HashGrid: return "hashgrid";
  }
  return "?";
}

std::size_t Architecture::parameterCount() const { return countParams(layers); }
int Architecture::maxWidth() const { return std::max(inputDim, maxWidthOf(layers)); }
std::string Architecture::summary() const {
  std::ostringstream s;
  summarise(layers, s);
  return s.str();
}

bool Domain::usesTime() const {
  return std::find(inputOrder.begin(), inputOrder.end(), int(kT)) != inputOrder.end();
}

void OutputMapping::affineAt(double t, float& a, float& b) const {
  if (!perTime) {
    a = scale;
    b = offset;
    return;
  }
  const auto& p = *perTime;
  double lo, hi;
  if (t <= p.times.front()) {
    lo = p.min.front();
    hi = p.max.front();
  } else if (t >= p.times.back()) {
    lo = p.min.back();
    hi = p.max.back();
  } else {
    const std::size_t i = std::upper_bound(p.times.begin(), p.times.end(), t) - p.times.begin() - 1;
    const double f = (t - p.times[i]) / (p.times[i + 1] - p.times[i]);
    lo = p.min[i] + f * (p.min[i + 1] - p.min[i]);
    hi = p.max[i] + f * (p.max[i + 1] - p.max[i]);
  }
  const double s = (hi - lo) / (p.networkHi - p.networkLo);
  a = static_cast<float>(s);
  b = static_cast<float>(lo - s * p.networkLo);
}

namespace {
InrModel loadChecked(const std::uint8_t* data, std::size_t size, const std::string& label) {
  SafeTensorFile file = parseSafeTensors(data, size, label);
  Builder builder(label, file);
  auto fmt = file.metadata.find("format");
  if (fmt == file.metadata.end() || fmt->second != kFormatName)
    builder.fail(std::string("not an INR Volume model: __metadata__.format must be \"") + kFormatName +
                 "\" (plain safetensors weights need an architecture and domain: convert them with "
                 "Tools/python/inr_export.py)");
  auto ver = file.metadata.find("format_version");
  if (ver == file.metadata.end()) builder.fail("__metadata__.format_version is missing");
  if (ver->second != std::to_string(kFormatVersion))
    builder.fail("format_version \"" + ver->second + "\" is not supported (this build reads version " +
                 std::to_string(kFormatVersion) + ")");

  InrModel m;
  m.path = label;
  m.architecture = builder.architecture();
  m.domain = builder.domain(m.architecture.inputDim);
  m.output = builder.output();
  const nlohmann::json vr = builder.parseJsonKey("value_range", false);
  if (!vr.is_null()) {
    auto r = builder.numberArray(vr, "value_range", 2);
    if (!(r[0] < r[1])) builder.fail("value_range must be [lo, hi] with lo < hi");
    if (!fitsFp32(r[0]) || !fitsFp32(r[1]) || !(float(r[0]) < float(r[1])))
      builder.fail("value_range [" + num(r[0]) + ", " + num(r[1]) + "] is not an interval in fp32");
    m.valueRange = std::array<float, 2>{float(r[0]), float(r[1])};
  }
  auto text = [&](const char* key) {
    auto it = file.metadata.find(key);
    return it == file.metadata.end() ? std::string() : it->second;
  };
  m.name = text("name");
  m.description = text("description");
  m.provenance = text("provenance");
  return m;
}
}  // namespace

InrModel InrModel::loadBytes(const std::uint8_t* data, std::size_t size, const std::string& label) {
  try {
    return loadChecked(data, size, label);
  } catch (const nlohmann::json::exception& e) {
    // loadChecked checks types before reading; this safety net keeps the file name on anything
    // the JSON library still throws.
    throw ModelError(label + ": malformed metadata: " + e.what());
  }
}


InrModel InrModel::loadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ModelError(path + ": cannot open file");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw ModelError(path + ": cannot determine file size");
  // Bound what we read before trusting any header: models are megabytes, not gigabytes.
  constexpr std::streamoff kMaxModelBytes = std::streamoff(4) << 30;
  if (size > kMaxModelBytes) throw ModelError(path + ": file is larger than 4 GiB; not an INR model");
  in.seekg(0);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size))
    throw ModelError(path + ": read error");
  return loadBytes(bytes.data(), bytes.size(), path);
}

}  // namespace inr
