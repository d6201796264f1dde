#include "Evaluator/CpuInrEvaluator.h"

#include <Eigen/Dense>
#include <algorithm>
#include <omp.h>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "Evaluator/Encodings.h"  // hashGridLevel
#include "Evaluator/MlpProgram.h"  // packHashGrid

namespace inr {
namespace {

// Small batches run on the calling thread: waking an OpenMP team costs more than a few chunks of
// GEMM on a loaded machine (measured: Benchmarks/RESULTS.md, "Figures moved out of code comments").
constexpr std::int64_t kMinParallelChunks = 8;

using Mat = Eigen::MatrixXf;  // column-major: one column per query
using RowMajorMap = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

struct CompiledLayer {
  LayerKind kind;
  int inWidth, outWidth;
  Mat weight;            // Linear: W [out x in]; Fourier: s*B [m x in]
  Eigen::VectorXf bias;  // Linear, may be empty
  float param = 0.f;
  IncludeInput includeInput = IncludeInput::None;
  std::vector<CompiledLayer> body, shortcut;
  float residualScale = 1.f;
  std::vector<float> hashGrid;  // HashGrid: packHashGrid's layout
};

std::vector<CompiledLayer> compile(const std::vector<Layer>& layers) {
  std::vector<CompiledLayer> out;
  for (const Layer& L : layers) {
    CompiledLayer c;
    c.kind = L.kind;
    c.inWidth = L.inWidth;
    c.outWidth = L.outWidth;
    c.param = L.param;
    c.includeInput = L.includeInput;
    c.residualScale = L.residualScale;
    if (L.kind == LayerKind::Linear) {
      c.weight = RowMajorMap(L.weight.data(), L.outWidth, L.inWidth);
      if (!L.bias.empty()) c.bias = Eigen::Map<const Eigen::VectorXf>(L.bias.data(), L.outWidth);
    } else if (L.kind == LayerKind::Fourier) {
      const int m = static_cast<int>(L.weight.size() / L.inWidth);
      c.weight = RowMajorMap(L.weight.data(), m, L.inWidth) * L.param;  // fold the 2π scale into B
    } else if (L.kind == LayerKind::HashGrid) {
      c.hashGrid = packHashGrid(L);
    }
    c.body = compile(L.body);
    c.shortcut = compile(L.shortcut);
    out.push_back(std::move(c));
  }
  return out;
}

// Forward-mode derivatives ride along the values: `dx`, where given, holds the derivatives of the
// activations x [width x count] along three directions (the world axes x, y, z) as one matrix
// [width x 3 count], direction d in columns [d count, (d + 1) count), so that a linear layer
// applies its weight to all three in one GEMM. Each layer maps (x, dx) to (y, J dx), J its
// Jacobian at x. The value arithmetic is the same code with or without dx, so
// evaluateWithGradient's values are evaluate's, bit for bit.
void run(const std::vector<CompiledLayer>& layers, Mat& x, Mat* dx);

// dx_d *= factor (element-wise) for each direction d; factor: [width x count].
void scaleTangents(Mat& dx, const Eigen::ArrayXXf& factor) {
  const Eigen::Index n = factor.cols();
  for (int d = 0; d < 3; ++d) dx.middleCols(d * n, n).array() *= factor;
}

// Whether runLayer propagates derivatives through a layer of this kind. A kind added to
// LayerKind without its Jacobian in runLayer answers false here (and -Wswitch names it at
// compile time), so evaluateWithGradient refuses the model instead of returning wrong numbers.
bool hasDerivative(LayerKind kind) {
  switch (kind) {
    case LayerKind::Fourier:
    case LayerKind::Linear:
    case LayerKind::Sine:
    case LayerKind::SiLU:
    case LayerKind::ReLU:
    case LayerKind::Sigmoid:
    case LayerKind::Tanh:
    case LayerKind::Identity:
    case LayerKind::Scale:
    case LayerKind::Residual:
    case LayerKind::HashGrid: return true;
  }
  return false;
}

// The first layer (depth first, with its path in the graph) that has no derivative, or "".
std::string firstLayerWithoutDerivative(const std::vector<CompiledLayer>& layers, const std::string& path) {
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const CompiledLayer& L = layers[i];
    const std::string here = path + "[" + std::to_string(i) + "]";
    if (!hasDerivative(L.kind))
      return "layer " + here + " of kind '" + layerKindName(L.kind) + "' (LayerKind " +
             std::to_string(static_cast<int>(L.kind)) + ")";
    for (const auto& [branch, name] : {std::pair{&L.body, ".body"}, std::pair{&L.shortcut, ".shortcut"}})
      if (std::string inner = firstLayerWithoutDerivative(*branch, here + name); !inner.empty()) return inner;
  }
  return {};
}

void runLayer(const CompiledLayer& L, Mat& x, Mat* dx) {
  switch (L.kind) {
    case LayerKind::Linear: {
      Mat y(L.outWidth, x.cols());
      y.noalias() = L.weight * x;
      if (L.bias.size()) y.colwise() += L.bias;
      x.swap(y);
      if (dx) {  // d(Wx + b) = W dx
        Mat dy(L.outWidth, dx->cols());
        dy.noalias() = L.weight * *dx;
        dx->swap(dy);
      }
      break;
    }
    case LayerKind::Fourier: {
      const int m = static_cast<int>(L.weight.rows());
      const int extra = L.includeInput == IncludeInput::None ? 0 : L.inWidth;
      Mat proj(m, x.cols());
      proj.noalias() = L.weight * x;
      Mat y(L.outWidth, x.cols());
      const int base = L.includeInput == IncludeInput::First ? L.inWidth : 0;
      y.middleRows(base, m) = proj.array().sin().matrix();
      y.middleRows(base + m, m) = proj.array().cos().matrix();
      if (L.includeInput == IncludeInput::First) y.topRows(extra) = x;
      if (L.includeInput == IncludeInput::Last) y.bottomRows(extra) = x;
      if (dx) {  // d sin(p) = cos(p) dp, d cos(p) = -sin(p) dp with dp = sB dx; included inputs pass dx
        const Eigen::Index n = x.cols();
        Mat dproj(m, dx->cols());
        dproj.noalias() = L.weight * *dx;
        Mat dy(L.outWidth, dx->cols());
        for (int d = 0; d < 3; ++d) {
          const auto dp = dproj.middleCols(d * n, n).array();
          dy.block(base, d * n, m, n) = (y.middleRows(base + m, m).array() * dp).matrix();
          dy.block(base + m, d * n, m, n) = (-y.middleRows(base, m).array() * dp).matrix();
        }
        if (L.includeInput == IncludeInput::First) dy.topRows(extra) = *dx;
        if (L.includeInput == IncludeInput::Last) dy.bottomRows(extra) = *dx;
        dx->swap(dy);
      }
      x.swap(y);
      break;
    }
    case LayerKind::HashGrid: {
      // No whole-array form: query by query and level by level, with the one implementation the
      // GPU paths run (Evaluator/Encodings.h), derivatives from the interpolation weights'.
      const HashGridView g{L.hashGrid.data()};
      const int dims = L.inWidth, F = g.features(), features = g.levels() * F;
      const int featureAt = L.includeInput == IncludeInput::First ? dims : 0;
      const int inputAt = L.includeInput == IncludeInput::First ? 0 : features;
      const Eigen::Index n = x.cols();
      Mat y(L.outWidth, n);
      Mat dy;
      if (dx) dy.resize(L.outWidth, dx->cols());
      float jac[8 * 4];  // d feature j / d input i of one level: jac[j * dims + i]
      for (Eigen::Index q = 0; q < n; ++q) {
        const auto input = [&](int i) { return x(i, q); };
        for (int l = 0; l < g.levels(); ++l) {
          float* v = &y(featureAt + l * F, q);
          hashGridLevel(g, l, dims, input, 0, F, v, dx ? jac : nullptr);
          if (dx)
            for (int j = 0; j < F; ++j)
              for (int d = 0; d < 3; ++d) {
                float t = 0.f;
                for (int i = 0; i < dims; ++i) t += jac[j * dims + i] * (*dx)(i, d * n + q);
                dy(featureAt + l * F + j, d * n + q) = t;
              }
        }
      }
      if (L.includeInput != IncludeInput::None) {
        y.middleRows(inputAt, dims) = x;
        if (dx) dy.middleRows(inputAt, dims) = *dx;
      }
      x.swap(y);
      if (dx) dx->swap(dy);
      break;
    }
    // The formulas of Common/Activation.h on whole arrays, by Eigen's vectorised sin/exp/tanh:
    // other implementations than the scalar library functions that definition calls, so calling
    // it per element would change this reference's results (and cost the vectorisation). The
    // derivatives likewise (activationDerivative there): a factor from the pre-activation, taken
    // before x is overwritten, or from the value, after.
    case LayerKind::Sine:
      if (dx) scaleTangents(*dx, (x.array() * L.param).cos() * L.param);
      x = (x.array() * L.param).sin().matrix();
      break;
    case LayerKind::SiLU:
      if (dx) {  // sigma(x) (1 + x (1 - sigma(x)))
        const Eigen::ArrayXXf s = 1.f / (1.f + (-x.array()).exp());
        scaleTangents(*dx, s * (1.f + x.array() * (1.f - s)));
      }
      x = (x.array() / (1.f + (-x.array()).exp())).matrix();
      break;
    case LayerKind::ReLU:
      if (dx) scaleTangents(*dx, (x.array() > 0.f).cast<float>());
      x = x.cwiseMax(0.f);
      break;
    case LayerKind::Sigmoid:
      x = (1.f / (1.f + (-x.array()).exp())).matrix();
      if (dx) scaleTangents(*dx, x.array() * (1.f - x.array()));
      break;
    case LayerKind::Tanh:
      x = x.array().tanh().matrix();
      if (dx) scaleTangents(*dx, 1.f - x.array().square());
      break;
    case LayerKind::Identity: break;
    case LayerKind::Scale:
      x *= L.param;
      if (dx) *dx *= L.param;
      break;
    case LayerKind::Residual: {
      Mat body = x;
      Mat dbody;
      if (dx) dbody = *dx;
      run(L.body, body, dx ? &dbody : nullptr);
      if (!L.shortcut.empty()) run(L.shortcut, x, dx);
      x = L.residualScale * (body + x);
      if (dx) *dx = L.residualScale * (dbody + *dx);
      break;
    }
  }
}

void run(const std::vector<CompiledLayer>& layers, Mat& x, Mat* dx) {
  for (const CompiledLayer& L : layers) runLayer(L, x, dx);
}

}  // namespace

