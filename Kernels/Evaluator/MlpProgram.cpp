#include "Evaluator/MlpProgram.h"

#include <algorithm>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "Common/Half.h"

namespace inr {
namespace {

int pad16(int w) { return (w + 15) / 16 * 16; }

MlpAct actOf(LayerKind k) {
  switch (k) {
    case LayerKind::Sine: return MlpAct::Sine;
    case LayerKind::SiLU: return MlpAct::SiLU;
    case LayerKind::ReLU: return MlpAct::ReLU;
    case LayerKind::Sigmoid: return MlpAct::Sigmoid;
    case LayerKind::Tanh: return MlpAct::Tanh;
    default: return MlpAct::None;
  }
}

bool isActivation(LayerKind k) {
  return k == LayerKind::Sine || k == LayerKind::SiLU || k == LayerKind::ReLU || k == LayerKind::Sigmoid ||
         k == LayerKind::Tanh || k == LayerKind::Identity;
}

// A value flowing through the graph: a buffer, or the raw coordinates (buf = -1).
struct Value {
  int buf = -1;
  int width = 0;
  bool owned = false;  // this list may free / overwrite it
};

class Compiler {
public:
  explicit Compiler(MlpProgram& p) : p_(p) {}

  int alloc() {
    for (std::size_t i = 0; i < inUse_.size(); ++i)
      if (!inUse_[i]) {
        inUse_[i] = true;
        return int(i);
      }
    inUse_.push_back(true);
    p_.numBuffers = std::max<int>(p_.numBuffers, int(inUse_.size()));
    return int(inUse_.size()) - 1;
  }
  void release(const Value& v) {
    if (v.owned && v.buf >= 0) inUse_[v.buf] = false;
  }
  void noteWidth(int w) { p_.maxWidthPad = std::max(p_.maxWidthPad, pad16(w)); }

  Value materialise(const Value& v) {
    if (v.buf >= 0) return v;
    MlpInstr in;
    in.op = MlpOp::LoadInput;
    in.dst = alloc();
    in.outWidth = v.width;
    in.nPad = pad16(v.width);
    noteWidth(v.width);
    p_.instrs.push_back(in);
    return {in.dst, v.width, true};
  }

  std::int64_t pushFloats(const std::vector<float>& v) {
    // 16-byte aligned, so the kernels can read biases as float2/float4.
    while (p_.floatWeights.size() % 4) p_.floatWeights.push_back(0.f);
    const std::int64_t off = std::int64_t(p_.floatWeights.size());
    p_.floatWeights.insert(p_.floatWeights.end(), v.begin(), v.end());
    return off;
  }

