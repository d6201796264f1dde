#pragma once
// Device code of the naive per-thread network evaluation (see CudaPerThreadMlp.h). Semantics of
// each instruction as in the generic fp32 path of CudaInrEvaluator (MlpProgram.h); activations
// and encodings in their exact form (Common/Activation.h, Evaluator/Encodings.h).
#include "Common/Activation.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/Encodings.h"
#include "Evaluator/MlpProgram.h"

namespace inr::cuda {

// Evaluates the network at world point (x, y, z, t) for thread slot `tid` of the scratch; with
// kTangents (forward mode, for gradient shading) also d value / d world x, y, z into grad: beside
// every activation the scratch holds its derivatives along the three world axes (the
// view's tangent planes), and each instruction applies its Jacobian to them as it computes the
// values (the CPU reference's runLayer, Evaluator/CpuInrEvaluator.cpp, element by element).
// Time is no direction. Without kTangents the arithmetic is the value path's alone. Host and
// device: the tests run it on the CPU against the reference (no GPU needed).
template <bool kTangents>
INR_HD float perThreadForward(const PerThreadMlpView& N, float x, float y, float z, float t, int tid,
                                         float* grad) {
  constexpr int D = kTangents ? 3 : 0;  // tangent directions
  const float world[4] = {x, y, z, t};
  float coords[4], dcoords[4][3];
  for (int i = 0; i < 4; ++i) {
    coords[i] = i < N.inputDim ? N.inScale[i] * world[N.inputCoord[i]] + N.inOffset[i] : 0.f;
    for (int a = 0; a < 3; ++a) dcoords[i][a] = i < N.inputDim && N.inputCoord[i] == a ? N.inScale[i] : 0.f;
  }
  const std::size_t stride = std::size_t(N.stride);
  const std::size_t plane = std::size_t(N.numBuffers) * N.width * stride;  // one direction's scratch
  // Direction 0 is the value, 1..3 the tangents along world x, y, z.
  auto at = [&](int buf, int c, int d = 0) -> float& {
    return N.scratch[d * plane + (std::size_t(buf) * N.width + c) * stride + tid];
  };
  auto load = [&](int buf, int c) -> float { return buf < 0 ? coords[c] : at(buf, c); };
  auto dload = [&](int buf, int c, int a) -> float { return buf < 0 ? dcoords[c][a] : at(buf, c, 1 + a); };
  float net = 0.f, dnet[3] = {0.f, 0.f, 0.f};
  for (int ip = 0; ip < N.numInstrs; ++ip) {
    const MlpInstr in = N.instrs[ip];
    switch (in.op) {
      case MlpOp::LoadInput:
        for (int c = 0; c < in.outWidth; ++c) {
          at(in.dst, c) = c < N.inputDim ? coords[c] : 0.f;
          for (int a = 0; a < D; ++a) at(in.dst, c, 1 + a) = c < N.inputDim ? dcoords[c][a] : 0.f;
        }
        break;
      case MlpOp::DenseFp32:
      case MlpOp::Gemm: {
        const float* W = N.weights + in.floatOffset;
        const float* bias = N.weights + in.biasOffset;
        const int src = in.coordInput ? -1 : in.src;  // coordInput: raw coordinates
        if (in.finalOutput) {  // the network's final width-1 layer: no destination buffer
          float acc = 0.f, dacc[3] = {0.f, 0.f, 0.f};
          for (int k = 0; k < in.inWidth; ++k) {
            acc += W[k] * load(in.src, k);
            for (int a = 0; a < D; ++a) dacc[a] += W[k] * dload(in.src, k, a);
          }
          net = activate(in.act, acc + bias[0]);
          if (kTangents) {
            const float f = activationDerivative(in.act, acc + bias[0]);
            for (int a = 0; a < 3; ++a) dnet[a] = f * dacc[a];
          }
          break;
        }
        // Blocks of 8 outputs in registers: each input is read once per block.
        constexpr int B = 8;
        for (int o0 = 0; o0 < in.outWidth; o0 += B) {
          float acc[B], dacc[B][kTangents ? 3 : 1];
#pragma unroll
          for (int j = 0; j < B; ++j) {
            acc[j] = 0.f;
            for (int a = 0; a < D; ++a) dacc[j][a] = 0.f;
          }
          for (int k = 0; k < in.inWidth; ++k) {
            const float xk = load(src, k);
            float dxk[3] = {0.f, 0.f, 0.f};
            for (int a = 0; a < D; ++a) dxk[a] = dload(src, k, a);
#pragma unroll
            for (int j = 0; j < B; ++j)
              if (o0 + j < in.outWidth) {
                const float w = W[std::size_t(o0 + j) * in.inWidth + k];
                acc[j] += w * xk;
                for (int a = 0; a < D; ++a) dacc[j][a] += w * dxk[a];
              }
          }
#pragma unroll
          for (int j = 0; j < B; ++j) {
            const int o = o0 + j;
            if (o >= in.outWidth) break;
            const float pre = acc[j] + bias[o];
            float v = activate(in.act, pre);
            if (in.other >= 0) v = in.combineScale * (v + at(in.other, o));
            at(in.dst, o) = v;
            if (kTangents) {
              const float f = activationDerivative(in.act, pre);
              for (int a = 0; a < 3; ++a) {
                float dv = f * dacc[j][a];
                if (in.other >= 0) dv = in.combineScale * (dv + at(in.other, o, 1 + a));
                at(in.dst, o, 1 + a) = dv;
              }
            }
          }
        }
        break;
      }
      case MlpOp::Fourier:  // every encoding (Evaluator/Encodings.h)
      case MlpOp::HashGrid: {
        auto input = [&](int k) { return load(in.src, k); };
        for (int c = 0; c < in.outWidth; ++c) {
          at(in.dst, c) = encodingElement(in, N.weights, input, c);
          for (int a = 0; a < D; ++a) {
            auto tangent = [&](int k) { return dload(in.src, k, a); };
            at(in.dst, c, 1 + a) = encodingElementTangent(in, N.weights, input, tangent, c);
          }
        }
        break;
      }
      case MlpOp::Activation:
        for (int c = 0; c < in.outWidth; ++c) {
          const float pre = in.actScale * at(in.dst, c);
          if (kTangents) {
            const float f = activationDerivative(in.act, pre) * in.actScale;
            for (int a = 0; a < 3; ++a) at(in.dst, c, 1 + a) *= f;
          }
          at(in.dst, c) = activate(in.act, pre);
        }
        break;
      case MlpOp::Combine:
        for (int c = 0; c < in.outWidth; ++c) {
          for (int a = 0; a < D; ++a)
            at(in.dst, c, 1 + a) =
                in.combineScale * (dload(in.src, c, a) + (in.other >= 0 ? at(in.other, c, 1 + a) : 0.f));
          at(in.dst, c) = in.combineScale * (load(in.src, c) + (in.other >= 0 ? at(in.other, c) : 0.f));
        }
        break;
      case MlpOp::OutputDot: {
        const float* W = N.weights + in.floatOffset;
        float acc = 0.f, dacc[3] = {0.f, 0.f, 0.f};
        for (int k = 0; k < in.inWidth; ++k) {
          acc += W[k] * load(in.src, k);
          for (int a = 0; a < D; ++a) dacc[a] += W[k] * dload(in.src, k, a);
        }
        const float pre = acc + N.weights[in.biasOffset];
        net = activate(in.act, pre);
        if (kTangents) {
          const float f = activationDerivative(in.act, pre);
          for (int a = 0; a < 3; ++a) dnet[a] = f * dacc[a];
        }
        break;
      }
      case MlpOp::Output:
        net = load(in.src, 0);
        for (int a = 0; a < D; ++a) dnet[a] = dload(in.src, 0, a);
        break;
    }
  }
  if (kTangents)
    for (int a = 0; a < 3; ++a) grad[a] = N.outA * dnet[a];
  return N.outA * net + N.outB;
}

// Evaluates the network at world point (x, y, z, t) for thread slot `tid` of the scratch.
__device__ inline float perThreadEvaluate(const PerThreadMlpView& N, float x, float y, float z, float t, int tid) {
  return perThreadForward<false>(N, x, y, z, t, tid, nullptr);
}

}  // namespace inr::cuda
