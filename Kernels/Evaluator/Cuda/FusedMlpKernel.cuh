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
// kTangents: value and gradient in one pass (forward mode, gradient shading). A tile's rows are
// then M / 4 queries' values and three tangents each (TileRows<true>, FusedMlpDevice.cuh), so
// the tangents ride as extra rows of the same GEMMs, through the same weight fragments; the
// epilogue computes act(z) for a value and act'(z) * (W dx) for a tangent (no bias: the
// accumulators of tangent rows start at zero), residual sums add the tangents' own rows, and
// the output is the value with its world gradient (float4 per query). Tangents are stored in
// fp16 like the values, scaled by MlpProgram::tangentScale (a power of two: fp16's range).
// The kernel's instantiations (tile x weight chunk x tangent rows) live in four translation
// units, FusedMlpKernel{Values,Tangents}K{64,32}.cu, one mmaSyncKernelFor each, so they compile
// in parallel; the evaluator reaches them through mmaSyncKernel() and mmaSyncTangentKernel()
// (FusedMlpKernels.h, FusedMlpKernel.cu). Include this header in those files only.
// The kernel body, fusedMlpTiles, reads the program through a policy: SharedMemoryProgram (the
// interpreter above: the instructions copied from FusedParams to shared memory and decoded as
// its loop runs) or ConstantProgram (a kernel generated for one network and compiled at run time
// by NVRTC, Evaluator/MlpKernelSource.h: the instructions and the buffer layout are compile-time
// constants, the loop over them is unrolled, and every branch on an instruction's fields folds
// away; where the interpreter dispatches on a field at run time (operation, activation, column
// blocks, residual, output), a constant instruction instantiates only its own branch:
// ConstantInstr, FusedMlpDevice.cuh). Both run the same code, so they compute the same bits.
#include <cuda_fp16.h>
#include <cuda_pipeline.h>

#include "Evaluator/Cuda/FusedMlpDevice.cuh"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/Cuda/FusedMlpRowInstructions.cuh"
#if !defined(__CUDACC_RTC__)
#include "Evaluator/Cuda/FusedMlpKernels.h"
#endif