struct CpuInrEvaluator::Impl {
  CpuEvaluatorOptions options;
  std::vector<CompiledLayer> layers;
  int inputDim;
  Domain domain;
  OutputMapping output;
  std::string layerWithoutDerivative;  // "" when evaluateWithGradient can run

  std::int64_t chunks(std::size_t n) const {
    return (static_cast<std::int64_t>(n) + options.chunkSize - 1) / options.chunkSize;
  }
  int threads() const { return options.threads > 0 ? options.threads : omp_get_max_threads(); }

  // fn(begin, count) for each chunk of [0, n), over the threads when there are enough chunks. fn
  // must not throw (an exception cannot leave an OpenMP region).
  template <class Fn>
  void forEachChunk(std::size_t n, Fn&& fn) const {
    const std::int64_t chunk = options.chunkSize;
    const std::int64_t count = chunks(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads()) if (count >= kMinParallelChunks)
    for (std::int64_t c = 0; c < count; ++c) {
      const std::int64_t begin = c * chunk;
      fn(begin, std::min<std::int64_t>(chunk, static_cast<std::int64_t>(n) - begin));
    }
  }

  // The network inputs of points [begin, begin + count): one column per query.
  Mat networkInputs(const QueryPoint* points, std::int64_t begin, std::int64_t count) const {
    Mat x(inputDim, count);
    for (std::int64_t q = 0; q < count; ++q) {
      const QueryPoint& p = points[begin + q];
      const double world[4] = {p.x, p.y, p.z, p.t};
      for (int i = 0; i < inputDim; ++i) {
        const int w = domain.inputOrder[i];
        x(i, q) = static_cast<float>(domain.toNetwork[w].apply(world[w]));
      }
    }
    return x;
  }

