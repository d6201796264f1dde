// The Hopper (wgmma) kernel (the design: FusedMlpKernelHopper.cuh). This file is compiled for
// sm_90a only (Kernels/Evaluator/Cuda/CMakeLists.txt), so on an H100/H200 the driver can only
// load the wgmma code, and on any other GPU the kernel reports no image and the evaluator keeps
// the mma.sync kernel. The kernel sets up the block's shared memory (HopperBlock), then its
// warpgroups take their roles: the producer (hopperProducer) streams the weights, the consumers
// (hopperConsumer) run the program on their tiles, each GEMM chunk's results written by
// hopperEpilogue.
#include "Evaluator/Cuda/FusedMlpKernelHopper.cuh"
#include "Evaluator/Cuda/FusedMlpKernels.h"
#include "Evaluator/Cuda/FusedMlpRowInstructions.cuh"

namespace inr::cuda {

// Named barriers: 1 + c = consumer c's own (128 threads; with the columns split, 1 is both
// consumers', 256 threads); 3 + c = consumer c's turn to issue a GEMM (256 threads: c waits, the
// other consumer arrives). 0 is __syncthreads.
constexpr int kConsumerBarrier = 1, kTurnBarrier = 3;

#if INR_HAVE_WGMMA
// What the kernel lays out in shared memory for its roles: the program and buffer layout, the
// ring of weight slots with their full / empty barriers, the consumers' regions (activation
// buffers and coordinates), the final dot's weights and the biases.
struct HopperBlock {
  const MlpInstr* program;
  const int* bufferStart;
  const int* bufferLd;
  std::uint64_t* fullBar;
  std::uint64_t* emptyBar;
  __half* ring;
  int stages, stageHalves;
  int actHalves, splitHalves;
  unsigned char* consumerBase;
  std::size_t consumerBytes;
  const float* dotWeights;
  const float* biases;
};

// Calls f(IntTag<K>{}) for the runtime k in [FIRST, LAST), and f(IntTag<LAST>{}) for any other:
// one straight run of wgmma per K length (a wgmma under a condition makes ptxas serialise them
// all: C7520), written once instead of a case per length.
template <int FIRST, int LAST, typename F>
__device__ __forceinline__ void dispatchKSteps(int k, F&& f) {
  if constexpr (FIRST >= LAST) {
    f(IntTag<LAST>{});
  } else {
    if (k == FIRST) f(IntTag<FIRST>{});
    else dispatchKSteps<FIRST + 1, LAST>(k, f);
  }
}

// The producer (one thread of warpgroup 0): every GEMM's weight chunks, in program order, round
// after round, into the ring's slots as the consumers release them.
template <int NC>
__device__ __forceinline__ void hopperProducer(const FusedParams& P, const HopperBlock& B, int numRounds) {
  const MlpInstr* const program = B.program;
  std::uint64_t* const fullBar = B.fullBar;
  std::uint64_t* const emptyBar = B.emptyBar;
  __half* const ring = B.ring;
  const int stages = B.stages, stageHalves = B.stageHalves;
  int slot = 0;
  unsigned phase = 0;
  for (int round = blockIdx.x; round < numRounds; round += gridDim.x)
    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr& in = program[ip];
      if (!isStreamedGemm(in)) continue;
      const __half* from = P.hopperWeights[chunkIndex(NC)] + P.hopperOffset[chunkIndex(NC)][ip];
      forEachHopperChunk(NC, in.nPad, in.kPad, [&](int rows, int, int kLen) {
        const unsigned halves = unsigned(rows * kLen);
        mbarrierWait(&emptyBar[slot], phase ^ 1u);  // a fresh barrier counts as released
        mbarrierArriveExpectTx(&fullBar[slot], halves * 2);
        bulkCopyToShared(ring + std::size_t(slot) * stageHalves, from, halves * 2, &fullBar[slot]);
        from += halves;
        if (++slot == stages) slot = 0, phase ^= 1u;
      });
    }
}

