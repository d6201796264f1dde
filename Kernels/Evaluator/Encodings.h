#pragma once
// The encodings of a program (MlpProgram.h), element by element, written once for every path
// that runs the program: the CPU emulation of the fused kernels, the generic fp32 CUDA path, the
// naive per-thread network, and the fused kernels (their row instructions and the GEMM operand
// loads an encoding is fused into). A path stores column k of an encoding instruction as
// encodingElement(f, weights, x, k); a new encoding is a case there and a function beside
// fourierElement, not a loop in each path.
//
// ActMath picks the arithmetic as for the activations (Common/Activation.h): Exact is the fp32
// library functions with the projection summed in input order (the emulation, the per-thread
// network, the generic path; where a target compiles with --use_fast_math nvcc maps sinf to its
// intrinsic, as before); FastDevice is the fused kernels' form (coordinates only, last input
// first in one fmaf chain, __sinf / __cosf), which the fused kernels' stored and fused encodings
// share bit for bit.
//
// The CPU reference evaluator (Evaluator/CpuInrEvaluator.cpp) computes the same formula on whole
// Eigen arrays instead, for the reason Common/Activation.h gives.
#include <cmath>

#include "Common/Activation.h"  // ActMath, INR_HD
#include "Evaluator/MlpProgram.h"

namespace inr {

// Which operations are encodings of their input (evaluated through encodingElement).
INR_HD bool isEncoding(MlpOp op) { return op == MlpOp::Fourier; }

// Where the columns of a Fourier instruction f come from: sin(B_j x) in column sinAt + j,
// cos(B_j x) in column sinAt + features + j, the `inputs` included inputs x_i in column
// inputAt + i before (includeInput 1) or after (2) them, zeros past f.outWidth.
struct FourierColumns {
  int inputs;    // 0 or f.inWidth
  int features;  // rows of B
  int sinAt;
  int inputAt;   // meaningful where inputs > 0
  INR_HD explicit FourierColumns(const MlpInstr& f)
      : inputs(f.includeInput ? f.inWidth : 0),
        features((f.outWidth - inputs) / 2),
        sinAt(f.includeInput == 1 ? f.inWidth : 0),
        inputAt(f.includeInput == 1 ? 0 : 2 * features) {}
};

// B_j x for Bj, row j of B (inWidth floats, pre-scaled); x(i) is input i.
template <ActMath M, class Input>
INR_HD float fourierProjection(const float* Bj, int inWidth, const Input& x) {
#if defined(__CUDA_ARCH__)
  if constexpr (M == ActMath::FastDevice) {  // at most 4 coordinates; weights past inWidth zero
    const float w0 = __ldg(Bj), w1 = inWidth > 1 ? __ldg(Bj + 1) : 0.f, w2 = inWidth > 2 ? __ldg(Bj + 2) : 0.f,
                w3 = inWidth > 3 ? __ldg(Bj + 3) : 0.f;
    return fmaf(w0, x(0), fmaf(w1, x(1), fmaf(w2, x(2), fmaf(w3, x(3), 0.f))));
  }
#endif
  float p = 0.f;
  for (int k = 0; k < inWidth; ++k) p += Bj[k] * x(k);
  return p;
}

// Column k of Fourier instruction f of the inputs x, before any fp16 rounding; B: f's weights.
template <ActMath M, class Input>
INR_HD float fourierElement(const MlpInstr& f, const float* B, const Input& x, int k) {
  const FourierColumns cols(f);
  if (cols.inputs && k >= cols.inputAt && k < cols.inputAt + cols.inputs) return x(k - cols.inputAt);
  const int j = k - cols.sinAt;
  if (j < 0 || j >= 2 * cols.features) return 0.f;
  const bool sine = j < cols.features;
  const float p = fourierProjection<M>(B + (sine ? j : j - cols.features) * f.inWidth, f.inWidth, x);
#if defined(__CUDA_ARCH__)
  if constexpr (M == ActMath::FastDevice) return sine ? __sinf(p) : __cosf(p);
#endif
  return sine ? sinf(p) : cosf(p);
}

// Column k of encoding instruction f (isEncoding(f.op)); weights: the program's floatWeights.
template <ActMath M = ActMath::Exact, class Input>
INR_HD float encodingElement(const MlpInstr& f, const float* weights, const Input& x, int k) {
  switch (f.op) {
    case MlpOp::Fourier: return fourierElement<M>(f, weights + f.floatOffset, x, k);
    default: return 0.f;
  }
}

// Forward-mode derivative of column k of encoding instruction f along one direction: dx(i) is
// the derivative of input i (the per-thread network's gradient, Cuda/CudaPerThreadMlp.cuh; the
// CPU reference carries the same formulas on Eigen arrays). Exact arithmetic only.
template <class Input, class Tangent>
INR_HD float encodingElementTangent(const MlpInstr& f, const float* weights, const Input& x, const Tangent& dx, int k) {
  switch (f.op) {
    case MlpOp::Fourier: {  // d sin(Bx) = cos(Bx) B dx, d cos(Bx) = -sin(Bx) B dx
      const float* B = weights + f.floatOffset;
      const FourierColumns cols(f);
      if (cols.inputs && k >= cols.inputAt && k < cols.inputAt + cols.inputs) return dx(k - cols.inputAt);
      const int j = k - cols.sinAt;
      if (j < 0 || j >= 2 * cols.features) return 0.f;
      const bool sine = j < cols.features;
      const float* Bj = B + (sine ? j : j - cols.features) * f.inWidth;
      const float p = fourierProjection<ActMath::Exact>(Bj, f.inWidth, x);
      const float dp = fourierProjection<ActMath::Exact>(Bj, f.inWidth, dx);
      return sine ? cosf(p) * dp : -sinf(p) * dp;
    }
    default: return NAN;  // an encoding without its derivative: no normal (ambient only)
  }
}

}  // namespace inr
