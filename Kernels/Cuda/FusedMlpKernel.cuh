#pragma once
// The fused INR evaluation kernel: a persistent grid of blocks of 4*WR warps; each block takes
// tiles of M = 32*WR queries and runs the whole MlpProgram on them without leaving the SM.
// Activations live in shared memory as fp16 rows (one per query, per-buffer stride). GEMM layers
// run on tensor cores with mma.sync m16n8k16 (fp16 in, fp32 accumulate), operands fetched with
// ldmatrix, weights streamed through a double-buffered shared-memory stage in K chunks of KC
// (cp.async). The accumulator layout of mma.sync is documented, so epilogues (activation,
// residual sum, and the network's final dot product) run in registers and store half2 straight
// into the destination buffer; accumulators start at the bias.
// Each warp owns 32 rows and the 16-column blocks colGroup + 4j (j < NB). NB is a template
// parameter, the same for every warp of a layer: warps whose last block lies past the layer's
// width compute it on whatever the (64-row aligned) weight stage holds and discard it, so the
// tensor-core loop has no per-warp branches (which would make every ldmatrix/mma reconverge).
// Coordinates, Fourier encodings and DenseFp32 layers stay fp32.
#include <cuda_fp16.h>
#include <cstdint>
#include <type_traits>
#include <vector>
#include <cuda_pipeline.h>

#include "Common/Activation.h"
#include "Cuda/MlpProgram.h"

