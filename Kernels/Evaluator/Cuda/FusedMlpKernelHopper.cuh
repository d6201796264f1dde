#pragma once
// The fused kernel on Hopper (sm_90a): warp-specialised, warpgroup MMA.
//
// A block is a producer warpgroup and one or two consumers (hopperThreads below; the register
// hand-over described here is the two-consumer block's). Warpgroup 0 is the producer:
// one thread streams every GEMM's
// weights, chunk after chunk in program order, into a ring of `stages` shared-memory slots with
// the bulk copy engine (cp.async.bulk, one copy per chunk: the weights are pre-packed chunk by
// chunk in the wgmma core-matrix layout), each slot guarded by a "full" mbarrier (the copy's
// bytes complete it) and an "empty" one (the consumers' warps arrive once their wgmma has read
// it). It gives its registers away (setmaxnreg.dec) to the consumers, warpgroups 1 and 2
// (setmaxnreg.inc), which each run the whole program on their own tile of 64 queries: a warp
// owns 16 rows and every column of them, so a consumer synchronises only with itself (named
// barrier) and the final dot product reduces within a quad. (Two consumers may instead share one
// tile, splitting its column chunks: "Columns split" below.)
// GEMM layers: A (the layer's input, K <= 256) goes to registers once per layer (ldmatrix from
// the row-major buffer, or the Fourier encoding computed in place); the weights arrive in chunks
// of 64 or 128 output columns (autotuned) x all K (one chunk per segment of 256 for wider K); a
// chunk's MMAs (m64n64k16 / m64n128k16, the first overwriting the accumulators) complete, then its epilogue (bias,
// sine/SiLU, residual, fp16 store or the final dot) runs while the other consumer's MMAs keep
// the tensor cores busy. (Overlapping within a warpgroup, with a second accumulator set in
// flight, makes ptxas serialise every wgmma of the kernel: C7514/C7515 for non-wgmma reads or
// writes of accumulators between a wgmma and its wait; copying them out first costs moves in
// every chunk and measured slower: Benchmarks/RESULTS.md, "Hopper kernel in column chunks".) A warp's GEMM reads only its own 16 rows, all of them before its
// epilogues write them: a GEMM may write over its input (MlpProgram::withGemmsInPlace(
// kHopperKSegment): one activation buffer for SIREN and FFN), and consecutive GEMM layers need
// no barrier between the consumer's warps (with the columns split, a barrier of both consumers
// after each GEMM's A is loaded and after its epilogues).
// Ping-pong (optional, autotuned): the consumers take turns issuing a chunk's MMAs (named
// barriers), so one's epilogue runs while the other's MMAs keep the tensor cores busy.
// A block of one consumer (hopperThreads below) runs the same code without turns.
// Columns split (optional, autotuned; hopperConsumer's COLUMNS): the two consumers run one tile
// together, consumer c taking the column chunks j with j % 2 == c and releasing the other's ring
// slots once full, so a small batch's single tile per block has two epilogues overlapping each
// other's MMAs; consumer 0 alone loads the coordinates, both run the row-wise instructions
// together (256 threads), and a final dot's halves meet in shared memory.
// A Fourier encoding of the coordinates (the FFN) runs in one of three forms (autotuned,
// CudaEvaluatorOptions::storedEncoding): fused, computed in the first GEMM's operand load for
// every weight chunk (no buffer); stored, written once per tile by the row instruction into a
// buffer the GEMM loads like any layer's input (a K > 256 GEMM is then not in place: the paper
// FFN's 512-wide buffer and its 256-wide output fit one-consumer blocks only); or split
// (FusedParams::hopperSplitGemm, its own kernel instantiation), for K 257..512: the first 256
// columns written in the core-matrix layout into a per-consumer operand region that the MMAs read
// from shared memory (wgmmaSS), the rest row-major into the GEMM's buffer, which the GEMM holds in
// registers for all its chunks and then overwrites with its output (in place).

