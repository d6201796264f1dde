#include "Evaluator/MlpKernelSource.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <locale>
#include <sstream>

namespace inr {
namespace {

const char* opEnumName(MlpOp op) {
  switch (op) {
    case MlpOp::LoadInput: return "LoadInput";
    case MlpOp::DenseFp32: return "DenseFp32";
    case MlpOp::Fourier: return "Fourier";
    case MlpOp::Gemm: return "Gemm";
    case MlpOp::Activation: return "Activation";
    case MlpOp::Combine: return "Combine";
    case MlpOp::OutputDot: return "OutputDot";
    case MlpOp::Output: return "Output";
    case MlpOp::HashGrid: return "HashGrid";
  }
  return nullptr;
}

const char* actEnumName(MlpAct a) {
  switch (a) {
    case MlpAct::None: return "None";
    case MlpAct::Sine: return "Sine";
    case MlpAct::SiLU: return "SiLU";
    case MlpAct::ReLU: return "ReLU";
    case MlpAct::Sigmoid: return "Sigmoid";
    case MlpAct::Tanh: return "Tanh";
  }
  return nullptr;
}

// An exact float literal (finite v): its integer significand in hexadecimal times a power of
// two, e.g. 0x1e00000p-20f for 30 (no decimal rounding, and no locale: printf's %a writes the
// locale's decimal point). The decimal value goes beside it in a comment for a reader.
std::string floatLiteral(float v) {
  std::uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  const bool negative = bits >> 31;
  const int biased = int((bits >> 23) & 0xffu);
  std::uint32_t significand = bits & 0x7fffffu;
  int exponent = -149;  // subnormals and zero: significand x 2^-149
  if (biased) {
    significand |= 0x800000u;
    exponent = biased - 150;
  }
  char text[48];
  std::snprintf(text, sizeof text, "%s0x%xp%+df", negative ? "-" : "", unsigned(significand), significand ? exponent : 0);
  return text;
}

std::string decimal(float v) {
  char d[32];
  std::snprintf(d, sizeof d, "%.9g", double(v));
  return d;
}

[[noreturn]] void bad(std::size_t i, const std::string& what) {
  throw std::invalid_argument("generated fused kernel: instruction " + std::to_string(i) + " " + what);
}

}  // namespace

std::string generatedKernelName(const GeneratedKernelSpec& s) {
  return "inr_mlp_p" + std::to_string(s.form) + "_t" + std::to_string(s.tile) + "_k" + std::to_string(s.kc) +
         (s.tangents ? "_tangents" : "_values");
}

FusedLayout fusedLayoutOf(const MlpProgram& p) {
  FusedLayout l;
  l.numBuffers = std::max(1, p.numBuffers);
  l.bufferLd.assign(std::size_t(l.numBuffers), 0);
  for (int b = 0; b < l.numBuffers; ++b)
    l.bufferLd[std::size_t(b)] = (std::size_t(b) < p.bufferWidthPad.size() ? p.bufferWidthPad[std::size_t(b)] : 16) + 8;
  l.maxGemmOutPad = std::max(16, p.maxGemmOutPad);
  for (const MlpInstr& in : p.instrs) l.fusedFourier |= in.fourierInput >= 0;
  return l;
}

void validateFusedProgram(const MlpProgram& p) {
  if (!p.fusable)
    throw std::invalid_argument("generated fused kernel: the program does not run on the fused kernel (" + p.whyNotFused + ")");
  if (p.instrs.empty()) throw std::invalid_argument("generated fused kernel: the program has no instructions");
  if (int(p.instrs.size()) > kMaxFusedInstrs)
    throw std::invalid_argument("generated fused kernel: the program has " + std::to_string(p.instrs.size()) +
                                " instructions (fused kernel: up to " + std::to_string(kMaxFusedInstrs) + ")");
  if (p.numBuffers > MlpProgram::kMaxFusedBuffers)
    throw std::invalid_argument("generated fused kernel: the program has " + std::to_string(p.numBuffers) +
                                " buffers (fused kernel: up to " + std::to_string(MlpProgram::kMaxFusedBuffers) + ")");
  if (p.inputDim < 1 || p.inputDim > 4)
    throw std::invalid_argument("generated fused kernel: the program has " + std::to_string(p.inputDim) +
                                " inputs (fused kernel: 1 to 4)");
  for (std::size_t b = 0; b < p.bufferWidthPad.size(); ++b)
    if (p.bufferWidthPad[b] < 16 || p.bufferWidthPad[b] % 16 || p.bufferWidthPad[b] > MlpProgram::kMaxFusedWidth)
      throw std::invalid_argument("generated fused kernel: buffer " + std::to_string(b) + " is " +
                                  std::to_string(p.bufferWidthPad[b]) + " wide (a multiple of 16, 16 to " +
                                  std::to_string(MlpProgram::kMaxFusedWidth) + ")");
  const std::int64_t halves = std::int64_t(p.halfWeights.size()), floats = std::int64_t(p.floatWeights.size());
  const int n = int(p.instrs.size());
  for (std::size_t i = 0; i < p.instrs.size(); ++i) {
    const MlpInstr& in = p.instrs[i];
    if (!opEnumName(in.op)) bad(i, "has an unknown operation (" + std::to_string(int(in.op)) + ")");
    if (!actEnumName(in.act)) bad(i, "has an unknown activation (" + std::to_string(int(in.act)) + ")");
    for (const auto& [name, b] : {std::pair<const char*, int>{"src", in.src}, {"dst", in.dst}, {"other", in.other}})
      if (b < -1 || b >= std::max(1, p.numBuffers))
        bad(i, std::string("(") + opEnumName(in.op) + ") has " + name + " buffer " + std::to_string(b) + " (the program has " +
                   std::to_string(p.numBuffers) + ")");
    // (an Output instruction reads column 0 of a value of any width: no padded input width)
    if (in.kPad < 0 || in.kPad % 16 || in.nPad < 0 || in.nPad % 16 || in.inWidth < 0 || in.outWidth < 0 ||
        (in.op != MlpOp::Output && in.inWidth > std::max(in.kPad, 16)) || in.outWidth > std::max(in.nPad, 16))
      bad(i, std::string("(") + opEnumName(in.op) + ") has widths " + std::to_string(in.inWidth) + "->" +
                 std::to_string(in.outWidth) + " padded to " + std::to_string(in.kPad) + "->" + std::to_string(in.nPad) +
                 " (padded widths are multiples of 16, at least the logical ones)");
    if (in.nPad > MlpProgram::kMaxFusedWidth || in.kPad > MlpProgram::kMaxFusedWidth)
      bad(i, "is wider than the fused kernel's " + std::to_string(MlpProgram::kMaxFusedWidth) + " columns");
    if (!std::isfinite(in.actScale) || !std::isfinite(in.combineScale))
      bad(i, "has a non-finite scale (actScale " + decimal(in.actScale) + ", combineScale " + decimal(in.combineScale) + ")");
    auto inside = [&](const char* name, std::int64_t off, std::int64_t count, std::int64_t size) {
      if (off < 0 || off + count > size)
        bad(i, std::string("(") + opEnumName(in.op) + ") has " + name + " " + std::to_string(off) + " for " +
                   std::to_string(count) + " values of " + std::to_string(size));
    };
    const bool fusedAway = in.fusedIntoPrevious || in.fusedIntoNext;
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) {
      if (in.nPad > MlpProgram::kMaxFusedGemmOut)
        bad(i, "(Gemm) has " + std::to_string(in.nPad) + " outputs (fused kernel: up to " +
                   std::to_string(MlpProgram::kMaxFusedGemmOut) + ")");
      if (in.kPad < 16 || in.nPad < 16) bad(i, "(Gemm) has an empty weight matrix");
      inside("halfOffset", in.halfOffset, std::int64_t(in.nPad) * in.kPad, halves);
      inside("biasOffset", in.biasOffset, in.nPad, floats);
      if (in.src < 0 && in.fourierInput < 0) bad(i, "(Gemm) reads the coordinates, not a buffer or a fused encoding");
      if (!in.finalOutput && !in.dotNext && in.dst < 0) bad(i, "(Gemm) writes no buffer and is not the output");
      if (in.nextGemm < -1 || in.nextGemm >= n || (in.nextGemm >= 0 && p.instrs[std::size_t(in.nextGemm)].op != MlpOp::Gemm))
        bad(i, "(Gemm) names instruction " + std::to_string(in.nextGemm) + " as the next GEMM, which is not one");
      if (in.fourierInput >= 0 && (in.fourierInput >= n || p.instrs[std::size_t(in.fourierInput)].op != MlpOp::Fourier ||
                                   !p.instrs[std::size_t(in.fourierInput)].fusedIntoNext))
        bad(i, "(Gemm) reads instruction " + std::to_string(in.fourierInput) + " as its fused encoding, which is not one");
      if (in.dotNext) {
        if (i + 1 >= p.instrs.size() || !p.instrs[i + 1].fusedIntoPrevious)
          bad(i, "(Gemm) fuses the final dot of the next instruction, which is not marked fused into it");
        inside("dotOffset", in.dotOffset, in.nPad, floats);
        inside("the final dot's biasOffset", p.instrs[i + 1].biasOffset, 1, floats);
      }
    }
    if (in.fusedIntoPrevious && (i == 0 || !p.instrs[i - 1].dotNext))
      bad(i, "is marked fused into the previous instruction, which does not fuse it");
    if (in.fusedIntoNext && (in.op != MlpOp::Fourier || i + 1 >= p.instrs.size() || p.instrs[i + 1].fourierInput != int(i)))
      bad(i, "is marked fused into the next instruction, which does not read it");
    if (fusedAway && in.op != MlpOp::Fourier) continue;
    switch (in.op) {
      case MlpOp::DenseFp32:
        if (in.inWidth > 16 && in.src >= 0) break;
        inside("floatOffset", in.floatOffset, std::int64_t(in.outWidth) * in.inWidth, floats);
        inside("biasOffset", in.biasOffset, in.outWidth, floats);
        break;
      case MlpOp::Fourier:
      case MlpOp::HashGrid:
        if (in.inWidth < 1 || in.inWidth > 4) bad(i, std::string("(") + opEnumName(in.op) + ") encodes " +
                                                       std::to_string(in.inWidth) + " inputs (1 to 4)");
        inside("floatOffset", in.floatOffset, 1, floats);
        if (in.op == MlpOp::HashGrid) inside("halfOffset", in.halfOffset, 1, halves);
        if (!in.fusedIntoNext && in.dst < 0) bad(i, "(encoding) writes no buffer");
        break;
      case MlpOp::OutputDot:
        inside("floatOffset", in.floatOffset, in.inWidth, floats);
        inside("biasOffset", in.biasOffset, 1, floats);
        break;
      case MlpOp::LoadInput:
      case MlpOp::Activation:
      case MlpOp::Combine:
        if (in.dst < 0) bad(i, std::string("(") + opEnumName(in.op) + ") writes no buffer");
        break;
      default: break;
    }
  }
  const MlpInstr& last = p.instrs.back();
  const bool ends = last.op == MlpOp::Output || last.op == MlpOp::OutputDot || (last.op == MlpOp::Gemm && last.finalOutput) ||
                    last.fusedIntoPrevious;
  if (!ends) bad(p.instrs.size() - 1, "is the last one but writes no network output");
}

