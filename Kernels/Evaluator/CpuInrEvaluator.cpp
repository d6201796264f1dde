#include "Evaluator/CpuInrEvaluator.h"

#include <Eigen/Dense>
#include <algorithm>
#include <omp.h>
#include <vector>

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
    }
    c.body = compile(L.body);
    c.shortcut = compile(L.shortcut);
    out.push_back(std::move(c));
  }
  return out;
}

void run(const std::vector<CompiledLayer>& layers, Mat& x);

void runLayer(const CompiledLayer& L, Mat& x) {
  switch (L.kind) {
    case LayerKind::Linear: {
      Mat y(L.outWidth, x.cols());
      y.noalias() = L.weight * x;
      if (L.bias.size()) y.colwise() += L.bias;
      x.swap(y);
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
      x.swap(y);
      break;
    }
    // The formulas of Common/Activation.h on whole arrays, by Eigen's vectorised sin/exp/tanh:
    // other implementations than the scalar library functions that definition calls, so calling
    // it per element would change this reference's results (and cost the vectorisation).
    case LayerKind::Sine: x = (x.array() * L.param).sin().matrix(); break;
    case LayerKind::SiLU: x = (x.array() / (1.f + (-x.array()).exp())).matrix(); break;
    case LayerKind::ReLU: x = x.cwiseMax(0.f); break;
    case LayerKind::Sigmoid: x = (1.f / (1.f + (-x.array()).exp())).matrix(); break;
    case LayerKind::Tanh: x = x.array().tanh().matrix(); break;
    case LayerKind::Identity: break;
    case LayerKind::Scale: x *= L.param; break;
    case LayerKind::Residual: {
      Mat body = x;
      run(L.body, body);
      if (!L.shortcut.empty()) run(L.shortcut, x);
      x = L.residualScale * (body + x);
      break;
    }
  }
}

void run(const std::vector<CompiledLayer>& layers, Mat& x) {
  for (const CompiledLayer& L : layers) runLayer(L, x);
}

}  // namespace

struct CpuInrEvaluator::Impl {
  CpuEvaluatorOptions options;
  std::vector<CompiledLayer> layers;
  int inputDim;
  Domain domain;
  OutputMapping output;
};

CpuInrEvaluator::CpuInrEvaluator(const InrModel& model, CpuEvaluatorOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->options.chunkSize = std::max(1, options.chunkSize);
  impl_->layers = compile(model.architecture.layers);
  impl_->inputDim = model.architecture.inputDim;
  impl_->domain = model.domain;
  impl_->output = model.output;
}

CpuInrEvaluator::~CpuInrEvaluator() = default;

void CpuInrEvaluator::evaluateNetwork(const float* inputs, std::size_t n, float* out) const {
  const Impl& I = *impl_;
  const std::int64_t chunk = I.options.chunkSize;
  const std::int64_t chunks = (static_cast<std::int64_t>(n) + chunk - 1) / chunk;
  const int threads = I.options.threads > 0 ? I.options.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (chunks >= kMinParallelChunks)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const std::int64_t begin = c * chunk;
    const std::int64_t count = std::min<std::int64_t>(chunk, static_cast<std::int64_t>(n) - begin);
    Mat x = Eigen::Map<const Mat>(inputs + begin * I.inputDim, I.inputDim, count);
    run(I.layers, x);
    Eigen::Map<Eigen::RowVectorXf>(out + begin, count) = x.row(0);
  }
}

void CpuInrEvaluator::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  const Impl& I = *impl_;
  const std::int64_t chunk = I.options.chunkSize;
  const std::int64_t chunks = (static_cast<std::int64_t>(n) + chunk - 1) / chunk;
  const int threads = I.options.threads > 0 ? I.options.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) if (chunks >= kMinParallelChunks)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const std::int64_t begin = c * chunk;
    const std::int64_t count = std::min<std::int64_t>(chunk, static_cast<std::int64_t>(n) - begin);
    Mat x(I.inputDim, count);
    for (std::int64_t q = 0; q < count; ++q) {
      const QueryPoint& p = points[begin + q];
      const double world[4] = {p.x, p.y, p.z, p.t};
      for (int i = 0; i < I.inputDim; ++i) {
        const int w = I.domain.inputOrder[i];
        x(i, q) = static_cast<float>(I.domain.toNetwork[w].apply(world[w]));
      }
    }
    run(I.layers, x);
    // Output mapping per query time (cheap; per-time tables are tiny).
    float a = 1.f, b = 0.f;
    float lastT = 0.f;
    bool have = false;
    for (std::int64_t q = 0; q < count; ++q) {
      const float t = points[begin + q].t;
      if (!have || t != lastT) {
        I.output.affineAt(t, a, b);
        lastT = t;
        have = true;
      }
      out[begin + q] = a * x(0, q) + b;
    }
  }
}

}  // namespace inr
