#pragma once
// The fused INR evaluation kernel: a persistent grid of blocks of 4*WR warps; each block takes
// tiles of M = 32*WR queries and runs the whole MlpProgram on them without leaving the SM.
// Activations live in shared memory as fp16 rows (one per query, per-buffer stride). GEMM layers
// run on tensor cores with mma.sync m16n8k16 (fp16 in, fp32 accumulate), operands fetched with
// ldmatrix, weights streamed through a double-buffered shared-memory stage in K chunks of 64
// (cp.async). The accumulator layout of mma.sync is documented, so epilogues (bias, activation,
// residual sum) run in registers and store half2 straight into the destination buffer.
// Coordinates, Fourier encodings, the first linear layer and the final dot product stay fp32.
#include <cuda_fp16.h>
#include <cuda_pipeline.h>

#include "Cuda/MlpProgram.h"

namespace inr::cuda {

constexpr int kWeightChunk = 64;                 // K columns of weights staged per step
constexpr int kWeightStride = kWeightChunk + 8;  // halves per staged row; +8 keeps ldmatrix conflict-free
constexpr int kMaxBuffers = MlpProgram::kMaxFusedBuffers;
constexpr int kMaxFusedInstrs = 64;

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
  const __half* halfWeights = nullptr;
  const float* floatWeights = nullptr;
  int inputDim = 4;
  int inputCoord[4] = {0, 1, 2, 3};  // world coordinate feeding each network input
  float inScale[4] = {1, 1, 1, 1}, inOffset[4] = {0, 0, 0, 0};
  int numBuffers = 1;
  int bufferLd[kMaxBuffers] = {};  // halves per row (width + 8)
  int maxGemmOutPad = 16;          // rows of the weight stage
  OutputMap output;
};

// Shared memory for a tile of M queries: activation buffers, weight double buffer, coordinates.
inline std::size_t fusedSharedBytes(int M, const FusedParams& P) {
  std::size_t halves = 0;
  for (int b = 0; b < P.numBuffers; ++b) halves += std::size_t(M) * P.bufferLd[b];
  halves += std::size_t(2) * P.maxGemmOutPad * kWeightStride;
  return halves * 2 + std::size_t(M) * 4 * 4;
}

__device__ inline float applyActivation(MlpAct a, float v) {
  switch (a) {
    case MlpAct::None: return v;
    case MlpAct::Sine: return __sinf(v);
    case MlpAct::SiLU: return v / (1.f + __expf(-v));
    case MlpAct::ReLU: return fmaxf(v, 0.f);
    case MlpAct::Sigmoid: return 1.f / (1.f + __expf(-v));
    case MlpAct::Tanh: return tanhf(v);
  }
  return v;
}

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

__device__ inline unsigned smemAddress(const void* p) { return unsigned(__cvta_generic_to_shared(p)); }

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

// Starts the asynchronous copy of K-chunk `chunk` of a GEMM's fp16 weights ([nPad][kPad] rows)
// into stage buffer (chunk & 1): 16-byte cp.async per thread, one commit group.
template <int THREADS>
__device__ inline void stageWeightChunk(const FusedParams& P, const MlpInstr& in, __half* wstage, int chunk, int tid) {
  const int k0 = chunk * kWeightChunk;
  __half* dstW = wstage + (chunk & 1) * P.maxGemmOutPad * kWeightStride;
  const __half* srcW = P.halfWeights + in.halfOffset + k0;
  if (in.kPad - k0 >= kWeightChunk) {  // full chunk: 8 segments per row, no division
    for (int idx = tid; idx < in.nPad * 8; idx += THREADS) {
      const int row = idx >> 3, seg = idx & 7;
      __pipeline_memcpy_async(dstW + row * kWeightStride + seg * 8, srcW + row * in.kPad + seg * 8, 16);
    }
  } else {
    const int segs = (in.kPad - k0) / 8;
    for (int idx = tid; idx < in.nPad * segs; idx += THREADS) {
      const int row = idx / segs, seg = idx - row * segs;
      __pipeline_memcpy_async(dstW + row * kWeightStride + seg * 8, srcW + row * in.kPad + seg * 8, 16);
    }
  }
  __pipeline_commit();
}