namespace inr::cuda {

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

// The interpreter's program: the instructions and the buffer layout in shared memory (uniform,
// indexable without local-memory spills), loaded once per block by fusedMlpKernel, each
// instruction copied to registers and decoded as the loop reaches it.
struct SharedMemoryProgram {
  const MlpInstr* instrs;
  int numInstrs;
  const int* start;  // per buffer, halves from the first
  const int* ld;     // per buffer, halves per row
  __device__ const MlpInstr& instr(int i) const { return instrs[i]; }
  __device__ const int* bufferStart() const { return start; }
  __device__ const int* bufferLd() const { return ld; }
  // f(in, ip, RuntimeInstr{}) for every instruction in order (in: a copy, so its fields stay in
  // registers).
  template <class F>
  __device__ __forceinline__ void forEachInstruction(F&& f) const {
    for (int ip = 0; ip < numInstrs; ++ip) {
      const MlpInstr in = instrs[ip];
      f(in, ip, RuntimeInstr{});
    }
  }
  // Halves of the activation buffers and rows of the weight stage for tiles of M rows.
  __device__ static int activationHalves(const FusedParams& P, int M) {
    int halves = 0;
    for (int b = 0; b < P.numBuffers; ++b) halves += M * P.bufferLd[b];
    return halves;
  }
  __device__ static int weightStageRows(const FusedParams& P) { return stageRows(P); }
  __device__ static bool fusedFourier(const FusedParams& P) { return P.fusedFourier != 0; }
  static constexpr bool kHashGrid = true;  // any instruction may be one
};

// A generated kernel's program (Evaluator/MlpKernelSource.h): Desc holds the instructions
// (static constexpr MlpInstr instr(int)), kNumInstrs, kNumBuffers, ld(b) (halves per row of
// buffer b), kMaxGemmOutPad, kFusedFourier and kHashGrid, all compile-time constants of one network; the
// FusedParams it runs with describe the same program (the host checks that: GeneratedKernels.h).
// The loop over the instructions is unrolled, each instruction a constexpr object, so the
// kernel's code for it is what that instruction needs and nothing decodes it at run time.
template <class Desc, int M>
struct ConstantProgram {
  static_assert(Desc::kNumInstrs > 0 && Desc::kNumInstrs <= kMaxFusedInstrs, "a fused program has 1..64 instructions");
  static_assert(Desc::kNumBuffers >= 1 && Desc::kNumBuffers <= kMaxBuffers, "a fused program has 1..4 buffers");
  int start[kMaxBuffers], ld[kMaxBuffers];  // constants; arrays for RowTile (indices fold too)
  __device__ ConstantProgram() {
    int at = 0;
#pragma unroll
    for (int b = 0; b < kMaxBuffers; ++b) {
      start[b] = at;
      ld[b] = b < Desc::kNumBuffers ? Desc::ld(b) : 0;
      at += b < Desc::kNumBuffers ? M * Desc::ld(b) : 0;
    }
  }
  __device__ static constexpr MlpInstr instr(int i) { return Desc::instr(i); }
  __device__ const int* bufferStart() const { return start; }
  __device__ const int* bufferLd() const { return ld; }
  template <int I, class F>
  __device__ __forceinline__ static void unrolled(F& f) {
    if constexpr (I < Desc::kNumInstrs) {
      constexpr MlpInstr in = Desc::instr(I);
      f(in, I, ConstantInstr<Desc, I>{});
      unrolled<I + 1>(f);
    }
  }
  template <class F>
  __device__ __forceinline__ void forEachInstruction(F&& f) const {
    unrolled<0>(f);
  }
  __device__ static constexpr int activationHalves(const FusedParams&, int m) {
    int halves = 0;
    for (int b = 0; b < Desc::kNumBuffers; ++b) halves += m * Desc::ld(b);
    return halves;
  }
  __device__ static constexpr int weightStageRows(const FusedParams&) {
    return (Desc::kMaxGemmOutPad + kStageRowAlign - 1) / kStageRowAlign * kStageRowAlign;
  }
  __device__ static constexpr bool fusedFourier(const FusedParams&) { return Desc::kFusedFourier != 0; }
  static constexpr bool kHashGrid = Desc::kHashGrid != 0;  // whether an instruction is a hash grid
};

// The kernel body: the persistent grid's tile loop, the program read through `prog`
// (SharedMemoryProgram or ConstantProgram, above; synchronised before the call where it is
// loaded into shared memory).
template <int WR, int KC, bool kTangents, class Program>
__device__ __forceinline__ void fusedMlpTiles(const Program& prog, const FusedParams& P, const float4* __restrict__ points,
                                              int n, const unsigned* __restrict__ deviceCount, float* __restrict__ out,
                                              const int* __restrict__ scatter) {
  // deviceCount: the batch size as written by an earlier kernel (n is then its upper bound), so
  // a producer-consumer loop needs no host round trip per batch.
  if (deviceCount) n = min(n, int(*deviceCount));
  constexpr int M = 32 * WR;  // rows per tile
  using Rows = TileRows<kTangents>;
  constexpr int Q = M / Rows::kDirections;  // queries per tile
  constexpr int THREADS = WR * 128;
  constexpr int kStride = KC + 8;  // halves per staged weight row
  extern __shared__ __align__(128) unsigned char smem[];
  const int* const bufferStart = prog.bufferStart();
  const int* const bufferLd = prog.bufferLd();
  __half* const actBase = reinterpret_cast<__half*>(smem);
  const int actHalves = Program::activationHalves(P, M);
  const int stageHalves = Program::weightStageRows(P) * kStride;
  __half* const wstage = actBase + actHalves;
  __half* const encStage = wstage + 2 * stageHalves;  // a fused Fourier encoding's chunk, if any
  float* const coords = reinterpret_cast<float*>(encStage + (Program::fusedFourier(P) ? M * (KC + 8) : 0));
  float* const dotPart = coords + M * 4;  // [colGroup][row] partial sums of the final dot
  float* const dotWeights = dotPart + M * 4;  // the final dot's weights (zero-padded), if any
  prog.forEachInstruction([&](const MlpInstr& in, int, auto) __attribute__((always_inline)) {
    if (in.dotNext)
      for (int c = threadIdx.x; c < in.nPad; c += THREADS) dotWeights[c] = P.floatWeights[in.dotOffset + c];
  });
  __syncthreads();

  const int tid = threadIdx.x;
  const int warp = tid >> 5, lane = tid & 31;
  const int g = lane >> 2, t4 = lane & 3;  // mma fragment coordinates
  const int rowGroup = warp >> 2, colGroup = warp & 3;

  const int numTiles = (n + Q - 1) / Q;
  bool firstChunkStaged = false;  // the coming GEMM's chunk 0 is already in flight
  for (int tile = blockIdx.x; tile < numTiles; tile += gridDim.x) {
    const int base = tile * Q;
    const int rows = min(Q, n - base);  // queries of this tile
    loadTileCoords<M, THREADS, kTangents>(P, points, base, rows, coords, tid);
    __syncthreads();

    prog.forEachInstruction([&](const MlpInstr& in, int ip, auto known) __attribute__((always_inline)) {
      using Known = decltype(known);
      // Done by a neighbouring GEMM (the final dot in its epilogue, an encoding in its operand).
      if (in.fusedIntoPrevious || in.fusedIntoNext) return;  // uniform
      if (in.op != MlpOp::Gemm) {
        runRowInstr<M, THREADS, kTangents, Program::kHashGrid>(P, in, RowTile{actBase, bufferStart, bufferLd, coords, rows, base},
                                                               tid, points, out, scatter, known);
        __syncthreads();
        return;
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
                  if constexpr (kFirst && kTangents) {  // bias in the value rows only
                    const float2 zero = make_float2(0.f, 0.f);
                    mma16816BiasUpperZero(acc[mt][j][0], a[mt], b[0], b[1], mt == 0 ? biasPair[j][0] : zero);
                    mma16816BiasUpperZero(acc[mt][j][1], a[mt], b[2], b[3], mt == 0 ? biasPair[j][1] : zero);
                  } else if constexpr (kFirst) {
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
              stageWeightChunk<THREADS, KC>(P, gemm, prog.instr(gemm).nPad, wstage, stageHalves, chunk, tid);
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
                const MlpInstr& f = prog.instr(in.fourierInput);
                for (int idx = tid; idx < M * (KC / 2); idx += THREADS) {
                  const int r = idx / (KC / 2), k = 2 * (idx % (KC / 2)), col = chunk * KC + k;
                  // A tangent row: the element's derivative at its query's value row's inputs.
                  const float* x = coords + Rows::row(Rows::query(r), 0) * 4;
                  const float* dx = coords + r * 4;
                  auto input = [x](int i) { return x[i]; };
                  auto tangent = [dx](int i) { return dx[i]; };
                  auto element = [&](int c) {
                    return Rows::direction(r) == 0 ? fourierElement<ActMath::FastDevice>(f, P.floatWeights + f.floatOffset, input, c)
                                                   : encodingElementTangent(f, P.floatWeights, input, tangent, c);
                  };
                  *reinterpret_cast<__half2*>(encStage + r * (KC + 8) + k) = __floats2half2_rn(element(col), element(col + 1));
                }
              }
              __syncthreads();
              const unsigned aChunk = encoded ? 0u : unsigned(chunk * KC * 2), bChunk = unsigned((chunk & 1) * stageHalves * 2);
              const int kLen = min(KC, in.kPad - chunk * KC);
              kStep(aChunk, bChunk, firstTag);  // every chunk holds at least one k step of 16
              if (in.kPad % KC == 0 || kLen == KC) {  // (the same; the first folds in a generated kernel)
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
            if constexpr (mayHave<Known>(&MlpInstr::finalOutput)) {  // (a constant GEMM: only where it is the output)
              if (in.finalOutput) {  // column 0 is the network output: fp32, straight to `out`
                if (colGroup == 0 && t4 == 0) {
                  if constexpr (kTangents) {  // this lane's four rows: query g's value and tangents
                    const int q = rowGroup * 8 + g;
                    if (q < rows)
                      emitOutput<true>(P, in.act, [&](int d) { return acc[d >> 1][0][0][2 * (d & 1)]; }, base + q, points, out,
                                       scatter);
                  } else {
#pragma unroll
                    for (int mt = 0; mt < 2; ++mt)
#pragma unroll
                      for (int half = 0; half < 2; ++half) {
                        const int row = rowBase + mt * 16 + g + half * 8;
                        if (row < rows)
                          emitOutput<false>(P, in.act, [&](int) { return acc[mt][0][0][2 * half]; }, base + row, points, out,
                                            scatter);
                      }
                  }
                }
                return;
              }
            }
            const int laneCol = colGroup * 16 + 2 * t4;
            withActivation(known, in.act, [&](auto A) {
              constexpr MlpAct kAct = decltype(A)::value;
              // act(acc) [+ residual], fp32; sigmoid(0) != 0, so its padding columns are masked.
              // A tangent row (kTangents: m16 tile 1, or rows g + 8 of tile 0) gets act'(z) times
              // its accumulator, z being the value row's (tile 0, fragment f & 1) pre-activation.
              auto value = [&](int mt, int j, int h, int f, int col) {
                if (kTangents && (mt > 0 || f >= 2))
                  return activationDerivative<ActMath::FastDevice>(kAct, acc[0][j][h][f & 1]) * acc[mt][j][h][f];
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
                // A constant instruction keeps the interpreter's runtime test of oRow in front of
                // the residual loop: it makes the loop's own test redundant, so the activation and
                // the residual sum share a basic block there as in the interpreter, and the
                // compiler fuses the same multiply-adds (tangent rows: act'(z) * acc + o) in both.
                // Without it the generated kernel's tangents differed in the last fp16 bit.
                if constexpr (Known::kConstant) {
                  if constexpr (Known::get().other >= 0) {
                    if (oRow) loop(BoolTag<true>{});
                  } else {
                    loop(BoolTag<false>{});
                  }
                } else if (oRow) {
                  loop(BoolTag<true>{});
                } else {
                  loop(BoolTag<false>{});
                }
              };
              if constexpr (mayHave<Known>(&MlpInstr::dotNext)) {  // (a constant GEMM: only where it fuses the dot)
                if (in.dotNext) {
                  // The network's final linear (next instruction): dot of the fp32 activations with
                  // its weights, reduced over the quad's lanes, then over the 4 column warps.
                  const MlpInstr& fin = prog.instr(ip + 1);
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
                  // The column groups' partial sums, M apart (named here: NVRTC's front end crashes
                  // on the constexpr M used inside the lambda below).
                  const float* const part1 = dotPart + M;
                  const float* const part2 = dotPart + 2 * M;
                  const float* const part3 = dotPart + 3 * M;
                  for (int q = tid; q < rows; q += THREADS) {
                    auto pre = [&](int d) {  // direction d's dot product (the value's with the bias)
                      const int r = Rows::row(q, d);
                      return dotPart[r] + part1[r] + part2[r] + part3[r] + (d == 0 ? dotBias : 0.f);
                    };
                    emitOutput<kTangents>(P, fin.act, pre, base + q, points, out, scatter);
                  }
                  return;
                }
              }
              __half* const dRow = dst + (rowBase + g) * ldDst + laneCol;
              forEachPair([&](int mt, int half, int j, int h, int, float v0, float v1) {
                *reinterpret_cast<__half2*>(dRow + (mt * 16 + half * 8) * ldDst + j * 64 + h * 8) = __floats2half2_rn(v0, v1);
              });
            });
          };
          // NB, the same for every warp of the block: (c16Count + 3) / 4, at most 4.
          if constexpr (Known::kConstant) {
            constexpr int kBlocks = (Known::get().nPad / 16 + 3) / 4;
            gemm(IntTag<(kBlocks >= 1 && kBlocks <= 3) ? kBlocks : 4>{});
          } else {
            switch ((c16Count + 3) / 4) {
              case 1: gemm(IntTag<1>{}); break;
              case 2: gemm(IntTag<2>{}); break;
              case 3: gemm(IntTag<3>{}); break;
              default: gemm(IntTag<4>{}); break;
            }
          }
      }
      __syncthreads();
    });
  }
}

// The interpreter. At most 128 registers per thread for every tile size (min. 512 threads per
// SM): smaller tiles exist so that two or four blocks share an SM and one's epilogue overlaps
// another's GEMM.
template <int WR, int KC, bool kTangents>
__global__ void __launch_bounds__(WR * 128, 4 / WR) fusedMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                                  const unsigned* __restrict__ deviceCount,
                                                                  float* __restrict__ out, const int* __restrict__ scatter) {
  constexpr int M = 32 * WR;
  __shared__ MlpInstr program[kMaxFusedInstrs];
  __shared__ int bufferStart[kMaxBuffers], bufferLd[kMaxBuffers];
  for (int i = threadIdx.x; i < P.numInstrs; i += WR * 128) program[i] = P.instrs[i];
  if (threadIdx.x == 0) {
    int at = 0;
    for (int b = 0; b < kMaxBuffers; ++b) {
      bufferStart[b] = at;
      bufferLd[b] = P.bufferLd[b];
      if (b < P.numBuffers) at += M * P.bufferLd[b];
    }
  }
  __syncthreads();
  fusedMlpTiles<WR, KC, kTangents>(SharedMemoryProgram{program, P.numInstrs, bufferStart, bufferLd}, P, points, n,
                                   deviceCount, out, scatter);
}

#if !defined(__CUDACC_RTC__)
// Tile of 32*WR rows, 4*WR warps; weight chunks of KC columns (declared in FusedMlpKernels.h).
template <bool kTangents, int KC>
FusedKernel mmaSyncKernelFor(int tile) {
  switch (tile) {
    case 128: return fusedMlpKernel<4, KC, kTangents>;
    case 64: return fusedMlpKernel<2, KC, kTangents>;
    default: return fusedMlpKernel<1, KC, kTangents>;
  }
}
#endif

}  // namespace inr::cuda
