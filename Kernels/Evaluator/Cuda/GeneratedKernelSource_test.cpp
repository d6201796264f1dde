// The source of the fused kernels generated per network (Evaluator/MlpKernelSource.h), without a
// GPU: deterministic, rejecting programs the kernel cannot run with a clear error, and compiling
// with NVRTC (to PTX, which needs no GPU) for compute_90 and compute_80 for every shipped model
// and the paper-size synthetic ones, exactly as the evaluator generates it at model load.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include "Evaluator/Cuda/GeneratedKernels.h"
#include "Evaluator/Cuda/NvrtcCompiler.h"
#include "Evaluator/MlpKernelSource.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

namespace inr {
namespace {

std::vector<std::pair<std::string, InrModel>> everyModel() {
  std::vector<std::pair<std::string, InrModel>> out;
  out.emplace_back("SIREN paper", bench::sirenPaper());
  out.emplace_back("FFN paper", bench::ffnPaper());
  out.emplace_back("CoordNet paper", bench::coordNetPaper());
  out.emplace_back("HashGrid 3D + 2x64", test::hashGridModel(test::hashGridMlp(3, 16, 16, 16, 1.5, 64, 2)));
  for (const char* folder : {"models", "real"})
    for (const auto& path : test::shippedModels(folder))
      out.emplace_back(std::filesystem::path(path).filename().string(), InrModel::loadFile(path));
  return out;
}

// The line of `source` holding `text`, for a failure message.
std::string lineWith(const std::string& source, const std::string& text) {
  const std::size_t at = source.find(text);
  if (at == std::string::npos) return "(not found)";
  const std::size_t begin = source.rfind('\n', at) + 1, end = source.find('\n', at);
  return source.substr(begin, end - begin);
}

TEST(GeneratedKernelSource, IsDeterministicAndFollowsTheProgram) {
  const MlpProgram siren = MlpProgram::compile(bench::sirenPaper().architecture);
  const ModelKernelSource a = generateModelKernels(siren), b = generateModelKernels(MlpProgram::compile(bench::sirenPaper().architecture));
  EXPECT_EQ(a.source, b.source);
  // Every kernel is there under its name, one form (no fused encoding) with tangents.
  ASSERT_EQ(a.forms.size(), 1u);
  EXPECT_EQ(a.kernels.size(), 12u);
  for (const GeneratedKernelSpec& k : a.kernels)
    EXPECT_NE(a.source.find("void __launch_bounds__(" + std::to_string(k.tile * 4) + ", " + std::to_string(128 / k.tile) + ") " +
                            generatedKernelName(k) + "("),
              std::string::npos)
        << generatedKernelName(k);
  // The FFN's fused encoding gives the stored form too (as the interpreter's candidates have it).
  const ModelKernelSource ffn = generateModelKernels(MlpProgram::compile(bench::ffnPaper().architecture));
  ASSERT_EQ(ffn.forms.size(), 2u);
  EXPECT_NE(ffn.source.find("kFusedFourier = 1"), std::string::npos);
  EXPECT_NE(ffn.source.find("kFusedFourier = 0"), std::string::npos);
  // A constant of the program changed changes the text: the residual scale, exactly (an exact
  // hexadecimal literal; 0.5 = 0x800000 x 2^-24).
  MlpProgram changed = siren;
  int gemm = -1;
  for (std::size_t i = 0; i < changed.instrs.size() && gemm < 0; ++i)
    if (changed.instrs[i].op == MlpOp::Gemm) gemm = int(i);
  ASSERT_GE(gemm, 0);
  changed.instrs[std::size_t(gemm)].combineScale = 0.5f;
  const std::string c = generateModelKernels(changed).source;
  EXPECT_NE(c, a.source);
  EXPECT_NE(c.find("in.combineScale = 0x800000p-24f;  // 0.5"), std::string::npos) << lineWith(c, "combineScale");
  // Widths and activations are written as the program has them.
  const MlpInstr& g = siren.instrs[std::size_t(gemm)];
  EXPECT_NE(a.source.find("in.nPad = " + std::to_string(g.nPad) + ";"), std::string::npos);
  EXPECT_NE(a.source.find("in.act = MlpAct::Sine;"), std::string::npos);
  // No hash grid in the SIREN (its gathers are left out of the kernel), one in a hash-grid network.
  EXPECT_NE(a.source.find("kHashGrid = 0"), std::string::npos);
  EXPECT_NE(generateModelKernels(MlpProgram::compile(test::hashGridModel(test::hashGridMlp(3, 8, 12, 16, 1.5, 64, 2)).architecture))
                .source.find("kHashGrid = 1"),
            std::string::npos);
}

TEST(GeneratedKernelSource, RejectsAProgramTheKernelCannotRun) {
  const MlpProgram siren = MlpProgram::compile(bench::sirenPaper().architecture);
  auto message = [](const MlpProgram& p) -> std::string {
    try {
      generateModelKernels(p);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  MlpProgram p = siren;
  p.instrs[1].dst = 7;  // no such buffer
  EXPECT_NE(message(p).find("instruction 1"), std::string::npos) << message(p);
  EXPECT_NE(message(p).find("dst buffer 7"), std::string::npos) << message(p);
  p = siren;
  p.instrs[1].kPad = 20;  // not a multiple of 16
  EXPECT_NE(message(p).find("padded"), std::string::npos) << message(p);
  p = siren;
  p.instrs[1].combineScale = INFINITY;
  EXPECT_NE(message(p).find("non-finite scale"), std::string::npos) << message(p);
  p = siren;
  p.fusable = false;
  p.whyNotFused = "a test's reason";
  EXPECT_NE(message(p).find("a test's reason"), std::string::npos) << message(p);
  p = siren;
  p.instrs.resize(kMaxFusedInstrs + 1, p.instrs.back());
  EXPECT_NE(message(p).find("up to 64"), std::string::npos) << message(p);
  p = siren;
  p.instrs.back().op = MlpOp::Activation;
  p.instrs.back().fusedIntoPrevious = 0;
  EXPECT_FALSE(message(p).empty());
  // And the shipped programs pass.
  EXPECT_EQ(message(siren), "");
  // A kernel the generator does not know.
  EXPECT_THROW(generateFusedKernelSource({siren}, {{0, 96, 64, false}}), std::invalid_argument);
  EXPECT_THROW(generateFusedKernelSource({siren}, {{1, 128, 64, false}}), std::invalid_argument);
}

// What NVRTC says about a source that does not compile: the error names the file and quotes the
// log's first lines (how the evaluator's report says why it fell back).
TEST(GeneratedKernelSource, NvrtcErrorsQuoteTheLog) {
  const cuda::NvrtcOutput out = cuda::compileWithNvrtc("extern \"C\" __global__ void k() { undeclared_name(); }\n",
                                                       "broken.cu", "compute_90");
  EXPECT_FALSE(out.ok);
  EXPECT_NE(out.error.find("broken.cu"), std::string::npos) << out.error;
  EXPECT_NE(out.error.find("undeclared_name"), std::string::npos) << out.error;
}

// Every model's generated kernels, exactly the evaluator's set, through NVRTC's front end for
// Hopper (every template instantiated with the model's constants and checked), and for Ampere
// too for the four models built here (one per family: the Ampere path differs by architecture,
// not by model); and one kernel of the paper SIREN (values, tile 128, chunk 64) compiled to PTX for
// Ampere and one with tangent rows of the paper FFN (its stored form) for Hopper (NVRTC's
// optimiser is slow on a CI machine, so not for every model and architecture). The PTX has the
// kernel's entry.
TEST(GeneratedKernelSource, CompilesWithNvrtcForEveryModel) {
  ASSERT_FALSE(cuda::cudaToolkitIncludeDir().empty()) << "no CUDA include folder with cuda_fp16.h (INR_CUDA_INCLUDE_DIR)";
  std::printf("NVRTC %s, CUDA headers %s\n", cuda::nvrtcVersionString().c_str(), cuda::cudaToolkitIncludeDir().c_str());
  std::map<std::string, std::string> compiled;  // arch and source -> the first model that had them
  for (const auto& [name, model] : everyModel()) {
    const MlpProgram program = MlpProgram::compile(model.architecture);
    if (!program.fusable || int(program.instrs.size()) > kMaxFusedInstrs) {
      std::printf("%-36s not fusable: %s\n", name.c_str(), program.whyNotFused.c_str());
      continue;
    }
    const ModelKernelSource m = generateModelKernels(program);
    const bool builtHere = name.find(".inr") == std::string::npos;  // one per family, not a shipped file
    for (const char* arch : {"compute_90", "compute_80"}) {
      if (!builtHere && std::string(arch) == "compute_80") continue;
      // Models of one program shape generate the same source (the weights are not in it):
      // compiled once, the others named beside it.
      const auto [seen, first] = compiled.emplace(std::string(arch) + "\n" + m.source, name);
      if (!first) {
        std::printf("%-36s %s: the same source as %s\n", name.c_str(), arch, seen->second.c_str());
        continue;
      }
      const cuda::NvrtcOutput out = cuda::compileWithNvrtc(m.source, name + ".cu", arch, true);
      ASSERT_TRUE(out.ok) << name << " " << arch << ": " << out.error << "\n" << out.log;
      std::printf("%-36s %s: %zu kernels through the front end, %.2f s\n", name.c_str(), arch, m.kernels.size(), out.seconds);
    }
  }
  struct Full {
    InrModel model;
    GeneratedKernelSpec kernel;
    const char* arch;
  };
  for (const Full& f : {Full{bench::sirenPaper(), {0, 128, 64, false}, "compute_80"},
                        Full{bench::ffnPaper(), {1, 64, 32, true}, "compute_90"}}) {
    const MlpProgram program = MlpProgram::compile(f.model.architecture);
    std::vector<MlpProgram> forms = {program};
    if (f.kernel.form == 1) forms.push_back(program.withEncodingsStored());
    const std::string source = generateFusedKernelSource(forms, {f.kernel});
    const cuda::NvrtcOutput out = cuda::compileWithNvrtc(source, generatedKernelName(f.kernel) + ".cu", f.arch);
    ASSERT_TRUE(out.ok) << generatedKernelName(f.kernel) << " " << f.arch << ": " << out.error << "\n" << out.log;
    EXPECT_NE(out.image.find(".entry " + generatedKernelName(f.kernel)), std::string::npos) << f.arch;
    std::printf("%s %s: %zu KB PTX, %.2f s\n", generatedKernelName(f.kernel).c_str(), f.arch, out.image.size() / 1024,
                out.seconds);
  }
}

// The evaluator's default (GeneratedKernelUse::Auto) compiles a model's kernels in the background
// (GeneratedKernels::startInBackground): here without a GPU, up to what needs one (take() loads
// them). The values and tangent-row kernels of the configuration asked for compile into the disk
// cache; a second start finds them there, ready at once; a start dropped while compiling neither
// waits nor keeps the compile threads from a start after it.
TEST(GeneratedKernelSource, CompilesInTheBackgroundIntoTheCache) {
  const std::filesystem::path cache =
      std::filesystem::temp_directory_path() / ("inr-background-source-" + std::to_string(::getpid()));
  std::filesystem::remove_all(cache);
  const MlpProgram program = MlpProgram::compile(bench::sirenOfDepth(2, 5).architecture);
  const std::vector<cuda::GeneratedKernelConfig> configs{{64, 32, false}, {64, 32, false}};  // one, asked twice
  const auto cubins = [](const std::filesystem::path& dir) {
    int n = 0;
    if (std::filesystem::exists(dir))
      for (const auto& e : std::filesystem::directory_iterator(dir)) n += e.path().extension() == ".cubin" ? 1 : 0;
    return n;
  };
  std::string why;
  const auto t0 = std::chrono::steady_clock::now();
  auto cold = cuda::GeneratedKernels::startInBackground(program, 9, 0, (cache / "a").string(), configs, why);
  const double startSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(cold) << why;
  EXPECT_NE(cold->what().find("2 kernels for sm_90: 0 from the cache, 2 compiling in the background"), std::string::npos)
      << cold->what();
  cold->wait();
  const double readySeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(cold->ready());
  EXPECT_EQ(cubins(cache / "a"), 2);
  std::printf("started in %.3f s, compiled in %.2f s: %s\n", startSeconds, readySeconds, cold->what().c_str());
  auto warm = cuda::GeneratedKernels::startInBackground(program, 9, 0, (cache / "a").string(), configs, why);
  ASSERT_TRUE(warm) << why;
  EXPECT_TRUE(warm->ready()) << warm->what();
  EXPECT_NE(warm->what().find("2 from the cache, 0 compiling"), std::string::npos) << warm->what();
  // Dropped at once, then another start: it completes.
  cuda::GeneratedKernels::startInBackground(program, 9, 0, (cache / "b").string(), configs, why).reset();
  auto after = cuda::GeneratedKernels::startInBackground(program, 9, 0, (cache / "c").string(), configs, why);
  ASSERT_TRUE(after) << why;
  after->wait();
  EXPECT_EQ(cubins(cache / "c"), 2);
  // A program the generator refuses: no start, and why.
  MlpProgram broken = program;
  broken.fusable = false;
  broken.whyNotFused = "test";
  EXPECT_FALSE(cuda::GeneratedKernels::startInBackground(broken, 9, 0, (cache / "d").string(), configs, why));
  EXPECT_NE(why.find("not generated"), std::string::npos) << why;
  std::filesystem::remove_all(cache);
}

}  // namespace
}  // namespace inr