// Where a consumer's GEMM sends chunk results: the instruction's bias, destination buffer,
// residual input and final-dot weights, and the rows of this thread's fragments (this warp's
// rows from rowBase, fragment row g, column pair t4) in the tile (rows queries from base).
struct HopperGemmOutput {
  const float* bias;
  __half* dst;
  int ldDst;
  const __half* other;
  int ldOther;
  const float* dotWeights;
  int rowBase, g, t4, rows, base;
};

// Chunk j's epilogue: act(acc + bias) [+ residual] to fp16 in dst, or into the final dot (part:
// rows g, g+8), or (finalOutput) column 0 straight to the output. Fragment i of acc is row
// g + 8*((i>>1)&1), column j*NC + 8*(i>>2) + 2*t4 + (i&1); chunkBias holds this thread's bias
// pairs of the chunk. One body per activation, residual and dot for whole chunks: runtime tests
// inside the unrolled loop cost a branch per pair.
template <int NC>
__device__ __forceinline__ void hopperEpilogue(const FusedParams& P, const MlpInstr& in, const HopperGemmOutput& O, int j,
                                               const float (&acc)[NC / 2], const float2 (&chunkBias)[NC / 8],
                                               float (&part)[2], const float4* __restrict__ points,
                                               float* __restrict__ out, const int* __restrict__ scatter) {
  const float* const bias = O.bias;
  __half* const dst = O.dst;
  const int ldDst = O.ldDst;
  const __half* const other = O.other;
  const int ldOther = O.ldOther;
  const float* const dotWeights = O.dotWeights;
  const int rowBase = O.rowBase, g = O.g, t4 = O.t4, rows = O.rows, base = O.base;
  if (in.finalOutput) {  // column 0 (t4 0, chunk 0): fragments 0 (row g) and 2 (row g+8)
    if (t4 == 0 && j == 0)
#pragma unroll
      for (int half = 0; half < 2; ++half) {
        const int row = rowBase + g + half * 8;
        if (row < rows)
          writeOutput(P.output, points[base + row].w, applyActivation(in.act, acc[2 * half] + bias[0]), base + row, out, scatter);
      }
    return;
  }
  const int width = min(NC, in.nPad - j * NC);  // a multiple of 16
  dispatchActivation(in.act, [&](auto A) {
    constexpr MlpAct kAct = decltype(A)::value;
    // The pair of columns (col, col + 1) of row g + 8*half from fragments 4*jj + 2*half, +1.
    auto pair = [&](int jj, int half, bool residual, bool dot) __attribute__((always_inline)) {
      const int col = j * NC + 8 * jj + 2 * t4;
      const float2 b = chunkBias[jj];
      float v0 = applyActivation(kAct, acc[4 * jj + 2 * half] + b.x);
      float v1 = applyActivation(kAct, acc[4 * jj + 2 * half + 1] + b.y);
      if (kAct == MlpAct::Sigmoid) {  // sigmoid(0) != 0: keep padding columns zero
        if (col >= in.outWidth) v0 = 0.f;
        if (col + 1 >= in.outWidth) v1 = 0.f;
      }
      const int row = rowBase + g + 8 * half;
      if (residual) {
        const float2 o = ldsHalf2AsFloat2InPlace(other + row * ldOther + col);
        v0 = in.combineScale * (v0 + o.x);
        v1 = in.combineScale * (v1 + o.y);
      }
      if (dot) {
        const float2 w = ldsFloat2InPlace(dotWeights + col);
        part[half] = fmaf(v0, w.x, fmaf(v1, w.y, part[half]));
      } else {
        *reinterpret_cast<__half2*>(dst + row * ldDst + col) = __floats2half2_rn(v0, v1);
      }
    };
    // A whole chunk: no test inside the unrolled loop, so ptxas interleaves all its pairs
    // (a branch per 8 columns left 4 sines in flight; MUFU latency showed as stalls).
    auto whole = [&](auto residual, auto dot) __attribute__((always_inline)) {
#pragma unroll
      for (int jj = 0; jj < NC / 8; ++jj)
#pragma unroll
        for (int half = 0; half < 2; ++half) pair(jj, half, decltype(residual)::value, decltype(dot)::value);
    };
    if (width == NC) {
      if (other) {
        if (in.dotNext) whole(BoolTag<true>{}, BoolTag<true>{});
        else whole(BoolTag<true>{}, BoolTag<false>{});
      } else {
        if (in.dotNext) whole(BoolTag<false>{}, BoolTag<true>{});
        else whole(BoolTag<false>{}, BoolTag<false>{});
      }
      return;
    }
#pragma unroll
    for (int jj = 0; jj < NC / 8; ++jj) {  // the last chunk of a layer narrower than NC
      if (8 * jj >= width) break;           // the same for the whole warpgroup
#pragma unroll
      for (int half = 0; half < 2; ++half) pair(jj, half, other != nullptr, in.dotNext != 0);
    }
  });
}

