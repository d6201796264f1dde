#pragma once
// The fused kernel on Hopper (sm_90a): warp-specialised, warpgroup MMA.
//
// A block is three warpgroups. Warpgroup 0 is the producer: one thread streams every GEMM's
// weights, K-chunk after K-chunk in program order, into a ring of `stages` shared-memory slots
// with the bulk copy engine (cp.async.bulk, one copy per chunk: the weights are pre-packed chunk
// by chunk in the wgmma core-matrix layout), each slot guarded by a "full" mbarrier (the copy's
// bytes complete it) and an "empty" one (the consumers' warps arrive once their wgmma has read
// it). It gives its registers away (setmaxnreg.dec) to warpgroups 1 and 2, the consumers
// (setmaxnreg.inc), which each run the whole program on their own tile of 64 queries: a warp
// owns 16 rows and every column of them, so a consumer synchronises only with itself (named
// barrier), its epilogues write exactly the rows its own wgmma read (a GEMM may write over its
// input: MlpProgram::withGemmsInPlace, one activation buffer for SIREN and FFN), and the final
// dot product reduces within a quad. GEMM layers: A (activations) in registers, loaded with
// ldmatrix from the row-major buffer, or computed in place for a fused Fourier encoding; B (the
// weights) from the ring slot through a no-swizzle K-major descriptor; accumulators for all N
// columns (wgmma m64nNk16, N up to 256). Chunks pipeline: chunk c+1 is issued before chunk c is
// waited for (wgmma.wait_group 1), and a slot is released as soon as its wgmma completed.
// Ping-pong: the consumers take turns issuing a GEMM layer (named barriers), so one's
// activation epilogue (sine/SiLU: special-function bound) runs while the other's GEMM keeps the
// tensor cores busy. A turn covers a whole layer, so a layer's chunks must all fit in the ring
// (else the second consumer could never free a slot the first one waits for): layers with more
// chunks than slots run unordered.
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
// setmaxnreg budgets (multiples of 8): 128 x 40 + 256 x 232 = 64512 of the SM's 65536.
constexpr int kHopperProducerRegisters = 40, kHopperConsumerRegisters = 232;

// wgmma N for a GEMM of nPad output columns (the instruction shapes instantiated below).
__host__ __device__ constexpr int hopperColumns(int nPad) {
  return nPad <= 16 ? 16 : nPad <= 32 ? 32 : nPad <= 48 ? 48 : nPad <= 64 ? 64 : nPad <= 96 ? 96 : nPad <= 128 ? 128
                                                                                                : nPad <= 192 ? 192 : 256;
}

// The GEMM weights ([nPad][kPad] fp16 in MlpProgram::halfWeights) packed chunk by chunk in the
// wgmma no-swizzle K-major layout: per K-chunk of KC, core matrices of 8 output rows x 8 k (128
// contiguous bytes), the KC/8 core matrices of an 8-row group next to each other (leading byte
// offset 128 between the two k halves of a k16 step), 8-row groups KC*16 bytes apart (stride
// byte offset); zeros past kPad. offsets[i] = instruction i's start (halves).
inline std::vector<std::uint16_t> packHopperWeights(const MlpProgram& prog, int KC, int* offsets, int maxInstrs) {
  std::vector<std::uint16_t> packed;
  for (std::size_t i = 0; i < prog.instrs.size() && i < std::size_t(maxInstrs); ++i) {
    const MlpInstr& in = prog.instrs[i];
    offsets[i] = 0;
    if (in.op != MlpOp::Gemm || in.fusedIntoPrevious) continue;
    offsets[i] = int(packed.size());
    const int chunks = (in.kPad + KC - 1) / KC;
    for (int c = 0; c < chunks; ++c) {
      const std::size_t at = packed.size();
      packed.resize(at + std::size_t(in.nPad) * KC, 0);
      for (int r = 0; r < in.nPad; ++r)
        for (int k = 0; k < KC; ++k) {
          const int col = c * KC + k;
          if (col >= in.kPad) continue;
          packed[at + std::size_t(r / 8) * (KC * 8) + (k / 8) * 64 + (r % 8) * 8 + (k % 8)] =
              prog.halfWeights[in.halfOffset + std::int64_t(r) * in.kPad + col];
        }
    }
  }
  return packed;
}

