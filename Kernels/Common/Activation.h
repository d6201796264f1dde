#pragma once
// The networks' activation functions, written once for every scalar evaluation path: the fused
// tensor-core kernel, the generic fp32 CUDA path, the naive per-thread network and the CPU
// emulation of the fused kernel (MlpProgram). A sine's w0 is applied before the call (folded into
// the preceding linear layer's weights, or the Activation instruction's actScale).
//
// The CPU reference evaluator (Evaluator/CpuInrEvaluator.cpp) computes the same formulas on whole
// Eigen arrays instead: Eigen's vectorised sin/exp/tanh are other implementations than the scalar
// library functions here, so routing it through this function would change its results (and
// speed).
#if !defined(__CUDACC_RTC__)  // NVRTC: the math functions are built in (Common/RtcCompat.h)
#include <cmath>
#endif

#include "Common/HostDevice.h"
#include "Common/RtcCompat.h"

namespace inr {

enum class MlpAct : std::int32_t { None, Sine, SiLU, ReLU, Sigmoid, Tanh };

// Exact: the fp32 library functions (sinf, expf, tanhf); where a target compiles with
// --use_fast_math (inr_cuda) nvcc maps sinf and expf to their intrinsics, as before.
// FastDevice: the fused kernel's special-function forms, one MUFU instruction each: __sinf, and
// SiLU, sigmoid and tanh through tanh.approx (x sigma(x) = h + h tanh(h) with h = x / 2). Device
// code only; elsewhere it computes Exact.
enum class ActMath { Exact, FastDevice };

#if defined(__CUDACC__)
// One MUFU.TANH (sm_75+); max. relative error ~2^-11, below the fp16 rounding the fused kernel's
// activations get anyway.
__device__ inline float tanhApprox(float v) {
  float r;
  asm("tanh.approx.f32 %0, %1;" : "=f"(r) : "f"(v));
  return r;
}
#endif

template <ActMath M = ActMath::Exact>
INR_HD float activate(MlpAct a, float v) {
#if defined(__CUDA_ARCH__)
  if constexpr (M == ActMath::FastDevice) {
    switch (a) {
      case MlpAct::None: return v;
      case MlpAct::Sine: return __sinf(v);
      case MlpAct::SiLU: {
        const float h = 0.5f * v;
        return fmaf(h, tanhApprox(h), h);
      }
      case MlpAct::ReLU: return fmaxf(v, 0.f);
      case MlpAct::Sigmoid: return fmaf(0.5f, tanhApprox(0.5f * v), 0.5f);
      case MlpAct::Tanh: return tanhApprox(v);
    }
    return v;
  }
#endif
  switch (a) {
    case MlpAct::None: return v;
    case MlpAct::Sine: return sinf(v);
    case MlpAct::SiLU: return v / (1.f + expf(-v));
    case MlpAct::ReLU:
#if defined(__CUDA_ARCH__)
      return fmaxf(v, 0.f);
#else
      return v > 0.f ? v : 0.f;  // the emulation's form: fmaxf but for the sign of a zero result
#endif
    case MlpAct::Sigmoid: return 1.f / (1.f + expf(-v));
    case MlpAct::Tanh: return tanhf(v);
  }
  return v;
}

// d activate(a, v) / dv at the pre-activation v (w0 already applied, as for activate: a sine
// layer's derivative with respect to its input is w0 * activationDerivative(Sine, w0 x)), for
// forward-mode gradients (value and d/dx in one pass: each tangent is multiplied by this factor).
// Exact: the fp32 library functions; FastDevice: the fused kernels' one-instruction forms, the
// same functions activate<FastDevice> computes the value with. ReLU's derivative at 0 is 0 (the
// subgradient the training frameworks use).
//
// The CPU reference evaluator computes the same formulas on whole Eigen arrays (its
// forward-mode pass in Evaluator/CpuInrEvaluator.cpp), for the reason given at the top.
template <ActMath M = ActMath::Exact>
INR_HD float activationDerivative(MlpAct a, float v) {
#if defined(__CUDA_ARCH__)
  if constexpr (M == ActMath::FastDevice) {
    switch (a) {
      case MlpAct::None: return 1.f;
      case MlpAct::Sine: return __cosf(v);
      case MlpAct::SiLU: {  // sigma(v) (1 + v (1 - sigma(v)))
        const float s = fmaf(0.5f, tanhApprox(0.5f * v), 0.5f);
        return s * fmaf(v, 1.f - s, 1.f);
      }
      case MlpAct::ReLU: return v > 0.f ? 1.f : 0.f;
      case MlpAct::Sigmoid: {
        const float s = fmaf(0.5f, tanhApprox(0.5f * v), 0.5f);
        return s * (1.f - s);
      }
      case MlpAct::Tanh: {
        const float t = tanhApprox(v);
        return fmaf(-t, t, 1.f);
      }
    }
    return 1.f;
  }
#endif
  switch (a) {
    case MlpAct::None: return 1.f;
    case MlpAct::Sine: return cosf(v);
    case MlpAct::SiLU: {
      const float s = 1.f / (1.f + expf(-v));
      return s * (1.f + v * (1.f - s));
    }
    case MlpAct::ReLU: return v > 0.f ? 1.f : 0.f;
    case MlpAct::Sigmoid: {
      const float s = 1.f / (1.f + expf(-v));
      return s * (1.f - s);
    }
    case MlpAct::Tanh: {
      const float t = tanhf(v);
      return 1.f - t * t;
    }
  }
  return 1.f;
}

}  // namespace inr