// One instruction shape and one epilogue per activation keep the kernel small: ptxas compiles
// it quickly (a variant with 48 shape x activation x residual instantiations took many times
// longer; compile times in Benchmarks/RESULTS.md), and the instruction cache holds it.
// ptxas allocates registers for the kernel's launch bound (65536 / 384 threads, rounded down to
// a multiple of 8: 168) whatever
// setmaxnreg later grants, so the consumer's working set is sized for 168: A 64, accumulators
// 32 or 64. (A block of one consumer, 256 threads, has 255 per thread and no setmaxnreg.)
// The wgmma/mbarrier/bulk-copy instructions exist only in sm_90a code (__CUDA_ARCH_FEAT_SM90_ALL);
// other targets compile the kernel body away and the host never launches it there (it asks the
// loaded code with hopperKernel() and cudaFuncGetAttributes).
// This header holds the layout the host prepares (packed weights, ring and shared-memory sizes)
// and the device primitives; the kernel itself is FusedMlpKernelHopper.cu (one translation unit,
// built for sm_90a only).
#include <cuda_fp16.h>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "Evaluator/Cuda/FusedMlpDevice.cuh"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/MlpProgram.h"

namespace inr::cuda {

#if defined(__CUDA_ARCH__) && defined(__CUDA_ARCH_FEAT_SM90_ALL)
#define INR_HAVE_WGMMA 1
#else
#define INR_HAVE_WGMMA 0
#endif

// Consumer warpgroups per block: two (their turns overlap one's epilogue with the other's
// MMAs: the throughput choice), or one (64 queries per round, so a small batch spreads over twice
// the blocks: the pipeline's late iterations hold a few thousand queries, and 128-query rounds
// leave half the SMs idle there), or two on one 64-query tile with its columns split (as many
// blocks as one consumer, two warpgroups each). The autotuner times them all (FusedLaunchAutotuner).
__host__ __device__ constexpr int hopperThreads(int consumers) { return 128 * (1 + consumers); }
constexpr int kHopperRows = 64;  // queries per consumer tile (wgmma's M)
constexpr int kHopperMaxStages = 8;
constexpr int kHopperChunkWidths[2] = {64, 128};  // output columns per weight chunk (wgmma's N), autotuned
constexpr int kHopperBiasPad = 128;               // each GEMM's biases padded to whole chunks of either width
__host__ __device__ constexpr int chunkIndex(int nc) { return nc == 64 ? 0 : 1; }
constexpr int kHopperKSegment = 256;     // K columns of A held in registers (64 per thread)
// setmaxnreg budgets (multiples of 8): 128 x 40 + 256 x 232 = 64512 of the SM's 65536.
constexpr int kHopperProducerRegisters = 40, kHopperConsumerRegisters = 232;

// Calls f(rows, k0, kLen) for the weight chunks of a GEMM in streaming order: column blocks of
// nc (the last may have fewer rows), each split into K segments of 256.
// (host and device: f is a host lambda in the packing code, a device one in the kernel)
#pragma nv_exec_check_disable
template <typename F>
__host__ __device__ inline void forEachHopperChunk(int nc, int nPad, int kPad, F&& f) {
  for (int j0 = 0; j0 < nPad; j0 += nc)
    for (int k0 = 0; k0 < kPad; k0 += kHopperKSegment)
      f(nPad - j0 < nc ? nPad - j0 : nc, k0, kPad - k0 < kHopperKSegment ? kPad - k0 : kHopperKSegment);
}

__host__ __device__ inline bool isStreamedGemm(const MlpInstr& in) { return in.op == MlpOp::Gemm && !in.fusedIntoPrevious; }

// The GEMM weights ([nPad][kPad] fp16 in MlpProgram::halfWeights) packed chunk by chunk
// (forEachHopperChunk) in the wgmma no-swizzle K-major layout: core matrices of 8 output rows x
// 8 k (128 contiguous bytes), the kLen/8 core matrices of an 8-row group next to each other
// (leading byte offset 128 between the two k halves of a k16 step), 8-row groups kLen*16 bytes
// apart (stride byte offset). offsets[i] = instruction i's first chunk (halves).
inline std::vector<std::uint16_t> packHopperWeights(const MlpProgram& prog, int nc, int* offsets, int maxInstrs) {
  std::vector<std::uint16_t> packed;
  for (std::size_t i = 0; i < prog.instrs.size() && i < std::size_t(maxInstrs); ++i) {
    const MlpInstr& in = prog.instrs[i];
    offsets[i] = 0;
    if (!isStreamedGemm(in)) continue;
    offsets[i] = int(packed.size());
    int j0 = -nc;
    forEachHopperChunk(nc, in.nPad, in.kPad, [&](int rows, int k0, int kLen) {
      if (k0 == 0) j0 += nc;  // the next column block
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

// Halves of a ring slot: nc rows of the widest K segment (wgmma reads nc rows of B; past a
// narrow layer's rows it reads what the slot held before and the columns fed are discarded).
inline int hopperStageHalves(const MlpProgram& prog, int nc) {
  int halves = nc * 16;
  for (const MlpInstr& in : prog.instrs)
    if (isStreamedGemm(in)) forEachHopperChunk(nc, in.nPad, in.kPad, [&](int, int, int kLen) { halves = std::max(halves, nc * kLen); });
  return halves;
}

// The GEMMs' biases in shared memory: starts[i] = instruction i's first (floats), each padded
// with zeros to whole chunks so a chunk's accumulators load them without a bounds check.
// Returns the floats in all.
inline int hopperBiasLayout(const MlpProgram& prog, int* starts, int maxInstrs) {
  int at = 0;
  for (std::size_t i = 0; i < prog.instrs.size() && i < std::size_t(maxInstrs); ++i) {
    starts[i] = at;
    if (isStreamedGemm(prog.instrs[i]))
      at += (prog.instrs[i].nPad + kHopperBiasPad - 1) / kHopperBiasPad * kHopperBiasPad;
  }
  return at;
}

// Dynamic shared memory of the Hopper kernel: the ring, then per tile region (one per consumer,
// or one for two with the columns split: hopperTileRegions) its activation buffers (64 rows
// each), a split encoding's operand (hopperSplitHalves) and coordinates, then the final dot's
// weights and the biases.
__host__ __device__ inline int hopperActHalves(const FusedParams& P) {
  int halves = 0;
  for (int b = 0; b < P.hopperNumBuffers; ++b) halves += kHopperRows * P.hopperBufferLd[b];
  return (halves + 63) / 64 * 64;  // keeps every consumer region 128-byte aligned
}
// A stored encoding split for its GEMM (FusedParams::hopperSplitGemm): its first K segment, 64
// rows x 256 columns in the wgmma core-matrix layout (the packed weights' layout, rows for
// output columns), per consumer.
__host__ __device__ inline int hopperSplitHalves(const FusedParams& P) {
  return P.hopperSplitGemm >= 0 ? kHopperRows * kHopperKSegment : 0;
}
// A consumer region's bytes from its activation and split-operand halves (the kernel passes the
// split's halves only in its split instantiation), then its rows' coordinates (float4 each).
__host__ __device__ constexpr std::size_t hopperConsumerBytes(int actHalves, int splitHalves) {
  return std::size_t(actHalves + splitHalves) * 2 + kHopperRows * 4 * 4;
}
__host__ __device__ inline std::size_t hopperConsumerBytes(const FusedParams& P) {
  return hopperConsumerBytes(hopperActHalves(P), hopperSplitHalves(P));
}
// Tiles in a block's shared memory: one per consumer, or one for both with their columns split.
__host__ __device__ constexpr int hopperTileRegions(int consumers, bool splitColumns) { return splitColumns ? 1 : consumers; }
__host__ __device__ inline std::size_t hopperSharedBytes(int nc, int stages, int tileRegions, const FusedParams& P) {
  return std::size_t(stages) * P.hopperStageHalves[chunkIndex(nc)] * 2 + std::size_t(tileRegions) * hopperConsumerBytes(P) +
         (MlpProgram::kMaxFusedGemmOut + std::size_t(P.hopperBiasFloats)) * 4;
}
// Halves from the start of a split operand to row r, column k (k < 256): core matrices of 8 rows
// x 8 columns (128 contiguous bytes), the 32 of an 8-row group next to each other.
__host__ __device__ constexpr int splitOperandIndex(int r, int k) {
  return (r >> 3) * (kHopperKSegment * 8) + (k >> 3) * 64 + (r & 7) * 8 + (k & 7);
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

// The accumulator operands of an m64nN wgmma ("+f" d[0] .. d[N/2 - 1]), for the asm blocks below.
#define INR_WGMMA_ACC8(d, i)                                                                              \
  "+f"(d[i]), "+f"(d[i + 1]), "+f"(d[i + 2]), "+f"(d[i + 3]), "+f"(d[i + 4]), "+f"(d[i + 5]), "+f"(d[i + 6]), \
      "+f"(d[i + 7])
#define INR_WGMMA_ACCUMULATORS_32(d) INR_WGMMA_ACC8(d, 0), INR_WGMMA_ACC8(d, 8), INR_WGMMA_ACC8(d, 16), INR_WGMMA_ACC8(d, 24)
#define INR_WGMMA_ACCUMULATORS_64(d) \
  INR_WGMMA_ACCUMULATORS_32(d), INR_WGMMA_ACC8(d, 32), INR_WGMMA_ACC8(d, 40), INR_WGMMA_ACC8(d, 48), INR_WGMMA_ACC8(d, 56)

// d(64 x N, f32, this thread's N/2 fragment values) = A(64 x 16, f16 registers) * B(16 x N, f16
// shared memory via desc) + (accumulate ? d : 0), issued by the whole warpgroup; N = 64 or 128.
template <int N>
__device__ inline void wgmmaRS(float (&d)[N / 2], const unsigned (&a)[4], std::uint64_t desc, int accumulate) {
  if constexpr (N == 64) {
    asm volatile(
          "{\n.reg .pred p;\nsetp.ne.b32 p, %37, 0;\n"
          "wgmma.mma_async.sync.aligned.m64n64k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31}, {%32, %33, %34, %35}, %36, p, 1, 1, 0;\n}\n"
          :
            INR_WGMMA_ACCUMULATORS_32(d)
          : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(accumulate));
  } else {
    asm volatile(
          "{\n.reg .pred p;\nsetp.ne.b32 p, %69, 0;\n"
          "wgmma.mma_async.sync.aligned.m64n128k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47, %48, %49, %50, %51, %52, %53, %54, %55, %56, %57, %58, %59, %60, %61, %62, %63}, {%64, %65, %66, %67}, %68, p, 1, 1, 0;\n}\n"
          :
            INR_WGMMA_ACCUMULATORS_64(d)
          : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(accumulate));
  }
}

// The same with A (64 x 16) from shared memory too (descA: K-major, no swizzle, the layout of
// splitOperandIndex), for a stored encoding's first K segment.
// The descriptors come as their 32-bit halves and the k step's offset OFF (16-byte units) as an
// immediate, added to both low halves in the asm: 64-bit descriptors for every k step, held at
// once, cost registers that the one-consumer kernels spilled.
template <int N, int OFF>
__device__ inline void wgmmaSS(float (&d)[N / 2], unsigned descALo, unsigned descAHi, unsigned descBLo, unsigned descBHi,
                               int accumulate) {
  if constexpr (N == 64) {
    asm volatile(
          "{\n.reg .pred p;\n.reg .b32 la, lb;\n.reg .b64 da, db;\nsetp.ne.b32 p, %36, 0;\nadd.s32 la, %32, %37;\nadd.s32 lb, %34, %37;\nmov.b64 da, {la, %33};\nmov.b64 db, {lb, %35};\n"
          "wgmma.mma_async.sync.aligned.m64n64k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31}, da, db, p, 1, 1, 0, 0;\n}\n"
          :
            INR_WGMMA_ACCUMULATORS_32(d)
          : "r"(descALo), "r"(descAHi), "r"(descBLo), "r"(descBHi), "r"(accumulate), "n"(OFF));
  } else {
    asm volatile(
          "{\n.reg .pred p;\n.reg .b32 la, lb;\n.reg .b64 da, db;\nsetp.ne.b32 p, %68, 0;\nadd.s32 la, %64, %69;\nadd.s32 lb, %66, %69;\nmov.b64 da, {la, %65};\nmov.b64 db, {lb, %67};\n"
          "wgmma.mma_async.sync.aligned.m64n128k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47, %48, %49, %50, %51, %52, %53, %54, %55, %56, %57, %58, %59, %60, %61, %62, %63}, da, db, p, 1, 1, 0, 0;\n}\n"
          :
            INR_WGMMA_ACCUMULATORS_64(d)
          : "r"(descALo), "r"(descAHi), "r"(descBLo), "r"(descBHi), "r"(accumulate), "n"(OFF));
  }
}

#undef INR_WGMMA_ACCUMULATORS_64
#undef INR_WGMMA_ACCUMULATORS_32
#undef INR_WGMMA_ACC8

// Orders this thread's generic-proxy shared-memory writes before later async-proxy reads (a
// wgmma reading an operand that threads stored; a barrier follows).
__device__ inline void fenceProxyAsyncShared() { asm volatile("fence.proxy.async.shared::cta;\n" ::: "memory"); }

// Keeps the compiler from moving reads of an accumulator above the wgmma wait that completes it
// (the asm of wgmma names the registers, the wait does not).
template <int M>
__device__ inline void fenceAccumulators(float (&d)[M]) {
#pragma unroll
  for (int i = 0; i < M; ++i) asm volatile("" : "+f"(d[i])::"memory");
}
#endif  // INR_HAVE_WGMMA

}  // namespace inr::cuda
