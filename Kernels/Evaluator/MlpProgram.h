#pragma once
// The GPU evaluators' view of a network: the layer graph compiled into a flat list of
// instructions over a few activation buffers, with packed weights. Host-only and CUDA-free, so
// the compiler and an exact CPU emulation of the fused kernel's arithmetic are tested on
// machines without a GPU.
//
// Buffers hold one row of activations per query (fp16 in the fused kernel), padded to a
// multiple of 16 columns with zeros. Instructions:
//   LoadInput    coordinates -> dst (when a buffer must hold the raw inputs, or split into fp16
//                hi/lo parts for a first layer on tensor cores)
//   DenseFp32    src (coordinates or buffer) -> dst, fp32 FMA: first layers, where coordinate
//                precision matters, and any linear with K <= 16
//   Fourier      src (coordinates or buffer) -> dst, fp32 [sin(Bx), cos(Bx)] (+x), B pre-scaled
//   HashGrid     src (coordinates or buffer) -> dst, hash-grid features (+x) interpolated in
//                fp32: the parameters from the packed layer (packHashGrid; Evaluator/Encodings.h
//                HashGridView), the table read from its fp32 copy there (generic and per-thread
//                paths) or from an fp16 copy in halfWeights (the fused kernels, at halfOffset)
//   Gemm         src -> dst on tensor cores, fp32 accumulate, + bias, activation epilogue,
//                optionally dst = combineScale * (act(acc) + other)
//   Activation   dst = act(actScale * dst) in place (standalone activations)
//   Combine      dst = combineScale * (src + other)
//   OutputDot    value = act(w . src + b) in fp32 (a final linear to width 1 with K <= 16;
//                wider ones run as a Gemm with finalOutput set)
//   Output       value = src[0]
// A final linear fed straight by a Gemm is folded into that Gemm's epilogue (dotNext).
// Sine's w0 and standalone scale layers feeding a linear are folded into that linear's weights.
#include <cstdint>
#include <string>
#include <vector>

#include "Common/Activation.h"  // MlpAct
#include "Evaluator/MlpInstr.h"
#include "Model/InrModel.h"

namespace inr {

struct MlpProgram {
  std::vector<MlpInstr> instrs;
  std::vector<std::uint16_t> halfWeights;  // fp16 bit patterns
  std::vector<float> floatWeights;
  int inputDim = 0;
  int numBuffers = 0;
  int maxWidthPad = 0;  // widest buffer, multiple of 16
  std::vector<int> bufferWidthPad;  // per buffer: widest value it ever holds (multiple of 16)
  int maxGemmOutPad = 0;            // widest tensor-core layer output (rows of staged weights)
  // Whether the fused tensor-core kernel can run it (activation widths <= kMaxFusedWidth, GEMM
  // outputs <= kMaxFusedGemmOut, buffers <= kMaxFusedBuffers); otherwise `whyNotFused` says why
  // and the generic path is used.
  bool fusable = true;
  std::string whyNotFused;
  // Forward-mode tangents (value + gradient, emulateFusedTangents and the fused kernel's tangent
  // rows) are stored in fp16 like the activations, multiplied by this power of two: the input
  // tangent is tangentScale (not 1) and the result is divided by it again in fp32, exactly. One
  // scale for the whole program, because every tangent operation is linear in the tangents
  // (residual sums add tangents of different layers: a per-layer scale would need rescaling
  // there). chooseTangentScale sets it from the largest tangent a sample of inputs stores.
  float tangentScale = 1.f;

  static constexpr int kMaxFusedWidth = 512;
  static constexpr int kMaxFusedGemmOut = 256;
  static constexpr int kMaxFusedBuffers = 4;

  static MlpProgram compile(const Architecture& arch);
  // The same instructions over fewer buffers: a Gemm with K <= maxK writes over its own input
  // wherever nothing reads that input afterwards (for a kernel whose warps each hold their A rows,
  // K <= maxK columns, in registers before their epilogue writes those rows; SIREN and FFN then
  // need one buffer, not two; a Gemm reading a fused Fourier encoding reads no buffer: any K).
  // Same arithmetic: emulateFusedProgram gives identical results. `alsoInPlace`: the index of one
  // more Gemm that may write over its input whatever its K (a kernel that holds that layer's
  // input otherwise: the wgmma kernel's split encoding), -1 none.
  MlpProgram withGemmsInPlace(int maxK, int alsoInPlace = -1) const;
  // The same program with every fused Fourier encoding stored in its buffer again (the Fourier
  // instruction writes it, the GEMM reads it; buffers as wide as that needs).
  MlpProgram withEncodingsStored() const;
  std::string describe() const;  // one line per instruction, for logs and `inr info`
};

// A hash-grid layer's parameters and table as one float array, the layout HashGridView
// (Evaluator/Encodings.h) reads: what a HashGrid instruction's floatOffset points at, and what
// the CPU reference evaluates from.
std::vector<float> packHashGrid(const Layer& hashGridLayer);

// Runs the program on the CPU exactly as the fused kernel does arithmetically (fp16 weights and
// activations, fp32 accumulation and epilogues), on network-space inputs (inputDim floats per
// query). Slow; for tests and for explaining fp16 error. In MlpProgramEmulation.cpp.
void emulateFusedProgram(const MlpProgram& program, const float* inputs, std::size_t n, float* out);

// The same with forward-mode tangents, exactly as the fused kernel's tangent rows compute them:
// for each query, the value and its derivatives along up to three network inputs
// (tangentInput[a], -1 = none: derivative 0), each tangent rounded to fp16 wherever the value is
// (scaled by program.tangentScale while stored), through the derivative of every instruction
// (dy = act'(Wx + b) * (W dx) for a layer, no bias; the encodings' element derivatives,
// Evaluator/Encodings.h; residual sums and scale layers linearly). values[q] = network output,
// tangents[3 q + a] = d output / d input tangentInput[a]. maxStoredTangent, when given, receives
// the largest |tangent| the program stores in a buffer (before fp16 rounding; the tangent scale
// included).
void emulateFusedTangents(const MlpProgram& program, const float* inputs, std::size_t n, const int tangentInput[3],
                          float* values, float* tangents, float* maxStoredTangent = nullptr);

// The power of two for program.tangentScale: the largest tangent stored for the sample `inputs`
// (n queries, network space, unit tangents along the inputs tangentInput names, as for
// emulateFusedTangents)
// scaled to about kTangentTarget. fp16 overflows at 65504: a SIREN's tangents grow by w0 (30)
// and a trained layer's gain at every layer, while the values stay in [-1, 1], so the tangents
// of a deep sine network can pass fp16's range where the values never do; scaled down, the
// largest sampled one lands at 2^10, leaving a factor 64 for points the sample missed, and
// scaled up (small domains' tangents) they stay clear of fp16's subnormals (below 6.1e-5).
// Clamped to [2^-16, 2^16].
float chooseTangentScale(const MlpProgram& program, const float* inputs, std::size_t n, const int tangentInput[3]);
constexpr float kTangentTarget = 1024.f;

// The network inputs the world axes x, y, z feed (tangentInput[a], -1 where axis a feeds none),
// as the fused kernel's tangent rows take them: false when an axis feeds more than one input
// (the fused tangent path does not run such a model).
bool tangentInputsOf(const Domain& domain, int inputDim, int tangentInput[3]);
// chooseTangentScale on kTangentSamplePoints points drawn (fixed seed) in the model's domain.
float chooseTangentScale(const MlpProgram& program, const Domain& domain);
constexpr int kTangentSamplePoints = 64;

}  // namespace inr