std::string generateFusedKernelSource(const std::vector<MlpProgram>& forms, const std::vector<GeneratedKernelSpec>& kernels) {
  if (forms.empty()) throw std::invalid_argument("generated fused kernel: no program given");
  if (kernels.empty()) throw std::invalid_argument("generated fused kernel: no kernel requested");
  for (const MlpProgram& p : forms) validateFusedProgram(p);
  std::ostringstream s;
  s.imbue(std::locale::classic());  // the text is a cache key: no locale's digit grouping
  s << "// Generated by INR Volume (Kernels/Evaluator/MlpKernelSource.cpp): the fused mma.sync kernel with\n"
       "// one network's program as compile-time constants (Evaluator/Cuda/FusedMlpKernel.cuh,\n"
       "// ConstantProgram). Compiled at run time by NVRTC; do not edit.\n"
       "#include \"Evaluator/Cuda/FusedMlpKernel.cuh\"\n\n"
       "namespace inr::cuda::generated {\n";
  for (std::size_t f = 0; f < forms.size(); ++f) {
    const MlpProgram& p = forms[f];
    const FusedLayout layout = fusedLayoutOf(p);
    s << "\n// Program " << f << ":\n";
    {
      std::istringstream lines(p.describe());
      for (std::string line; std::getline(lines, line);) s << "//   " << line << "\n";
    }
    s << "struct Program" << f << " {\n"
      << "  static constexpr int kNumInstrs = " << p.instrs.size() << ";\n"
      << "  static constexpr int kNumBuffers = " << layout.numBuffers << ";\n"
      << "  static constexpr int kMaxGemmOutPad = " << layout.maxGemmOutPad << ";\n"
      << "  static constexpr int kFusedFourier = " << (layout.fusedFourier ? 1 : 0) << ";\n"
      << "  static constexpr int kHashGrid = "
      << (std::any_of(p.instrs.begin(), p.instrs.end(), [](const MlpInstr& in) { return in.op == MlpOp::HashGrid; }) ? 1 : 0)
      << ";\n"
      << "  __host__ __device__ static constexpr int ld(int b) {\n    switch (b) {\n";
    for (int b = 0; b < layout.numBuffers; ++b) s << "      case " << b << ": return " << layout.bufferLd[std::size_t(b)] << ";\n";
    s << "      default: return 0;\n    }\n  }\n"
      << "  __host__ __device__ static constexpr MlpInstr instr(int i) {\n    MlpInstr in{};\n    switch (i) {\n";
    for (std::size_t i = 0; i < p.instrs.size(); ++i) {
      const MlpInstr& in = p.instrs[i];
      s << "      case " << i << ":  // " << opEnumName(in.op) << "\n"
        << "        in.op = MlpOp::" << opEnumName(in.op) << ";\n"
        << "        in.src = " << in.src << ";\n        in.dst = " << in.dst << ";\n        in.other = " << in.other << ";\n"
        << "        in.inWidth = " << in.inWidth << ";\n        in.outWidth = " << in.outWidth << ";\n"
        << "        in.kPad = " << in.kPad << ";\n        in.nPad = " << in.nPad << ";\n"
        << "        in.act = MlpAct::" << actEnumName(in.act) << ";\n"
        << "        in.actScale = " << floatLiteral(in.actScale) << ";  // " << decimal(in.actScale) << "\n"
        << "        in.combineScale = " << floatLiteral(in.combineScale) << ";  // " << decimal(in.combineScale) << "\n"
        << "        in.includeInput = " << in.includeInput << ";\n"
        << "        in.halfOffset = " << in.halfOffset << "ll;\n        in.floatOffset = " << in.floatOffset << "ll;\n"
        << "        in.biasOffset = " << in.biasOffset << "ll;\n        in.nextGemm = " << in.nextGemm << ";\n"
        << "        in.finalOutput = " << in.finalOutput << ";\n        in.splitPrecision = " << in.splitPrecision << ";\n"
        << "        in.coordInput = " << in.coordInput << ";\n        in.dotNext = " << in.dotNext << ";\n"
        << "        in.fusedIntoPrevious = " << in.fusedIntoPrevious << ";\n        in.dotOffset = " << in.dotOffset << "ll;\n"
        << "        in.fusedIntoNext = " << in.fusedIntoNext << ";\n        in.fourierInput = " << in.fourierInput << ";\n"
        << "        break;\n";
    }
    s << "      default: break;\n    }\n    return in;\n  }\n};\n";
  }
  s << "\n}  // namespace inr::cuda::generated\n";
  for (const GeneratedKernelSpec& k : kernels) {
    if (k.form < 0 || k.form >= int(forms.size()))
      throw std::invalid_argument("generated fused kernel: kernel of program form " + std::to_string(k.form) + " (there are " +
                                  std::to_string(forms.size()) + ")");
    if (k.tile != 128 && k.tile != 64 && k.tile != 32)
      throw std::invalid_argument("generated fused kernel: tile of " + std::to_string(k.tile) + " rows (128, 64 or 32)");
    if (k.kc != 64 && k.kc != 32)
      throw std::invalid_argument("generated fused kernel: weight chunk of " + std::to_string(k.kc) + " columns (64 or 32)");
    const int wr = k.tile / 32;
    s << "\n// Tiles of " << k.tile << " rows, weight chunks of " << k.kc << " columns"
      << (k.tangents ? ", tangent rows (value + gradient)" : ", values") << ", program " << k.form << ".\n"
      << "extern \"C\" __global__ void __launch_bounds__(" << wr * 128 << ", " << 4 / wr << ") " << generatedKernelName(k)
      << "(\n    inr::cuda::FusedParams P, const float4* __restrict__ points, int n, const unsigned* __restrict__ deviceCount,\n"
      << "    float* __restrict__ out, const int* __restrict__ scatter) {\n"
      << "  inr::cuda::fusedMlpTiles<" << wr << ", " << k.kc << ", " << (k.tangents ? "true" : "false") << ">(\n"
      << "      inr::cuda::ConstantProgram<inr::cuda::generated::Program" << k.form << ", " << k.tile
      << ">{}, P, points, n, deviceCount, out, scatter);\n}\n";
  }
  return s.str();
}

}  // namespace inr

namespace inr {

ModelKernelSource generateModelKernels(const MlpProgram& program, const std::vector<int>& tiles,
                                       const std::vector<int>& chunks, bool tangents) {
  ModelKernelSource m;
  m.forms.push_back(program);
  if (fusedLayoutOf(program).fusedFourier) m.forms.push_back(program.withEncodingsStored());
  for (int form = 0; form < int(m.forms.size()); ++form)
    for (const bool t : {false, true}) {
      if (t && !tangents) continue;
      for (const int tile : tiles)
        for (const int kc : chunks) m.kernels.push_back({form, tile, kc, t});
    }
  m.source = generateFusedKernelSource(m.forms, m.kernels);
  return m;
}

}  // namespace inr