  // d(network inputs)/d(world x, y, z) in the tangent layout of run(): input i reads world axis
  // w with slope toNetwork[w].scale, so direction w has that slope in row i and zeros elsewhere
  // (time, the fourth coordinate, is no direction).
  Mat inputTangents(std::int64_t count) const {
    Mat dx = Mat::Zero(inputDim, 3 * count);
    for (int i = 0; i < inputDim; ++i) {
      const int w = domain.inputOrder[i];
      if (w < 3) dx.block(i, w * count, 1, count).setConstant(static_cast<float>(domain.toNetwork[w].scale));
    }
    return dx;
  }

  // store(q, a, b) for each query q of the chunk, with value = a * net + b the output mapping at
  // the query's time (looked up once per run of equal times; the per-time tables are tiny).
  template <class Store>
  void forEachOutputMap(const QueryPoint* points, std::int64_t begin, std::int64_t count, Store store) const {
    float a = 1.f, b = 0.f;
    float lastT = 0.f;
    bool have = false;
    for (std::int64_t q = 0; q < count; ++q) {
      const float t = points[begin + q].t;
      if (!have || t != lastT) {
        output.affineAt(t, a, b);
        lastT = t;
        have = true;
      }
      store(q, a, b);
    }
  }
};

CpuInrEvaluator::CpuInrEvaluator(const InrModel& model, CpuEvaluatorOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->options.chunkSize = std::max(1, options.chunkSize);
  impl_->layers = compile(model.architecture.layers);
  impl_->inputDim = model.architecture.inputDim;
  impl_->domain = model.domain;
  impl_->output = model.output;
  impl_->layerWithoutDerivative = firstLayerWithoutDerivative(impl_->layers, "layers");
}

