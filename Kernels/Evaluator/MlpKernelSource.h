#pragma once
// The evaluator compiled for the model (issue 50): the CUDA source of fused kernels specialised
// to one network. The fused mma.sync kernel (Evaluator/Cuda/FusedMlpKernel.cuh) is an
// interpreter: it reads an MlpProgram's instructions from shared memory and decodes them as its
// loop runs. A generated kernel runs the same device code with the program as compile-time
// constants (ConstantProgram there): the instruction list, every width, activation, residual,
// epilogue and fusion flag, the buffer layout; the loop over the instructions is unrolled, so the
// compiled kernel holds exactly the code this network needs, no loop state and no run-time
// decoding, and computes the interpreter's bits. The source is compiled at model load by NVRTC
// (Evaluator/Cuda/GeneratedKernels.h) against the project's device headers, embedded in the
// binary.
//
// CUDA-free and deterministic (the same program gives the same text, byte for byte: the text is
// the key of the compiled-kernel cache), so CI checks it without a GPU.
#include <stdexcept>
#include <string>
#include <vector>

#include "Evaluator/MlpProgram.h"

namespace inr {

// One kernel of a generated source: the mma.sync design for tiles of `tile` rows (128, 64 or
// 32) and weight K-chunks of `kc` columns (64 or 32), values only or with tangent rows (value +
// gradient, TileRows<true>), of the program forms[form] (generateFusedKernelSource).
struct GeneratedKernelSpec {
  int form = 0;
  int tile = 128;
  int kc = 64;
  bool tangents = false;
};

// The kernel's extern "C" name in the generated source, e.g. "inr_mlp_p0_t128_k64_values".
std::string generatedKernelName(const GeneratedKernelSpec& spec);

// Throws std::invalid_argument, naming the instruction, the field and the problem, for a program
// the fused kernel cannot run (MlpProgram::fusable false, more than kMaxFusedInstrs
// instructions, a buffer index, width or offset out of range, a non-finite scale, a fused
// instruction without its partner). Every program MlpProgram::compile marks fusable passes.
void validateFusedProgram(const MlpProgram& program);

// The CUDA source of `kernels` (each of forms[spec.form]: the program exactly as the launch's
// FusedParams describe it, e.g. MlpProgram::compile's and withEncodingsStored()'s), to be
// compiled by NVRTC with the embedded device headers on the include path. Validates every form
// (validateFusedProgram) and spec (std::invalid_argument).
std::string generateFusedKernelSource(const std::vector<MlpProgram>& forms, const std::vector<GeneratedKernelSpec>& kernels);

// The buffer layout a program's fused launch uses (as the evaluator fills FusedParams): halves
// per row of buffer b (bufferWidthPad + 8), the buffers (at least one), the weight stage's rows
// (at least 16) and whether a Fourier encoding is fused into a GEMM's operand load.
struct FusedLayout {
  std::vector<int> bufferLd;
  int numBuffers = 1;
  int maxGemmOutPad = 16;
  bool fusedFourier = false;
};
FusedLayout fusedLayoutOf(const MlpProgram& program);

}  // namespace inr

namespace inr {

// What the evaluator generates for a model (GeneratedKernels.h): the program as compiled (form
// 0) and, where a Fourier encoding is fused into a GEMM's operand load, the same program with it
// stored (form 1: FusedConfig::storedEncoding), each for every tile in `tiles` and weight chunk in
// `chunks`, values and, with `tangents`, tangent rows; the source of them all.
struct ModelKernelSource {
  std::vector<MlpProgram> forms;
  std::vector<GeneratedKernelSpec> kernels;
  std::string source;
};
ModelKernelSource generateModelKernels(const MlpProgram& program, const std::vector<int>& tiles = {128, 64, 32},
                                       const std::vector<int>& chunks = {64, 32}, bool tangents = true);

}  // namespace inr
