#pragma once
// The fused kernel on Hopper (sm_90a): warp-specialised, warpgroup MMA.
//
// A block is three warpgroups. Warpgroup 0 is the producer: one thread streams every GEMM's
// weights, chunk after chunk in program order, into a ring of `stages` shared-memory slots with
// the bulk copy engine (cp.async.bulk, one copy per chunk: the weights are pre-packed chunk by
// chunk in the wgmma core-matrix layout), each slot guarded by a "full" mbarrier (the copy's
// bytes complete it) and an "empty" one (the consumers' warps arrive once their wgmma has read
// it). It gives its registers away (setmaxnreg.dec) to warpgroups 1 and 2, the consumers
// (setmaxnreg.inc), which each run the whole program on their own tile of 64 queries: a warp
// owns 16 rows and every column of them, so a consumer synchronises only with itself (named
// barrier) and the final dot product reduces within a quad.
// GEMM layers: A (the layer's input, K <= 256) goes to registers once per layer (ldmatrix from
// the row-major buffer, or the Fourier encoding computed in place); the weights arrive as chunks
// of NC <= 64 output columns x all K (one chunk per segment of 256 for wider K); accumulators are
// double-buffered, so chunk j+1's wgmma (m64nNCk16) runs while chunk j's epilogue (bias,
// sine/SiLU, residual, fp16 store or the final dot) executes: the special-function work of
// one chunk overlaps the tensor-core work of the next. A warp has read all its A rows before
// any epilogue writes them, so a GEMM may write over its input (MlpProgram::withGemmsInPlace:
// one activation buffer for SIREN and FFN).
// Ping-pong (optional, autotuned): the consumers take turns issuing a GEMM layer (named
// barriers). A turn covers a whole layer, so a layer's chunks must all fit in the ring (else the
// second consumer could never free a slot the first one waits for): layers with more chunks
// than slots run unordered.
// ptxas allocates registers for the kernel's launch bound (168 for 384 threads) whatever
// setmaxnreg later grants, so the consumer's working set is sized for 168: A 64, accumulators
// 2 x 32.
// The wgmma/mbarrier/bulk-copy instructions exist only in sm_90a code (__CUDA_ARCH_FEAT_SM90_ALL);
// other targets compile the kernel body away and the host never launches it there (it asks the
// loaded code with hopperKernelFor() and cudaFuncGetAttributes).
#include <cuda_fp16.h>
#include <cstdint>
#include <vector>

#include "Cuda/FusedMlpKernel.cuh"
#include "Cuda/MlpProgram.h"