  // A linear layer (weights scaled by inScale for folded scale layers) with its following
  // activation fused. `finalOutput`: the network's last layer, to width 1.
  Value linear(const Layer& L, Value x, float inScale, MlpAct act, float w0, bool finalOutput) {
    std::vector<float> W(L.weight.size());
    std::vector<float> b(L.outWidth, 0.f);
    const float s = act == MlpAct::Sine ? w0 : 1.f;
    for (std::size_t i = 0; i < W.size(); ++i) W[i] = L.weight[i] * inScale * s;
    for (int o = 0; o < L.outWidth; ++o) b[o] = (L.bias.empty() ? 0.f : L.bias[o]) * s;
    MlpInstr in;
    in.src = x.buf;
    in.inWidth = L.inWidth;
    in.outWidth = L.outWidth;
    in.kPad = pad16(L.inWidth);
    in.nPad = pad16(L.outWidth);
    in.act = act;
    std::vector<float> bp(in.nPad, 0.f);
    std::copy(b.begin(), b.end(), bp.begin());
    in.biasOffset = pushFloats(bp);
    const bool tensorCores = x.buf >= 0 && L.inWidth > 16;
    auto packHalf = [&]() {
      in.halfOffset = std::int64_t(p_.halfWeights.size());
      p_.halfWeights.resize(p_.halfWeights.size() + std::size_t(in.nPad) * in.kPad, 0);
      for (int o = 0; o < L.outWidth; ++o)
        for (int k = 0; k < L.inWidth; ++k)
          p_.halfWeights[in.halfOffset + std::int64_t(o) * in.kPad + k] = floatToHalfBits(W[std::size_t(o) * L.inWidth + k]);
    };
    if (finalOutput) {
      in.floatOffset = pushFloats(W);
      if (tensorCores && L.inWidth <= 64) {
        // The final dot product on tensor cores too (a 16-wide GEMM whose column 0 is the
        // output, kept in fp32 and written straight to the result): faster on the small models
        // (K <= 64, one weight chunk); for K = 256 the four synchronised chunks with a quarter of
        // the warps busy made SIREN slower than the fp32 dot (figures: Benchmarks/RESULTS.md,
        // "Figures moved out of code comments").
        in.op = MlpOp::Gemm;
        in.finalOutput = 1;
        packHalf();
      } else {
        in.op = MlpOp::OutputDot;
      }
      p_.instrs.push_back(in);
      release(x);
      return {-1, 1, false};
    }
    noteWidth(L.outWidth);
    in.floatOffset = pushFloats(W);  // Gemm: the fp32 copy is the generic (cuBLAS) path's
    if (x.buf < 0 && L.inWidth <= 4 && L.outWidth > 16) {
      // First layer from the coordinates on tensor cores, in split precision (see splitPrecision).
      MlpInstr ld;
      ld.op = MlpOp::LoadInput;
      ld.splitPrecision = 1;
      ld.dst = alloc();
      ld.outWidth = 12;
      ld.nPad = 16;
      noteWidth(16);
      p_.instrs.push_back(ld);
      in.op = MlpOp::Gemm;
      in.coordInput = 1;
      in.src = ld.dst;
      in.kPad = 16;
      in.halfOffset = std::int64_t(p_.halfWeights.size());
      p_.halfWeights.resize(p_.halfWeights.size() + std::size_t(in.nPad) * 16, 0);
      for (int o = 0; o < L.outWidth; ++o)
        for (int k = 0; k < L.inWidth; ++k) {
          const float w = W[std::size_t(o) * L.inWidth + k];
          const std::uint16_t hi = floatToHalfBits(w);
          const std::uint16_t lo = floatToHalfBits(w - halfBitsToFloat(hi));
          std::uint16_t* row = &p_.halfWeights[in.halfOffset + std::int64_t(o) * 16];
          row[k] = hi;      // x_hi * W_hi
          row[4 + k] = hi;  // x_lo * W_hi
          row[8 + k] = lo;  // x_hi * W_lo
        }
      x = Value{ld.dst, 12, true};
    } else if (!tensorCores) {
      in.op = MlpOp::DenseFp32;
    } else {
      in.op = MlpOp::Gemm;
      packHalf();
    }
    release(x);  // consumed; free before allocating dst only if owned (dst must differ from src)
    in.dst = alloc();
    if (in.dst == x.buf) {  // never write a GEMM over its own input: take another buffer
      in.dst = alloc();
      inUse_[x.buf] = false;
    }
    p_.instrs.push_back(in);
    return {in.dst, L.outWidth, true};
  }