// Rows of a ring slot: the widest GEMM's wgmma N (rows past a layer's nPad are read and the
// columns they feed discarded).
inline int hopperStageRows(const MlpProgram& prog) {
  int rows = 16;
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) rows = rows > hopperColumns(in.nPad) ? rows : hopperColumns(in.nPad);
  return rows;
}

// The most K-chunks of one GEMM layer (a ping-pong turn needs them all in the ring).
inline int hopperMaxChunks(const MlpProgram& prog, int KC) {
  int chunks = 1;
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) chunks = chunks > (in.kPad + KC - 1) / KC ? chunks : (in.kPad + KC - 1) / KC;
  return chunks;
}

// Dynamic shared memory of the Hopper kernel: the ring, then per consumer its activation
// buffers (64 rows each) and coordinates, then the final dot's weights.
__host__ __device__ inline int hopperActHalves(const FusedParams& P) {
  int halves = 0;
  for (int b = 0; b < P.hopperNumBuffers; ++b) halves += kHopperRows * P.hopperBufferLd[b];
  return (halves + 63) / 64 * 64;  // keeps every consumer region 128-byte aligned
}
__host__ __device__ inline std::size_t hopperSharedBytes(int KC, int stages, const FusedParams& P) {
  return std::size_t(stages) * P.hopperStageRows * KC * 2 +
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
  } else if constexpr (N == 96) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %53, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n96k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47}, {%48, %49, %50, %51}, %52, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23]),
          "+f"(d[24]), "+f"(d[25]), "+f"(d[26]), "+f"(d[27]), "+f"(d[28]), "+f"(d[29]), "+f"(d[30]), "+f"(d[31]),
          "+f"(d[32]), "+f"(d[33]), "+f"(d[34]), "+f"(d[35]), "+f"(d[36]), "+f"(d[37]), "+f"(d[38]), "+f"(d[39]),
          "+f"(d[40]), "+f"(d[41]), "+f"(d[42]), "+f"(d[43]), "+f"(d[44]), "+f"(d[45]), "+f"(d[46]), "+f"(d[47])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 128) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %69, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n128k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47, %48, %49, %50, %51, %52, %53, %54, %55, %56, %57, %58, %59, %60, %61, %62, %63}, {%64, %65, %66, %67}, %68, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23]),
          "+f"(d[24]), "+f"(d[25]), "+f"(d[26]), "+f"(d[27]), "+f"(d[28]), "+f"(d[29]), "+f"(d[30]), "+f"(d[31]),
          "+f"(d[32]), "+f"(d[33]), "+f"(d[34]), "+f"(d[35]), "+f"(d[36]), "+f"(d[37]), "+f"(d[38]), "+f"(d[39]),
          "+f"(d[40]), "+f"(d[41]), "+f"(d[42]), "+f"(d[43]), "+f"(d[44]), "+f"(d[45]), "+f"(d[46]), "+f"(d[47]),
          "+f"(d[48]), "+f"(d[49]), "+f"(d[50]), "+f"(d[51]), "+f"(d[52]), "+f"(d[53]), "+f"(d[54]), "+f"(d[55]),
          "+f"(d[56]), "+f"(d[57]), "+f"(d[58]), "+f"(d[59]), "+f"(d[60]), "+f"(d[61]), "+f"(d[62]), "+f"(d[63])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 192) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %101, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n192k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47, %48, %49, %50, %51, %52, %53, %54, %55, %56, %57, %58, %59, %60, %61, %62, %63, %64, %65, %66, %67, %68, %69, %70, %71, %72, %73, %74, %75, %76, %77, %78, %79, %80, %81, %82, %83, %84, %85, %86, %87, %88, %89, %90, %91, %92, %93, %94, %95}, {%96, %97, %98, %99}, %100, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23]),
          "+f"(d[24]), "+f"(d[25]), "+f"(d[26]), "+f"(d[27]), "+f"(d[28]), "+f"(d[29]), "+f"(d[30]), "+f"(d[31]),
          "+f"(d[32]), "+f"(d[33]), "+f"(d[34]), "+f"(d[35]), "+f"(d[36]), "+f"(d[37]), "+f"(d[38]), "+f"(d[39]),
          "+f"(d[40]), "+f"(d[41]), "+f"(d[42]), "+f"(d[43]), "+f"(d[44]), "+f"(d[45]), "+f"(d[46]), "+f"(d[47]),
          "+f"(d[48]), "+f"(d[49]), "+f"(d[50]), "+f"(d[51]), "+f"(d[52]), "+f"(d[53]), "+f"(d[54]), "+f"(d[55]),
          "+f"(d[56]), "+f"(d[57]), "+f"(d[58]), "+f"(d[59]), "+f"(d[60]), "+f"(d[61]), "+f"(d[62]), "+f"(d[63]),
          "+f"(d[64]), "+f"(d[65]), "+f"(d[66]), "+f"(d[67]), "+f"(d[68]), "+f"(d[69]), "+f"(d[70]), "+f"(d[71]),
          "+f"(d[72]), "+f"(d[73]), "+f"(d[74]), "+f"(d[75]), "+f"(d[76]), "+f"(d[77]), "+f"(d[78]), "+f"(d[79]),
          "+f"(d[80]), "+f"(d[81]), "+f"(d[82]), "+f"(d[83]), "+f"(d[84]), "+f"(d[85]), "+f"(d[86]), "+f"(d[87]),
          "+f"(d[88]), "+f"(d[89]), "+f"(d[90]), "+f"(d[91]), "+f"(d[92]), "+f"(d[93]), "+f"(d[94]), "+f"(d[95])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  } else if constexpr (N == 256) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %133, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n256k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15, %16, %17, %18, %19, %20, %21, %22, %23, %24, %25, %26, %27, %28, %29, %30, %31, %32, %33, %34, %35, %36, %37, %38, %39, %40, %41, %42, %43, %44, %45, %46, %47, %48, %49, %50, %51, %52, %53, %54, %55, %56, %57, %58, %59, %60, %61, %62, %63, %64, %65, %66, %67, %68, %69, %70, %71, %72, %73, %74, %75, %76, %77, %78, %79, %80, %81, %82, %83, %84, %85, %86, %87, %88, %89, %90, %91, %92, %93, %94, %95, %96, %97, %98, %99, %100, %101, %102, %103, %104, %105, %106, %107, %108, %109, %110, %111, %112, %113, %114, %115, %116, %117, %118, %119, %120, %121, %122, %123, %124, %125, %126, %127}, {%128, %129, %130, %131}, %132, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15]),
          "+f"(d[16]), "+f"(d[17]), "+f"(d[18]), "+f"(d[19]), "+f"(d[20]), "+f"(d[21]), "+f"(d[22]), "+f"(d[23]),
          "+f"(d[24]), "+f"(d[25]), "+f"(d[26]), "+f"(d[27]), "+f"(d[28]), "+f"(d[29]), "+f"(d[30]), "+f"(d[31]),
          "+f"(d[32]), "+f"(d[33]), "+f"(d[34]), "+f"(d[35]), "+f"(d[36]), "+f"(d[37]), "+f"(d[38]), "+f"(d[39]),
          "+f"(d[40]), "+f"(d[41]), "+f"(d[42]), "+f"(d[43]), "+f"(d[44]), "+f"(d[45]), "+f"(d[46]), "+f"(d[47]),
          "+f"(d[48]), "+f"(d[49]), "+f"(d[50]), "+f"(d[51]), "+f"(d[52]), "+f"(d[53]), "+f"(d[54]), "+f"(d[55]),
          "+f"(d[56]), "+f"(d[57]), "+f"(d[58]), "+f"(d[59]), "+f"(d[60]), "+f"(d[61]), "+f"(d[62]), "+f"(d[63]),
          "+f"(d[64]), "+f"(d[65]), "+f"(d[66]), "+f"(d[67]), "+f"(d[68]), "+f"(d[69]), "+f"(d[70]), "+f"(d[71]),
          "+f"(d[72]), "+f"(d[73]), "+f"(d[74]), "+f"(d[75]), "+f"(d[76]), "+f"(d[77]), "+f"(d[78]), "+f"(d[79]),
          "+f"(d[80]), "+f"(d[81]), "+f"(d[82]), "+f"(d[83]), "+f"(d[84]), "+f"(d[85]), "+f"(d[86]), "+f"(d[87]),
          "+f"(d[88]), "+f"(d[89]), "+f"(d[90]), "+f"(d[91]), "+f"(d[92]), "+f"(d[93]), "+f"(d[94]), "+f"(d[95]),
          "+f"(d[96]), "+f"(d[97]), "+f"(d[98]), "+f"(d[99]), "+f"(d[100]), "+f"(d[101]), "+f"(d[102]), "+f"(d[103]),
          "+f"(d[104]), "+f"(d[105]), "+f"(d[106]), "+f"(d[107]), "+f"(d[108]), "+f"(d[109]), "+f"(d[110]), "+f"(d[111]),
          "+f"(d[112]), "+f"(d[113]), "+f"(d[114]), "+f"(d[115]), "+f"(d[116]), "+f"(d[117]), "+f"(d[118]), "+f"(d[119]),
          "+f"(d[120]), "+f"(d[121]), "+f"(d[122]), "+f"(d[123]), "+f"(d[124]), "+f"(d[125]), "+f"(d[126]), "+f"(d[127])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  }
}
#endif  // INR_HAVE_WGMMA

