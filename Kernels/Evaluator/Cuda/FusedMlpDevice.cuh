#pragma once
// Device code both fused kernels share: activations, the output mapping, network inputs, a
// tile's coordinates, shared-memory loads that stay where they stand, ldmatrix and mma.sync
// (the Hopper kernel loads its A operand with ldmatrix too), and compile-time tags.
#include <cuda_fp16.h>

#include "Common/Activation.h"
#include "Common/RtcCompat.h"
#include "Evaluator/Cuda/FusedMlpParams.cuh"

namespace inr::cuda {

// The fused kernel's activations: the special-function forms of Common/Activation.h.
__device__ inline float applyActivation(MlpAct a, float v) { return activate<ActMath::FastDevice>(a, v); }

template <MlpAct A>
struct ActTag {
  static constexpr MlpAct value = A;
};

// Calls f(ActTag<A>{}) for the runtime activation, so loops inside f see it as a constant.
template <typename F>
__device__ inline void dispatchActivation(MlpAct a, F&& f) {
  switch (a) {
    case MlpAct::None: f(ActTag<MlpAct::None>{}); break;
    case MlpAct::Sine: f(ActTag<MlpAct::Sine>{}); break;
    case MlpAct::SiLU: f(ActTag<MlpAct::SiLU>{}); break;
    case MlpAct::ReLU: f(ActTag<MlpAct::ReLU>{}); break;
    case MlpAct::Sigmoid: f(ActTag<MlpAct::Sigmoid>{}); break;
    case MlpAct::Tanh: f(ActTag<MlpAct::Tanh>{}); break;
  }
}

__device__ inline void outputAffine(const OutputMap& m, float t, float& a, float& b) {
  if (m.count == 0) {
    a = m.a;
    b = m.b;
    return;
  }
  const float* T = m.table;
  if (t <= T[0]) {
    a = T[1];
    b = T[2];
    return;
  }
  for (int i = 1; i < m.count; ++i) {
    if (t <= T[3 * i]) {
      const float f = (t - T[3 * (i - 1)]) / (T[3 * i] - T[3 * (i - 1)]);
      a = T[3 * (i - 1) + 1] + f * (T[3 * i + 1] - T[3 * (i - 1) + 1]);
      b = T[3 * (i - 1) + 2] + f * (T[3 * i + 2] - T[3 * (i - 1) + 2]);
      return;
    }
  }
  a = T[3 * (m.count - 1) + 1];
  b = T[3 * (m.count - 1) + 2];
}

// The value query q gets from the network output `net` at time t (the output map), stored at
// q or, with a scatter array, at scatter[q].
__device__ inline void writeOutput(const OutputMap& m, float t, float net, int q, float* __restrict__ out,
                                   const int* __restrict__ scatter) {
  float a, b;
  outputAffine(m, t, a, b);
  out[scatter ? scatter[q] : q] = a * net + b;
}

// Value + gradient: query q's value a * net + b and world gradient (P.gradientScale[k] times
// the network output's tangent dnet[k]) as one float4 in out (float4 per query, no scatter).
__device__ inline void writeGradientOutput(const FusedParams& P, float net, const float (&dnet)[3], int q,
                                           float* __restrict__ out) {
  reinterpret_cast<float4*>(out)[q] = make_float4(P.output.a * net + P.output.b, P.gradientScale[0] * dnet[0],
                                                  P.gradientScale[1] * dnet[1], P.gradientScale[2] * dnet[2]);
}

// The rows of a tile. Values only: row r holds query r. With tangents (value + gradient in one
// pass): each warp row group's 32 rows hold 8 queries, row 32 (q / 8) + 8 d + q % 8 holding
// direction d of query q (0 the value, 1..3 its tangents along the inputs P.tangentInput names).
// An mma.sync accumulator fragment's rows g and g + 8 of a warp's two m16 tiles are then one
// query's value and three tangents: every thread holds the same (query, column) of all four,
// so the epilogue's act(z) and act'(z) * dz are thread-local, and the GEMMs run unchanged.
template <bool kTangents>
struct TileRows {
  static constexpr int kDirections = kTangents ? 4 : 1;
  __device__ static int row(int q, int d) { return kTangents ? ((q >> 3) << 5) | (d << 3) | (q & 7) : q; }
  __device__ static int query(int r) { return kTangents ? ((r >> 5) << 3) | (r & 7) : r; }
  __device__ static int direction(int r) { return kTangents ? (r >> 3) & 3 : 0; }
};

// Query q's output from its final pre-activation, pre(d) for direction d (the network's last
// layer, activation act): the value through writeOutput, or with tangents the value and
// gradient, act'(pre(0)) * pre(d) being the output's tangents.
template <bool kTangents, class Pre>
__device__ inline void emitOutput(const FusedParams& P, MlpAct act, const Pre& pre, int q, const float4* __restrict__ points,
                                  float* __restrict__ out, const int* __restrict__ scatter) {
  const float p0 = pre(0);
  if constexpr (kTangents) {
    const float f = activationDerivative<ActMath::FastDevice>(act, p0);
    const float dnet[3] = {f * pre(1), f * pre(2), f * pre(3)};
    writeGradientOutput(P, activate<ActMath::FastDevice>(act, p0), dnet, q, out);
  } else {
    writeOutput(P.output, points[q].w, activate<ActMath::FastDevice>(act, p0), q, out, scatter);
  }
}

// The network inputs of a query at world point p (x, y, z, t): the model's input order and
// domain mapping, zero past inputDim.
__device__ inline void networkInputs(const FusedParams& P, float4 p, float* x) {
  const float w[4] = {p.x, p.y, p.z, p.w};
#pragma unroll
  for (int i = 0; i < 4; ++i) x[i] = i < P.inputDim ? P.inScale[i] * w[P.inputCoord[i]] + P.inOffset[i] : 0.f;
}

// Coordinates of a tile's M rows (network inputs, 4 floats per row; zero rows past `rows`),
// THREADS threads, tid this thread's index among them; the caller synchronises.
// With tangents (TileRows<true>), `rows` counts queries and a tangent row holds its input
// tangent: P.tangentScale at the input its direction moves, zeros elsewhere.
template <int M, int THREADS, bool kTangents = false>
__device__ inline void loadTileCoords(const FusedParams& P, const float4* __restrict__ points, int base, int rows,
                                      float* coords, int tid) {
  using L = TileRows<kTangents>;
  for (int r = tid; r < M; r += THREADS) {
    const int d = L::direction(r), q = L::query(r);
    if (d > 0) {
#pragma unroll
      for (int k = 0; k < 4; ++k) coords[r * 4 + k] = k == P.tangentInput[d - 1] ? P.tangentScale : 0.f;
    } else {
      networkInputs(P, q < rows ? points[base + q] : make_float4(0.f, 0.f, 0.f, 0.f), coords + r * 4);
    }
  }
}

__device__ inline unsigned smemAddress(const void* p) { return unsigned(__cvta_generic_to_shared(p)); }

// Reads a half2 from shared memory where it stands (see ldsFloat2InPlace): the residual operand
// of an epilogue, which the compiler would otherwise hoist as 32 loads ahead of the arithmetic.
__device__ inline float2 ldsHalf2AsFloat2InPlace(const __half* p) {
  unsigned bits;
  asm volatile("ld.shared.b32 %0, [%1];\n" : "=r"(bits) : "r"(smemAddress(p)));
  __half2 h;
  memcpy(&h, &bits, sizeof h);
  return __half22float2(h);
}

// Reads two floats from shared memory where it stands: the final dot's weights are loaded in
// the epilogue one pair at a time, not hoisted (64 live accumulators leave no room for them).
__device__ inline float2 ldsFloat2InPlace(const float* p) {
  float2 v;
  asm volatile("ld.shared.v2.f32 {%0, %1}, [%2];\n" : "=f"(v.x), "=f"(v.y) : "r"(smemAddress(p)));
  return v;
}

// Loads four 8x8 b16 matrices; `addr` is this lane's shared-memory byte address (its row).
__device__ inline void ldmatrixX4(unsigned (&r)[4], unsigned addr) {
  asm volatile("ldmatrix.sync.aligned.m8n8.x4.shared.b16 {%0,%1,%2,%3}, [%4];\n"
               : "=r"(r[0]), "=r"(r[1]), "=r"(r[2]), "=r"(r[3])
               : "r"(addr));
}

// D += A(16x16) * B(16x8), fp16 operands, fp32 accumulators. Turing (sm_75) has no m16n8k16
// for f16: it runs as two m16n8k8 halves over k with the same register fragments.
__device__ inline void mma16816(float (&d)[4], const unsigned (&a)[4], unsigned b0, unsigned b1) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
  asm(
      "mma.sync.aligned.m16n8k16.row.col.f32.f16.f16.f32 {%0,%1,%2,%3}, {%4,%5,%6,%7}, {%8,%9}, "
      "{%0,%1,%2,%3};\n"
      : "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3])
      : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "r"(b0), "r"(b1));
#else
  asm("mma.sync.aligned.m16n8k8.row.col.f32.f16.f16.f32 {%0,%1,%2,%3}, {%4,%5}, {%6}, {%0,%1,%2,%3};\n"
               : "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3])
               : "r"(a[0]), "r"(a[1]), "r"(b0));
  asm("mma.sync.aligned.m16n8k8.row.col.f32.f16.f16.f32 {%0,%1,%2,%3}, {%4,%5}, {%6}, {%0,%1,%2,%3};\n"
               : "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3])
               : "r"(a[2]), "r"(a[3]), "r"(b1));
#endif
}