  Value list(const std::vector<Layer>& layers, Value x, bool topLevel) {
    Value cur = x;
    float pendingScale = 1.f;
    for (std::size_t i = 0; i < layers.size(); ++i) {
      const Layer& L = layers[i];
      const bool last = topLevel && i + 1 == layers.size();
      switch (L.kind) {
        case LayerKind::Scale:
          if (i + 1 < layers.size() && layers[i + 1].kind == LayerKind::Linear) {
            pendingScale *= L.param;  // folded into the next linear's weights
          } else {
            cur = activationInPlace(cur, MlpAct::None, L.param);
          }
          break;
        case LayerKind::Linear: {
          MlpAct act = MlpAct::None;
          float w0 = 1.f;
          bool fusedAct = false;
          if (i + 1 < layers.size() && isActivation(layers[i + 1].kind)) {
            act = actOf(layers[i + 1].kind);
            w0 = layers[i + 1].param;
            fusedAct = true;
          }
          const bool isFinal = topLevel && L.outWidth == 1 && (i + 1 == layers.size() || (fusedAct && i + 2 == layers.size()));
          cur = linear(L, cur, pendingScale, act, w0, isFinal);
          pendingScale = 1.f;
          if (fusedAct) ++i;
          if (isFinal) return cur;
          break;
        }
        case LayerKind::Fourier:
        case LayerKind::HashGrid: cur = encoding(L, cur); break;
        case LayerKind::Identity: break;
        case LayerKind::Sine:
        case LayerKind::SiLU:
        case LayerKind::ReLU:
        case LayerKind::Sigmoid:
        case LayerKind::Tanh: {
          cur = activationInPlace(cur, actOf(L.kind), L.kind == LayerKind::Sine ? L.param : 1.f);
          break;
        }
        case LayerKind::Residual: cur = residual(L, cur); break;
      }
      (void)last;
    }
    if (topLevel) {
      MlpInstr in;
      in.op = MlpOp::Output;
      cur = materialise(cur);
      in.src = cur.buf;
      in.inWidth = cur.width;
      p_.instrs.push_back(in);
      release(cur);
      return {-1, 1, false};
    }
    return cur;
  }

  // An encoding layer (Fourier, hash grid) of x into a fresh buffer (never x's own: the
  // encoding reads all of x for every column).
  Value encoding(const Layer& L, const Value& x) {
    MlpInstr in;
    in.op = L.kind == LayerKind::Fourier ? MlpOp::Fourier : MlpOp::HashGrid;
    in.src = x.buf;
    in.inWidth = L.inWidth;
    in.outWidth = L.outWidth;
    in.kPad = pad16(L.inWidth);
    in.nPad = pad16(L.outWidth);
    in.includeInput = L.includeInput == IncludeInput::None ? 0 : L.includeInput == IncludeInput::First ? 1 : 2;
    if (L.kind == LayerKind::Fourier) {
      std::vector<float> B(L.weight.size());
      for (std::size_t k = 0; k < B.size(); ++k) B[k] = L.weight[k] * L.param;  // B pre-scaled
      in.floatOffset = pushFloats(B);
    } else {
      in.floatOffset = pushFloats(packHashGrid(L));
      // The fused kernels gather from an fp16 copy of the table, as tiny-cuda-nn stores it: half
      // the bytes, so a large table stays in L2. 16-byte aligned: an entry of 8 features is one
      // load there.
      while (p_.halfWeights.size() % 8) p_.halfWeights.push_back(0);
      in.halfOffset = std::int64_t(p_.halfWeights.size());
      for (float v : L.weight) p_.halfWeights.push_back(floatToHalfBits(v));
    }
    noteWidth(L.outWidth);
    release(x);
    in.dst = alloc();
    if (in.dst == x.buf) {
      in.dst = alloc();
      inUse_[x.buf] = false;
    }
    p_.instrs.push_back(in);
    return {in.dst, in.outWidth, true};
  }

  // act(scale * x) over the value, in a buffer this list owns (a Scale layer not folded into a
  // linear is MlpAct::None: a plain multiply).
  Value activationInPlace(Value v, MlpAct act, float scale) {
    v = ownedCopy(v);
    MlpInstr in;
    in.op = MlpOp::Activation;
    in.dst = in.src = v.buf;
    in.outWidth = v.width;
    in.nPad = pad16(v.width);
    in.act = act;
    in.actScale = scale;
    p_.instrs.push_back(in);
    return v;
  }

  // A buffer this list may overwrite: the value itself if owned, else a copy.
  Value ownedCopy(const Value& v) {
    if (v.owned && v.buf >= 0) return v;
    if (v.buf < 0) return materialise(v);
    MlpInstr in;  // copy = combine with scale 1 and no other... use Activation(None) on a copy
    in.op = MlpOp::Combine;
    in.src = v.buf;
    in.other = -1;
    in.dst = alloc();
    in.outWidth = v.width;
    in.nPad = pad16(v.width);
    in.combineScale = 1.f;
    p_.instrs.push_back(in);
    return {in.dst, v.width, true};
  }

