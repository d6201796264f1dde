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
#if !defined(__CUDACC_RTC__)  // NVRTC: the fused kernels' device code only (Common/RtcCompat.h)
#include <cmath>

#include "Evaluator/MlpProgram.h"
#endif

#include "Common/Activation.h"  // ActMath, INR_HD
#include "Common/RtcCompat.h"
#include "Evaluator/MlpInstr.h"

namespace inr {

// Which operations are encodings of their input (evaluated through encodingElement).
INR_HD bool isEncoding(MlpOp op) { return op == MlpOp::Fourier || op == MlpOp::HashGrid; }

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

// A hash-grid encoding's packed weights (packHashGrid, MlpProgram.h): a header of 4 words
// (levels, features per level, smoothstep, 0), then 4 words per level (scale as fp32, then
// resolution, first entry and entry count as uint32 bit patterns), then the table, one row of
// features per entry. Integers travel as bit patterns because the offsets exceed fp32's 2^24.
struct HashGridView {
  const float* data;
  INR_HD std::uint32_t word(int i) const {
    std::uint32_t u;
    memcpy(&u, data + i, sizeof u);
    return u;
  }
  INR_HD int levels() const { return int(word(0)); }
  INR_HD int features() const { return int(word(1)); }
  INR_HD bool smoothstep() const { return word(2) != 0; }
  INR_HD float scale(int level) const { return data[4 + 4 * level]; }
  INR_HD std::uint32_t resolution(int level) const { return word(5 + 4 * level); }
  INR_HD std::uint32_t firstEntry(int level) const { return word(6 + 4 * level); }
  INR_HD std::uint32_t entries(int level) const { return word(7 + 4 * level); }
  INR_HD const float* table() const { return data + 4 + 4 * levels(); }
};

// Where the columns of a hash-grid instruction f come from: feature j of level l in column
// featureAt + l * features + j, the included inputs x_i in column inputAt + i.
struct HashGridColumns {
  int inputs;  // 0 or f.inWidth
  int featureAt;
  int inputAt;
  INR_HD explicit HashGridColumns(const MlpInstr& f)
      : inputs(f.includeInput ? f.inWidth : 0),
        featureAt(f.includeInput == 1 ? f.inWidth : 0),
        inputAt(f.includeInput == 1 ? 0 : f.outWidth - inputs) {}
};

// instant-ngp's spatial hash multiplies vertex coordinate d by this prime (1 for x, so that
// neighbours along x land in neighbouring entries) before XORing the axes.
INR_HD constexpr std::uint32_t hashGridPrime(int d) {
  return d == 0 ? 1u : d == 1 ? 2654435761u : d == 2 ? 805459861u : 3674653429u;
}

// index modulo a level's `entries`, without a division where none is needed (hashed levels hold
// a power of 2, dense ones wrap only for vertices past the grid).
INR_HD std::uint32_t hashGridWrap(std::uint32_t index, std::uint32_t entries) {
  if ((entries & (entries - 1)) == 0) return index & (entries - 1);
  return index < entries ? index : index % entries;
}

// The entry of grid vertex v (dims coordinates) in a level of `entries` entries at resolution
// res: the dense index while the grid fits the level (row-major, x fastest), else instant-ngp's
// spatial hash (XOR of v_i times a prime per axis); both modulo the level's size, in uint32
// arithmetic, as tiny-cuda-nn computes it (so out-of-grid vertices wrap, as there).
INR_HD std::uint32_t hashGridEntry(const std::uint32_t* v, int dims, std::uint32_t res, std::uint32_t entries) {
  std::uint32_t stride = 1, index = 0;
  for (int d = 0; d < dims && stride <= entries; ++d) {
    index += v[d] * stride;
    stride *= res;
  }
  if (entries < stride) {
    index = 0;
    for (int d = 0; d < dims; ++d) index ^= v[d] * hashGridPrime(d);
  }
  return hashGridWrap(index, entries);
}

// The cell of a level around inputs x: per axis its lower vertex, the interpolation weight of the
// upper vertex (linear, or smoothstep) and that weight's derivative along the input.
struct HashGridCell {
  std::uint32_t lower[4];
  float w[4], dw[4];
};

template <class Input>
INR_HD HashGridCell hashGridCell(const HashGridView& g, int level, int dims, const Input& x) {
  const float scale = g.scale(level);
  HashGridCell c;
  for (int d = 0; d < dims; ++d) {
    const float p = fmaf(scale, x(d), 0.5f);
    // Clamped before the integer conversion, so any input (far outside [0, 1], NaN) is defined.
    const float corner = fminf(fmaxf(floorf(p), -1073741824.f), 1073741824.f);
    c.lower[d] = static_cast<std::uint32_t>(static_cast<std::int32_t>(corner));
    const float t = p - corner;
    // fmaf spelled out: nvcc would contract 3 - 2t and the host compiler not, and the fused
    // kernels' emulation must round as they do.
    c.w[d] = g.smoothstep() ? t * t * fmaf(-2.f, t, 3.f) : t;
    c.dw[d] = g.smoothstep() ? 6.f * t * (1.f - t) * scale : scale;
  }
  return c;
}

// The interpolation weight of corner `corner` of the cell (bit d set: the upper vertex along d).
INR_HD float hashGridCornerWeight(const HashGridCell& c, int dims, int corner) {
  float weight = 1.f;
  for (int d = 0; d < dims; ++d) weight *= ((corner >> d) & 1) ? c.w[d] : 1.f - c.w[d];
  return weight;
}

// The entries of a cell's corners on one level, as hashGridEntry gives them, from what each
// axis's lower and upper vertex contribute (v * res^d, summed, on a dense level; v * prime_d,
// XORed, on a hashed one), so a corner costs DIMS - 1 adds or XORs.
template <int DIMS>
struct HashGridCorners {
  std::uint32_t lo[DIMS], hi[DIMS], entries;
  bool hashed;
  INR_HD HashGridCorners(const std::uint32_t* lower, std::uint32_t res, std::uint32_t levelEntries)
      : entries(levelEntries) {
    std::uint32_t stride = 1;  // as hashGridEntry decides dense or hashed
    for (int d = 0; d < DIMS && stride <= entries; ++d) stride *= res;
    hashed = entries < stride;
    std::uint32_t s = 1;
    for (int d = 0; d < DIMS; ++d) {
      const std::uint32_t k = hashed ? hashGridPrime(d) : s;
      lo[d] = lower[d] * k;
      hi[d] = (lower[d] + 1u) * k;
      s *= res;
    }
  }
  INR_HD std::uint32_t entry(int corner) const {
    std::uint32_t index = (corner & 1) ? hi[0] : lo[0];
    for (int d = 1; d < DIMS; ++d) {
      const std::uint32_t part = ((corner >> d) & 1) ? hi[d] : lo[d];
      index = hashed ? index ^ part : index + part;
    }
    return hashGridWrap(index, entries);
  }
};

// Features [first, first + count) of hash-grid level `level` at the inputs x (x(i), i < dims),
// interpolated (d-linearly, or with smoothstep weights) between the 2^dims vertices of the cell
// around x * scale + 0.5, into out[0, count). With dOut, also their derivatives along each input:
// dOut[j * dims + i] = d out[j] / d x_i. The fp32 reference form (CPU, generic and per-thread
// GPU paths); the fused kernels' is hashGridLevelFused.
template <class Input>
INR_HD void hashGridLevel(const HashGridView& g, int level, int dims, const Input& x, int first, int count, float* out,
                          float* dOut = nullptr) {
  const std::uint32_t res = g.resolution(level), entries = g.entries(level);
  const int F = g.features();
  const float* table = g.table() + std::size_t(g.firstEntry(level)) * F;
  const HashGridCell c = hashGridCell(g, level, dims, x);
  for (int j = 0; j < count; ++j) out[j] = 0.f;
  if (dOut)
    for (int j = 0; j < count * dims; ++j) dOut[j] = 0.f;
  for (int corner = 0; corner < (1 << dims); ++corner) {
    std::uint32_t v[4];
    for (int d = 0; d < dims; ++d) v[d] = c.lower[d] + (((corner >> d) & 1) ? 1u : 0u);
    const float weight = hashGridCornerWeight(c, dims, corner);
    const float* entry = table + std::size_t(hashGridEntry(v, dims, res, entries)) * F + first;
    for (int j = 0; j < count; ++j) out[j] += weight * entry[j];
    if (dOut) {
      for (int i = 0; i < dims; ++i) {  // d weight / d x_i: the factor of axis i differentiated
        float dweight = ((corner >> i) & 1) ? c.dw[i] : -c.dw[i];
        for (int d = 0; d < dims; ++d)
          if (d != i) dweight *= ((corner >> d) & 1) ? c.w[d] : 1.f - c.w[d];
        for (int j = 0; j < count; ++j) dOut[j * dims + i] += dweight * entry[j];
      }
    }
  }
}

// All F features of hash-grid level `level` as the fused kernels compute them
// (Cuda/FusedHashGrid.cuh) from the fp16 copy of the table: value(e, j) is feature j of the
// level's entry e as stored there. The corners whose x vertex is the lower one and those whose
// is the upper one are summed apart (fmaf, in corner order) and the two sums then added: the
// kernels may give the two halves to the two lanes of a pair. The CPU emulation runs this.
template <int DIMS, class Input, class Value>
INR_HD void hashGridLevelFused(const HashGridView& g, int level, const Input& x, const Value& value, float* out) {
  const int F = g.features();
  const HashGridCell c = hashGridCell(g, level, DIMS, x);
  const HashGridCorners<DIMS> corners(c.lower, g.resolution(level), g.entries(level));
  float half[2][8];
  for (int xb = 0; xb < 2; ++xb) {
    for (int j = 0; j < F; ++j) half[xb][j] = 0.f;
    for (int corner = xb; corner < (1 << DIMS); corner += 2) {
      const float weight = hashGridCornerWeight(c, DIMS, corner);
      const std::uint32_t e = corners.entry(corner);
      for (int j = 0; j < F; ++j) half[xb][j] = fmaf(weight, value(e, j), half[xb][j]);
    }
  }
  for (int j = 0; j < F; ++j) out[j] = half[0][j] + half[1][j];
}

// hashGridLevelFused for a grid of `dims` (3 or 4) inputs.
template <class Input, class Value>
INR_HD void hashGridLevelFusedDims(const HashGridView& g, int level, int dims, const Input& x, const Value& value,
                                   float* out) {
  if (dims == 3)
    hashGridLevelFused<3>(g, level, x, value, out);
  else
    hashGridLevelFused<4>(g, level, x, value, out);
}

// Column k of hash-grid instruction f of the inputs x; grid: f's packed weights.
template <class Input>
INR_HD float hashGridElement(const MlpInstr& f, const float* grid, const Input& x, int k) {
  const HashGridColumns cols(f);
  if (cols.inputs && k >= cols.inputAt && k < cols.inputAt + cols.inputs) return x(k - cols.inputAt);
  const HashGridView g{grid};
  const int j = k - cols.featureAt;
  if (j < 0 || j >= g.levels() * g.features()) return 0.f;
  float v;
  hashGridLevel(g, j / g.features(), f.inWidth, x, j % g.features(), 1, &v);
  return v;
}

// Column k of encoding instruction f (isEncoding(f.op)); weights: the program's floatWeights.
template <ActMath M = ActMath::Exact, class Input>
INR_HD float encodingElement(const MlpInstr& f, const float* weights, const Input& x, int k) {
  switch (f.op) {
    case MlpOp::Fourier: return fourierElement<M>(f, weights + f.floatOffset, x, k);
    case MlpOp::HashGrid: return hashGridElement(f, weights + f.floatOffset, x, k);
    default: return 0.f;
  }
}

// Forward-mode derivative of column k of encoding instruction f along one direction: dx(i) is
// the derivative of input i (the per-thread network's gradient, Cuda/CudaPerThreadMlp.cuh; the
// fused kernel's tangent rows and their emulation; the CPU reference carries the same formulas
// on Eigen arrays). Exact arithmetic only.
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
    case MlpOp::HashGrid: {  // the interpolation weights' derivatives (hashGridLevel's dOut)
      const HashGridColumns cols(f);
      if (cols.inputs && k >= cols.inputAt && k < cols.inputAt + cols.inputs) return dx(k - cols.inputAt);
      const HashGridView g{weights + f.floatOffset};
      const int j = k - cols.featureAt;
      if (j < 0 || j >= g.levels() * g.features()) return 0.f;
      float v, dv[4];
      hashGridLevel(g, j / g.features(), f.inWidth, x, j % g.features(), 1, &v, dv);
      float t = 0.f;
      for (int i = 0; i < f.inWidth; ++i) t += dv[i] * dx(i);
      return t;
    }
    default: return NAN;  // an encoding without its derivative: no normal (ambient only)
  }
}

}  // namespace inr