// D = A(16x16) * B(16x8) + C with C = the bias pair of this lane's columns in both rows: the
// first k step of a GEMM, so accumulators start at the bias without separate moves.
__device__ inline void mma16816Bias(float (&d)[4], const unsigned (&a)[4], unsigned b0, unsigned b1, float2 c) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
  asm("mma.sync.aligned.m16n8k16.row.col.f32.f16.f16.f32 {%0,%1,%2,%3}, {%4,%5,%6,%7}, {%8,%9}, "
      "{%10,%11,%10,%11};\n"
      : "=f"(d[0]), "=f"(d[1]), "=f"(d[2]), "=f"(d[3])
      : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "r"(b0), "r"(b1), "f"(c.x), "f"(c.y));
#else
  d[0] = d[2] = c.x;
  d[1] = d[3] = c.y;
  mma16816(d, a, b0, b1);
#endif
}

// The same with the bias in rows g only (row g + 8 starts at zero): a tangent tile's first m16
// tile, whose rows g are values and rows g + 8 tangents (TileRows<true>), which have no bias.
__device__ inline void mma16816BiasUpperZero(float (&d)[4], const unsigned (&a)[4], unsigned b0, unsigned b1, float2 c) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
  asm("mma.sync.aligned.m16n8k16.row.col.f32.f16.f16.f32 {%0,%1,%2,%3}, {%4,%5,%6,%7}, {%8,%9}, "
      "{%10,%11,%12,%12};\n"
      : "=f"(d[0]), "=f"(d[1]), "=f"(d[2]), "=f"(d[3])
      : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "r"(b0), "r"(b1), "f"(c.x), "f"(c.y), "f"(0.f));
