#pragma once
// The fused kernels' parameters as the host prepares them: FusedParams (the program, the packed
// weights and their offsets, the input and output mappings, the buffer layout of both kernels),
// the mma.sync kernel's weight packing and its shared-memory size. Host and device code read
// these; the kernels themselves are FusedMlpKernel.cu (mma.sync) and FusedMlpKernelHopper.cu
// (wgmma), their entry points FusedMlpKernels.h.
// The host-only parts (the packing, the shared-memory size) are left out under NVRTC, which
// compiles the device code of a generated kernel (Evaluator/MlpKernelSource.h).
#include <cuda_fp16.h>

#include "Common/RtcCompat.h"
#include "Evaluator/MlpInstr.h"
#if !defined(__CUDACC_RTC__)
#include <vector>

#include "Evaluator/MlpProgram.h"
#endif

namespace inr::cuda {

constexpr int kMaxBuffers = 4;  // MlpProgram::kMaxFusedBuffers (static_assert below)
using inr::kMaxFusedInstrs;
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
  // The hash-grid tables in fp16 (MlpProgram::halfWeights, uploaded; a HashGrid instruction's
  // table at its halfOffset), and how the gather (FusedHashGrid.cuh) lays its work over lanes: a
  // pair of lanes per row and level, splitting the corners (1), or one lane (0). Same bits.
  const __half* hashTables = nullptr;
  int hashGridPairs = 1;
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
  // The wgmma kernel's program with a stored Fourier encoding split for the GEMM reading it, K
  // 257..512 (that GEMM's instruction index; -1: none): the Fourier instruction writes the
  // encoding's first 256 columns into a per-consumer operand region that the GEMM's MMAs read
  // from shared memory (hopperSplitHalves), the rest row-major into the GEMM's buffer; the GEMM
  // holds those in registers for all its chunks and writes its output over them (in place): per
  // consumer a 32 KB operand region beside the 32 KB activation buffer, where the stored form
  // needs the 64 KB encoding and a 32 KB output buffer.
  int hopperSplitGemm = -1;
  OutputMap output;
  // Value + gradient launches (the mma.sync kernel's tangent rows, TileRows<true>): the network
  // input each world axis x, y, z moves (-1: none), the tangents' power-of-two scale
  // (MlpProgram::tangentScale; the input tangent rows hold it), and per axis the factor from the
  // network's scaled tangent to the world gradient: output slope * input slope / tangentScale.
  int tangentInput[3] = {-1, -1, -1};
  float tangentScale = 1.f;
  float gradientScale[3] = {0.f, 0.f, 0.f};
};

__host__ __device__ constexpr int kcIndex(int kc) { return kc == 64 ? 0 : 1; }

#if !defined(__CUDACC_RTC__)
static_assert(kMaxBuffers == MlpProgram::kMaxFusedBuffers, "the fused kernels' buffer limit is the program's");

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

#endif  // !__CUDACC_RTC__

__host__ __device__ inline int stageRows(const FusedParams& P) {
  return (P.maxGemmOutPad + kStageRowAlign - 1) / kStageRowAlign * kStageRowAlign;
}

// Shared memory for a tile of M queries and weight chunks of KC: activation buffers, the
// weight double buffer, a fused Fourier encoding's chunk, coordinates (M x 4 floats), the final
// dot's partial sums (4 x M) and weights.
__host__ __device__ inline int encodingStageHalves(int M, int KC, const FusedParams& P) {
  return P.fusedFourier ? M * (KC + 8) : 0;
}

#if !defined(__CUDACC_RTC__)
inline std::size_t fusedSharedBytes(int M, int KC, const FusedParams& P) {
  std::size_t halves = 0;
  for (int b = 0; b < P.numBuffers; ++b) halves += std::size_t(M) * P.bufferLd[b];
  halves += std::size_t(2) * stageRows(P) * (KC + 8) + encodingStageHalves(M, KC, P);
  return halves * 2 + (std::size_t(M) * 8 + MlpProgram::kMaxFusedGemmOut) * 4;
}
#endif

}  // namespace inr::cuda
