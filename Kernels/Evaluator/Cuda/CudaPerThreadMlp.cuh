#pragma once
// Device code of the naive per-thread network evaluation (see CudaPerThreadMlp.h). Semantics of
// each instruction as in the generic fp32 path of CudaInrEvaluator (MlpProgram.h); activations
// and encodings in their exact form (Common/Activation.h, Evaluator/Encodings.h).
#include "Common/Activation.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/Encodings.h"
#include "Evaluator/MlpProgram.h"

namespace inr::cuda {

// Evaluates the network at world point (x, y, z, t) for thread slot `tid` of the scratch.
__device__ inline float perThreadEvaluate(const PerThreadMlpView& N, float x, float y, float z, float t, int tid) {
  const float world[4] = {x, y, z, t};
  float coords[4];
  for (int i = 0; i < 4; ++i)
    coords[i] = i < N.inputDim ? N.inScale[i] * world[N.inputCoord[i]] + N.inOffset[i] : 0.f;
  const std::size_t stride = std::size_t(N.stride);
  auto at = [&](int buf, int c) -> float& { return N.scratch[(std::size_t(buf) * N.width + c) * stride + tid]; };
  auto load = [&](int buf, int c) -> float { return buf < 0 ? coords[c] : at(buf, c); };
  float net = 0.f;
  for (int ip = 0; ip < N.numInstrs; ++ip) {
    const MlpInstr in = N.instrs[ip];
    switch (in.op) {
      case MlpOp::LoadInput:
        for (int c = 0; c < in.outWidth; ++c) at(in.dst, c) = c < N.inputDim ? coords[c] : 0.f;
        break;
      case MlpOp::DenseFp32:
      case MlpOp::Gemm: {
        const float* W = N.weights + in.floatOffset;
        const float* bias = N.weights + in.biasOffset;
        if (in.finalOutput) {  // the network's final width-1 layer: no destination buffer
          float acc = 0.f;
          for (int k = 0; k < in.inWidth; ++k) acc += W[k] * load(in.src, k);
          net = activate(in.act, acc + bias[0]);
          break;
        }
        // Blocks of 8 outputs in registers: each input is read once per block.
        constexpr int B = 8;
        for (int o0 = 0; o0 < in.outWidth; o0 += B) {
          float acc[B];
#pragma unroll
          for (int j = 0; j < B; ++j) acc[j] = 0.f;
          for (int k = 0; k < in.inWidth; ++k) {
            const float xk = load(in.coordInput ? -1 : in.src, k);  // coordInput: raw coordinates
#pragma unroll
            for (int j = 0; j < B; ++j)
              if (o0 + j < in.outWidth) acc[j] += W[std::size_t(o0 + j) * in.inWidth + k] * xk;
          }
#pragma unroll
          for (int j = 0; j < B; ++j) {
            const int o = o0 + j;
            if (o >= in.outWidth) break;
            float v = activate(in.act, acc[j] + bias[o]);
            if (in.other >= 0) v = in.combineScale * (v + at(in.other, o));
            at(in.dst, o) = v;
          }
        }
        break;
      }
      case MlpOp::Fourier:  // every encoding (Evaluator/Encodings.h)
      case MlpOp::HashGrid: {
        auto input = [&](int k) { return load(in.src, k); };
        for (int c = 0; c < in.outWidth; ++c) at(in.dst, c) = encodingElement(in, N.weights, input, c);
        break;
      }
      case MlpOp::Activation:
        for (int c = 0; c < in.outWidth; ++c) at(in.dst, c) = activate(in.act, in.actScale * at(in.dst, c));
        break;
      case MlpOp::Combine:
        for (int c = 0; c < in.outWidth; ++c)
          at(in.dst, c) = in.combineScale * (load(in.src, c) + (in.other >= 0 ? at(in.other, c) : 0.f));
        break;
      case MlpOp::OutputDot: {
        const float* W = N.weights + in.floatOffset;
        float acc = 0.f;
        for (int k = 0; k < in.inWidth; ++k) acc += W[k] * load(in.src, k);
        net = activate(in.act, acc + N.weights[in.biasOffset]);
        break;
      }
      case MlpOp::Output: net = load(in.src, 0); break;
    }
  }
  return N.outA * net + N.outB;
}

}  // namespace inr::cuda