namespace inr::cuda {

#if defined(__CUDA_ARCH__) && defined(__CUDA_ARCH_FEAT_SM90_ALL)
#define INR_HAVE_WGMMA 1
#else
#define INR_HAVE_WGMMA 0
#endif

constexpr int kHopperConsumers = 2;
constexpr int kHopperRows = 64;  // queries per consumer tile (wgmma's M)
constexpr int kHopperThreads = 128 * (1 + kHopperConsumers);
constexpr int kHopperQueriesPerRound = kHopperRows * kHopperConsumers;
constexpr int kHopperMaxStages = 8;
constexpr int kHopperKSegment = 256;  // K columns of A held in registers (64 per thread)
// setmaxnreg budgets (multiples of 8): 128 x 40 + 256 x 232 = 64512 of the SM's 65536.
constexpr int kHopperProducerRegisters = 40, kHopperConsumerRegisters = 232;

// Output columns per weight chunk (the wgmma N) for a GEMM of nPad output columns.
__host__ __device__ constexpr int hopperChunkColumns(int nPad) { return nPad <= 16 ? 16 : nPad <= 32 ? 32 : nPad <= 48 ? 48 : 64; }

// Calls f(rows, k0, kLen) for the weight chunks of a GEMM in streaming order: column blocks of
// hopperChunkColumns(nPad) (the last may have fewer rows), each split into K segments of 256.
// (host and device: f is a host lambda in the packing code, a device one in the kernel)
#pragma nv_exec_check_disable
template <typename F>
__host__ __device__ inline void forEachHopperChunk(int nPad, int kPad, F&& f) {
  const int nc = hopperChunkColumns(nPad);
  for (int j0 = 0; j0 < nPad; j0 += nc)
    for (int k0 = 0; k0 < kPad; k0 += kHopperKSegment)
      f(nPad - j0 < nc ? nPad - j0 : nc, k0, kPad - k0 < kHopperKSegment ? kPad - k0 : kHopperKSegment);
}

// The GEMM weights ([nPad][kPad] fp16 in MlpProgram::halfWeights) packed chunk by chunk
// (forEachHopperChunk) in the wgmma no-swizzle K-major layout: core matrices of 8 output rows x
// 8 k (128 contiguous bytes), the kLen/8 core matrices of an 8-row group next to each other
// (leading byte offset 128 between the two k halves of a k16 step), 8-row groups kLen*16 bytes
// apart (stride byte offset). offsets[i] = instruction i's first chunk (halves).
inline std::vector<std::uint16_t> packHopperWeights(const MlpProgram& prog, int* offsets, int maxInstrs) {
  std::vector<std::uint16_t> packed;
  for (std::size_t i = 0; i < prog.instrs.size() && i < std::size_t(maxInstrs); ++i) {
    const MlpInstr& in = prog.instrs[i];
    offsets[i] = 0;
    if (in.op != MlpOp::Gemm || in.fusedIntoPrevious) continue;
    offsets[i] = int(packed.size());
    int j0 = 0, lastK0 = -1;
    forEachHopperChunk(in.nPad, in.kPad, [&](int rows, int k0, int kLen) {
      if (k0 <= lastK0) j0 += hopperChunkColumns(in.nPad);  // the next column block
      lastK0 = k0;
      const std::size_t at = packed.size();
      packed.resize(at + std::size_t(rows) * kLen, 0);
      for (int r = 0; r < rows; ++r)
        for (int k = 0; k < kLen; ++k)
          packed[at + std::size_t(r / 8) * (kLen * 8) + (k / 8) * 64 + (r % 8) * 8 + (k % 8)] =
              prog.halfWeights[in.halfOffset + std::int64_t(j0 + r) * in.kPad + k0 + k];
    });
  }
  return packed;
}

// Halves of a ring slot: the largest chunk.
inline int hopperStageHalves(const MlpProgram& prog) {
  int halves = 16 * 16;
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious)
      forEachHopperChunk(in.nPad, in.kPad, [&](int rows, int, int kLen) { halves = std::max(halves, rows * kLen); });
  return halves;
}

// The most chunks of one GEMM layer (a ping-pong turn needs them all in the ring).
inline int hopperMaxChunks(const MlpProgram& prog) {
  int most = 1;
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) {
      int chunks = 0;
      forEachHopperChunk(in.nPad, in.kPad, [&](int, int, int) { ++chunks; });
      most = std::max(most, chunks);
    }
  return most;
}

// Dynamic shared memory of the Hopper kernel: the ring, then per consumer its activation
// buffers (64 rows each) and coordinates, then the final dot's weights.
__host__ __device__ inline int hopperActHalves(const FusedParams& P) {
  int halves = 0;
  for (int b = 0; b < P.hopperNumBuffers; ++b) halves += kHopperRows * P.hopperBufferLd[b];
  return (halves + 63) / 64 * 64;  // keeps every consumer region 128-byte aligned
}
__host__ __device__ inline std::size_t hopperSharedBytes(int stages, const FusedParams& P) {
  return std::size_t(stages) * P.hopperStageHalves * 2 +
         std::size_t(kHopperConsumers) * (std::size_t(hopperActHalves(P)) * 2 + kHopperRows * 4 * 4) +
         MlpProgram::kMaxFusedGemmOut * 4;
}

// Shared-memory matrix descriptor, no swizzle: start address, leading byte offset (between the
// two k-halves of a k16 step), stride byte offset (between 8-row groups), all in 16-byte units.
__device__ inline std::uint64_t wgmmaDescriptor(unsigned smemByteAddress, unsigned leadingBytes, unsigned strideBytes) {
  return std::uint64_t((smemByteAddress & 0x3FFFF) >> 4) | (std::uint64_t(leadingBytes >> 4) << 16) |
         (std::uint64_t(strideBytes >> 4) << 32);
}