  Value residual(const Layer& L, Value x) {
    // Shortcut first (it needs x, as does the body), so the body's last GEMM can fold the sum
    // into its epilogue: out = scale * (act(acc) + shortcut).
    Value borrowed = x;
    borrowed.owned = false;
    Value s;
    if (L.shortcut.empty()) {
      s = x.buf >= 0 ? borrowed : materialise(x);  // coordinates stay available to the body
    } else {
      s = list(L.shortcut, borrowed, false);
    }
    const std::size_t bodyStart = p_.instrs.size();
    // The body reads x but never frees it: x is released once, below, after the sum.
    Value bodyIn = x;
    bodyIn.owned = false;
    Value b = list(L.body, bodyIn, false);
    MlpInstr& lastBody = p_.instrs.back();
    const bool canFold = p_.instrs.size() > bodyStart && lastBody.op == MlpOp::Gemm && lastBody.dst == b.buf &&
                         lastBody.other < 0 && s.buf != b.buf;
    if (canFold) {
      lastBody.other = s.buf;
      lastBody.combineScale = L.residualScale;
    } else {
      b = ownedCopy(b);
      MlpInstr in;
      in.op = MlpOp::Combine;
      in.src = b.buf;
      in.other = s.buf;
      in.dst = b.buf;
      in.outWidth = b.width;
      in.nPad = pad16(b.width);
      in.combineScale = L.residualScale;
      p_.instrs.push_back(in);
    }
    if (s.buf != x.buf) release(s);
    release(x);
    return b;
  }

private:
  MlpProgram& p_;
  std::vector<bool> inUse_;
};

// Whether buffer b's value is read by instruction `from` or a later one before being overwritten.
// A standalone activation reads its destination (it works in place).
bool readsBeforeWrite(const std::vector<MlpInstr>& instrs, std::size_t from, int b) {
  for (std::size_t j = from; j < instrs.size(); ++j) {
    const MlpInstr& in = instrs[j];
    if (in.src == b || in.other == b || (in.op == MlpOp::Activation && in.dst == b)) return true;
    if (in.dst == b) return false;
  }
  return false;
}

// Per buffer, the widest value an instruction stores there (a fused encoding is never stored).
std::vector<int> bufferWidths(const MlpProgram& p) {
  std::vector<int> width(std::size_t(std::max(p.numBuffers, 1)), 16);
  for (const MlpInstr& in : p.instrs)
    if (in.dst >= 0 && !in.fusedIntoNext) width[std::size_t(in.dst)] = std::max(width[std::size_t(in.dst)], in.nPad);
  return width;
}

const char* opName(MlpOp op) {
  switch (op) {
    case MlpOp::LoadInput: return "load-input";
    case MlpOp::DenseFp32: return "dense-fp32";
    case MlpOp::Fourier: return "fourier-fp32";
    case MlpOp::HashGrid: return "hashgrid";
    case MlpOp::Gemm: return "gemm-fp16";
    case MlpOp::Activation: return "activation";
    case MlpOp::Combine: return "combine";
    case MlpOp::OutputDot: return "output-dot-fp32";
    case MlpOp::Output: return "output";
  }
  return "?";
}

const char* actName(MlpAct a) {
  switch (a) {
    case MlpAct::None: return "none";
    case MlpAct::Sine: return "sine";
    case MlpAct::SiLU: return "silu";
    case MlpAct::ReLU: return "relu";
    case MlpAct::Sigmoid: return "sigmoid";
    case MlpAct::Tanh: return "tanh";
  }
  return "?";
}

}  // namespace

std::vector<float> packHashGrid(const Layer& L) {
  const HashGridSpec& g = L.hashGrid;
  std::vector<float> packed(4 + 4 * std::size_t(g.levels) + L.weight.size());
  auto putWord = [&](std::size_t i, std::uint32_t u) { std::memcpy(&packed[i], &u, sizeof u); };
  putWord(0, std::uint32_t(g.levels));
  putWord(1, std::uint32_t(g.featuresPerLevel));
  putWord(2, g.smoothstep ? 1u : 0u);
  putWord(3, 0u);
  for (int l = 0; l < g.levels; ++l) {
    packed[4 + 4 * l] = g.levelScale[l];
    putWord(5 + 4 * l, g.levelResolution[l]);
    putWord(6 + 4 * l, g.levelOffset[l]);
    putWord(7 + 4 * l, g.levelSize[l]);
  }
  std::copy(L.weight.begin(), L.weight.end(), packed.begin() + 4 + 4 * g.levels);
  return packed;
}

MlpProgram MlpProgram::compile(const Architecture& arch) {
  MlpProgram p;
  p.inputDim = arch.inputDim;
  p.maxWidthPad = 16;
  Compiler c(p);
  c.list(arch.layers, Value{-1, arch.inputDim, false}, true);
  // The final dot product into the epilogue of the Gemm that produces its input (the final
  // instruction reads nothing else, so that Gemm's buffer need not be written).
  for (std::size_t i = 1; i < p.instrs.size(); ++i) {
    MlpInstr& fin = p.instrs[i];
    MlpInstr& prev = p.instrs[i - 1];
    const bool finalLinear = fin.op == MlpOp::OutputDot || (fin.op == MlpOp::Gemm && fin.finalOutput);
    if (finalLinear && i + 1 == p.instrs.size() && prev.op == MlpOp::Gemm && !prev.finalOutput &&
        prev.dst == fin.src && fin.inWidth == prev.outWidth && fin.floatOffset >= 0) {
      prev.dotNext = 1;
      fin.fusedIntoPrevious = 1;
      // A zero-padded copy of the dot weights (16-byte aligned), so the epilogue reads float2
      // pairs over the whole padded width.
      while (p.floatWeights.size() % 4) p.floatWeights.push_back(0.f);
      prev.dotOffset = std::int64_t(p.floatWeights.size());
      const std::int64_t w = fin.floatOffset;
      for (int k = 0; k < prev.nPad; ++k) p.floatWeights.push_back(k < fin.inWidth ? p.floatWeights[w + k] : 0.f);
    }
  }
  // A Fourier encoding of the coordinates read only by the next instruction, a Gemm, is computed
  // inside that Gemm's operand load (no 2m-wide buffer; Evaluator/Encodings.h fourierElement).
  for (std::size_t i = 0; i + 1 < p.instrs.size(); ++i) {
    MlpInstr& f = p.instrs[i];
    MlpInstr& g = p.instrs[i + 1];
    if (f.op != MlpOp::Fourier || f.src >= 0 || f.inWidth > 4 || g.op != MlpOp::Gemm || g.fusedIntoPrevious ||
        g.src != f.dst || g.other == f.dst)
      continue;
    if (readsBeforeWrite(p.instrs, i + 2, f.dst)) continue;
    f.fusedIntoNext = 1;
    g.fourierInput = int(i);
  }
  std::vector<int> gemms;
  for (std::size_t i = 0; i < p.instrs.size(); ++i)
    if (p.instrs[i].op == MlpOp::Gemm && !p.instrs[i].fusedIntoPrevious) gemms.push_back(int(i));
  for (std::size_t g = 0; g < gemms.size(); ++g) p.instrs[gemms[g]].nextGemm = gemms[(g + 1) % gemms.size()];
  p.bufferWidthPad = bufferWidths(p);
  for (const MlpInstr& in : p.instrs)
    if (in.op == MlpOp::Gemm && !in.fusedIntoPrevious) p.maxGemmOutPad = std::max(p.maxGemmOutPad, in.nPad);
  if (p.maxGemmOutPad > kMaxFusedGemmOut) {
    p.fusable = false;
    p.whyNotFused = "a linear layer has " + std::to_string(p.maxGemmOutPad) + " outputs (fused kernel: up to " +
                    std::to_string(kMaxFusedGemmOut) + ")";
  } else if (p.maxWidthPad > kMaxFusedWidth) {
    p.fusable = false;
    p.whyNotFused = "a layer is " + std::to_string(p.maxWidthPad) + " wide (fused kernel: up to " +
                    std::to_string(kMaxFusedWidth) + ")";
  } else if (p.numBuffers > kMaxFusedBuffers) {
    p.fusable = false;
    p.whyNotFused = "the graph needs " + std::to_string(p.numBuffers) + " live activation buffers (fused kernel: up to " +
                    std::to_string(kMaxFusedBuffers) + "; deeply nested residual blocks)";
  }
  return p;
}

MlpProgram MlpProgram::withEncodingsStored() const {
  MlpProgram p = *this;
  for (MlpInstr& in : p.instrs) {
    in.fusedIntoNext = 0;
    in.fourierInput = -1;
  }
  p.bufferWidthPad = bufferWidths(p);
  return p;
}

MlpProgram MlpProgram::withGemmsInPlace(int maxK, int alsoInPlace) const {
  MlpProgram p = *this;
  std::vector<int> slotOf(std::max(numBuffers, 1), -1);  // buffer -> slot holding its current value
  std::vector<bool> busy;
  auto take = [&]() {
    for (std::size_t s = 0; s < busy.size(); ++s)
      if (!busy[s]) {
        busy[s] = true;
        return int(s);
      }
    busy.push_back(true);
    return int(busy.size()) - 1;
  };
  for (std::size_t i = 0; i < instrs.size(); ++i) {
    const MlpInstr& in = instrs[i];
    MlpInstr& to = p.instrs[i];
    const int s = in.src >= 0 ? slotOf[in.src] : -1, o = in.other >= 0 ? slotOf[in.other] : -1;
    to.src = s;
    to.other = o;
    const bool srcDies = in.src >= 0 && in.src != in.dst && in.src != in.other && !readsBeforeWrite(instrs, i + 1, in.src);
    int d = -1;
    if (in.dst >= 0) {
      if (in.dst == in.src || (in.op == MlpOp::Activation && slotOf[in.dst] >= 0)) {
        d = slotOf[in.dst];  // already in place
      } else if (in.dst == in.other) {
        d = o;
      } else {
        // The destination's previous value is overwritten: its slot is free (it is not read here).
        if (slotOf[in.dst] >= 0) busy[slotOf[in.dst]] = false;
        slotOf[in.dst] = -1;
        // (a Gemm reading a fused encoding never reads its source buffer: any K)
        d = in.op == MlpOp::Gemm && (in.kPad <= maxK || in.fourierInput >= 0 || int(i) == alsoInPlace) && srcDies ? s : take();
      }
    }
    to.dst = d;
    if (srcDies && s != d) busy[s] = false;
    if (srcDies) slotOf[in.src] = -1;
    if (in.other >= 0 && in.other != in.dst && !readsBeforeWrite(instrs, i + 1, in.other)) {
      if (o != d) busy[o] = false;
      slotOf[in.other] = -1;
    }
    if (in.dst >= 0) slotOf[in.dst] = d;
  }
  p.numBuffers = int(busy.size());
  p.bufferWidthPad = bufferWidths(p);
  return p;
}

std::string MlpProgram::describe() const {
  std::ostringstream s;
  for (const MlpInstr& in : instrs) {
    s << opName(in.op) << " " << (in.src < 0 ? std::string("in") : "b" + std::to_string(in.src)) << "->"
      << (in.dst < 0 ? std::string("out") : "b" + std::to_string(in.dst)) << " " << in.inWidth << "->" << in.outWidth;
    if (in.act != MlpAct::None) s << " " << actName(in.act);
    if (in.other >= 0) s << " +b" << in.other << " x" << in.combineScale;
    if (in.finalOutput) s << " (final, fp32 result)";
    if (in.dotNext) s << " (+ final dot in the epilogue)";
    if (in.fusedIntoPrevious) s << " (fused into the previous gemm)";
    if (in.splitPrecision) s << " (fp16 hi/lo split)";
    if (in.fusedIntoNext) s << " (computed in the next gemm's operand load)";
    if (in.op == MlpOp::HashGrid) s << " (fp32 table; fused kernels: fp16 table)";
    s << "\n";
  }
  s << numBuffers << " buffers, width " << maxWidthPad << (fusable ? ", fused" : ", generic: " + whyNotFused);
  return s.str();
}

}  // namespace inr