// The MMAs of a split encoding's first K segment, k steps KS .. KSTEPS - 1 (A and B from shared
// memory; each k step 256 bytes further in both: + 16 in the descriptors' address fields, which
// never carry), the first overwriting the accumulators.
template <int NC, int KS, int KSTEPS>
__device__ __forceinline__ void splitSegmentMmas(float (&acc)[NC / 2], unsigned aLo, unsigned aHi, unsigned bLo, unsigned bHi) {
  if constexpr (KS < KSTEPS) {
    wgmmaSS<NC, KS * 16>(acc, aLo, aHi, bLo, bHi, KS > 0);
    splitSegmentMmas<NC, KS + 1, KSTEPS>(acc, aLo, aHi, bLo, bHi);
  }
}

// A stored Fourier encoding split for its GEMM (FusedParams::hopperSplitGemm), by one consumer's
// 128 threads: columns 0..255 into the operand region (splitOperandIndex), the rest row-major
// into `rest` (the GEMM's buffer, ldRest halves a row) from its column 0. The same elements as
// runRowInstr's Fourier case. A warp fills one 8 x 8 core matrix per step (lane: row lane / 4,
// columns 2 * (lane % 4) + {0, 1}): 128 contiguous bytes in the operand, four 16-byte runs per
// row of the rest. Then fences its stores for the MMAs' async-proxy reads (the caller's barrier
// follows).
__device__ __forceinline__ void writeSplitEncoding(const FusedParams& P, const MlpInstr& f, const float* coords,
                                                   __half* operand, __half* rest, int ldRest, int tid) {
  const int warp = tid >> 5, lane = tid & 31;
  const int groups = f.nPad >> 3;  // core matrices across a row (8 columns each)
#pragma unroll 1
  for (int m = warp; m < 8 * groups; m += 4) {
    const int q = (m & 7) * 8 + (lane >> 2), cg = m >> 3;  // row, column group
    const int col = cg * 8 + 2 * (lane & 3);
    const float* x = coords + q * 4;
    auto input = [x](int i) { return x[i]; };
    const float v0 = col < f.outWidth ? encodingElement<ActMath::FastDevice>(f, P.floatWeights, input, col) : 0.f;
    const float v1 = col + 1 < f.outWidth ? encodingElement<ActMath::FastDevice>(f, P.floatWeights, input, col + 1) : 0.f;
    const __half2 h = __floats2half2_rn(v0, v1);
    if (col < kHopperKSegment)  // the same for the whole warp
      *reinterpret_cast<__half2*>(operand + splitOperandIndex(q, col)) = h;
    else
      *reinterpret_cast<__half2*>(rest + q * ldRest + col - kHopperKSegment) = h;
  }
  fenceProxyAsyncShared();
}