#if INR_HAVE_WGMMA
__device__ inline void wgmmaFence() { asm volatile("wgmma.fence.sync.aligned;\n" ::: "memory"); }
__device__ inline void wgmmaCommit() { asm volatile("wgmma.commit_group.sync.aligned;\n" ::: "memory"); }
template <int PENDING>
__device__ inline void wgmmaWait() {
  asm volatile("wgmma.wait_group.sync.aligned %0;\n" ::"n"(PENDING) : "memory");
}
__device__ inline void mbarrierInit(std::uint64_t* bar, unsigned count) {
  asm volatile("mbarrier.init.shared::cta.b64 [%0], %1;\n" ::"r"(smemAddress(bar)), "r"(count) : "memory");
}
// Makes the initialised barriers visible to the async proxy (the bulk copies complete on them).
__device__ inline void fenceBarrierInit() { asm volatile("fence.mbarrier_init.release.cluster;\n" ::: "memory"); }
__device__ inline void mbarrierArrive(std::uint64_t* bar) {
  asm volatile("{\n.reg .b64 state;\nmbarrier.arrive.shared::cta.b64 state, [%0];\n}\n" ::"r"(smemAddress(bar)) : "memory");
}
__device__ inline void mbarrierArriveExpectTx(std::uint64_t* bar, unsigned bytes) {
  asm volatile("{\n.reg .b64 state;\nmbarrier.arrive.expect_tx.shared::cta.b64 state, [%0], %1;\n}\n" ::"r"(smemAddress(bar)),
               "r"(bytes)
               : "memory");
}
// Waits until the barrier's phase of the given parity has completed.
__device__ inline void mbarrierWait(std::uint64_t* bar, unsigned parity) {
  asm volatile(
      "{\n.reg .pred done;\nWAIT:\n"
      "mbarrier.try_wait.parity.shared::cta.b64 done, [%0], %1;\n"
      "@!done bra WAIT;\n}\n" ::"r"(smemAddress(bar)),
      "r"(parity)
      : "memory");
}
// One bulk copy global -> shared, completing `bytes` transactions on `bar`.
__device__ inline void bulkCopyToShared(void* dst, const void* src, unsigned bytes, std::uint64_t* bar) {
  asm volatile("cp.async.bulk.shared::cluster.global.mbarrier::complete_tx::bytes [%0], [%1], %2, [%3];\n" ::"r"(
                   smemAddress(dst)),
               "l"(src), "r"(bytes), "r"(smemAddress(bar))
               : "memory");
}
__device__ inline void namedBarrierSync(int id, int threads) { asm volatile("bar.sync %0, %1;\n" ::"r"(id), "r"(threads) : "memory"); }
__device__ inline void namedBarrierArrive(int id, int threads) {
  asm volatile("bar.arrive %0, %1;\n" ::"r"(id), "r"(threads) : "memory");
}
template <int REGS>
__device__ inline void setMaxRegistersDec() {
  asm volatile("setmaxnreg.dec.sync.aligned.u32 %0;\n" ::"n"(REGS));
}
template <int REGS>
__device__ inline void setMaxRegistersInc() {
  asm volatile("setmaxnreg.inc.sync.aligned.u32 %0;\n" ::"n"(REGS));
}

// d(64 x N, f32, this thread's N/2 fragment values) += A(64 x 16, f16 registers) * B(16 x N, f16
// shared memory via desc), issued by the whole warpgroup.
template <int N>
__device__ inline void wgmmaRS(float (&d)[N / 2], const unsigned (&a)[4], std::uint64_t desc) {
  if constexpr (N == 16) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %13, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n16k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7}, {%8, %9, %10, %11}, %12, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 32) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %21, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n32k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15}, {%16, %17, %18, %19}, %20, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 48) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %29, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n48k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23}, {%24, %25, %26, %27}, %28, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 64) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %37, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n64k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31}, {%32, %33, %34, %35}, %36, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23]),
          "+f"(d[24]), "+f"(d[25]), "+f"(d[26]), "+f"(d[27]), "+f"(d[28]), "+f"(d[29]), "+f"(d[30]), "+f"(d[31])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  }
}
#endif  // INR_HAVE_WGMMA