template <int WR>
__global__ void __launch_bounds__(WR * 128) fusedMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                          float* __restrict__ out, const int* __restrict__ scatter) {
  constexpr int M = 32 * WR;  // queries per tile
  constexpr int THREADS = WR * 128;
  constexpr int WARPS = THREADS / 32;
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
  __half* const wstage = actBase + actHalves;
  float* const coords = reinterpret_cast<float*>(wstage + 2 * P.maxGemmOutPad * kWeightStride);
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
    for (int r = tid; r < M; r += THREADS) {
      const float4 p = r < rows ? points[base + r] : make_float4(0.f, 0.f, 0.f, 0.f);
      const float w[4] = {p.x, p.y, p.z, p.w};
#pragma unroll
      for (int i = 0; i < 4; ++i)
        coords[r * 4 + i] = i < P.inputDim ? P.inScale[i] * w[P.inputCoord[i]] + P.inOffset[i] : 0.f;
    }
    __syncthreads();

    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr in = program[ip];  // a copy: fields stay in registers inside the loops
      const int ldDst = in.dst >= 0 ? bufferLd[in.dst] : 0;
      const int ldSrc = in.src >= 0 ? bufferLd[in.src] : 0;
      __half* dst = in.dst >= 0 ? actBase + bufferStart[in.dst] : nullptr;
      const __half* src = in.src >= 0 ? actBase + bufferStart[in.src] : nullptr;
      const __half* other = in.other >= 0 ? actBase + bufferStart[in.other] : nullptr;
      const int ldOther = in.other >= 0 ? bufferLd[in.other] : 0;
      auto input = [&](int r, int k) -> float {
        return in.src < 0 ? coords[r * 4 + k] : __half2float(src[r * ldSrc + k]);
      };
      switch (in.op) {
        case MlpOp::LoadInput:
          for (int r = warp; r < M; r += WARPS)
            for (int c = lane; c < in.nPad; c += 32) {
              float v = 0.f;
              if (!in.splitPrecision) {
                v = c < P.inputDim ? coords[r * 4 + c] : 0.f;
              } else if (c < 12 && (c & 3) < P.inputDim) {  // hi | lo | hi
                const float x = coords[r * 4 + (c & 3)];
                const float hi = __half2float(__float2half(x));
                v = (c >> 2) == 1 ? x - hi : x;
              }
              dst[r * ldDst + c] = __float2half(v);
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
        case MlpOp::Gemm: {
          const int c16Count = in.nPad / 16;
          const int numChunks = (in.kPad + kWeightChunk - 1) / kWeightChunk;
          float acc[2][4][2][4];  // [m16 tile][16-column block][n8 half][fragment]
#pragma unroll
          for (int a = 0; a < 2; ++a)
#pragma unroll
            for (int j = 0; j < 4; ++j)
#pragma unroll
              for (int h = 0; h < 2; ++h)
#pragma unroll
                for (int f = 0; f < 4; ++f) acc[a][j][h][f] = 0.f;

          auto stage = [&](int chunk) { stageWeightChunk<THREADS>(P, in, wstage, chunk, tid); };
          const int rowBase = rowGroup * 32;
          // Per-lane shared-memory byte addresses for ldmatrix, computed once per layer; the k
          // steps inside a chunk only add immediates.
          unsigned aAddr[2];
#pragma unroll
          for (int mt = 0; mt < 2; ++mt) {
            const int r = rowBase + mt * 16 + ((lane >> 3) & 1) * 8 + (lane & 7);
            aAddr[mt] = smemAddress(src + r * ldSrc + (lane >> 4) * 8);
          }
          unsigned bAddr[4];
#pragma unroll
          for (int j = 0; j < 4; ++j) {
            const int nrow = (colGroup + 4 * j) * 16 + (lane >> 4) * 8 + (lane & 7);
            bAddr[j] = smemAddress(wstage + nrow * kWeightStride + ((lane >> 3) & 1) * 8);
          }
          const unsigned stageBytes = unsigned(P.maxGemmOutPad * kWeightStride * 2);
          auto kStep = [&](unsigned aOff, unsigned bOff) {
            unsigned a[2][4];
#pragma unroll
            for (int mt = 0; mt < 2; ++mt) ldmatrixX4(a[mt], aAddr[mt] + aOff);
#pragma unroll
            for (int j = 0; j < 4; ++j) {
              if (colGroup + 4 * j < c16Count) {
                unsigned b[4];  // b[0], b[1]: n8 tile 0 (k lo, k hi); b[2], b[3]: n8 tile 1
                ldmatrixX4(b, bAddr[j] + bOff);
#pragma unroll
                for (int mt = 0; mt < 2; ++mt) {
                  mma16816(acc[mt][j][0], a[mt], b[0], b[1]);
                  mma16816(acc[mt][j][1], a[mt], b[2], b[3]);
                }
              }
            }
          };
          if (!firstChunkStaged) stage(0);  // else prefetched by the previous GEMM
          firstChunkStaged = false;
          for (int chunk = 0; chunk < numChunks; ++chunk) {
            if (chunk + 1 < numChunks) {
              stage(chunk + 1);
              __pipeline_wait_prior(1);
            } else {
              __pipeline_wait_prior(0);
            }
            __syncthreads();
            const unsigned aChunk = unsigned(chunk * kWeightChunk * 2), bChunk = (chunk & 1) * stageBytes;
            const int kLen = min(kWeightChunk, in.kPad - chunk * kWeightChunk);
            if (kLen == kWeightChunk) {
#pragma unroll
              for (int kk = 0; kk < kWeightChunk; kk += 16) kStep(aChunk + kk * 2, bChunk + kk * 2);
            } else {
              for (int kk = 0; kk < kLen; kk += 16) kStep(aChunk + kk * 2, bChunk + kk * 2);
            }
            __syncthreads();  // the next stage() overwrites this buffer
          }
          // Both stage buffers are free now: start fetching the next GEMM's first chunk (the
          // next tile's first GEMM after the last one) while the epilogue and the cheap ops run.
          if (in.nextGemm >= 0 && (in.nextGemm > ip || tile + int(gridDim.x) < numTiles)) {
            stageWeightChunk<THREADS>(P, program[in.nextGemm], wstage, 0, tid);
            firstChunkStaged = true;
          }
          // Epilogue in registers: fragment element (row g / g+8, columns 2*t4, 2*t4+1).
          const float* bias = P.floatWeights + in.biasOffset;
          if (in.finalOutput) {  // column 0 is the network output: fp32, straight to `out`
            if (colGroup == 0 && t4 == 0) {
#pragma unroll
              for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                for (int half = 0; half < 2; ++half) {
                  const int row = rowBase + mt * 16 + g + half * 8;
                  if (row < rows) {
                    const float net = applyActivation(in.act, acc[mt][0][0][2 * half] + bias[0]);
                    float a, b;
                    outputAffine(P.output, points[base + row].w, a, b);
                    const int q = base + row;
                    out[scatter ? scatter[q] : q] = a * net + b;
                  }
                }
            }
            break;
          }
          dispatchActivation(in.act, [&](auto A) {
#pragma unroll
            for (int j = 0; j < 4; ++j) {
              const int c16 = colGroup + 4 * j;
              if (c16 >= c16Count) continue;
#pragma unroll
              for (int h = 0; h < 2; ++h) {
                const int col = c16 * 16 + h * 8 + 2 * t4;
                const float2 bb = *reinterpret_cast<const float2*>(bias + col);
                const bool keep0 = col < in.outWidth, keep1 = col + 1 < in.outWidth;
#pragma unroll
                for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                  for (int half = 0; half < 2; ++half) {
                    const int row = rowBase + mt * 16 + g + half * 8;
                    float v0 = applyActivation(decltype(A)::value, acc[mt][j][h][2 * half] + bb.x);
                    float v1 = applyActivation(decltype(A)::value, acc[mt][j][h][2 * half + 1] + bb.y);
                    if (other) {
                      const float2 o = __half22float2(*reinterpret_cast<const __half2*>(other + row * ldOther + col));
                      v0 = in.combineScale * (v0 + o.x);
                      v1 = in.combineScale * (v1 + o.y);
                    }
                    *reinterpret_cast<__half2*>(dst + row * ldDst + col) =
                        __floats2half2_rn(keep0 ? v0 : 0.f, keep1 ? v1 : 0.f);
                  }
              }
            }
          });
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
              float a, b;
              outputAffine(P.output, points[base + r].w, a, b);
              const int q = base + r;
              out[scatter ? scatter[q] : q] = a * net + b;
            }
          }
          break;
        }
      }
      __syncthreads();
    }
  }
}

}  // namespace inr::cuda