// Consumer c = warpgroup - 1 (warpgroups 1 .. CONSUMERS): per round its tile of 64 queries through the whole
// program, the row-wise instructions by runRowInstr, the GEMMs on wgmma with the weights from the ring.
// COLUMNS (two consumers): both run the same tile, splitting each GEMM's column chunks (consumer
// c takes chunks j with j % 2 == c, and releases the other's slots once they are full, so the
// ring's protocol is unchanged), so a small batch's single tile per block has two warpgroups'
// epilogues overlapping each other's MMAs. The tile's buffers are shared: consumer 0 alone loads
// the coordinates, the row-wise instructions run on both consumers' 256 threads (one consumer
// alone left the other waiting at the barrier through a whole Fourier encoding), a final dot's
// halves meet in shared memory, and the two sync (named barrier 1, 256 threads) after each GEMM's
// A is in registers (its epilogues may write over it) and after its epilogues (the next reads all
// columns).
template <int NC, int CONSUMERS, bool SPLIT, bool COLUMNS>
__device__ __forceinline__ void hopperConsumer(const FusedParams& P, const HopperBlock& B, int numRounds,
                                               const float4* __restrict__ points, int n, float* __restrict__ out,
                                               const int* __restrict__ scatter) {
  // (one consumer would wait at a 256-thread barrier alone; a split encoding's operand is per consumer)
  static_assert(!COLUMNS || (CONSUMERS == 2 && !SPLIT), "the columns split takes two consumers and no split encoding");
  constexpr int KSTEPS = kHopperKSegment / 16;
  const MlpInstr* const program = B.program;
  const int* const bufferStart = B.bufferStart;
  const int* const bufferLd = B.bufferLd;
  std::uint64_t* const fullBar = B.fullBar;
  std::uint64_t* const emptyBar = B.emptyBar;
  __half* const ring = B.ring;
  const int stages = B.stages, stageHalves = B.stageHalves, actHalves = B.actHalves, splitHalves = B.splitHalves;
  unsigned char* const consumerBase = B.consumerBase;
  const std::size_t consumerBytes = B.consumerBytes;
  const float* const dotWeights = B.dotWeights;
  const float* const biases = B.biases;
  const int wg = threadIdx.x / 128;
  const int c = wg - 1;
  const int tid = threadIdx.x - 128 * wg;
  const int warp = tid >> 5, lane = tid & 31;
  const int g = lane >> 2, t4 = lane & 3;  // mma fragment coordinates
  const int rowBase = warp * 16;           // this warp's rows of the consumer tile
  const int region = COLUMNS ? 0 : c;      // the tile's shared-memory region
  __half* const act = reinterpret_cast<__half*>(consumerBase + region * consumerBytes);
  __half* const operand = act + actHalves;  // a split encoding's first K segment (splitHalves; 128-byte aligned)
  float* const coords = reinterpret_cast<float*>(consumerBase + region * consumerBytes + std::size_t(actHalves + splitHalves) * 2);
  auto consumerSync = [&]() {
    if constexpr (COLUMNS) namedBarrierSync(kConsumerBarrier, 256);
    else namedBarrierSync(kConsumerBarrier + c, 128);
  };
  // The rows of a final dot's other half (COLUMNS: consumer 1's partial sums, read by consumer 0).
  __shared__ float otherDotHalf[COLUMNS ? kHopperRows : 1];
  // Ping-pong: the consumers take turns issuing a chunk's MMAs (named barriers; consumer 1
  // gives the first turn). A turn passes as soon as the MMAs are issued, so the other
  // consumer's queue behind them while this one waits and runs the chunk's epilogue: the
  // tensor cores always have one consumer's chunk to work on, and the two epilogues never
  // coincide. After the last chunk of the block's last round consumer 1 gives no turn (nobody
  // would take it). Deadlock-free with any ring of >= 2 slots: a consumer is at most one chunk
  // ahead of the other, so every slot older than the chunk it waits for has been released.
  // With the columns split (no turns) each consumer waits for every slot's "full" phase, its own
  // chunks' and the other's, before arriving on its "empty" barrier: the producer refills a slot
  // only once both arrived, so neither consumer can run a whole phase ahead of the other on it.
  int lastGemm = -1;
  for (int ip = 0; ip < P.numInstrs; ++ip)
    if (isStreamedGemm(program[ip])) lastGemm = ip;
  const bool turns = CONSUMERS == 2 && !COLUMNS && P.hopperPingPong && lastGemm >= 0;
  if (turns && c == 1 && int(blockIdx.x) < numRounds) namedBarrierArrive(kTurnBarrier + 0, 256);

  int slot = 0;
  unsigned phase = 0;
  for (int round = blockIdx.x; round < numRounds; round += gridDim.x) {
    const int base = (COLUMNS ? round : round * CONSUMERS + c) * kHopperRows;
    const int rows = max(0, min(kHopperRows, n - base));  // 0: this consumer only keeps the pace
    consumerSync();  // the previous round's last reads of the coordinates are done
    if (!COLUMNS || c == 0) loadTileCoords<kHopperRows, 128>(P, points, base, rows, coords, tid);
    consumerSync();
    const bool lastRound = round + int(gridDim.x) >= numRounds;
    const RowTile view{act, bufferStart, bufferLd, coords, rows, base};
    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr in = program[ip];
      if (in.fusedIntoPrevious || in.fusedIntoNext) continue;
      if (in.op != MlpOp::Gemm) {
        if (SPLIT && in.op == MlpOp::Fourier && ip + 1 == P.hopperSplitGemm)
          writeSplitEncoding(P, in, coords, operand, act + bufferStart[in.dst], bufferLd[in.dst], tid);
        else if constexpr (COLUMNS)  // both consumers' 256 threads on the shared tile
          runRowInstr<kHopperRows, 256>(P, in, view, tid + 128 * c, points, out, scatter);
        else
          runRowInstr<kHopperRows, 128>(P, in, view, tid, points, out, scatter);
        consumerSync();
        continue;
      }
      const int kSegments = (in.kPad + kHopperKSegment - 1) / kHopperKSegment;
      const int numChunks = (in.nPad + NC - 1) / NC;  // column chunks, kSegments slots each
      const float* const bias = biases + P.hopperBiasStart[ip];
      const int ldSrc = in.src >= 0 ? bufferLd[in.src] : 0;
      const __half* src = in.src >= 0 ? act + bufferStart[in.src] : nullptr;
      const int fourier = in.fourierInput;
      __half* const dst = in.dst >= 0 ? act + bufferStart[in.dst] : nullptr;
      const int ldDst = in.dst >= 0 ? bufferLd[in.dst] : 0;
      const __half* const other = in.other >= 0 ? act + bufferStart[in.other] : nullptr;
      const int ldOther = in.other >= 0 ? bufferLd[in.other] : 0;
      const unsigned aAddr = src ? smemAddress(src + (rowBase + ((lane >> 3) & 1) * 8 + (lane & 7)) * ldSrc + (lane >> 4) * 8) : 0u;
      const unsigned ringBase = smemAddress(ring);
      // A: K columns k0 .. k0 + kLen of this warp's 16 rows, by ldmatrix from the buffer or as
      // the Fourier encoding computed for this thread's fragment (rows g, g+8; columns
      // 2*t4 + {0,1} + {0,8} of each k16 step).
      unsigned a[KSTEPS][4];
      auto loadA = [&](int k0, int kLen) {
        if (SPLIT || fourier < 0) {  // (a program with a split encoding has every encoding stored)
#pragma unroll
          for (int ks = 0; ks < KSTEPS; ++ks)
            if (ks * 16 < kLen) ldmatrixX4(a[ks], aAddr + unsigned((k0 + ks * 16) * 2));
          return;
        }
        const MlpInstr& f = program[fourier];
#pragma unroll
        for (int ks = 0; ks < KSTEPS; ++ks) {
          if (ks * 16 >= kLen) continue;
          const int kb = k0 + ks * 16 + 2 * t4;
#pragma unroll
          for (int q = 0; q < 4; ++q) {  // a[q]: row g + 8*(q&1), columns kb + 8*(q>>1) + {0,1}
            const float* x = coords + (rowBase + g + 8 * (q & 1)) * 4;
            auto input = [x](int i) { return x[i]; };
            const int k = kb + 8 * (q >> 1);
            const __half2 h = __floats2half2_rn(fourierElement<ActMath::FastDevice>(f, P.floatWeights + f.floatOffset, input, k),
                                                fourierElement<ActMath::FastDevice>(f, P.floatWeights + f.floatOffset, input, k + 1));
            a[ks][q] = *reinterpret_cast<const unsigned*>(&h);
          }
        }
      };
      // A split encoding (K 257..512): its first segment read from shared memory by the MMAs
      // (wgmmaSS), the second, row-major in src from column 0, held in registers for every chunk,
      // so the epilogues may write over it (in place).
      const bool split = SPLIT && ip == P.hopperSplitGemm;
      const std::uint64_t operandDesc = wgmmaDescriptor(smemAddress(operand), 128, kHopperKSegment * 16);
      if (kSegments == 1) loadA(0, in.kPad);  // before any wait: overlaps the weights' arrival
      else if (split) loadA(0, in.kPad - kHopperKSegment);
      if (COLUMNS) consumerSync();  // both hold A: the epilogues may write over it
      float part[2] = {0.f, 0.f};             // the final dot's partial sums (rows g, g+8)
      float acc[NC / 2];
      // Chunk j's MMAs, complete on return (slots released): one wgmma per k16 step per K
      // segment, the first overwriting the accumulators (the bias joins in the epilogue, which
      // costs less than starting them at the bias: ptxas shuffled those loads into place with
      // a move per register). With turns, the turn is taken before the first MMA and passed on
      // once the last is issued.
      float2 chunkBias[NC / 8];  // this thread's bias pairs of the chunk (columns 8*jj + 2*t4 + {0,1})
      auto step = [&](int j) __attribute__((always_inline)) {
#pragma unroll
        for (int jj = 0; jj < NC / 8; ++jj)  // loaded while the MMAs run (bias is zero-padded per chunk)
          chunkBias[jj] = *reinterpret_cast<const float2*>(bias + j * NC + 8 * jj + 2 * t4);
        for (int s = 0; s < kSegments; ++s) {
          const int k0 = s * kHopperKSegment, kLen = min(kHopperKSegment, in.kPad - k0);
          if (kSegments > 1 && !split) loadA(k0, kLen);  // K > 256: A per segment
          mbarrierWait(&fullBar[slot], phase);
          const unsigned chunkBase = ringBase + unsigned(slot * stageHalves * 2);
          // One straight run of wgmma per K length: a wgmma under a condition makes ptxas
          // serialise them all (C7520).
          // k step ks starts 256 bytes further: + 16 in the descriptor's address field (in 16-byte
          // units; shared addresses stay below 2^18, so the field never carries).
          const std::uint64_t desc = wgmmaDescriptor(chunkBase, 128, kLen * 16);
          auto mma = [&](auto kSteps) __attribute__((always_inline)) {
            wgmmaFence();
#pragma unroll
            for (int ks = 0; ks < decltype(kSteps)::value; ++ks) wgmmaRS<NC>(acc, a[ks], desc + std::uint64_t(ks * 16), s > 0 || ks > 0);
            wgmmaCommit();
          };
          if (split && s == 0) {  // the split encoding's first segment: a whole one, A from shared memory
            wgmmaFence();
            splitSegmentMmas<NC, 0, KSTEPS>(acc, unsigned(operandDesc), unsigned(operandDesc >> 32), unsigned(desc),
                                            unsigned(desc >> 32));
            wgmmaCommit();
          } else if (kLen == kHopperKSegment) {
            mma(IntTag<KSTEPS>{});  // the common case first
          } else {
            dispatchKSteps<1, KSTEPS>(kLen / 16, mma);
          }
          if (s + 1 == kSegments && turns && !(c == 1 && lastRound && ip == lastGemm && j + 1 == numChunks))
            namedBarrierArrive(kTurnBarrier + (1 - c), 256);
          wgmmaWait<0>();
          if (lane == 0) mbarrierArrive(&emptyBar[slot]);
          if (++slot == stages) slot = 0, phase ^= 1u;
        }
        fenceAccumulators(acc);
      };
      const HopperGemmOutput gemmOut{bias, dst, ldDst, other, ldOther, dotWeights, rowBase, g, t4, rows, base};
      for (int j = 0; j < numChunks; ++j) {
        if (COLUMNS && (j & 1) != c) {  // the other consumer's chunk: release its slots once full
          for (int s = 0; s < kSegments; ++s) {
            mbarrierWait(&fullBar[slot], phase);
            if (lane == 0) mbarrierArrive(&emptyBar[slot]);
            if (++slot == stages) slot = 0, phase ^= 1u;
          }
          continue;
        }
        if (turns) namedBarrierSync(kTurnBarrier + c, 256);
        step(j);
        hopperEpilogue<NC>(P, in, gemmOut, j, acc, chunkBias, part, points, out, scatter);
      }
      if (in.dotNext) {  // this warp holds every column (COLUMNS: its consumer's half) of its 16 rows: reduce over the quad
        const MlpInstr& fin = program[ip + 1];
        const float dotBias = P.floatWeights[fin.biasOffset];
        float v[2];
#pragma unroll
        for (int half = 0; half < 2; ++half) {
          v[half] = part[half];
          v[half] += __shfl_xor_sync(0xffffffffu, v[half], 1);
          v[half] += __shfl_xor_sync(0xffffffffu, v[half], 2);
        }
        if (COLUMNS) {  // consumer 1's half through shared memory to consumer 0
          if (c == 1 && t4 == 0) otherDotHalf[rowBase + g] = v[0], otherDotHalf[rowBase + g + 8] = v[1];
          consumerSync();
          if (c == 0) v[0] += otherDotHalf[rowBase + g], v[1] += otherDotHalf[rowBase + g + 8];
        }
#pragma unroll
        for (int half = 0; half < 2; ++half) {
          const int row = rowBase + g + 8 * half;
          if ((!COLUMNS || c == 0) && t4 == 0 && row < rows)
            writeOutput(P.output, points[base + row].w, applyActivation(fin.act, v[half] + dotBias), base + row, out, scatter);
        }
      }
      // A warp's GEMM epilogues write only the rows its next GEMM reads: a barrier only before
      // a row-wise instruction (other warps' rows), and with the columns split after every GEMM
      // (the next reads the other consumer's columns; the final dot's shared half is read).
      int next = ip + 1;
      while (next < P.numInstrs && (program[next].fusedIntoPrevious || program[next].fusedIntoNext)) ++next;
      if (COLUMNS || (next < P.numInstrs && program[next].op != MlpOp::Gemm)) consumerSync();
    }
  }
}
#endif  // INR_HAVE_WGMMA