#else
  d[0] = c.x;
  d[1] = c.y;
  d[2] = d[3] = 0.f;
  mma16816(d, a, b0, b1);
#endif
}

// Compile-time tags for the kernels' generic lambdas (warp column blocks, k steps, first k step,
// residual).
template <int N>
using IntTag = std::integral_constant<int, N>;
template <bool B>
using BoolTag = std::bool_constant<B>;

// What a kernel knows of an instruction before it runs: RuntimeInstr (the interpreter decodes it
// as its loop reaches it) or ConstantInstr<Desc, I> (a generated kernel: instruction I of the
// program Desc, Evaluator/MlpKernelSource.h, a compile-time constant). For a constant one the
// dispatchers below (withActivation, mayBe, and the kernels' block-count and residual choices)
// instantiate only the branch it takes. A runtime switch on a constant would fold too, but only
// after the optimiser has inlined every branch's force-inlined body: a generated kernel then
// paid, at each of its instructions, for every activation, block count and operation, and
// NVRTC spent most of its time removing them again.
struct RuntimeInstr {
  static constexpr bool kConstant = false;
};
template <class Desc, int I>
struct ConstantInstr {
  static constexpr bool kConstant = true;
  __host__ __device__ static constexpr MlpInstr get() { return Desc::instr(I); }
};

// Whether an instruction known as K may be operation `op` (a runtime one may be any).
template <class K>
__host__ __device__ constexpr bool mayBe(MlpOp op) {
  if constexpr (K::kConstant)
    return K::get().op == op;
  else
    return true;
}

// Whether an instruction known as K may have the flag `field` set (finalOutput: a GEMM writes the
// network's output; dotNext: it fuses the final dot); a runtime one may.
template <class K>
__host__ __device__ constexpr bool mayHave(std::int32_t MlpInstr::*field) {
  if constexpr (K::kConstant)
    return K::get().*field != 0;
  else
    return true;
}

// f(ActTag<A>{}) for the instruction's activation `a`: the one instantiation a constant
// instruction needs, else the runtime dispatch.
template <class K, typename F>
__device__ __forceinline__ void withActivation(K, MlpAct a, F&& f) {
  if constexpr (K::kConstant)
    f(ActTag<K::get().act>{});
  else
    dispatchActivation(a, f);
}

}  // namespace inr::cuda
