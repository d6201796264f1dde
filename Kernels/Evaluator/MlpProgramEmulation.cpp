// The CPU emulation of the fused kernel's arithmetic (MlpProgram.h: emulateFusedProgram, and
// emulateFusedTangents for the kernel's tangent rows).
#include <algorithm>
#include <cmath>
#include <vector>

#include "Common/Activation.h"
#include "Common/Half.h"
#include "Evaluator/Encodings.h"
#include "Evaluator/MlpProgram.h"

namespace inr {
namespace {

// Hash-grid instruction f's row of `width` columns as the fused kernels store it: the features
// from the fp16 table (Evaluator/Encodings.h hashGridLevelFused) and any included inputs, rounded
// to fp16, zeros past f.outWidth.
template <class Input>
void hashGridRowAsFused(const MlpProgram& p, const MlpInstr& f, const Input& x, int width, float* row) {
  const HashGridView g{p.floatWeights.data() + f.floatOffset};
  const HashGridColumns cols(f);
  const int F = g.features();
  for (int c = 0; c < width; ++c) row[c] = 0.f;
  for (int i = 0; i < cols.inputs; ++i) row[cols.inputAt + i] = roundToHalf(x(i));
  for (int l = 0; l < g.levels(); ++l) {
    const std::uint16_t* table = p.halfWeights.data() + f.halfOffset + std::size_t(g.firstEntry(l)) * F;
    auto value = [&](std::uint32_t e, int j) { return halfBitsToFloat(table[std::size_t(e) * F + j]); };
    float v[8];
    hashGridLevelFusedDims(g, l, f.inWidth, x, value, v);
    for (int j = 0; j < F; ++j) row[cols.featureAt + l * F + j] = roundToHalf(v[j]);
  }
}


// D = 1: values only; D = 4: the value (direction 0) and three tangents (directions 1..3), each
// held in buffers of its own, as the kernel's tangent rows are. The value arithmetic is the same
// code for both, so emulateFusedTangents' values are emulateFusedProgram's, bit for bit.
// tangentInput, values, tangents, maxStored: see emulateFusedTangents (D = 4 only).
template <int D>
void emulate(const MlpProgram& p, const float* inputs, std::size_t n, const int* tangentInput, float* out,
             float* tangents, float* maxStored) {
  const int W = p.maxWidthPad;
  // buf[d][b]: buffer b of direction d
  std::vector<std::vector<std::vector<float>>> buf(
      D, std::vector<std::vector<float>>(std::max(p.numBuffers, 1), std::vector<float>(W, 0.f)));
  std::vector<std::vector<float>> tmp(D, std::vector<float>(W));
  std::vector<float> column;  // a weight column, converted once for all directions (dots below)
  auto h = [](float v) { return roundToHalf(v); };
  float largest = 0.f;
  // A tangent about to be stored in fp16: noted for maxStored, then rounded.
  auto ht = [&](float v) {
    largest = std::max(largest, std::abs(v));
    return roundToHalf(v);
  };
  const float s = p.tangentScale;
  float x[D][4];  // network inputs (direction 0), input tangents (1..3)
  for (std::size_t q = 0; q < n; ++q) {
    for (int c = 0; c < 4; ++c) x[0][c] = c < p.inputDim ? inputs[q * p.inputDim + c] : 0.f;
    for (int d = 1; d < D; ++d)
      for (int c = 0; c < 4; ++c) x[d][c] = c < p.inputDim && tangentInput[d - 1] == c ? s : 0.f;
    auto srcAt = [&](int d, int src, int k) -> float { return src < 0 ? (k < p.inputDim ? x[d][k] : 0.f) : buf[d][src][k]; };
    float net = 0.f, dnet[3] = {0.f, 0.f, 0.f};
    // The network output from its pre-activation `pre` (value) and the tangents' dot products
    // dpre[d - 1] (the output layer's tangents: act'(pre) * dpre, in fp32).
    auto output = [&](MlpAct act, float pre, const float* dpre) {
      net = activate(act, pre);
      for (int d = 1; d < D; ++d) dnet[d - 1] = activationDerivative(act, pre) * dpre[d - 1];
    };
    for (std::size_t ii = 0; ii < p.instrs.size(); ++ii) {
      const MlpInstr& in = p.instrs[ii];
      if (in.fusedIntoPrevious) continue;
      switch (in.op) {
        case MlpOp::LoadInput:  // the same for the value and the tangents (the kernel's rows)
          for (int d = 0; d < D; ++d) {
            std::vector<float>& dst = buf[d][in.dst];
            for (int c = 0; c < W; ++c) dst[c] = c < p.inputDim ? h(x[d][c]) : 0.f;
            if (in.splitPrecision)
              for (int c = 0; c < p.inputDim; ++c) {
                dst[c] = dst[8 + c] = h(x[d][c]);
                dst[4 + c] = h(x[d][c] - h(x[d][c]));
              }
          }
          break;
        case MlpOp::DenseFp32:
        case MlpOp::Gemm: {
          // Weight (o, k) as this instruction reads it; a Gemm reads its padded K (zeros past
          // inWidth, or the split coordinate columns).
          const bool gemm = in.op == MlpOp::Gemm;
          auto weight = [&](int o, int k) {
            return gemm ? halfBitsToFloat(p.halfWeights[in.halfOffset + std::int64_t(o) * in.kPad + k])
                        : p.floatWeights[in.floatOffset + std::int64_t(o) * in.inWidth + k];
          };
          // Column o's dot products over the K columns, per direction (the tangents without bias).
          // The column's weights are converted once for all directions; each direction's loop
          // keeps one shape in both instantiations, so the compiler contracts the value's the same
          // way with tangents as without (the values stay emulateFusedProgram's).
          if (column.size() < std::size_t(std::max(in.kPad, in.inWidth)))
            column.resize(std::size_t(std::max(in.kPad, in.inWidth)));
          auto dots = [&](int o, int K, float* acc) {
            for (int k = 0; k < K; ++k) column[std::size_t(k)] = weight(o, k);
            for (int d = 0; d < D; ++d) {
              acc[d] = 0.f;
              for (int k = 0; k < K; ++k) acc[d] += column[std::size_t(k)] * srcAt(d, in.src, k);
            }
          };
          float acc[D];
          if (in.finalOutput) {  // fp16 weights, fp32 accumulation, result not rounded
            dots(0, in.inWidth, acc);
            output(in.act, acc[0] + p.floatWeights[in.biasOffset], acc + 1);
            break;
          }
          // Column o after the epilogue, per direction, fp32: act(pre) [+ residual] for the value,
          // act'(pre) * acc [+ the residual's tangent] for the tangents.
          auto epilogue = [&](int o, float* v) {
            dots(o, gemm ? in.kPad : in.inWidth, acc);
            const float pre = acc[0] + p.floatWeights[in.biasOffset + o];
            for (int d = 0; d < D; ++d) {
              v[d] = d == 0 ? activate(in.act, pre) : activationDerivative(in.act, pre) * acc[d];
              if (in.other >= 0) v[d] = in.combineScale * (v[d] + buf[d][in.other][o]);
            }
          };
          float v[D];
          if (in.dotNext) {  // fp32 activations straight into the final dot product
            const MlpInstr& fin = p.instrs[ii + 1];
            float dot[D] = {};
            for (int o = 0; o < in.outWidth; ++o) {
              epilogue(o, v);
              for (int d = 0; d < D; ++d) dot[d] += v[d] * p.floatWeights[fin.floatOffset + o];
            }
            output(fin.act, dot[0] + p.floatWeights[fin.biasOffset], dot + 1);
            break;
          }
          for (int o = 0; o < in.nPad; ++o) {
            for (int d = 0; d < D; ++d) v[d] = 0.f;
            if (o < in.outWidth) epilogue(o, v);
            for (int d = 0; d < D; ++d) tmp[d][o] = d == 0 ? h(v[d]) : ht(v[d]);
          }
          for (int d = 0; d < D; ++d)
            for (int o = 0; o < W; ++o) buf[d][in.dst][o] = o < in.nPad ? tmp[d][o] : 0.f;
          break;
        }
        case MlpOp::Fourier:  // every encoding (Evaluator/Encodings.h)
        case MlpOp::HashGrid: {
          auto input = [&](int k) { return srcAt(0, in.src, k); };
          // The value row as the value kernels compute it (a hash grid from its fp16 table, in the
          // tangent kernel too); the tangents element by element.
          if (in.op == MlpOp::HashGrid)
            hashGridRowAsFused(p, in, input, W, tmp[0].data());
          else
            for (int c = 0; c < W; ++c) tmp[0][c] = c < in.outWidth ? h(encodingElement(in, p.floatWeights.data(), input, c)) : 0.f;
          for (int d = 1; d < D; ++d) {
            auto tangent = [&](int k) { return srcAt(d, in.src, k); };
            for (int c = 0; c < W; ++c)
              tmp[d][c] = c < in.outWidth ? ht(encodingElementTangent(in, p.floatWeights.data(), input, tangent, c)) : 0.f;
          }
          for (int d = 0; d < D; ++d) buf[d][in.dst] = tmp[d];
          break;
        }
        case MlpOp::Activation:
          for (int c = 0; c < in.outWidth; ++c) {
            const float pre = in.actScale * buf[0][in.dst][c];
            for (int d = 1; d < D; ++d)
              buf[d][in.dst][c] = ht(activationDerivative(in.act, pre) * in.actScale * buf[d][in.dst][c]);
            buf[0][in.dst][c] = h(activate(in.act, pre));
          }
          break;
        case MlpOp::Combine:  // linear: the same for the tangents
          for (int d = 0; d < D; ++d) {
            for (int c = 0; c < in.outWidth; ++c) {
              const float v = in.combineScale * (buf[d][in.src][c] + (in.other >= 0 ? buf[d][in.other][c] : 0.f));
              tmp[d][c] = d == 0 ? h(v) : ht(v);
            }
            for (int c = 0; c < in.outWidth; ++c) buf[d][in.dst][c] = tmp[d][c];
          }
          break;
        case MlpOp::OutputDot: {
          float acc[D];
          for (int d = 0; d < D; ++d) {
            acc[d] = 0.f;
            for (int k = 0; k < in.inWidth; ++k) acc[d] += p.floatWeights[in.floatOffset + k] * srcAt(d, in.src, k);
          }
          output(in.act, acc[0] + p.floatWeights[in.biasOffset], acc + 1);
          break;
        }
        case MlpOp::Output:
          net = buf[0][in.src][0];
          for (int d = 1; d < D; ++d) dnet[d - 1] = buf[d][in.src][0];
          break;
      }
    }
    out[q] = net;
    for (int d = 1; d < D; ++d) tangents[3 * q + d - 1] = tangentInput[d - 1] >= 0 ? dnet[d - 1] / s : 0.f;
  }
  if (maxStored) *maxStored = largest;
}

}  // namespace

void emulateFusedProgram(const MlpProgram& p, const float* inputs, std::size_t n, float* out) {
  emulate<1>(p, inputs, n, nullptr, out, nullptr, nullptr);
}

void emulateFusedTangents(const MlpProgram& p, const float* inputs, std::size_t n, const int tangentInput[3],
                          float* values, float* tangents, float* maxStoredTangent) {
  emulate<4>(p, inputs, n, tangentInput, values, tangents, maxStoredTangent);
}

float chooseTangentScale(const MlpProgram& program, const float* inputs, std::size_t n, const int tangentInput[3]) {
  MlpProgram unscaled = program;
  unscaled.tangentScale = 1.f;
  std::vector<float> values(n), tangents(3 * n);
  // The points one at a time in parallel: a GPU evaluator chooses its scale inside the first frame
  // that asks for a gradient, and the emulation of a deep network takes milliseconds a point.
  float largest = 0.f;
  const int count = int(n);
#pragma omp parallel for schedule(dynamic, 1) reduction(max : largest)
  for (int q = 0; q < count; ++q) {
    float mine = 0.f;
    emulateFusedTangents(unscaled, inputs + std::size_t(q) * std::size_t(program.inputDim), 1, tangentInput,
                         values.data() + q, tangents.data() + 3 * std::size_t(q), &mine);
    largest = std::max(largest, mine);
  }
  if (!(largest > 0.f) || !std::isfinite(largest)) return 1.f;  // nothing stored, or no finite bound
  const int e = int(std::floor(std::log2(kTangentTarget / largest)));
  return std::ldexp(1.f, std::clamp(e, -16, 16));
}

bool tangentInputsOf(const Domain& domain, int inputDim, int tangentInput[3]) {
  for (int a = 0; a < 3; ++a) tangentInput[a] = -1;
  for (int i = 0; i < inputDim; ++i) {
    const int w = domain.inputOrder[std::size_t(i)];
    if (w >= 3) continue;  // time: no direction
    if (tangentInput[w] >= 0) return false;
    tangentInput[w] = i;
  }
  return true;
}

float chooseTangentScale(const MlpProgram& program, const Domain& dom) {
  int tangentInput[3];
  const int dim = program.inputDim;
  tangentInputsOf(dom, dim, tangentInput);
  std::vector<float> inputs(std::size_t(kTangentSamplePoints) * dim);
  std::uint32_t state = 20251127u;
  auto uniform = [&](double lo, double hi) {
    state = state * 1664525u + 1013904223u;
    return lo + (hi - lo) * ((state >> 8) * (1.0 / 16777216.0));
  };
  for (int q = 0; q < kTangentSamplePoints; ++q) {
    const double world[4] = {uniform(dom.bounds[0], dom.bounds[1]), uniform(dom.bounds[2], dom.bounds[3]),
                             uniform(dom.bounds[4], dom.bounds[5]), uniform(dom.timeBegin, dom.timeEnd)};
    for (int i = 0; i < dim; ++i) {
      const int w = dom.inputOrder[std::size_t(i)];
      inputs[std::size_t(q) * dim + i] = float(dom.toNetwork[w].apply(world[w]));
    }
  }
  return chooseTangentScale(program, inputs.data(), std::size_t(kTangentSamplePoints), tangentInput);
}

}  // namespace inr
