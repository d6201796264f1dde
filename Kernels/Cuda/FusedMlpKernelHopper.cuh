#pragma once
// Hopper (sm_90a) pieces of the fused kernel: GEMM layers on warpgroup MMA (wgmma.mma_async).
// A warpgroup (4 consecutive warps) computes 64 rows x NW columns of a layer: A (the previous
// layer's activations) goes to registers with ldmatrix from the row-major activation buffer
// (the wgmma A-register fragment of each warp is the mma.sync m16n8k16 one), B (the weights)
// is read by the tensor cores straight from the staged chunk through a shared-memory matrix
// descriptor. The weights are therefore packed on the host in the wgmma "no swizzle" K-major
// layout: per K-chunk of KC, core matrices of 8 output rows x 8 k (128 contiguous bytes), the
// KC/8 core matrices of an 8-row group next to each other (leading byte offset 128), 8-row
// groups KC*16 bytes apart (stride byte offset).
// Warpgroup wg of a tile of M = 64 * WR/2 queries takes rows 64*(wg/2) and column half (wg&1):
// NW columns from (wg&1)*NW, NW the smallest of 16/32/64/128 covering half the layer.
// The wgmma instructions exist only in sm_90a code (__CUDA_ARCH_FEAT_SM90_ALL); other targets
// compile these wrappers to a trap and the host never launches the Hopper variant there (it asks
// the loaded code with hopperKernelAvailable()).
#include <cuda_fp16.h>
#include <cstdint>
#include <vector>

#include "Cuda/MlpProgram.h"

namespace inr::cuda {

#if defined(__CUDA_ARCH__) && defined(__CUDA_ARCH_FEAT_SM90_ALL)
#define INR_HAVE_WGMMA 1
#else
#define INR_HAVE_WGMMA 0
#endif

// Columns per warpgroup for a GEMM of nPad output columns (two column halves).
__host__ __device__ constexpr int hopperColumns(int nPad) {
  return nPad <= 32 ? 16 : nPad <= 64 ? 32 : nPad <= 128 ? 64 : 128;
}

// The GEMM weights ([nPad][kPad] fp16 in MlpProgram::halfWeights) packed chunk by chunk in the
// wgmma core-matrix layout (see above), zeros past kPad; offsets[i] = instruction i's start.
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

// Rows of the Hopper weight stage: both column halves of the widest GEMM.
inline int hopperStageRows(const MlpProgram& prog) {
  int rows = 32;
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) rows = rows > 2 * hopperColumns(in.nPad) ? rows : 2 * hopperColumns(in.nPad);
  return rows;
}

// Shared-memory matrix descriptor, no swizzle: start address, leading byte offset (between the
// two k-halves of a k16 step), stride byte offset (between 8-row groups), all in 16-byte units.
__device__ inline std::uint64_t wgmmaDescriptor(unsigned smemByteAddress, unsigned leadingBytes, unsigned strideBytes) {
  return std::uint64_t((smemByteAddress & 0x3FFFF) >> 4) | (std::uint64_t(leadingBytes >> 4) << 16) |
         (std::uint64_t(strideBytes >> 4) << 32);
}

__device__ inline void wgmmaFence() {
#if INR_HAVE_WGMMA
  asm volatile("wgmma.fence.sync.aligned;\n" ::: "memory");
#endif
}
__device__ inline void wgmmaCommit() {
#if INR_HAVE_WGMMA
  asm volatile("wgmma.commit_group.sync.aligned;\n" ::: "memory");
#endif
}
__device__ inline void wgmmaWaitAll() {
#if INR_HAVE_WGMMA
  asm volatile("wgmma.wait_group.sync.aligned 0;\n" ::: "memory");
#endif
}
// Makes this thread's generic-proxy shared-memory writes (cp.async weight chunks) visible to the
// async proxy that wgmma reads B through.
__device__ inline void fenceProxyAsyncShared() {
#if INR_HAVE_WGMMA
  asm volatile("fence.proxy.async.shared::cta;\n" ::: "memory");
#endif
}

// d(64 x N, f32, this thread's N/2 fragment values) += A(64 x 16, f16 registers) * B(16 x N, f16
// shared memory via desc), issued by the whole warpgroup.
template <int N>
__device__ inline void wgmmaRS(float (&d)[N / 2], const unsigned (&a)[4], std::uint64_t desc) {
#if INR_HAVE_WGMMA
  if constexpr (N == 16) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %13, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n16k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7}, {%8, %9, %10, %11}, %12, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  }
  else   if constexpr (N == 32) {
    asm volatile(
        "{\n.reg .pred p;\nsetp.ne.b32 p, %21, 0;\n"
        "wgmma.mma_async.sync.aligned.m64n32k16.f32.f16.f16 {%0, %1, %2, %3, %4, %5, %6, %7, %8, %9, %10, %11, %12, %13, %14, %15}, {%16, %17, %18, %19}, %20, p, 1, 1, 0;\n}\n"
        :
          "+f"(d[0]), "+f"(d[1]), "+f"(d[2]), "+f"(d[3]), "+f"(d[4]), "+f"(d[5]), "+f"(d[6]), "+f"(d[7]),
          "+f"(d[8]), "+f"(d[9]), "+f"(d[10]), "+f"(d[11]), "+f"(d[12]), "+f"(d[13]), "+f"(d[14]), "+f"(d[15])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "l"(desc), "r"(1));
  }
  else   if constexpr (N == 64) {
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
  else   if constexpr (N == 128) {
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
  }

#else
  (void)d;
  (void)a;
  (void)desc;
  __trap();
#endif
}

}  // namespace inr::cuda