namespace inr::cuda {

constexpr int kMaxBuffers = MlpProgram::kMaxFusedBuffers;
constexpr int kMaxFusedInstrs = 64;
constexpr int kStageRowAlign = 64;  // weight stage rows: GEMM outputs rounded up to 4 warps x 16

struct OutputMap {
  // value = a(t) * net + b(t); a, b piecewise linear over `count` (t, a, b) entries (clamped),
  // or constant when count == 0.
  float a = 1.f, b = 0.f;
  int count = 0;
  const float* table = nullptr;  // count * 3 floats: t, a, b
};

struct FusedParams {
  const MlpInstr* instrs = nullptr;
  int numInstrs = 0;
  // fp16 GEMM weights in the stage's layout (packStagedWeights), per weight chunk width
  // (index kcIndex(KC)), and each instruction's offset into them (halves).
  const __half* stagedWeights[2] = {nullptr, nullptr};
  int stagedOffset[2][kMaxFusedInstrs] = {};
  const float* floatWeights = nullptr;
  int inputDim = 4;
  int inputCoord[4] = {0, 1, 2, 3};  // world coordinate feeding each network input
  float inScale[4] = {1, 1, 1, 1}, inOffset[4] = {0, 0, 0, 0};
  int numBuffers = 1;
  int bufferLd[kMaxBuffers] = {};  // halves per row (width + 8)
  int maxGemmOutPad = 16;          // rows of the weight stage
  // The program has a Fourier encoding fused into a GEMM: the mma.sync kernel computes it chunk
  // by chunk into a stage of M x (KC + 8) halves.
  int fusedFourier = 0;
  // The Hopper kernel (FusedMlpKernelHopper.cuh): its program (MlpProgram::withGemmsInPlace, the
  // same instructions over fewer buffers) and buffers, its weights (packHopperWeights) with each
  // instruction's offset (per chunk width), each GEMM's bias offset in shared memory
  // (hopperBiasLayout) and their total, the size and number of ring slots, and whether the
  // consumers take turns.
  const MlpInstr* hopperInstrs = nullptr;
  int hopperNumBuffers = 1;
  int hopperBufferLd[kMaxBuffers] = {};
  const __half* hopperWeights[2] = {nullptr, nullptr};  // per chunk width (chunkIndex)
  int hopperOffset[2][kMaxFusedInstrs] = {};
  int hopperBiasStart[kMaxFusedInstrs] = {};
  int hopperBiasFloats = 0;
  int hopperStageHalves[2] = {1024, 2048};
  int hopperStages = 2;
  int hopperPingPong = 1;
  OutputMap output;
};

__host__ __device__ constexpr int kcIndex(int kc) { return kc == 64 ? 0 : 1; }

// The GEMM weights ([nPad][kPad] fp16 in MlpProgram::halfWeights) repacked chunk by chunk exactly
// as the kernel's stage holds them: per K-chunk of KC, nPad rows of KC + 8 halves (zeros past
// kPad and in the 8 padding columns). Staging a chunk is then one contiguous copy.
inline std::vector<std::uint16_t> packStagedWeights(const MlpProgram& prog, int KC, int* offsets) {
  std::vector<std::uint16_t> packed;
  for (std::size_t i = 0; i < prog.instrs.size() && i < std::size_t(kMaxFusedInstrs); ++i) {
    const MlpInstr& in = prog.instrs[i];
    offsets[i] = 0;
    if (in.op != MlpOp::Gemm || in.fusedIntoPrevious) continue;
    offsets[i] = int(packed.size());
    const int chunks = (in.kPad + KC - 1) / KC;
    for (int c = 0; c < chunks; ++c)
      for (int r = 0; r < in.nPad; ++r)
        for (int k = 0; k < KC + 8; ++k) {
          const int col = c * KC + k;
          packed.push_back(k < KC && col < in.kPad ? prog.halfWeights[in.halfOffset + std::int64_t(r) * in.kPad + col] : 0);
        }
  }
  return packed;
}

__host__ __device__ inline int stageRows(const FusedParams& P) {
  return (P.maxGemmOutPad + kStageRowAlign - 1) / kStageRowAlign * kStageRowAlign;
}

// Shared memory for a tile of M queries and weight chunks of KC: activation buffers, the
// weight double buffer, a fused Fourier encoding's chunk, coordinates (M x 4 floats), the final
// dot's partial sums (4 x M) and weights.
__host__ __device__ inline int encodingStageHalves(int M, int KC, const FusedParams& P) {
  return P.fusedFourier ? M * (KC + 8) : 0;
}

inline std::size_t fusedSharedBytes(int M, int KC, const FusedParams& P) {
  std::size_t halves = 0;
  for (int b = 0; b < P.numBuffers; ++b) halves += std::size_t(M) * P.bufferLd[b];
  halves += std::size_t(2) * stageRows(P) * (KC + 8) + encodingStageHalves(M, KC, P);
  return halves * 2 + (std::size_t(M) * 8 + MlpProgram::kMaxFusedGemmOut) * 4;
}

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

// The network inputs of a query at world point p (x, y, z, t): the model's input order and
// domain mapping, zero past inputDim.
__device__ inline void networkInputs(const FusedParams& P, float4 p, float* x) {
  const float w[4] = {p.x, p.y, p.z, p.w};
#pragma unroll
  for (int i = 0; i < 4; ++i) x[i] = i < P.inputDim ? P.inScale[i] * w[P.inputCoord[i]] + P.inOffset[i] : 0.f;
}

// Coordinates of a tile's M rows (network inputs, 4 floats per row; zero rows past `rows`),
// THREADS threads, tid this thread's index among them; the caller synchronises.
template <int M, int THREADS>
__device__ inline void loadTileCoords(const FusedParams& P, const float4* __restrict__ points, int base, int rows,
                                      float* coords, int tid) {
  for (int r = tid; r < M; r += THREADS)
    networkInputs(P, r < rows ? points[base + r] : make_float4(0.f, 0.f, 0.f, 0.f), coords + r * 4);
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

// Starts the asynchronous copy of K-chunk `chunk` of GEMM instruction `ip`'s weights into stage
// buffer (chunk & 1): one contiguous block (packStagedWeights), 16-byte cp.async per thread, one
// commit group.
template <int THREADS, int KC>
__device__ inline void stageWeightChunk(const FusedParams& P, int ip, int nPad, __half* wstage, int stageHalves,
                                        int chunk, int tid) {
  const int blockHalves = nPad * (KC + 8);
  const int4* src = reinterpret_cast<const int4*>(P.stagedWeights[kcIndex(KC)] + P.stagedOffset[kcIndex(KC)][ip] +
                                                  std::size_t(chunk) * blockHalves);
  int4* dst = reinterpret_cast<int4*>(wstage + (chunk & 1) * stageHalves);
  const int segs = blockHalves / 8;
  for (int i = tid; i < segs; i += THREADS) __pipeline_memcpy_async(dst + i, src + i, 16);
  __pipeline_commit();
}

// Compile-time tags for the generic lambdas below (warp column blocks, first k step, residual).
template <int N>
using IntTag = std::integral_constant<int, N>;
template <bool B>
using BoolTag = std::bool_constant<B>;

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

// LoadInput, DenseFp32, Fourier, Activation, Combine, OutputDot and Output on M rows with THREADS
// threads (tid: this thread's index among them); the caller synchronises afterwards.
template <int M, int THREADS>
__device__ inline void runRowInstr(const FusedParams& P, const MlpInstr& in, const RowTile& t, int tid,
                                   const float4* __restrict__ points, float* __restrict__ out,
                                   const int* __restrict__ scatter) {
  constexpr int WARPS = THREADS / 32;
  const int warp = tid >> 5, lane = tid & 31;
  const int rows = t.rows, base = t.base;
  const float* const coords = t.coords;
  const int ldDst = in.dst >= 0 ? t.bufferLd[in.dst] : 0;
  const int ldSrc = in.src >= 0 ? t.bufferLd[in.src] : 0;
  __half* dst = in.dst >= 0 ? t.act + t.bufferStart[in.dst] : nullptr;
  const __half* src = in.src >= 0 ? t.act + t.bufferStart[in.src] : nullptr;
  const __half* other = in.other >= 0 ? t.act + t.bufferStart[in.other] : nullptr;
  const int ldOther = in.other >= 0 ? t.bufferLd[in.other] : 0;
  auto input = [&](int r, int k) -> float { return in.src < 0 ? coords[r * 4 + k] : __half2float(src[r * ldSrc + k]); };
  switch (in.op) {
    case MlpOp::LoadInput:
      if (in.splitPrecision) {  // columns hi | lo | hi | 0, one thread per (row, coordinate)
        for (int idx = tid; idx < M * 4; idx += THREADS) {
          const int r = idx >> 2, c = idx & 3;
          const float x = c < P.inputDim ? coords[r * 4 + c] : 0.f;
          const __half hi = __float2half(x);
          __half* d = dst + r * ldDst + c;
          d[0] = hi;
          d[4] = __float2half(x - __half2float(hi));
          d[8] = hi;
          d[12] = __float2half(0.f);
        }
      } else {
        for (int r = warp; r < M; r += WARPS)
          for (int c = lane; c < in.nPad; c += 32) dst[r * ldDst + c] = __float2half(c < P.inputDim ? coords[r * 4 + c] : 0.f);
      }
      break;
    case MlpOp::DenseFp32:
    case MlpOp::Fourier: {
      // One thread per output column (its weights in registers), looping over the rows.
      const bool fourier = in.op == MlpOp::Fourier;
      const int inc = fourier && in.includeInput ? in.inWidth : 0;
      const int m = fourier ? (in.outWidth - inc) / 2 : in.outWidth;  // computed columns
      const int sinBase = fourier && in.includeInput == 1 ? in.inWidth : 0;
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
            dst[r * ldDst + sinBase + o] = __float2half(sn);
            dst[r * ldDst + sinBase + m + o] = __float2half(cs);
          }
        } else {
          dispatchActivation(in.act, [&](auto A) {
            for (int r = rStart; r < M; r += rowsPerPass) {
              float v = applyActivation(decltype(A)::value, dot(r));
              if (other) v = in.combineScale * (v + __half2float(other[r * ldOther + o]));
              dst[r * ldDst + o] = __float2half(v);
            }
          });
        }
      }
      // Included inputs and zero padding: only those columns.
      const int at = fourier && in.includeInput == 1 ? 0 : 2 * m;
      for (int r = warp; r < M; r += WARPS) {
        for (int c = lane; c < inc; c += 32) dst[r * ldDst + at + c] = __float2half(input(r, c));
        for (int c = in.outWidth + lane; c < in.nPad; c += 32) dst[r * ldDst + c] = __float2half(0.f);
      }
      break;
    }
    case MlpOp::Activation:
      for (int r = warp; r < M; r += WARPS)
        for (int c = lane; c < in.outWidth; c += 32)
          dst[r * ldDst + c] = __float2half(applyActivation(in.act, in.actScale * __half2float(dst[r * ldDst + c])));
      break;
    case MlpOp::Combine: {
      for (int r = warp; r < M; r += WARPS)
        for (int c = lane; c < in.nPad; c += 32) {
          const float v = __half2float(src[r * ldSrc + c]) + (other ? __half2float(other[r * ldOther + c]) : 0.f);
          dst[r * ldDst + c] = __float2half(in.combineScale * v);
        }
      break;
    }
    case MlpOp::OutputDot:
    case MlpOp::Output: {
      const float* W = in.op == MlpOp::OutputDot ? P.floatWeights + in.floatOffset : nullptr;
      for (int r = warp; r < rows; r += WARPS) {
        float acc = 0.f;
        if (W) {
          for (int k = lane; k < in.inWidth; k += 32) acc = fmaf(__ldg(W + k), input(r, k), acc);
#pragma unroll
          for (int off = 16; off > 0; off >>= 1) acc += __shfl_xor_sync(0xffffffffu, acc, off);
        }
        if (lane == 0) {
          const float net = W ? applyActivation(in.act, acc + P.floatWeights[in.biasOffset]) : input(r, 0);
          writeOutput(P.output, points[base + r].w, net, base + r, out, scatter);
        }
      }
      break;
    }
    default: break;  // Gemm: the kernels' own code
  }
}

