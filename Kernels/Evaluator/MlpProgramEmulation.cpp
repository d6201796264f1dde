// The CPU emulation of the fused kernel's arithmetic (MlpProgram.h: emulateFusedProgram).
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
    if (f.inWidth == 3)
      hashGridLevelFused<3>(g, l, x, value, v);
    else
      hashGridLevelFused<4>(g, l, x, value, v);
    for (int j = 0; j < F; ++j) row[cols.featureAt + l * F + j] = roundToHalf(v[j]);
  }
}

}  // namespace

void emulateFusedProgram(const MlpProgram& p, const float* inputs, std::size_t n, float* out) {
  const int W = p.maxWidthPad;
  std::vector<std::vector<float>> buf(std::max(p.numBuffers, 1), std::vector<float>(W, 0.f));
  std::vector<float> tmp(W);
  auto h = [](float v) { return roundToHalf(v); };
  for (std::size_t q = 0; q < n; ++q) {
    const float* x = inputs + q * p.inputDim;
    auto srcAt = [&](int src, int k) -> float { return src < 0 ? (k < p.inputDim ? x[k] : 0.f) : buf[src][k]; };
    for (std::size_t ii = 0; ii < p.instrs.size(); ++ii) {
      const MlpInstr& in = p.instrs[ii];
      if (in.fusedIntoPrevious) continue;
      switch (in.op) {
        case MlpOp::LoadInput:
          for (int c = 0; c < W; ++c) buf[in.dst][c] = c < p.inputDim ? h(x[c]) : 0.f;
          if (in.splitPrecision)
            for (int c = 0; c < p.inputDim; ++c) {
              buf[in.dst][c] = buf[in.dst][8 + c] = h(x[c]);
              buf[in.dst][4 + c] = h(x[c] - h(x[c]));
            }
          break;
        case MlpOp::DenseFp32:
        case MlpOp::Gemm:
          if (in.finalOutput) {  // fp16 weights, fp32 accumulation, result not rounded
            float acc = 0.f;
            for (int k = 0; k < in.inWidth; ++k)
              acc += halfBitsToFloat(p.halfWeights[in.halfOffset + k]) * srcAt(in.src, k);
            out[q] = activate(in.act, acc + p.floatWeights[in.biasOffset]);
            break;
          }
          if (in.dotNext) {  // fp32 activations straight into the final dot product
            const MlpInstr& fin = p.instrs[ii + 1];
            float dot = 0.f;
            for (int o = 0; o < in.outWidth; ++o) {
              float acc = 0.f;
              for (int k = 0; k < in.kPad; ++k)
                acc += halfBitsToFloat(p.halfWeights[in.halfOffset + std::int64_t(o) * in.kPad + k]) * srcAt(in.src, k);
              float v = activate(in.act, acc + p.floatWeights[in.biasOffset + o]);
              if (in.other >= 0) v = in.combineScale * (v + buf[in.other][o]);
              dot += v * p.floatWeights[fin.floatOffset + o];
            }
            out[q] = activate(fin.act, dot + p.floatWeights[fin.biasOffset]);
            break;
          }
          for (int o = 0; o < in.nPad; ++o) {
            float v = 0.f;
            if (o < in.outWidth) {
              float acc = 0.f;
              // A Gemm reads its padded K (zeros past inWidth, or the split coordinate columns).
              for (int k = 0; k < (in.op == MlpOp::Gemm ? in.kPad : in.inWidth); ++k) {
                const float w = in.op == MlpOp::Gemm
                                    ? halfBitsToFloat(p.halfWeights[in.halfOffset + std::int64_t(o) * in.kPad + k])
                                    : p.floatWeights[in.floatOffset + std::int64_t(o) * in.inWidth + k];
                acc += w * srcAt(in.src, k);
              }
              v = activate(in.act, acc + p.floatWeights[in.biasOffset + o]);
              if (in.other >= 0) v = in.combineScale * (v + buf[in.other][o]);
            }
            tmp[o] = h(v);
          }
          for (int o = 0; o < W; ++o) buf[in.dst][o] = o < in.nPad ? tmp[o] : 0.f;
          break;
        case MlpOp::Fourier:  // every encoding (Evaluator/Encodings.h)
        case MlpOp::HashGrid: {
          auto input = [&](int k) { return srcAt(in.src, k); };
          if (in.op == MlpOp::HashGrid)
            hashGridRowAsFused(p, in, input, W, tmp.data());
          else
            for (int c = 0; c < W; ++c) tmp[c] = c < in.outWidth ? h(encodingElement(in, p.floatWeights.data(), input, c)) : 0.f;
          buf[in.dst] = tmp;
          break;
        }
        case MlpOp::Activation:
          for (int c = 0; c < in.outWidth; ++c) buf[in.dst][c] = h(activate(in.act, in.actScale * buf[in.dst][c]));
          break;
        case MlpOp::Combine:
          for (int c = 0; c < in.outWidth; ++c)
            tmp[c] = h(in.combineScale * (buf[in.src][c] + (in.other >= 0 ? buf[in.other][c] : 0.f)));
          for (int c = 0; c < in.outWidth; ++c) buf[in.dst][c] = tmp[c];
          break;
        case MlpOp::OutputDot: {
          float acc = 0.f;
          for (int k = 0; k < in.inWidth; ++k) acc += p.floatWeights[in.floatOffset + k] * srcAt(in.src, k);
          out[q] = activate(in.act, acc + p.floatWeights[in.biasOffset]);
          break;
        }
        case MlpOp::Output: out[q] = buf[in.src][0]; break;
      }
    }
  }
}

}  // namespace inr
