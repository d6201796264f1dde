#pragma once
// The row-wise instructions of a fused program (everything but a GEMM: inputs, fp32 layers, the
// Fourier encoding, activations, residual sums, the output), run by a group of threads on a
// tile's rows in shared memory; both fused kernels call runRowInstr between their GEMMs. Where an
// encoding is fused into a GEMM's operand load instead, the kernels compute its elements with
// Evaluator/Encodings.h (fourierElement<ActMath::FastDevice>), the same arithmetic as stored here.
// The hash-grid encoding's gathers are FusedHashGrid.cuh.
#include <cuda_fp16.h>

#include "Evaluator/Cuda/FusedHashGrid.cuh"
#include "Evaluator/Cuda/FusedMlpDevice.cuh"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/Encodings.h"

namespace inr::cuda {

// The rows of a tile that a group of threads runs the row-wise instructions on (everything but
// a GEMM): the activation buffers, the network inputs, how many rows are queries, and the query
// index of row 0.
struct RowTile {
  __half* act;
  const int* bufferStart;  // per buffer, halves from act
  const int* bufferLd;
  const float* coords;  // 4 floats per row
  int rows, base;
};

// An instruction's buffers in a tile (null where it has none) and their row strides (halves).
struct InstrBuffers {
  __half* dst;
  const __half* src;
  const __half* other;
  int ldDst, ldSrc, ldOther;
  __device__ InstrBuffers(const MlpInstr& in, const RowTile& t)
      : dst(in.dst >= 0 ? t.act + t.bufferStart[in.dst] : nullptr),
        src(in.src >= 0 ? t.act + t.bufferStart[in.src] : nullptr),
        other(in.other >= 0 ? t.act + t.bufferStart[in.other] : nullptr),
        ldDst(in.dst >= 0 ? t.bufferLd[in.dst] : 0),
        ldSrc(in.src >= 0 ? t.bufferLd[in.src] : 0),
        ldOther(in.other >= 0 ? t.bufferLd[in.other] : 0) {}
};

// With tangents (TileRows<true>: t.rows counts queries), the instructions whose tangent rows
// need their query's value row (the derivative of a nonlinearity at the value; an in-place
// activation; the output): one thread per (query, column) computes the value and its three
// tangents, as emulateFusedTangents does (MlpProgramEmulation.cpp). LoadInput and Combine treat
// every row alike (linear), so runRowInstr runs them for tangent rows too.
template <int M, int THREADS, class K = RuntimeInstr>
__device__ __forceinline__ void runTangentRowInstr(const FusedParams& P, const MlpInstr& in, const RowTile& t, int tid,
                                          float* __restrict__ out, K = {}) {
  using L = TileRows<true>;
  constexpr int Q = M / 4;
  const InstrBuffers b(in, t);
  // Input k of direction d of query q (a coordinate row holds the input tangent).
  auto x = [&](int q, int d, int k) -> float {
    const int r = L::row(q, d);
    return in.src < 0 ? t.coords[r * 4 + k] : __half2float(b.src[r * b.ldSrc + k]);
  };
  auto store = [&](int q, int d, int c, float v) { b.dst[L::row(q, d) * b.ldDst + c] = __float2half(v); };
  switch (in.op) {
    case MlpOp::HashGrid: {
      if constexpr (!mayBe<K>(MlpOp::HashGrid)) break;
      // The value row from the fp16 tables with the value kernels' arithmetic (hashGridLevelFused,
      // as FusedHashGrid.cuh gathers): a shaded sample's value is its unshaded value, bit for bit.
      // The other columns (included inputs, padding) and the tangents below, element by element
      // from the fp32 tables.
      const HashGridView g{P.floatWeights + in.floatOffset};
      const HashGridColumns cols(in);
      const int levels = g.levels(), F = g.features();
      for (int idx = tid; idx < Q * levels; idx += THREADS) {
        const int q = idx / levels, l = idx - q * levels;
        auto input = [&](int k) { return x(q, 0, k); };
        const __half* table = P.hashTables + in.halfOffset + std::size_t(g.firstEntry(l)) * F;
        auto value = [&](std::uint32_t e, int j) { return __half2float(table[std::size_t(e) * F + j]); };
        float v[8];
        hashGridLevelFusedDims(g, l, in.inWidth, input, value, v);
        for (int j = 0; j < F; ++j) store(q, 0, cols.featureAt + l * F + j, v[j]);
      }
      for (int idx = tid; idx < Q * in.nPad; idx += THREADS) {
        const int q = idx / in.nPad, c = idx - q * in.nPad;
        auto input = [&](int k) { return x(q, 0, k); };
        const bool live = c < in.outWidth, feature = c >= cols.featureAt && c < cols.featureAt + levels * F;
        if (!feature) store(q, 0, c, live ? encodingElement<ActMath::FastDevice>(in, P.floatWeights, input, c) : 0.f);
        for (int d = 1; d < 4; ++d) {
          auto tangent = [&](int k) { return x(q, d, k); };
          store(q, d, c, live ? encodingElementTangent(in, P.floatWeights, input, tangent, c) : 0.f);
        }
      }
      break;
    }
    case MlpOp::Fourier:  // every encoding, element by element (Evaluator/Encodings.h)
      if constexpr (!mayBe<K>(MlpOp::Fourier)) break;
      for (int idx = tid; idx < Q * in.nPad; idx += THREADS) {
        const int q = idx / in.nPad, c = idx - q * in.nPad;
        auto input = [&](int k) { return x(q, 0, k); };
        const bool live = c < in.outWidth;
        store(q, 0, c, live ? encodingElement<ActMath::FastDevice>(in, P.floatWeights, input, c) : 0.f);
        for (int d = 1; d < 4; ++d) {
          auto tangent = [&](int k) { return x(q, d, k); };
          store(q, d, c, live ? encodingElementTangent(in, P.floatWeights, input, tangent, c) : 0.f);
        }
      }
      break;
    case MlpOp::DenseFp32:
      if constexpr (!mayBe<K>(MlpOp::DenseFp32)) break;
      for (int idx = tid; idx < Q * in.nPad; idx += THREADS) {
        const int q = idx / in.nPad, o = idx - q * in.nPad;
        float v[4] = {0.f, 0.f, 0.f, 0.f};  // zero padding columns
        if (o < in.outWidth) {
          const float* W = P.floatWeights + in.floatOffset + o * in.inWidth;
          v[0] = __ldg(P.floatWeights + in.biasOffset + o);
          for (int k = 0; k < in.inWidth; ++k)
            for (int d = 0; d < 4; ++d) v[d] = fmaf(__ldg(W + k), x(q, d, k), v[d]);
          const float pre = v[0], f = activationDerivative<ActMath::FastDevice>(in.act, pre);
          for (int d = 0; d < 4; ++d) {
            v[d] = d == 0 ? applyActivation(in.act, pre) : f * v[d];
            if (b.other) v[d] = in.combineScale * (v[d] + __half2float(b.other[L::row(q, d) * b.ldOther + o]));
          }
        }
        for (int d = 0; d < 4; ++d) store(q, d, o, v[d]);
      }
      break;
    case MlpOp::Activation:  // in place: the value row is read before it is overwritten
      if constexpr (!mayBe<K>(MlpOp::Activation)) break;
      for (int idx = tid; idx < Q * in.outWidth; idx += THREADS) {
        const int q = idx / in.outWidth, c = idx - q * in.outWidth;
        const float pre = in.actScale * __half2float(b.dst[L::row(q, 0) * b.ldDst + c]);
        const float f = activationDerivative<ActMath::FastDevice>(in.act, pre) * in.actScale;
        for (int d = 1; d < 4; ++d) store(q, d, c, f * __half2float(b.dst[L::row(q, d) * b.ldDst + c]));
        store(q, 0, c, applyActivation(in.act, pre));
      }
      break;
    case MlpOp::OutputDot:
    case MlpOp::Output:
      if constexpr (!mayBe<K>(MlpOp::OutputDot) && !mayBe<K>(MlpOp::Output)) break;
      for (int q = tid; q < t.rows; q += THREADS) {
        const float* W = in.op == MlpOp::OutputDot ? P.floatWeights + in.floatOffset : nullptr;
        float pre[4] = {0.f, 0.f, 0.f, 0.f};
        for (int d = 0; d < 4; ++d) {
          if (!W) pre[d] = x(q, d, 0);
          for (int k = 0; W && k < in.inWidth; ++k) pre[d] = fmaf(__ldg(W + k), x(q, d, k), pre[d]);
        }
        if (W) pre[0] += P.floatWeights[in.biasOffset];
        emitOutput<true>(P, W ? in.act : MlpAct::None, [&](int d) { return pre[d]; }, t.base + q, nullptr, out, nullptr);
      }
      break;
    default: break;  // LoadInput, Combine: runRowInstr; Gemm: the kernel's own code
  }
}

// LoadInput, DenseFp32, Fourier, HashGrid, Activation, Combine, OutputDot and Output on M rows with THREADS
// threads (tid: this thread's index among them); the caller synchronises afterwards. With
// kTangents (the rows of TileRows<true>), runTangentRowInstr runs what needs a query's rows together.
// kHashGrid false: the program has no hash grid, so the gathers (FusedHashGrid.cuh, a dozen
// template instantiations) are not compiled at all (a generated kernel: the optimiser would
// otherwise spend about as long on them as on the rest of the kernel). Force-inlined: a generated
// kernel calls it once per row instruction, with that instruction's constants.
template <int M, int THREADS, bool kTangents = false, bool kHashGrid = true, class K = RuntimeInstr>
__device__ __forceinline__ void runRowInstr(const FusedParams& P, const MlpInstr& in, const RowTile& t, int tid,
                                   const float4* __restrict__ points, float* __restrict__ out,
                                   const int* __restrict__ scatter, K known = {}) {
  if constexpr (kTangents) {
    if (in.op != MlpOp::LoadInput && in.op != MlpOp::Combine) {
      runTangentRowInstr<M, THREADS>(P, in, t, tid, out, known);
      return;
    }
  }
  constexpr int WARPS = THREADS / 32;
  const int warp = tid >> 5, lane = tid & 31;
  const int rows = t.rows, base = t.base;
  const float* const coords = t.coords;
  const InstrBuffers b(in, t);
  auto input = [&](int r, int k) -> float { return in.src < 0 ? coords[r * 4 + k] : __half2float(b.src[r * b.ldSrc + k]); };
  switch (in.op) {
    case MlpOp::LoadInput:
      if constexpr (!mayBe<K>(MlpOp::LoadInput)) break;
      if (in.splitPrecision) {  // columns hi | lo | hi | 0, one thread per (row, coordinate)
        for (int idx = tid; idx < M * 4; idx += THREADS) {
          const int r = idx >> 2, c = idx & 3;
          const float x = c < P.inputDim ? coords[r * 4 + c] : 0.f;
          const __half hi = __float2half(x);
          __half* d = b.dst + r * b.ldDst + c;
          d[0] = hi;
          d[4] = __float2half(x - __half2float(hi));
          d[8] = hi;
          d[12] = __float2half(0.f);
        }
      } else {
        for (int r = warp; r < M; r += WARPS)
          for (int c = lane; c < in.nPad; c += 32) b.dst[r * b.ldDst + c] = __float2half(c < P.inputDim ? coords[r * 4 + c] : 0.f);
      }
      break;
    case MlpOp::DenseFp32:
    case MlpOp::Fourier: {
      if constexpr (!mayBe<K>(MlpOp::DenseFp32) && !mayBe<K>(MlpOp::Fourier)) break;
      // One thread per output column (its weights in registers), looping over the rows.
      // A Fourier encoding's columns as Evaluator/Encodings.h lays them out; its projection is
      // the dense dot below with a zero bias: of the coordinates, the arithmetic of
      // fourierProjection<ActMath::FastDevice>, so a GEMM fusing the encoding changes no bit.
      const bool fourier = in.op == MlpOp::Fourier;
      const FourierColumns cols(in);
      const int inc = fourier ? cols.inputs : 0;
      const int m = fourier ? cols.features : in.outWidth;  // computed columns
      const int sinBase = cols.sinAt;
      const float* W = P.floatWeights + in.floatOffset;
      const int colsPerPass = min(m, THREADS), rowsPerPass = THREADS / colsPerPass;
      for (int c0 = 0; c0 < m; c0 += colsPerPass) {
        const int o = c0 + tid % colsPerPass;
        if (tid >= rowsPerPass * colsPerPass || o >= m) continue;
        float w[16];
#pragma unroll
        for (int k = 0; k < 16; ++k) w[k] = k < in.inWidth ? __ldg(W + o * in.inWidth + k) : 0.f;
        const float bias = fourier ? 0.f : __ldg(P.floatWeights + in.biasOffset + o);
        const int rStart = tid / colsPerPass;
        auto dot = [&](int r) {
          float acc = bias;
          if (in.src < 0) {  // coordinates: one 16-byte load; weights past inputDim are zero
            const float4 c = reinterpret_cast<const float4*>(coords)[r];
            acc = fmaf(w[0], c.x, fmaf(w[1], c.y, fmaf(w[2], c.z, fmaf(w[3], c.w, acc))));
          } else if (in.inWidth <= 16) {
#pragma unroll
            for (int k = 0; k < 16; ++k)
              if (k < in.inWidth) acc = fmaf(w[k], input(r, k), acc);
          } else {
            for (int k = 0; k < in.inWidth; ++k) acc = fmaf(__ldg(W + o * in.inWidth + k), input(r, k), acc);
          }
          return acc;
        };
        if (fourier) {
          for (int r = rStart; r < M; r += rowsPerPass) {
            float sn, cs;
            __sincosf(dot(r), &sn, &cs);
            b.dst[r * b.ldDst + sinBase + o] = __float2half(sn);
            b.dst[r * b.ldDst + sinBase + m + o] = __float2half(cs);
          }
        } else {
          withActivation(known, in.act, [&](auto A) {
            for (int r = rStart; r < M; r += rowsPerPass) {
              float v = applyActivation(decltype(A)::value, dot(r));
              if (b.other) v = in.combineScale * (v + __half2float(b.other[r * b.ldOther + o]));
              b.dst[r * b.ldDst + o] = __float2half(v);
            }
          });
        }
      }
      // Included inputs and zero padding: only those columns.
      for (int r = warp; r < M; r += WARPS) {
        for (int c = lane; c < inc; c += 32) b.dst[r * b.ldDst + cols.inputAt + c] = __float2half(input(r, c));
        for (int c = in.outWidth + lane; c < in.nPad; c += 32) b.dst[r * b.ldDst + c] = __float2half(0.f);
      }
      break;
    }
    case MlpOp::HashGrid: {
      if constexpr (kHashGrid) {
        // The features from the fp16 tables (FusedHashGrid.cuh), rounded to fp16 like every buffer.
        const HashGridColumns cols(in);
        hashGridRows<M, THREADS>(HashGridView{P.floatWeights + in.floatOffset}, P.hashTables + in.halfOffset, in.inWidth,
                                 P.hashGridPairs != 0, coords, b.src, b.ldSrc, b.dst, b.ldDst, cols.featureAt, tid);
        // Included inputs and zero padding: only those columns.
        for (int r = warp; r < M; r += WARPS) {
          for (int c = lane; c < cols.inputs; c += 32) b.dst[r * b.ldDst + cols.inputAt + c] = __float2half(input(r, c));
          for (int c = in.outWidth + lane; c < in.nPad; c += 32) b.dst[r * b.ldDst + c] = __float2half(0.f);
        }
      }
      break;
    }
    case MlpOp::Activation:
      if constexpr (!mayBe<K>(MlpOp::Activation)) break;
      for (int r = warp; r < M; r += WARPS)
        for (int c = lane; c < in.outWidth; c += 32)
          b.dst[r * b.ldDst + c] = __float2half(applyActivation(in.act, in.actScale * __half2float(b.dst[r * b.ldDst + c])));
      break;
    case MlpOp::Combine: {
      if constexpr (!mayBe<K>(MlpOp::Combine)) break;
      for (int r = warp; r < M; r += WARPS)
        for (int c = lane; c < in.nPad; c += 32) {
          const float v = __half2float(b.src[r * b.ldSrc + c]) + (b.other ? __half2float(b.other[r * b.ldOther + c]) : 0.f);
          b.dst[r * b.ldDst + c] = __float2half(in.combineScale * v);
        }
      break;
    }
    case MlpOp::OutputDot:
    case MlpOp::Output: {
      if constexpr (!mayBe<K>(MlpOp::OutputDot) && !mayBe<K>(MlpOp::Output)) break;
      const float* W = in.op == MlpOp::OutputDot ? P.floatWeights + in.floatOffset : nullptr;
      for (int r = warp; r < rows; r += WARPS) {
        float acc = 0.f;
        if (W) {
          for (int k = lane; k < in.inWidth; k += 32) acc = fmaf(__ldg(W + k), input(r, k), acc);
#pragma unroll
          for (int off = 16; off > 0; off >>= 1) acc += __shfl_xor_sync(0xffffffffu, acc, off);
        }
        if (lane == 0) {
          const float pre = W ? acc + P.floatWeights[in.biasOffset] : input(r, 0);
          emitOutput<false>(P, W ? in.act : MlpAct::None, [&](int) { return pre; }, base + r, points, out, scatter);
        }
      }
      break;
    }
    default: break;  // Gemm: the kernels' own code
  }
}

}  // namespace inr::cuda
