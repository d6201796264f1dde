// The program compiler, checked on every architecture family through the CPU emulation of the
// fused kernel's arithmetic (fp16 weights/activations, fp32 accumulation) against the fp32
// reference evaluator. Runs without a GPU.
#include "Evaluator/MlpProgram.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "Evaluator/CpuInrEvaluator.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

namespace inr {
namespace {

struct ErrorStats {
  double maxAbs = 0, meanAbs = 0, range = 0;
};

ErrorStats compareWithReference(const InrModel& model, int n, unsigned seed) {
  const MlpProgram program = MlpProgram::compile(model.architecture);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> inputs(std::size_t(n) * model.architecture.inputDim);
  for (auto& v : inputs) v = u(rng);
  std::vector<float> ref(n), emu(n);
  CpuInrEvaluator(model).evaluateNetwork(inputs.data(), n, ref.data());
  emulateFusedProgram(program, inputs.data(), n, emu.data());
  ErrorStats s;
  float lo = ref[0], hi = ref[0];
  for (int i = 0; i < n; ++i) {
    const double e = std::abs(double(ref[i]) - double(emu[i]));
    s.maxAbs = std::max(s.maxAbs, e);
    s.meanAbs += e / n;
    lo = std::min(lo, ref[i]);
    hi = std::max(hi, ref[i]);
  }
  s.range = hi - lo;
  return s;
}

TEST(MlpProgram, SirenCompilesToTwoBuffersWithFoldedOutput) {
  const InrModel m = bench::sirenPaper();
  const MlpProgram p = MlpProgram::compile(m.architecture);
  EXPECT_TRUE(p.fusable) << p.whyNotFused;
  EXPECT_EQ(p.numBuffers, 2);
  EXPECT_EQ(p.maxWidthPad, 256);
  ASSERT_EQ(p.instrs.size(), 7u) << p.describe();
  // First layer: coordinates split into fp16 hi/lo, then a tensor-core GEMM with packed weights.
  EXPECT_EQ(p.instrs[0].op, MlpOp::LoadInput);
  EXPECT_EQ(p.instrs[0].splitPrecision, 1);
  EXPECT_EQ(p.instrs[1].op, MlpOp::Gemm);
  EXPECT_EQ(p.instrs[1].coordInput, 1);
  EXPECT_EQ(p.instrs[1].act, MlpAct::Sine);
  for (int i = 1; i <= 5; ++i) EXPECT_EQ(p.instrs[i].op, MlpOp::Gemm);
  // The final dot rides on the last hidden GEMM's epilogue; the generic path still sees it.
  EXPECT_EQ(p.instrs.back().op, MlpOp::OutputDot);
  EXPECT_EQ(p.instrs.back().fusedIntoPrevious, 1);
  EXPECT_EQ(p.instrs[5].dotNext, 1);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(p.instrs[i].dotNext, 0);
  EXPECT_EQ(p.instrs[5].nextGemm, 1);  // prefetch wraps to the first GEMM, not the fused dot
}

TEST(MlpProgram, NarrowFinalLayerFoldsIntoTheLastGemm) {
  const InrModel m = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr");
  const MlpProgram p = MlpProgram::compile(m.architecture);
  ASSERT_GE(p.instrs.size(), 2u);
  EXPECT_EQ(p.instrs.back().op, MlpOp::Gemm) << p.describe();
  EXPECT_EQ(p.instrs.back().finalOutput, 1);
  EXPECT_EQ(p.instrs.back().dst, -1);
  EXPECT_EQ(p.instrs.back().fusedIntoPrevious, 1);
  EXPECT_EQ(p.instrs[p.instrs.size() - 2].dotNext, 1);
  // The fused final layer's weights are never staged: the stage holds the hidden GEMMs only.
  EXPECT_EQ(p.maxGemmOutPad, p.instrs[p.instrs.size() - 2].nPad);
}

TEST(MlpProgram, CoordNetFoldsResidualSumsIntoGemmEpilogues) {
  const InrModel m = bench::coordNetPaper();
  const MlpProgram p = MlpProgram::compile(m.architecture);
  EXPECT_TRUE(p.fusable) << p.whyNotFused << "\n" << p.describe();
  EXPECT_LE(p.numBuffers, MlpProgram::kMaxFusedBuffers);
  int folded = 0, combines = 0;
  for (const auto& in : p.instrs) {
    folded += in.op == MlpOp::Gemm && in.other >= 0;
    combines += in.op == MlpOp::Combine;
  }
  EXPECT_GE(folded, 7) << p.describe();  // the 192-wide blocks' sums ride on their last GEMM
  EXPECT_EQ(p.instrs.back().op, MlpOp::Output);
}

TEST(MlpProgram, EmulationMatchesFp32ReferenceWithinFp16Error) {
  struct Case {
    InrModel model;
    const char* name;
  };
  std::vector<Case> cases;
  cases.push_back({bench::sirenPaper(), "siren"});
  cases.push_back({bench::ffnPaper(), "ffn"});
  cases.push_back({bench::coordNetPaper(), "coordnet"});
  for (const auto& c : cases) {
    const ErrorStats s = compareWithReference(c.model, 256, 11);
    std::printf("%-9s fp16 emulation vs fp32: max abs %.3g, mean abs %.3g, output range %.3g\n", c.name, s.maxAbs,
                s.meanAbs, s.range);
    // Bounds for fp16 storage of weights and activations; the line above prints the errors.
    EXPECT_LT(s.meanAbs, 1e-3) << c.name;
    EXPECT_LT(s.maxAbs, 5e-3) << c.name;
  }
}

TEST(MlpProgram, ShippedModelsCompileAndEmulate) {
  int count = 0;
  for (const auto& path : test::shippedModels()) {  // throws (fails) when the folder is missing or empty
    const InrModel m = InrModel::loadFile(path);
    const ErrorStats s = compareWithReference(m, 512, 5);
    std::printf("%-28s max abs %.3g mean abs %.3g range %.3g\n", std::filesystem::path(path).filename().c_str(),
                s.maxAbs, s.meanAbs, s.range);
    EXPECT_LT(s.meanAbs, 2e-3 * std::max(1.0, s.range)) << path;
    EXPECT_LT(s.maxAbs, 2e-2 * std::max(1.0, s.range)) << path;
    ++count;
  }
  EXPECT_GT(count, 0);
}

// The FFN's encoding is computed inside its first GEMM's operand load: no buffer holds the
// 2m-wide encoding, so the buffers are as wide as the hidden layers.
TEST(MlpProgram, FourierEncodingFusesIntoTheFirstGemm) {
  const InrModel m = bench::ffnPaper();
  const MlpProgram p = MlpProgram::compile(m.architecture);
  ASSERT_GE(p.instrs.size(), 2u);
  EXPECT_EQ(p.instrs[0].op, MlpOp::Fourier) << p.describe();
  EXPECT_EQ(p.instrs[0].fusedIntoNext, 1);
  EXPECT_EQ(p.instrs[1].op, MlpOp::Gemm);
  EXPECT_EQ(p.instrs[1].fourierInput, 0);
  EXPECT_GT(p.instrs[1].kPad, 256) << "the paper FFN's encoding is 2 x 256 features wide";
  for (int w : p.bufferWidthPad) EXPECT_LE(w, 256) << p.describe();
  for (std::size_t i = 2; i < p.instrs.size(); ++i) EXPECT_EQ(p.instrs[i].fourierInput, -1);
  // Stored again (the mma.sync kernel's alternative): no fusion, the encoding's buffer wide enough.
  const MlpProgram stored = p.withEncodingsStored();
  for (const MlpInstr& in : stored.instrs) {
    EXPECT_EQ(in.fusedIntoNext, 0);
    EXPECT_EQ(in.fourierInput, -1);
  }
  EXPECT_GE(stored.bufferWidthPad[std::size_t(stored.instrs[0].dst)], p.instrs[1].kPad) << stored.describe();
}

// Every model (synthetic paper sizes, shipped and real ones) emulates bit-identically through
// the in-place buffer plan, which never needs more buffers; SIREN and FFN chains need one.
TEST(MlpProgram, GemmsInPlaceKeepTheArithmeticAndSaveBuffers) {
  std::vector<std::pair<std::string, InrModel>> models = {
      {"siren", bench::sirenPaper()}, {"ffn", bench::ffnPaper()}, {"coordnet", bench::coordNetPaper()}};
  for (const char* folder : {"models", "real"})
    for (const auto& path : test::shippedModels(folder)) models.emplace_back(path, InrModel::loadFile(path));
  for (const auto& [name, model] : models) {
    const MlpProgram p = MlpProgram::compile(model.architecture);
    const MlpProgram q = p.withGemmsInPlace(256);
    ASSERT_EQ(q.instrs.size(), p.instrs.size());
    EXPECT_LE(q.numBuffers, p.numBuffers) << name << "\n" << p.describe() << "\n" << q.describe();
    EXPECT_EQ(int(q.bufferWidthPad.size()), q.numBuffers);
    if (name == "siren" || name == "ffn") EXPECT_EQ(q.numBuffers, 1) << q.describe();
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    constexpr int n = 64;
    std::vector<float> inputs(std::size_t(n) * model.architecture.inputDim), a(n), b(n);
    for (auto& v : inputs) v = u(rng);
    emulateFusedProgram(p, inputs.data(), n, a.data());
    emulateFusedProgram(q, inputs.data(), n, b.data());
    for (int i = 0; i < n; ++i) ASSERT_EQ(a[i], b[i]) << name << " query " << i << "\n" << q.describe();
  }
}

// The wgmma kernel's split encoding (FusedParams::hopperSplitGemm): the paper FFN's stored
// program with its K 512 first GEMM also in place (alsoInPlace) runs on one buffer, the
// encoding's and the GEMM's, and emulates bit-identically to the stored program. (The emulation
// computes each GEMM into a temporary: the kernel's in-place overwrite is checked on the GPU, by
// CudaInrEvaluator's forced split configurations against the CPU reference.)
TEST(MlpProgram, StoredEncodingGemmInPlaceForTheSplitEncoding) {
  const MlpProgram p = MlpProgram::compile(bench::ffnPaper().architecture);
  ASSERT_EQ(p.instrs[1].fourierInput, 0) << p.describe();
  ASSERT_EQ(p.instrs[1].kPad, 512);
  const MlpProgram stored = p.withEncodingsStored();
  const MlpProgram plain = stored.withGemmsInPlace(256), split = stored.withGemmsInPlace(256, 1);
  EXPECT_EQ(plain.numBuffers, 2) << plain.describe();
  EXPECT_NE(plain.instrs[1].dst, plain.instrs[1].src) << plain.describe();
  EXPECT_EQ(split.numBuffers, 1) << split.describe();
  EXPECT_EQ(split.instrs[0].dst, split.instrs[1].src) << split.describe();
  EXPECT_EQ(split.instrs[1].dst, split.instrs[1].src) << split.describe();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  constexpr int n = 64;
  std::vector<float> inputs(std::size_t(n) * p.inputDim), a(n), b(n);
  for (auto& v : inputs) v = u(rng);
  emulateFusedProgram(stored, inputs.data(), n, a.data());
  emulateFusedProgram(split, inputs.data(), n, b.data());
  for (int i = 0; i < n; ++i) ASSERT_EQ(a[i], b[i]) << "query " << i << "\n" << split.describe();
}

}  // namespace
}  // namespace inr