CpuInrEvaluator::~CpuInrEvaluator() = default;

void CpuInrEvaluator::evaluateNetwork(const float* inputs, std::size_t n, float* out) const {
  const Impl& I = *impl_;
  I.forEachChunk(n, [&](std::int64_t begin, std::int64_t count) {
    Mat x = Eigen::Map<const Mat>(inputs + begin * I.inputDim, I.inputDim, count);
    run(I.layers, x, nullptr);
    Eigen::Map<Eigen::RowVectorXf>(out + begin, count) = x.row(0);
  });
}

void CpuInrEvaluator::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  const Impl& I = *impl_;
  I.forEachChunk(n, [&](std::int64_t begin, std::int64_t count) {
    Mat x = I.networkInputs(points, begin, count);
    run(I.layers, x, nullptr);
    I.forEachOutputMap(points, begin, count, [&](std::int64_t q, float a, float b) { out[begin + q] = a * x(0, q) + b; });
  });
}

void CpuInrEvaluator::evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values,
                                           float* gradients) const {
  const Impl& I = *impl_;
  // Checked here, before the parallel loop (an exception must not leave an OpenMP region).
  if (!I.layerWithoutDerivative.empty())
    throw std::runtime_error("CpuInrEvaluator::evaluateWithGradient: " + I.layerWithoutDerivative +
                             " has no derivative; a layer kind needs its Jacobian in runLayer "
                             "(Evaluator/CpuInrEvaluator.cpp) before gradients can be evaluated");
  I.forEachChunk(n, [&](std::int64_t begin, std::int64_t count) {
    Mat x = I.networkInputs(points, begin, count);
    Mat dx = I.inputTangents(count);
    run(I.layers, x, &dx);
    I.forEachOutputMap(points, begin, count, [&](std::int64_t q, float a, float b) {
      values[begin + q] = a * x(0, q) + b;
      for (int d = 0; d < 3; ++d) gradients[3 * (begin + q) + d] = a * dx(0, d * count + q);
    });
  });
}

}  // namespace inr