// Column k of Fourier instruction f's encoding of the coordinates x (4 floats), before fp16
// rounding: what runRowInstr stores there (the same fp32 arithmetic, so fusing the encoding into
// a GEMM's operand changes no bit): sin / cos of the projection, the inputs first or last, zero
// past the encoding's width.
__device__ inline float fourierElement(const FusedParams& P, const MlpInstr& f, const float* x, int k) {
  const int inc = f.includeInput ? f.inWidth : 0;
  const int m = (f.outWidth - inc) / 2;
  if (inc) {
    const int at = f.includeInput == 1 ? 0 : 2 * m;
    if (k >= at && k < at + inc) return x[k - at];
  }
  const int j = k - (f.includeInput == 1 ? f.inWidth : 0);
  if (j < 0 || j >= 2 * m) return 0.f;
  const float* w = P.floatWeights + f.floatOffset + (j < m ? j : j - m) * f.inWidth;
  const float w0 = __ldg(w), w1 = f.inWidth > 1 ? __ldg(w + 1) : 0.f, w2 = f.inWidth > 2 ? __ldg(w + 2) : 0.f,
              w3 = f.inWidth > 3 ? __ldg(w + 3) : 0.f;
  const float d = fmaf(w0, x[0], fmaf(w1, x[1], fmaf(w2, x[2], fmaf(w3, x[3], 0.f))));
  return j < m ? __sinf(d) : __cosf(d);
}