// SPLIT: the instantiation for a program with a split encoding (FusedParams::hopperSplitGemm; its
// own kernel, so the others keep their registers: the split GEMM holds A and reads an operand
// descriptor across its chunks). COLUMNS: two consumers on one tile, splitting its columns
// (hopperConsumer).
template <int NC, int CONSUMERS, bool SPLIT, bool COLUMNS>
__global__ void __launch_bounds__(hopperThreads(CONSUMERS), 1) hopperMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                                   const unsigned* __restrict__ deviceCount,
                                                                   float* __restrict__ out, const int* __restrict__ scatter) {
#if INR_HAVE_WGMMA
  if (deviceCount) n = min(n, int(*deviceCount));
  extern __shared__ __align__(1024) unsigned char smem[];
  __shared__ MlpInstr program[kMaxFusedInstrs];
  __shared__ int bufferStart[kMaxBuffers], bufferLd[kMaxBuffers];
  __shared__ alignas(8) std::uint64_t fullBar[kHopperMaxStages], emptyBar[kHopperMaxStages];
  const int stages = P.hopperStages;
  const int stageHalves = P.hopperStageHalves[chunkIndex(NC)];
  __half* const ring = reinterpret_cast<__half*>(smem);
  const int actHalves = hopperActHalves(P), splitHalves = SPLIT ? hopperSplitHalves(P) : 0;
  unsigned char* const consumerBase = smem + std::size_t(stages) * stageHalves * 2;
  const std::size_t consumerBytes = hopperConsumerBytes(actHalves, splitHalves);
  constexpr int kThreads = hopperThreads(CONSUMERS);
  constexpr int kRegions = hopperTileRegions(CONSUMERS, COLUMNS);
  float* const dotWeights = reinterpret_cast<float*>(consumerBase + kRegions * consumerBytes);
  float* const biases = dotWeights + MlpProgram::kMaxFusedGemmOut;
  for (int i = threadIdx.x; i < P.numInstrs; i += kThreads) program[i] = P.hopperInstrs[i];
  for (int ip = 0; ip < P.numInstrs; ++ip) {
    const MlpInstr& in = P.hopperInstrs[ip];
    if (in.dotNext)
      for (int c = threadIdx.x; c < in.nPad; c += kThreads) dotWeights[c] = P.floatWeights[in.dotOffset + c];
    if (isStreamedGemm(in))
      for (int c = threadIdx.x; c < (in.nPad + kHopperBiasPad - 1) / kHopperBiasPad * kHopperBiasPad; c += kThreads)
        biases[P.hopperBiasStart[ip] + c] = c < in.nPad ? P.floatWeights[in.biasOffset + c] : 0.f;
  }
  if (threadIdx.x == 0) {
    int at = 0;
    for (int b = 0; b < kMaxBuffers; ++b) {
      bufferStart[b] = at;
      bufferLd[b] = P.hopperBufferLd[b];
      if (b < P.hopperNumBuffers) at += kHopperRows * P.hopperBufferLd[b];
    }
    for (int s = 0; s < stages; ++s) {
      mbarrierInit(&fullBar[s], 1);                      // the producer's arrive (+ the copy's bytes)
      mbarrierInit(&emptyBar[s], 4 * CONSUMERS);  // one arrive per consumer warp
    }
    fenceBarrierInit();
  }
  __syncthreads();  // the last block-wide barrier: the producer leaves early

  const int numTiles = (n + kHopperRows - 1) / kHopperRows;
  const int numRounds = COLUMNS ? numTiles : (numTiles + CONSUMERS - 1) / CONSUMERS;
  const int wg = threadIdx.x / 128;
  const HopperBlock block{program, bufferStart, bufferLd, fullBar, emptyBar, ring, stages, stageHalves,
                          actHalves, splitHalves, consumerBase, consumerBytes, dotWeights, biases};
  // Two consumers share 168 registers a thread at launch: the producer's go to them. One consumer
  // has 255 from the start (256 threads), so nothing moves.
  if (wg == 0) {
    if constexpr (CONSUMERS == 2) setMaxRegistersDec<kHopperProducerRegisters>();
    if (threadIdx.x != 0) return;
    hopperProducer<NC>(P, block, numRounds);
    return;
  }
  if constexpr (CONSUMERS == 2) setMaxRegistersInc<kHopperConsumerRegisters>();
  hopperConsumer<NC, CONSUMERS, SPLIT, COLUMNS>(P, block, numRounds, points, n, out, scatter);
#else
  (void)P, (void)points, (void)n, (void)deviceCount, (void)out, (void)scatter;
#endif
}

FusedKernel hopperKernel(int chunkColumns, int consumers, bool splitEncoding, bool splitColumns) {
  if (splitEncoding) {  // two consumers with 128-column slots: not instantiated (the paper FFN's 512-wide encoding does not fit them)
    if (splitColumns) return nullptr;  // not instantiated either: the split encoding's operand is per consumer
    if (consumers == 1) return chunkColumns == 128 ? hopperMlpKernel<128, 1, true, false> : hopperMlpKernel<64, 1, true, false>;
    return chunkColumns == 128 ? nullptr : hopperMlpKernel<64, 2, true, false>;
  }
  if (consumers == 1) return splitColumns ? nullptr : chunkColumns == 128 ? hopperMlpKernel<128, 1, false, false> : hopperMlpKernel<64, 1, false, false>;
  if (splitColumns) return chunkColumns == 128 ? hopperMlpKernel<128, 2, false, true> : hopperMlpKernel<64, 2, false, true>;
  return chunkColumns == 128 ? hopperMlpKernel<128, 2, false, false> : hopperMlpKernel<64, 2, false, false>;
}

}  // namespace inr::cuda