// Named barriers: 1 + c = consumer c's own (128 threads); 3 + c = consumer c's turn to issue a
// GEMM (256 threads: c waits, the other consumer arrives). 0 is __syncthreads.
constexpr int kConsumerBarrier = 1, kTurnBarrier = 3;

template <int KC>
__global__ void __launch_bounds__(kHopperThreads, 1) hopperMlpKernel(FusedParams P, const float4* __restrict__ points, int n,
                                                                   const unsigned* __restrict__ deviceCount,
                                                                   float* __restrict__ out, const int* __restrict__ scatter) {
#if INR_HAVE_WGMMA
  if (deviceCount) n = min(n, int(*deviceCount));
  constexpr int KSTEPS = KC / 16;
  extern __shared__ __align__(1024) unsigned char smem[];
  __shared__ MlpInstr program[kMaxFusedInstrs];
  __shared__ int bufferStart[kMaxBuffers], bufferLd[kMaxBuffers];
  __shared__ alignas(8) std::uint64_t fullBar[kHopperMaxStages], emptyBar[kHopperMaxStages];
  const int stages = P.hopperStages;
  const int stageHalves = P.hopperStageRows * KC;
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
        const int chunks = (in.kPad + KC - 1) / KC;
        const unsigned bytes = unsigned(in.nPad) * KC * 2;
        const __half* from = P.hopperWeights[kcIndex(KC)] + P.hopperOffset[kcIndex(KC)][ip];
        for (int c = 0; c < chunks; ++c) {
          mbarrierWait(&emptyBar[slot], phase ^ 1u);  // a fresh barrier counts as released
          mbarrierArriveExpectTx(&fullBar[slot], bytes);
          bulkCopyToShared(ring + std::size_t(slot) * stageHalves, from + std::size_t(c) * in.nPad * KC, bytes, &fullBar[slot]);
          if (++slot == stages) slot = 0, phase ^= 1u;
        }
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
    for (int ip = 0; ip < P.numInstrs; ++ip)
      if (program[ip].op == MlpOp::Gemm && !program[ip].fusedIntoPrevious && (program[ip].kPad + KC - 1) / KC <= stages)
        lastOrdered = ip;
  if (lastOrdered >= 0 && c == 1 && int(blockIdx.x) < numRounds) namedBarrierArrive(kTurnBarrier + 0, 256);

  int slot = 0;
  unsigned phase = 0;
  for (int round = blockIdx.x; round < numRounds; round += gridDim.x) {
    const int base = (round * kHopperConsumers + c) * kHopperRows;
    const int rows = max(0, min(kHopperRows, n - base));  // 0: this consumer only keeps the pace
    loadTileCoords<kHopperRows, 128>(P, points, base, rows, coords, tid);
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
      const int numChunks = (in.kPad + KC - 1) / KC;
      const bool ordered = lastOrdered >= 0 && numChunks <= stages;
      const bool giveTurn = ordered && !(c == 1 && lastRound && ip == lastOrdered);
      const float* bias = P.floatWeights + in.biasOffset;
      const int ldSrc = in.src >= 0 ? bufferLd[in.src] : 0;
      const __half* src = in.src >= 0 ? act + bufferStart[in.src] : nullptr;
      const int fourier = in.fourierInput;
      auto gemm = [&](auto nTag) __attribute__((always_inline)) {
        constexpr int N = decltype(nTag)::value;
        // Accumulators start at the bias: fragment i is row g + 8*((i>>1)&1), column
        // 8*(i>>2) + 2*t4 + (i&1).
        float acc[N / 2];
#pragma unroll
        for (int i = 0; i < N / 2; ++i) {
          const int col = 8 * (i >> 2) + 2 * t4 + (i & 1);
          acc[i] = col < in.nPad ? bias[col] : 0.f;
        }
        const unsigned aAddr =
            src ? smemAddress(src + (rowBase + ((lane >> 3) & 1) * 8 + (lane & 7)) * ldSrc + (lane >> 4) * 8) : 0u;
        const unsigned ringBase = smemAddress(ring);
        // A operand of k step ks of `chunk`: ldmatrix from the buffer, or the Fourier encoding
        // computed for this thread's fragment (rows g, g+8; columns 2*t4 + {0,1} + {0,8}).
        auto loadA = [&](unsigned (&a)[KSTEPS][4], int chunk, int kLen) {
#pragma unroll
          for (int ks = 0; ks < KSTEPS; ++ks) {
            if (ks * 16 >= kLen) continue;
            if (fourier < 0) {
              ldmatrixX4(a[ks], aAddr + unsigned((chunk * KC + ks * 16) * 2));
            } else {
              const MlpInstr& f = program[fourier];
              const int k0 = chunk * KC + ks * 16 + 2 * t4;
#pragma unroll
              for (int q = 0; q < 4; ++q) {  // a[q]: row g + 8*(q&1), columns k0 + 8*(q>>1) + {0,1}
                const float* x = coords + (rowBase + g + 8 * (q & 1)) * 4;
                const int k = k0 + 8 * (q >> 1);
                const __half2 h = __floats2half2_rn(fourierElement(P, f, x, k), fourierElement(P, f, x, k + 1));
                a[ks][q] = *reinterpret_cast<const unsigned*>(&h);
              }
            }
          }
        };
        unsigned aEven[KSTEPS][4], aOdd[KSTEPS][4];
        int prevSlot = -1;
        auto issue = [&](unsigned (&a)[KSTEPS][4], int chunk) __attribute__((always_inline)) {
          const int kLen = min(KC, in.kPad - chunk * KC);
          loadA(a, chunk, kLen);  // before the wait: the encoding's arithmetic overlaps the copy
          mbarrierWait(&fullBar[slot], phase);
          wgmmaFence();
          const unsigned chunkBase = ringBase + unsigned(slot * stageHalves * 2);
#pragma unroll
          for (int ks = 0; ks < KSTEPS; ++ks)
            if (ks * 16 < kLen) wgmmaRS<N>(acc, a[ks], wgmmaDescriptor(chunkBase + ks * 256, 128, KC * 16));
          wgmmaCommit();
          wgmmaWait<1>();  // the previous chunk's MMAs are done: its slot and A registers are free
          if (prevSlot >= 0 && lane == 0) mbarrierArrive(&emptyBar[prevSlot]);
          prevSlot = slot;
          if (++slot == stages) slot = 0, phase ^= 1u;
        };
        if (ordered) namedBarrierSync(kTurnBarrier + c, 256);
        for (int chunk = 0; chunk < numChunks; chunk += 2) {
          issue(aEven, chunk);
          if (chunk + 1 < numChunks) issue(aOdd, chunk + 1);
        }
        if (giveTurn) namedBarrierArrive(kTurnBarrier + (1 - c), 256);
        wgmmaWait<0>();
        if (lane == 0) mbarrierArrive(&emptyBar[prevSlot]);
        if (in.finalOutput) {  // column 0 (t4 0): fragments 0 (row g) and 2 (row g+8)
          if (t4 == 0) {
#pragma unroll
            for (int half = 0; half < 2; ++half) {
              const int row = rowBase + g + half * 8;
              if (row < rows) {
                const float net = applyActivation(in.act, acc[2 * half]);
                writeOutput(P.output, points[base + row].w, net, base + row, out, scatter);
              }
            }
          }
          return;
        }
        __half* const dst = act + bufferStart[in.dst];
        const int ldDst = bufferLd[in.dst];
        const __half* const other = in.other >= 0 ? act + bufferStart[in.other] : nullptr;
        const int ldOther = in.other >= 0 ? bufferLd[in.other] : 0;
        dispatchActivation(in.act, [&](auto A) {
          constexpr MlpAct kAct = decltype(A)::value;
          // f(half, col, v0, v1) per owned pair of columns (col, col+1) of row g + 8*half.
          auto forEachPair = [&](auto f) {
            auto loop = [&](auto residual) {
              constexpr bool kResidual = decltype(residual)::value;
#pragma unroll
              for (int j = 0; j < N / 8; ++j) {
                const int col = 8 * j + 2 * t4;
                if (8 * j >= in.nPad) continue;
#pragma unroll
                for (int half = 0; half < 2; ++half) {
                  float v0 = applyActivation(kAct, acc[4 * j + 2 * half]);
                  float v1 = applyActivation(kAct, acc[4 * j + 2 * half + 1]);
                  if (kAct == MlpAct::Sigmoid) {  // sigmoid(0) != 0: keep padding columns zero
                    if (col >= in.outWidth) v0 = 0.f;
                    if (col + 1 >= in.outWidth) v1 = 0.f;
                  }
                  if constexpr (kResidual) {
                    const float2 o = ldsHalf2AsFloat2InPlace(other + (rowBase + g + 8 * half) * ldOther + col);
                    v0 = in.combineScale * (v0 + o.x);
                    v1 = in.combineScale * (v1 + o.y);
                  }
                  f(half, col, v0, v1);
                }
              }
            };
            if (other)
              loop(BoolTag<true>{});
            else
              loop(BoolTag<false>{});
          };
          if (in.dotNext) {  // the final linear: this warp holds every column of its 16 rows
            const MlpInstr& fin = program[ip + 1];
            float part[2] = {0.f, 0.f};
            forEachPair([&](int half, int col, float v0, float v1) {
              const float2 w = ldsFloat2InPlace(dotWeights + col);
              part[half] = fmaf(v0, w.x, fmaf(v1, w.y, part[half]));
            });
            const float dotBias = P.floatWeights[fin.biasOffset];
#pragma unroll
            for (int half = 0; half < 2; ++half) {
              float v = part[half];
              v += __shfl_xor_sync(0xffffffffu, v, 1);
              v += __shfl_xor_sync(0xffffffffu, v, 2);
              const int row = rowBase + g + 8 * half;
              if (t4 == 0 && row < rows) {
                const float net = applyActivation(fin.act, v + dotBias);
                writeOutput(P.output, points[base + row].w, net, base + row, out, scatter);
              }
            }
            return;
          }
          __half* const dRow = dst + (rowBase + g) * ldDst;
          forEachPair([&](int half, int col, float v0, float v1) {
            *reinterpret_cast<__half2*>(dRow + half * 8 * ldDst + col) = __floats2half2_rn(v0, v1);
          });
        });
      };
      switch (hopperColumns(in.nPad)) {  // the same for the whole consumer
        case 16: gemm(IntTag<16>{}); break;
        case 32: gemm(IntTag<32>{}); break;
        case 48: gemm(IntTag<48>{}); break;
        case 64: gemm(IntTag<64>{}); break;
        case 96: gemm(IntTag<96>{}); break;
        case 128: gemm(IntTag<128>{}); break;
        case 192: gemm(IntTag<192>{}); break;
        default: gemm(IntTag<256>{}); break;
      }
      consumerSync();
    }
  }
#else
  (void)P, (void)points, (void)n, (void)deviceCount, (void)out, (void)scatter;
#endif
}

}  // namespace inr::cuda