// At most 128 registers per thread for every tile size (min. 512 threads per SM): smaller tiles
// exist so that two or four blocks share an SM and one's epilogue overlaps another's GEMM.
template <int WR, int KC>
__global__ void __launch_bounds__(WR * 128, 4 / WR) fusedMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                                  const unsigned* __restrict__ deviceCount,
                                                                  float* __restrict__ out, const int* __restrict__ scatter) {
  // deviceCount: the batch size as written by an earlier kernel (n is then its upper bound), so
  // a producer-consumer loop needs no host round trip per batch.
  if (deviceCount) n = min(n, int(*deviceCount));
  constexpr int M = 32 * WR;  // queries per tile
  constexpr int THREADS = WR * 128;
  constexpr int kStride = KC + 8;  // halves per staged weight row
  extern __shared__ __align__(128) unsigned char smem[];
  // The program and the buffer layout are read from shared memory (uniform, indexable without
  // local-memory spills), loaded once per block.
  __shared__ MlpInstr program[kMaxFusedInstrs];
  __shared__ int bufferStart[kMaxBuffers], bufferLd[kMaxBuffers];
  __half* const actBase = reinterpret_cast<__half*>(smem);
  for (int i = threadIdx.x; i < P.numInstrs; i += THREADS) program[i] = P.instrs[i];
  if (threadIdx.x == 0) {
    int at = 0;
    for (int b = 0; b < kMaxBuffers; ++b) {
      bufferStart[b] = at;
      bufferLd[b] = P.bufferLd[b];
      if (b < P.numBuffers) at += M * P.bufferLd[b];
    }
  }
  int actHalves = 0;
  for (int b = 0; b < P.numBuffers; ++b) actHalves += M * P.bufferLd[b];
  const int stageHalves = stageRows(P) * kStride;
  __half* const wstage = actBase + actHalves;
  __half* const encStage = wstage + 2 * stageHalves;  // a fused Fourier encoding's chunk, if any
  float* const coords = reinterpret_cast<float*>(encStage + encodingStageHalves(M, KC, P));
  float* const dotPart = coords + M * 4;  // [colGroup][row] partial sums of the final dot
  float* const dotWeights = dotPart + M * 4;  // the final dot's weights (zero-padded), if any
  for (int ip = 0; ip < P.numInstrs; ++ip)
    if (P.instrs[ip].dotNext)
      for (int c = threadIdx.x; c < P.instrs[ip].nPad; c += THREADS)
        dotWeights[c] = P.floatWeights[P.instrs[ip].dotOffset + c];
  __syncthreads();

  const int tid = threadIdx.x;
  const int warp = tid >> 5, lane = tid & 31;
  const int g = lane >> 2, t4 = lane & 3;  // mma fragment coordinates
  const int rowGroup = warp >> 2, colGroup = warp & 3;

  const int numTiles = (n + M - 1) / M;
  bool firstChunkStaged = false;  // the coming GEMM's chunk 0 is already in flight
  for (int tile = blockIdx.x; tile < numTiles; tile += gridDim.x) {
    const int base = tile * M;
    const int rows = min(M, n - base);
    loadTileCoords<M, THREADS>(P, points, base, rows, coords, tid);
    __syncthreads();

    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr in = program[ip];  // a copy: fields stay in registers inside the loops
      // Done by a neighbouring GEMM (the final dot in its epilogue, an encoding in its operand).
      if (in.fusedIntoPrevious || in.fusedIntoNext) continue;  // uniform
      if (in.op != MlpOp::Gemm) {
        runRowInstr<M, THREADS>(P, in, RowTile{actBase, bufferStart, bufferLd, coords, rows, base}, tid, points, out, scatter);
        __syncthreads();
        continue;
      }
      const int ldDst = in.dst >= 0 ? bufferLd[in.dst] : 0;
      __half* dst = in.dst >= 0 ? actBase + bufferStart[in.dst] : nullptr;
      const __half* other = in.other >= 0 ? actBase + bufferStart[in.other] : nullptr;
      const int ldOther = in.other >= 0 ? bufferLd[in.other] : 0;
      // A fused Fourier encoding is computed chunk by chunk into encStage (below), read like a
      // buffer whose column 0 is the chunk's first.
      const bool encoded = in.fourierInput >= 0;
      const int ldSrc = encoded ? KC + 8 : bufferLd[in.src];
      const __half* src = encoded ? encStage : actBase + bufferStart[in.src];
      {
          const int c16Count = in.nPad / 16;
          const int numChunks = (in.kPad + KC - 1) / KC;
          const float* bias = P.floatWeights + in.biasOffset;
          const int rowBase = rowGroup * 32;
          const bool prefetchNext = in.nextGemm >= 0 && (in.nextGemm > ip || tile + int(gridDim.x) < numTiles);
          auto gemm = [&](auto nbTag) __attribute__((always_inline)) {
            constexpr int NB = decltype(nbTag)::value;
            // Accumulators [m16 tile][16-column block][n8 half][fragment]: the first k step
            // writes them as A*B + bias (mma's C operand), so they need no initialisation.
            float acc[2][NB][2][4];
            float2 biasPair[NB][2];
#pragma unroll
            for (int j = 0; j < NB; ++j)
#pragma unroll
              for (int h = 0; h < 2; ++h) {
                const int col = (colGroup + 4 * j) * 16 + h * 8 + 2 * t4;
                biasPair[j][h] = colGroup + 4 * j < c16Count ? *reinterpret_cast<const float2*>(bias + col)
                                                             : make_float2(0.f, 0.f);
              }
            // Per-lane shared-memory byte addresses for ldmatrix, computed once per layer; the k
            // steps inside a chunk only add immediates.
            unsigned aAddr[2];
#pragma unroll
            for (int mt = 0; mt < 2; ++mt) {
              const int r = rowBase + mt * 16 + ((lane >> 3) & 1) * 8 + (lane & 7);
              aAddr[mt] = smemAddress(src + r * ldSrc + (lane >> 4) * 8);
            }
            const unsigned bBase =
                smemAddress(wstage + (colGroup * 16 + (lane >> 4) * 8 + (lane & 7)) * kStride + ((lane >> 3) & 1) * 8);
            auto kStep = [&](unsigned aOff, unsigned bOff, auto firstTag) {
              constexpr bool kFirst = decltype(firstTag)::value;
              unsigned a[2][4];
#pragma unroll
              for (int mt = 0; mt < 2; ++mt) ldmatrixX4(a[mt], aAddr[mt] + aOff);
#pragma unroll
              for (int j = 0; j < NB; ++j) {
                unsigned b[4];  // b[0], b[1]: n8 tile 0 (k lo, k hi); b[2], b[3]: n8 tile 1
                ldmatrixX4(b, bBase + bOff + unsigned(j * 64 * kStride * 2));
#pragma unroll
                for (int mt = 0; mt < 2; ++mt) {
                  if constexpr (kFirst) {
                    mma16816Bias(acc[mt][j][0], a[mt], b[0], b[1], biasPair[j][0]);
                    mma16816Bias(acc[mt][j][1], a[mt], b[2], b[3], biasPair[j][1]);
                  } else {
                    mma16816(acc[mt][j][0], a[mt], b[0], b[1]);
                    mma16816(acc[mt][j][1], a[mt], b[2], b[3]);
                  }
                }
              }
            };
            auto stage = [&](int gemm, int chunk) {
              stageWeightChunk<THREADS, KC>(P, gemm, program[gemm].nPad, wstage, stageHalves, chunk, tid);
            };
            if (!firstChunkStaged) stage(ip, 0);  // else prefetched by the previous GEMM
            firstChunkStaged = false;
            auto runChunk = [&](int chunk, auto firstTag) {
              if (chunk + 1 < numChunks) {
                stage(ip, chunk + 1);
                __pipeline_wait_prior(1);
              } else {
                __pipeline_wait_prior(0);
              }
              if (encoded) {  // this chunk's columns of the encoding, two per thread and step
                const MlpInstr& f = program[in.fourierInput];
                for (int idx = tid; idx < M * (KC / 2); idx += THREADS) {
                  const int r = idx / (KC / 2), k = 2 * (idx % (KC / 2)), col = chunk * KC + k;
                  const float* x = coords + r * 4;
                  *reinterpret_cast<__half2*>(encStage + r * (KC + 8) + k) =
                      __floats2half2_rn(fourierElement(P, f, x, col), fourierElement(P, f, x, col + 1));
                }
              }
              __syncthreads();
              const unsigned aChunk = encoded ? 0u : unsigned(chunk * KC * 2), bChunk = unsigned((chunk & 1) * stageHalves * 2);
              const int kLen = min(KC, in.kPad - chunk * KC);
              kStep(aChunk, bChunk, firstTag);  // every chunk holds at least one k step of 16
              if (kLen == KC) {
#pragma unroll
                for (int kk = 16; kk < KC; kk += 16) kStep(aChunk + kk * 2, bChunk + kk * 2, BoolTag<false>{});
              } else {
                for (int kk = 16; kk < kLen; kk += 16) kStep(aChunk + kk * 2, bChunk + kk * 2, BoolTag<false>{});
              }
              __syncthreads();  // the next stage() overwrites this buffer
            };
            runChunk(0, BoolTag<true>{});
            for (int chunk = 1; chunk < numChunks; ++chunk) runChunk(chunk, BoolTag<false>{});
            // Both stage buffers are free now: start fetching the next GEMM's first chunk (the
            // next tile's first GEMM after the last one) while the epilogue and the cheap ops run.
            if (prefetchNext) {
              stage(in.nextGemm, 0);
              firstChunkStaged = true;
            }
            // Epilogue in registers: fragment element (row g / g+8, columns 2*t4, 2*t4+1).
            if (in.finalOutput) {  // column 0 is the network output: fp32, straight to `out`
              if (colGroup == 0 && t4 == 0) {
#pragma unroll
                for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                  for (int half = 0; half < 2; ++half) {
                    const int row = rowBase + mt * 16 + g + half * 8;
                    if (row < rows) {
                      const float net = applyActivation(in.act, acc[mt][0][0][2 * half]);
                      writeOutput(P.output, points[base + row].w, net, base + row, out, scatter);
                    }
                  }
              }
              return;
            }
            const int laneCol = colGroup * 16 + 2 * t4;
            dispatchActivation(in.act, [&](auto A) {
              constexpr MlpAct kAct = decltype(A)::value;
              // act(acc) [+ residual], fp32; sigmoid(0) != 0, so its padding columns are masked.
              auto value = [&](int mt, int j, int h, int f, int col) {
                float v = applyActivation(kAct, acc[mt][j][h][f]);
                if (kAct == MlpAct::Sigmoid && col >= in.outWidth) v = 0.f;
                return v;
              };
              // Calls f(mt, half, j, h, col, v0, v1) per owned fragment pair: the finished fp32
              // values of row (mt, half) at columns col, col + 1. The residual
              // sum is a template branch: a runtime one inside the unrolled loops is if-converted
              // into predicated loads and arithmetic that every layer pays for.
              const __half* const oRow = other ? other + (rowBase + g) * ldOther + laneCol : nullptr;
              auto forEachPair = [&](auto f) {
                auto loop = [&](auto residual) {
                  constexpr bool kResidual = decltype(residual)::value;
#pragma unroll
                  for (int j = 0; j < NB; ++j) {
                    if (colGroup + 4 * j >= c16Count) continue;
#pragma unroll
                    for (int h = 0; h < 2; ++h) {
                      const int col = laneCol + j * 64 + h * 8;
#pragma unroll
                      for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                        for (int half = 0; half < 2; ++half) {
                          float v0 = value(mt, j, h, 2 * half, col), v1 = value(mt, j, h, 2 * half + 1, col + 1);
                          if (kResidual && oRow) {
                            const float2 o = ldsHalf2AsFloat2InPlace(oRow + (mt * 16 + half * 8) * ldOther + j * 64 + h * 8);
                            v0 = in.combineScale * (v0 + o.x);
                            v1 = in.combineScale * (v1 + o.y);
                          }
                          f(mt, half, j, h, col, v0, v1);
                        }
                    }
                  }
                };
                if (oRow)
                  loop(BoolTag<true>{});
                else
                  loop(BoolTag<false>{});
              };
              if (in.dotNext) {
                // The network's final linear (next instruction): dot of the fp32 activations with
                // its weights, reduced over the quad's lanes, then over the 4 column warps.
                const MlpInstr& fin = program[ip + 1];
                float part[2][2] = {{0.f, 0.f}, {0.f, 0.f}};
                forEachPair([&](int mt, int half, int, int, int col, float v0, float v1) {
                  const float2 w = ldsFloat2InPlace(dotWeights + col);
                  part[mt][half] = fmaf(v0, w.x, fmaf(v1, w.y, part[mt][half]));
                });
#pragma unroll
                for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                  for (int half = 0; half < 2; ++half) {
                    float v = part[mt][half];
                    v += __shfl_xor_sync(0xffffffffu, v, 1);
                    v += __shfl_xor_sync(0xffffffffu, v, 2);
                    if (t4 == 0) dotPart[colGroup * M + rowBase + mt * 16 + g + half * 8] = v;
                  }
                __syncthreads();
                const float dotBias = P.floatWeights[fin.biasOffset];
                for (int r = tid; r < rows; r += THREADS) {
                  const float net =
                      applyActivation(fin.act, dotPart[r] + dotPart[M + r] + dotPart[2 * M + r] + dotPart[3 * M + r] + dotBias);
                  writeOutput(P.output, points[base + r].w, net, base + r, out, scatter);
                }
                return;
              }
              __half* const dRow = dst + (rowBase + g) * ldDst + laneCol;
              forEachPair([&](int mt, int half, int j, int h, int, float v0, float v1) {
                *reinterpret_cast<__half2*>(dRow + (mt * 16 + half * 8) * ldDst + j * 64 + h * 8) = __floats2half2_rn(v0, v1);
              });
            });
          };
          switch ((c16Count + 3) / 4) {  // the same for every warp of the block
            case 1: gemm(IntTag<1>{}); break;
            case 2: gemm(IntTag<2>{}); break;
            case 3: gemm(IntTag<3>{}); break;
            default: gemm(IntTag<4>{}); break;
          }
      }
      __syncthreads();
    }
  }
}

using FusedKernel = void (*)(FusedParams, const float4*, int, const unsigned*, float*, const int*);
// The Hopper kernel (FusedMlpKernelHopper.cuh) for weight chunks of 64 or 128 output columns
// (128 queries per round; FusedMlpKernelHopper.cu, built for sm_90a when the CUDA architectures
// include 90); nullptr when not built.
FusedKernel hopperKernel(int chunkColumns);

}  // namespace inr::cuda
