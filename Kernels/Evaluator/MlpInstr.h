#pragma once
// One instruction of a compiled network (MlpProgram.h, which documents the instruction set): the
// part of the program the fused kernels read, in a header of its own with no host-only include,
// so the kernels' device code also compiles under NVRTC (a kernel generated for one network,
// Evaluator/MlpKernelSource.h, where the program's instructions are compile-time constants).
#include "Common/Activation.h"  // MlpAct
#include "Common/RtcCompat.h"

namespace inr {

// The most instructions a fused kernel runs (its shared-memory copy of the program, the per
// instruction weight offsets of its parameters).
constexpr int kMaxFusedInstrs = 64;

enum class MlpOp : std::int32_t { LoadInput, DenseFp32, Fourier, Gemm, Activation, Combine, OutputDot, Output, HashGrid };

struct MlpInstr {
  MlpOp op = MlpOp::Output;
  std::int32_t src = -1, dst = -1, other = -1;  // buffer indices; -1 = coordinates / none
  std::int32_t inWidth = 0, outWidth = 0;       // logical widths
  std::int32_t kPad = 0, nPad = 0;              // padded to multiples of 16
  MlpAct act = MlpAct::None;
  float actScale = 1.f;      // Activation: scale before the activation (scale layers)
  float combineScale = 1.f;  // Combine / Gemm with `other`
  std::int32_t includeInput = 0;  // Fourier, HashGrid: 0 none, 1 first, 2 last
  std::int64_t halfOffset = -1;   // Gemm: fp16 weights [nPad][kPad] in MlpProgram::halfWeights;
                                  // HashGrid: its fp16 table [entries][features] there
  std::int64_t floatOffset = -1;  // fp32 weights [out][in] (B [m][in]); Gemm: the generic path's copy
  std::int64_t biasOffset = -1;   // fp32 bias [nPad] in floatWeights, -1 = none
  // Gemm: index of the next Gemm in execution order (wrapping to the first one, whose weights
  // the next tile needs), so the kernel can prefetch its first weight chunk; -1 if none.
  std::int32_t nextGemm = -1;
  // Gemm: the network's final layer (width 1): column 0 of the fp32 accumulator, after bias and
  // activation, is the network output (no fp16 rounding, no destination buffer).
  std::int32_t finalOutput = 0;
  // LoadInput: write each coordinate as fp16 hi, lo (= x - hi), hi in columns 0-3, 4-7, 8-11, so
  // a Gemm with weights packed [W_hi, W_hi, W_lo] computes x_hi W_hi + x_lo W_hi + x_hi W_lo:
  // the first layer on tensor cores with ~fp32 accuracy (error ~ x_lo W_lo).
  std::int32_t splitPrecision = 0;
  // Gemm fed by such a split buffer: the fp32 paths (generic, per-thread, emulation of inputs)
  // read the raw coordinates with inWidth = input dimension instead.
  std::int32_t coordInput = 0;
  // Gemm followed by the network's final linear (width 1) reading its output: the fused kernel
  // computes that dot product in this Gemm's epilogue, from the fp32 activations (never rounded
  // to fp16 or stored), and skips the next instruction, which has fusedIntoPrevious set. The
  // generic path runs both instructions as written.
  std::int32_t dotNext = 0;
  std::int32_t fusedIntoPrevious = 0;
  std::int64_t dotOffset = -1;  // dotNext: the final layer's fp32 weights, zero-padded to nPad
  // Fourier (of the coordinates) read only by the next instruction, a Gemm: never stored; that
  // Gemm computes each encoding element where it loads its A operand (fourierInput).
  std::int32_t fusedIntoNext = 0;
  std::int32_t fourierInput = -1;  // Gemm: index of the fused Fourier instruction it reads, or -1
};

}  // namespace inr