// Named barriers: 1 + c = consumer c's own (128 threads); 3 + c = consumer c's turn to issue a
// GEMM (256 threads: c waits, the other consumer arrives). 0 is __syncthreads.
constexpr int kConsumerBarrier = 1, kTurnBarrier = 3;

__global__ void __launch_bounds__(kHopperThreads, 1) hopperMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                                   const unsigned* __restrict__ deviceCount,
                                                                   float* __restrict__ out, const int* __restrict__ scatter) {
#if INR_HAVE_WGMMA
  if (deviceCount) n = min(n, int(*deviceCount));
  constexpr int KSTEPS = kHopperKSegment / 16;
  extern __shared__ __align__(1024) unsigned char smem[];
  __shared__ MlpInstr program[kMaxFusedInstrs];
  __shared__ int bufferStart[kMaxBuffers], bufferLd[kMaxBuffers];
  __shared__ alignas(8) std::uint64_t fullBar[kHopperMaxStages], emptyBar[kHopperMaxStages];
  const int stages = P.hopperStages;
  const int stageHalves = P.hopperStageHalves;
  __half* const ring = reinterpret_cast<__half*>(smem);
  const int actHalves = hopperActHalves(P);
  unsigned char* const consumerBase = smem + std::size_t(stages) * stageHalves * 2;
  const std::size_t consumerBytes = std::size_t(actHalves) * 2 + kHopperRows * 4 * 4;
  float* const dotWeights = reinterpret_cast<float*>(consumerBase + kHopperConsumers * consumerBytes);
  for (int i = threadIdx.x; i < P.numInstrs; i += kHopperThreads) program[i] = P.hopperInstrs[i];
  for (int ip = 0; ip < P.numInstrs; ++ip)
    if (P.hopperInstrs[ip].dotNext)
      for (int c = threadIdx.x; c < P.hopperInstrs[ip].nPad; c += kHopperThreads)
        dotWeights[c] = P.floatWeights[P.hopperInstrs[ip].dotOffset + c];
  if (threadIdx.x == 0) {
    int at = 0;
    for (int b = 0; b < kMaxBuffers; ++b) {
      bufferStart[b] = at;
      bufferLd[b] = P.hopperBufferLd[b];
      if (b < P.hopperNumBuffers) at += kHopperRows * P.hopperBufferLd[b];
    }
    for (int s = 0; s < stages; ++s) {
      mbarrierInit(&fullBar[s], 1);                      // the producer's arrive (+ the copy's bytes)
      mbarrierInit(&emptyBar[s], 4 * kHopperConsumers);  // one arrive per consumer warp
    }
    fenceBarrierInit();
  }
  __syncthreads();  // the last block-wide barrier: the producer leaves early

  const int numTiles = (n + kHopperRows - 1) / kHopperRows;
  const int numRounds = (numTiles + kHopperConsumers - 1) / kHopperConsumers;
  const int wg = threadIdx.x / 128;
  if (wg == 0) {
    setMaxRegistersDec<kHopperProducerRegisters>();
    if (threadIdx.x != 0) return;
    int slot = 0;
    unsigned phase = 0;
    for (int round = blockIdx.x; round < numRounds; round += gridDim.x)
      for (int ip = 0; ip < P.numInstrs; ++ip) {
        const MlpInstr& in = program[ip];
        if (in.op != MlpOp::Gemm || in.fusedIntoPrevious) continue;
        const __half* from = P.hopperWeights + P.hopperOffset[ip];
        forEachHopperChunk(in.nPad, in.kPad, [&](int rows, int, int kLen) {
          const unsigned halves = unsigned(rows * kLen);
          mbarrierWait(&emptyBar[slot], phase ^ 1u);  // a fresh barrier counts as released
          mbarrierArriveExpectTx(&fullBar[slot], halves * 2);
          bulkCopyToShared(ring + std::size_t(slot) * stageHalves, from, halves * 2, &fullBar[slot]);
          from += halves;
          if (++slot == stages) slot = 0, phase ^= 1u;
        });
      }
    return;
  }
  setMaxRegistersInc<kHopperConsumerRegisters>();

  const int c = wg - 1;
  const int tid = threadIdx.x - 128 * wg;
  const int warp = tid >> 5, lane = tid & 31;
  const int g = lane >> 2, t4 = lane & 3;  // mma fragment coordinates
  const int rowBase = warp * 16;           // this warp's rows of the consumer tile
  __half* const act = reinterpret_cast<__half*>(consumerBase + c * consumerBytes);
  float* const coords = reinterpret_cast<float*>(consumerBase + c * consumerBytes + std::size_t(actHalves) * 2);
  auto consumerSync = [&]() { namedBarrierSync(kConsumerBarrier + c, 128); };
  // Ping-pong turns: GEMM layers whose chunks all fit in the ring; the last such layer of the
  // block's last round, after which consumer 1 gives no turn (nobody would take it).
  int lastOrdered = -1;
  if (P.hopperPingPong)
    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr& in = program[ip];
      int chunks = 0;
      if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) {
        forEachHopperChunk(in.nPad, in.kPad, [&](int, int, int) { ++chunks; });
        if (chunks <= stages) lastOrdered = ip;
      }
    }
  if (lastOrdered >= 0 && c == 1 && int(blockIdx.x) < numRounds) namedBarrierArrive(kTurnBarrier + 0, 256);

  int slot = 0;
  unsigned phase = 0;
  for (int round = blockIdx.x; round < numRounds; round += gridDim.x) {
    const int base = (round * kHopperConsumers + c) * kHopperRows;
    const int rows = max(0, min(kHopperRows, n - base));  // 0: this consumer only keeps the pace
    for (int r = tid; r < kHopperRows; r += 128) {
      const float4 p = r < rows ? points[base + r] : make_float4(0.f, 0.f, 0.f, 0.f);
      const float w[4] = {p.x, p.y, p.z, p.w};
#pragma unroll
      for (int i = 0; i < 4; ++i) coords[r * 4 + i] = i < P.inputDim ? P.inScale[i] * w[P.inputCoord[i]] + P.inOffset[i] : 0.f;
    }
    consumerSync();
    const bool lastRound = round + int(gridDim.x) >= numRounds;
    const RowTile view{act, bufferStart, bufferLd, coords, rows, base};
    for (int ip = 0; ip < P.numInstrs; ++ip) {
      const MlpInstr in = program[ip];
      if (in.fusedIntoPrevious || in.fusedIntoNext) continue;
      if (in.op != MlpOp::Gemm) {
        runRowInstr<kHopperRows, 128>(P, in, view, tid, points, out, scatter);
        consumerSync();
        continue;
      }
      const int kSegments = (in.kPad + kHopperKSegment - 1) / kHopperKSegment;
      const bool ordered = lastOrdered >= 0 && (in.nPad + hopperChunkColumns(in.nPad) - 1) / hopperChunkColumns(in.nPad) * kSegments <= stages;
      const bool giveTurn = ordered && !(c == 1 && lastRound && ip == lastOrdered);
      const float* bias = P.floatWeights + in.biasOffset;
      const int ldSrc = in.src >= 0 ? bufferLd[in.src] : 0;
      const __half* src = in.src >= 0 ? act + bufferStart[in.src] : nullptr;
      const int fourier = in.fourierInput;
      __half* const dst = in.dst >= 0 ? act + bufferStart[in.dst] : nullptr;
      const int ldDst = in.dst >= 0 ? bufferLd[in.dst] : 0;
      const __half* const other = in.other >= 0 ? act + bufferStart[in.other] : nullptr;
      const int ldOther = in.other >= 0 ? bufferLd[in.other] : 0;
      auto gemm = [&](auto nTag, auto actTag, auto residualTag) __attribute__((always_inline)) {
        constexpr int NC = decltype(nTag)::value;
        constexpr MlpAct kAct = decltype(actTag)::value;
        constexpr bool kResidual = decltype(residualTag)::value;
        const int numChunks = (in.nPad + NC - 1) / NC;
        const unsigned aAddr =
            src ? smemAddress(src + (rowBase + ((lane >> 3) & 1) * 8 + (lane & 7)) * ldSrc + (lane >> 4) * 8) : 0u;
        const unsigned ringBase = smemAddress(ring);
        // A: K columns k0 .. k0 + kLen of this warp's 16 rows, by ldmatrix from the buffer or as
        // the Fourier encoding computed for this thread's fragment (rows g, g+8; columns
        // 2*t4 + {0,1} + {0,8} of each k16 step).
        unsigned a[KSTEPS][4];
        auto loadA = [&](int k0, int kLen) {
#pragma unroll
          for (int ks = 0; ks < KSTEPS; ++ks) {
            if (ks * 16 >= kLen) continue;
            if (fourier < 0) {
              ldmatrixX4(a[ks], aAddr + unsigned((k0 + ks * 16) * 2));
            } else {
              const MlpInstr& f = program[fourier];
              const int kb = k0 + ks * 16 + 2 * t4;
#pragma unroll
              for (int q = 0; q < 4; ++q) {  // a[q]: row g + 8*(q&1), columns kb + 8*(q>>1) + {0,1}
                const float* x = coords + (rowBase + g + 8 * (q & 1)) * 4;
                const int k = kb + 8 * (q >> 1);
                const __half2 h = __floats2half2_rn(fourierElement(P, f, x, k), fourierElement(P, f, x, k + 1));
                a[ks][q] = *reinterpret_cast<const unsigned*>(&h);
              }
            }
          }
        };
        if (kSegments == 1) loadA(0, in.kPad);  // before any wait: overlaps the weights' arrival
        float part[2] = {0.f, 0.f};  // the final dot's partial sums (rows g, g+8)
        int prevSlot = -1;
        // Chunk j into acc: accumulators start at the bias (fragment i: row g + 8*((i>>1)&1),
        // column j*NC + 8*(i>>2) + 2*t4 + (i&1)), then one wgmma per k16 step per K segment.
        auto issue = [&](float (&acc)[NC / 2], int j) __attribute__((always_inline)) {
#pragma unroll
          for (int i = 0; i < NC / 2; ++i) {
            const int col = j * NC + 8 * (i >> 2) + 2 * t4 + (i & 1);
            acc[i] = col < in.nPad ? bias[col] : 0.f;
          }
          for (int s = 0; s < kSegments; ++s) {
            const int k0 = s * kHopperKSegment, kLen = min(kHopperKSegment, in.kPad - k0);
            if (kSegments > 1) {  // K > 256: A per segment; its registers are free once all MMAs are done
              wgmmaWait<0>();
              if (prevSlot >= 0 && lane == 0) mbarrierArrive(&emptyBar[prevSlot]);
              prevSlot = -1;
              loadA(k0, kLen);
            }
            mbarrierWait(&fullBar[slot], phase);
            wgmmaFence();
            const unsigned chunkBase = ringBase + unsigned(slot * stageHalves * 2);
#pragma unroll
            for (int ks = 0; ks < KSTEPS; ++ks)
              if (ks * 16 < kLen) wgmmaRS<NC>(acc, a[ks], wgmmaDescriptor(chunkBase + ks * 256, 128, kLen * 16));
            wgmmaCommit();
            if (s + 1 < kSegments) {
              wgmmaWait<0>();
              if (lane == 0) mbarrierArrive(&emptyBar[slot]);
            } else {
              wgmmaWait<1>();  // the previous chunk's MMAs are done: its slot and accumulators are free
              if (prevSlot >= 0 && lane == 0) mbarrierArrive(&emptyBar[prevSlot]);
              prevSlot = slot;
            }
            if (++slot == stages) slot = 0, phase ^= 1u;
          }
        };
        // Chunk j's epilogue from acc: act(acc) [+ residual] to fp16 in dst, or into the final
        // dot, or (finalOutput) column 0 straight to the output.
        auto epilogue = [&](float (&acc)[NC / 2], int j) __attribute__((always_inline)) {
          if (in.finalOutput) {  // column 0 (t4 0, chunk 0): fragments 0 (row g) and 2 (row g+8)
            if (t4 == 0 && j == 0) {
#pragma unroll
              for (int half = 0; half < 2; ++half) {
                const int row = rowBase + g + half * 8;
                if (row < rows) {
                  const float net = applyActivation(in.act, acc[2 * half]);
                  float a, b;
                  outputAffine(P.output, points[base + row].w, a, b);
                  const int q = base + row;
                  out[scatter ? scatter[q] : q] = a * net + b;
                }
              }
            }
            return;
          }
#pragma unroll
          for (int jj = 0; jj < NC / 8; ++jj) {
            const int col = j * NC + 8 * jj + 2 * t4;
            if (j * NC + 8 * jj >= in.nPad) continue;
#pragma unroll
            for (int half = 0; half < 2; ++half) {
              float v0 = applyActivation(kAct, acc[4 * jj + 2 * half]);
              float v1 = applyActivation(kAct, acc[4 * jj + 2 * half + 1]);
              if (kAct == MlpAct::Sigmoid) {  // sigmoid(0) != 0: keep padding columns zero
                if (col >= in.outWidth) v0 = 0.f;
                if (col + 1 >= in.outWidth) v1 = 0.f;
              }
              const int row = rowBase + g + 8 * half;
              if constexpr (kResidual) {
                const float2 o = ldsHalf2AsFloat2InPlace(other + row * ldOther + col);
                v0 = in.combineScale * (v0 + o.x);
                v1 = in.combineScale * (v1 + o.y);
              }
              if (in.dotNext) {
                const float2 w = ldsFloat2InPlace(dotWeights + col);
                part[half] = fmaf(v0, w.x, fmaf(v1, w.y, part[half]));
              } else {
                *reinterpret_cast<__half2*>(dst + row * ldDst + col) = __floats2half2_rn(v0, v1);
              }
            }
          }
        };
        if (ordered) namedBarrierSync(kTurnBarrier + c, 256);
        float accEven[NC / 2], accOdd[NC / 2];
        // Iteration j issues chunk j (if any) and finishes chunk j - 1 while chunk j runs.
        for (int j = 0; j <= numChunks; ++j) {
          if (j < numChunks) {
            if (j & 1)
              issue(accOdd, j);
            else
              issue(accEven, j);
            if (j + 1 == numChunks && giveTurn) namedBarrierArrive(kTurnBarrier + (1 - c), 256);
          } else {
            wgmmaWait<0>();
            if (lane == 0) mbarrierArrive(&emptyBar[prevSlot]);
          }
          if (j > 0) {
            if ((j - 1) & 1)
              epilogue(accOdd, j - 1);
            else
              epilogue(accEven, j - 1);
          }
        }
        if (in.dotNext) {  // this warp holds every column of its 16 rows: reduce over the quad
          const MlpInstr& fin = program[ip + 1];
          const float dotBias = P.floatWeights[fin.biasOffset];
#pragma unroll
          for (int half = 0; half < 2; ++half) {
            float v = part[half];
            v += __shfl_xor_sync(0xffffffffu, v, 1);
            v += __shfl_xor_sync(0xffffffffu, v, 2);
            const int row = rowBase + g + 8 * half;
            if (t4 == 0 && row < rows) {
              const float net = applyActivation(fin.act, v + dotBias);
              float a, b;
              outputAffine(P.output, points[base + row].w, a, b);
              const int q = base + row;
              out[scatter ? scatter[q] : q] = a * net + b;
            }
          }
        }
      };
      auto withWidth = [&](auto actTag, auto residualTag) {
        switch (hopperChunkColumns(in.nPad)) {  // the same for the whole consumer
          case 16: gemm(IntTag<16>{}, actTag, residualTag); break;
          case 32: gemm(IntTag<32>{}, actTag, residualTag); break;
          case 48: gemm(IntTag<48>{}, actTag, residualTag); break;
          default: gemm(IntTag<64>{}, actTag, residualTag); break;
        }
      };
      dispatchActivation(in.act, [&](auto A) {
        if (other)
          withWidth(A, BoolTag<true>{});
        else
          withWidth(A, BoolTag<false>{});
      });
      consumerSync();
    }
  }
#else
  (void)P, (void)points, (void)n, (void)deviceCount, (void)out, (void)scatter;
#endif
}

}  // namespace inr::cuda
