// GPU evaluator against the CPU references (ctest label `cuda`). Without a usable GPU every test
// here is reported as skipped, with the reason.
#include "Evaluator/Cuda/CudaInrEvaluator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unistd.h>
#include <vector>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/ShippedModels.h"

namespace inr {
namespace {

using test::randomQueryPoints;

struct Err {
  double maxAbs = 0, meanAbs = 0;
};

Err compare(const std::vector<float>& a, const std::vector<float>& b) {
  Err e;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = std::abs(double(a[i]) - double(b[i]));
    if (!std::isfinite(a[i])) return {INFINITY, INFINITY};
    e.maxAbs = std::max(e.maxAbs, d);
    e.meanAbs += d / a.size();
  }
  return e;
}

// Options for one fixed fused configuration of the `mma` kernel (the first that fits, no timing).
CudaEvaluatorOptions fixedFused(FusedMma mma) {
  CudaEvaluatorOptions o;
  o.path = CudaEvaluatorPath::Fused;
  o.mma = mma;
  o.autotuneBatch = 0;
  return o;
}

// The fused kernels' arithmetic emulated on the CPU (emulateFusedProgram) for the first `count`
// world points, through the model's input and output mappings.
std::vector<float> emulated(const InrModel& model, const std::vector<QueryPoint>& pts, std::size_t count) {
  const int D = model.architecture.inputDim;
  std::vector<float> net(count * D), emu(count);
  for (std::size_t q = 0; q < count; ++q) {
    const double w[4] = {pts[q].x, pts[q].y, pts[q].z, pts[q].t};
    for (int i = 0; i < D; ++i) {
      const int c = model.domain.inputOrder[i];
      net[q * D + i] = float(model.domain.toNetwork[c].apply(w[c]));
    }
  }
  emulateFusedProgram(MlpProgram::compile(model.architecture), net.data(), count, emu.data());
  for (std::size_t q = 0; q < count; ++q) {
    float a, b;
    model.output.affineAt(pts[q].t, a, b);
    emu[q] = a * emu[q] + b;
  }
  return emu;
}

// Hash grids (tiny-cuda-nn's HashGrid): 16 levels of 2 features with 2^16 entries (dense coarse
// levels, hashed fine ones) into 2 x 64 ReLU; and a 4D smoothstep grid with the inputs appended.
InrModel hashGrid3d() { return test::hashGridModel(test::hashGridMlp(3, 16, 16, 16, 1.5, 64, 2)); }

InrModel hashGrid4d() {
  test::HashGridOptions o = test::hashGridMlp(4, 8, 14, 4, 2.0, 64, 2);
  o.featuresPerLevel = 4;
  o.smoothstep = true;
  o.includeInput = "last";
  o.seed = 4;
  return test::hashGridModel(o);
}

std::vector<std::pair<std::string, InrModel>> allModels() {
  std::vector<std::pair<std::string, InrModel>> out;
  out.emplace_back("SIREN paper", bench::sirenPaper());
  out.emplace_back("FFN paper", bench::ffnPaper());
  out.emplace_back("CoordNet paper", bench::coordNetPaper());
  out.emplace_back("HashGrid 3D + 2x64", hashGrid3d());
  out.emplace_back("HashGrid 4D smoothstep", hashGrid4d());
  for (const char* folder : {"models", "real"})
    for (const auto& path : test::shippedModels(folder))
      out.emplace_back(std::filesystem::path(path).filename().string(), InrModel::loadFile(path));
  return out;
}

TEST(CudaInrEvaluator, FusedMatchesCpuReferenceOnEveryModel) {
  REQUIRE_GPU();
  for (const auto& [name, model] : allModels()) {
    const CudaInrEvaluator gpu(model);
    const auto pts = randomQueryPoints(model, 20011, 3);  // not a multiple of the tile
    std::vector<float> ref(pts.size()), got(pts.size(), NAN);
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    gpu.evaluate(pts.data(), pts.size(), got.data());
    const Err e = compare(got, ref);
    float lo = *std::min_element(ref.begin(), ref.end()), hi = *std::max_element(ref.begin(), ref.end());
    std::printf("%-30s %-44s max abs %.3g  mean abs %.3g  (range %.3g)\n", name.c_str(), gpu.name().substr(0, 44).c_str(),
                e.maxAbs, e.meanAbs, hi - lo);
    const double scale = std::max(1.0, double(hi - lo));
    EXPECT_LT(e.meanAbs, 2e-3 * scale) << name;
    EXPECT_LT(e.maxAbs, 3e-2 * scale) << name;
  }
}

TEST(CudaInrEvaluator, FusedMatchesItsCpuEmulationClosely) {
  REQUIRE_GPU();
  // Same arithmetic (fp16 storage, fp32 accumulation): differences come only from summation
  // order and fast-math sine, so the bound is much tighter than against fp32.
  for (const auto& [name, model] : allModels()) {
    const MlpProgram program = MlpProgram::compile(model.architecture);
    if (!program.fusable) continue;
    const auto pts = randomQueryPoints(model, 4000, 9);
    const std::vector<float> emu = emulated(model, pts, pts.size());
    std::vector<float> got(pts.size());
    CudaInrEvaluator(model).evaluate(pts.data(), pts.size(), got.data());
    const Err e = compare(got, emu);
    std::printf("%-30s fused vs emulation: max abs %.3g mean abs %.3g\n", name.c_str(), e.maxAbs, e.meanAbs);
    EXPECT_LT(e.meanAbs, 5e-4) << name;
  }
}

// The Hopper kernel (wgmma, sm_90a) in each of its launch configurations, forced, against the
// CPU in fp32 (the bounds of the mma.sync kernel) and against the fp16 emulation.
TEST(CudaInrEvaluator, WgmmaKernelMatchesCpuReferenceAndEmulation) {
  REQUIRE_GPU();
  {
    CudaEvaluatorOptions o;
    o.path = CudaEvaluatorPath::Fused;
    o.mma = FusedMma::Wgmma;
    o.autotuneBatch = 0;
    try {
      const CudaInrEvaluator probe(bench::sirenPaper(), o);
    } catch (const std::runtime_error& e) {
      GTEST_SKIP() << "wgmma kernel unavailable here: " << e.what();
    }
  }
  for (const auto& [name, model] : allModels()) {
    const MlpProgram program = MlpProgram::compile(model.architecture);
    if (!program.fusable) continue;
    // The fp32 comparison on the points of FusedMatchesCpuReferenceOnEveryModel (its bounds are
    // fp16 error bounds for those points: on another draw the fp16 arithmetic itself, emulated,
    // comes within 2% of the maximum bound on coordnet_cylinder_u), the emulation (slow) on the
    // first kEmulated of them.
    const auto pts = randomQueryPoints(model, 20011, 3);  // not a multiple of the tile
    constexpr std::size_t kEmulated = 4001;
    std::vector<float> ref(pts.size());
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    const std::vector<float> emu = emulated(model, pts, kEmulated);
    const float lo = *std::min_element(ref.begin(), ref.end()), hi = *std::max_element(ref.begin(), ref.end());
    const double scale = std::max(1.0, double(hi - lo));
    // Both chunk widths: two consumers with and without turns, then one consumer; 20011 points =
    // 313 tiles of 64, so with two consumers the last round leaves one without queries (it must
    // keep the pace and write nothing), and the last tile is partial. A program with a fused
    // Fourier encoding (the FFNs) also with the encoding stored once per tile (stored 1) and, where
    // its GEMM's K is 257..512 (the paper FFN), stored split (2): every case is tried; one
    // consumer with 64-column chunks must fit stored, two with 64-column chunks split (the
    // others may not fit).
    struct Case {
      int consumers, pingPong, columns, stored, columnSplit = 0;
    };
    bool fusedFourier = false, splits = false;
    for (const MlpInstr& in : program.instrs) {
      fusedFourier |= in.fourierInput >= 0;
      splits |= in.fourierInput >= 0 && in.kPad > 256 && in.kPad <= 512;
    }
    // Two consumers on one tile with its columns split (the last two of the first eight) take
    // the fused and the stored encoding, not the split one.
    std::vector<Case> cases = {{2, 0, 128, 0}, {2, 1, 128, 0}, {2, 0, 64, 0}, {2, 1, 64, 0},
                               {1, 0, 128, 0}, {1, 0, 64, 0},  {2, 0, 128, 0, 1}, {2, 0, 64, 0, 1}};
    for (const int stored : {1, 2})
      if (stored == 1 ? fusedFourier : splits)
        for (int i = 0; i < (stored == 1 ? 8 : 6); ++i)
          cases.push_back({cases[i].consumers, cases[i].pingPong, cases[i].columns, stored, cases[i].columnSplit});
    // The fused form's output per configuration (consumers, turns, columns, columns split),
    // against which the stored forms of the same configuration are compared element by element:
    // the same fp16 encoding and the same MMAs in the same K order, so the same bits (bounded at
    // 1e-6 of the range rather than 0). And per form and chunk width the outputs of two consumers
    // on two tiles without turns and of one consumer, against which the same on one tile with its
    // columns split is compared: the same arithmetic per element but a final dot's halves summed
    // apart (fp32 reordering only).
    std::map<std::tuple<int, int, int, int>, std::vector<float>> fusedOutputs;
    std::map<std::tuple<int, int, int>, std::vector<float>> tileOutputs;  // (consumers, stored, columns)
    for (const Case& k : cases) {
      const int consumers = k.consumers, pingPong = k.pingPong, columns = k.columns, stored = k.stored;
      CudaEvaluatorOptions o = fixedFused(FusedMma::Wgmma);
      o.wgmmaPingPong = pingPong;
      o.wgmmaChunkColumns = columns;
      o.wgmmaConsumers = consumers;
      o.wgmmaColumnSplit = k.columnSplit;
      if (fusedFourier) o.storedEncoding = stored;
      const std::string which = " consumers " + std::to_string(consumers) + " turns " + std::to_string(pingPong) + " N " +
                                std::to_string(columns) + (k.columnSplit ? " one tile, columns split" : "") +
                                (stored == 2 ? " stored encoding split" : stored ? " stored encoding" : "");
      std::unique_ptr<CudaInrEvaluator> made;
      try {
        made = std::make_unique<CudaInrEvaluator>(model, o);
      } catch (const std::runtime_error& e) {  // every model fits with 64-column chunks (>= 2 slots)
        if (stored) {
          // (the columns split has one tile's shared memory, as one consumer)
          ASSERT_FALSE(columns == 64 && (consumers == 1 || stored == 2 || k.columnSplit))
              << name << " (stored encoding " << stored << "): " << e.what();
        } else {
          ASSERT_EQ(columns, 128) << name << ": " << e.what();
        }
        std::printf("%-30s%s: does not fit (%s)\n", name.c_str(), which.c_str(), e.what());
        continue;
      }
      const CudaInrEvaluator& gpu = *made;
      ASSERT_TRUE(gpu.usesWgmma()) << name << ": " << gpu.launchReport();
      ASSERT_NE(gpu.launchReport().find("wgmma " + std::to_string(consumers) + "x64"), std::string::npos) << gpu.launchReport();
      ASSERT_EQ(gpu.launchReport().find("stored encoding") != std::string::npos, stored > 0) << gpu.launchReport();
      ASSERT_EQ(gpu.launchReport().find("stored encoding split") != std::string::npos, stored == 2) << gpu.launchReport();
      ASSERT_EQ(gpu.launchReport().find("columns split") != std::string::npos, k.columnSplit == 1) << gpu.launchReport();
      std::vector<float> got(pts.size(), NAN);
      gpu.evaluate(pts.data(), pts.size(), got.data());
      const Err e = compare(got, ref), em = compare(std::vector<float>(got.begin(), got.begin() + kEmulated), emu);
      std::printf("%-30s %s: vs fp32 max %.3g mean %.3g; vs emulation mean %.3g\n", name.c_str(),
                  gpu.launchReport().c_str(), e.maxAbs, e.meanAbs, em.meanAbs);
      EXPECT_LT(e.meanAbs, 2e-3 * scale) << name << which;
      EXPECT_LT(e.maxAbs, 3e-2 * scale) << name << which;
      EXPECT_LT(em.meanAbs, 5e-4) << name << which;
      if (pingPong == 0 && !k.columnSplit) tileOutputs[std::make_tuple(consumers, stored, columns)] = got;
      if (k.columnSplit) {
        for (const int tiles : {2, 1}) {  // two consumers on two tiles, one consumer
          const auto found = tileOutputs.find(std::make_tuple(tiles, stored, columns));
          if (found == tileOutputs.end()) continue;  // did not fit
          const Err t = compare(got, found->second);
          std::printf("%-30s %s: vs %s max %.3g mean %.3g\n", name.c_str(), which.c_str(),
                      tiles == 2 ? "two tiles" : "one consumer", t.maxAbs, t.meanAbs);
          EXPECT_LT(t.maxAbs, 1e-4 * scale) << name << which << " against " << tiles << " consumer tile(s)";
        }
        // A race would show as a run that differs: twice more over the batch, and over a batch of
        // two tiles, the last partial (the kernel is deterministic, so the same bits each time).
        for (int again = 0; again < 2; ++again) {
          std::vector<float> rerun(pts.size(), NAN);
          gpu.evaluate(pts.data(), pts.size(), rerun.data());
          EXPECT_EQ(0, std::memcmp(rerun.data(), got.data(), got.size() * sizeof(float))) << name << which << " run " << again + 2;
        }
        std::vector<float> small(100, NAN);
        gpu.evaluate(pts.data(), small.size(), small.data());
        EXPECT_EQ(0, std::memcmp(small.data(), got.data(), small.size() * sizeof(float))) << name << which << ", 100 queries";
      }
      const auto key = std::make_tuple(consumers, pingPong, columns, k.columnSplit);
      if (!fusedFourier) continue;
      if (stored == 0) {
        fusedOutputs[key] = got;
      } else if (fusedOutputs.count(key)) {
        const Err f = compare(got, fusedOutputs[key]);
        std::printf("%-30s %s: vs the fused form max %.3g mean %.3g\n", name.c_str(), which.c_str(), f.maxAbs, f.meanAbs);
        EXPECT_LE(f.maxAbs, 1e-6 * scale) << name << which << " against the fused form";
      }
    }
  }
}

// The paper FFN's 512-wide encoding is computed inside the first GEMM's operand load, so the
// mma.sync kernel runs it at the 128-query tile (before: 64 at most, the encoding buffer alone
// took 130 KB of shared memory), with the accuracy of the stored encoding.
TEST(CudaInrEvaluator, FusedFourierEncodingRunsAtTheLargestTile) {
  REQUIRE_GPU();
  const InrModel model = bench::ffnPaper();
  CudaEvaluatorOptions o;
  o.path = CudaEvaluatorPath::Fused;
  o.mma = FusedMma::MmaSync;
  o.tileQueries = 128;
  o.autotuneBatch = 0;
  const CudaInrEvaluator gpu(model, o);
  EXPECT_NE(gpu.launchReport().find("tile 128"), std::string::npos) << gpu.launchReport();
  EXPECT_EQ(gpu.launchReport().find("stored encoding"), std::string::npos) << gpu.launchReport();
  const auto pts = randomQueryPoints(model, 5003, 9);
  std::vector<float> ref(pts.size()), got(pts.size(), NAN);
  CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
  gpu.evaluate(pts.data(), pts.size(), got.data());
  const Err e = compare(got, ref);
  const float lo = *std::min_element(ref.begin(), ref.end()), hi = *std::max_element(ref.begin(), ref.end());
  const double scale = std::max(1.0, double(hi - lo));
  std::printf("ffn paper, fused encoding, %s: vs fp32 max %.3g mean %.3g\n", gpu.launchReport().c_str(), e.maxAbs, e.meanAbs);
  EXPECT_LT(e.meanAbs, 2e-3 * scale);
  EXPECT_LT(e.maxAbs, 3e-2 * scale);
}

// The hash-grid gathers from fp16 tables (Cuda/FusedHashGrid.cuh), on both kernels and in both
// lane arrangements: identical outputs for the two arrangements (the same arithmetic), close to
// the emulation of that arithmetic, and within issue 34's parity target against the fp32
// reference (1e-3 of the value range; the emulation's own margin: HashGrid_test.cpp).
TEST(CudaInrEvaluator, HashGridGathersMatchEmulationAndParityTarget) {
  REQUIRE_GPU();
  std::vector<std::pair<std::string, InrModel>> models;
  models.emplace_back("HashGrid 3D + 2x64", hashGrid3d());
  models.emplace_back("HashGrid 4D smoothstep", hashGrid4d());
  models.emplace_back("hashgrid_mri_head_small",
                      InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/real/hashgrid_mri_head_small.inr"));
  for (const auto& [name, model] : models) {
    const auto pts = randomQueryPoints(model, 20011, 8);
    constexpr std::size_t kEmulated = 4001;
    std::vector<float> ref(pts.size());
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    const std::vector<float> emu = emulated(model, pts, kEmulated);
    const float lo = *std::min_element(ref.begin(), ref.end()), hi = *std::max_element(ref.begin(), ref.end());
    for (const FusedMma mma : {FusedMma::MmaSync, FusedMma::Wgmma}) {
      std::vector<float> byPairs[2];
      for (const int pairs : {1, 0}) {
        CudaEvaluatorOptions o = fixedFused(mma);
        o.hashGridPairs = pairs;
        std::unique_ptr<CudaInrEvaluator> gpu;
        try {
          gpu = std::make_unique<CudaInrEvaluator>(model, o);
        } catch (const std::runtime_error& e) {
          ASSERT_EQ(mma, FusedMma::Wgmma) << name << ": " << e.what();
          std::printf("%-26s wgmma unavailable: %s\n", name.c_str(), e.what());
          break;
        }
        std::vector<float>& got = byPairs[pairs];
        got.assign(pts.size(), NAN);
        gpu->evaluate(pts.data(), pts.size(), got.data());
        const Err e = compare(got, ref), em = compare(std::vector<float>(got.begin(), got.begin() + kEmulated), emu);
        std::printf("%-26s %s: vs fp32 max %.3g (%.2e of the range) mean %.3g; vs emulation max %.3g mean %.3g\n",
                    name.c_str(), gpu->launchReport().c_str(), e.maxAbs, e.maxAbs / (hi - lo), e.meanAbs, em.maxAbs,
                    em.meanAbs);
        EXPECT_LT(e.maxAbs, 1e-3 * (hi - lo)) << name << " " << gpu->launchReport();
        EXPECT_LT(em.meanAbs, 5e-4) << name << " " << gpu->launchReport();
      }
      if (!byPairs[0].empty() && !byPairs[1].empty())
        for (std::size_t q = 0; q < pts.size(); ++q) ASSERT_EQ(byPairs[0][q], byPairs[1][q]) << name << " query " << q;
    }
  }
}

TEST(CudaInrEvaluator, GenericPathMatchesCpuInFp32) {
  REQUIRE_GPU();
  for (const auto& [name, model] : allModels()) {
    CudaEvaluatorOptions o;
    o.path = CudaEvaluatorPath::Generic;
    const CudaInrEvaluator gpu(model, o);
    const auto pts = randomQueryPoints(model, 70001, 5);  // spans two generic chunks
    std::vector<float> ref(pts.size()), got(pts.size(), NAN);
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    gpu.evaluate(pts.data(), pts.size(), got.data());
    const Err e = compare(got, ref);
    std::printf("%-30s generic fp32: max abs %.3g mean abs %.3g\n", name.c_str(), e.maxAbs, e.meanAbs);
    EXPECT_LT(e.maxAbs, 1e-3) << name;
    EXPECT_LT(e.meanAbs, 1e-4) << name;
  }
}

TEST(CudaInrEvaluator, HashGridPerThreadNetworkMatchesCpuInFp32) {
  REQUIRE_GPU();
  for (const InrModel& model : {hashGrid3d(), hashGrid4d()}) {
    const CudaPerThreadMlp gpu(model);
    const auto pts = randomQueryPoints(model, 20011, 6);
    std::vector<float> ref(pts.size()), got(pts.size(), NAN);
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    gpu.evaluate(pts.data(), pts.size(), got.data());
    const Err e = compare(got, ref);
    std::printf("%-30s per-thread fp32: max abs %.3g mean abs %.3g\n", model.architecture.summary().substr(0, 30).c_str(),
                e.maxAbs, e.meanAbs);
    EXPECT_LT(e.maxAbs, 1e-3);
    EXPECT_LT(e.meanAbs, 1e-4);
  }
}

TEST(CudaInrEvaluator, ScatterWritesThroughTheIndexArray) {
  REQUIRE_GPU();
  const InrModel model = bench::sirenPaper();
  const CudaInrEvaluator gpu(model);
  const int n = 1000;
  const auto pts = randomQueryPoints(model, n, 1);
  std::vector<int> idx(n);
  for (int i = 0; i < n; ++i) idx[i] = (i * 7919) % n;  // a permutation (7919 prime, coprime to n)
  cuda::DeviceBuffer<float4> dPts(n);
  cuda::DeviceBuffer<float> dOut(n);
  cuda::DeviceBuffer<int> dIdx(n);
  INR_CUDA_CHECK(cudaMemcpy(dPts.get(), pts.data(), n * sizeof(float4), cudaMemcpyHostToDevice));
  INR_CUDA_CHECK(cudaMemcpy(dIdx.get(), idx.data(), n * sizeof(int), cudaMemcpyHostToDevice));
  INR_CUDA_CHECK(cudaMemset(dOut.get(), 0xff, n * sizeof(float)));  // NaN poison
  gpu.evaluateDevice(dPts.get(), n, dOut.get(), dIdx.get(), nullptr);
  std::vector<float> scattered(n), direct(n);
  INR_CUDA_CHECK(cudaMemcpy(scattered.data(), dOut.get(), n * sizeof(float), cudaMemcpyDeviceToHost));
  gpu.evaluate(pts.data(), n, direct.data());
  for (int i = 0; i < n; ++i) ASSERT_EQ(scattered[idx[i]], direct[i]) << i;
}

// The count comes from device memory (as the pipeline's traversal writes it): exactly the first
// *count points are evaluated, on both paths, with the configuration for the bound.
TEST(CudaInrEvaluator, DeviceCountBoundsTheBatch) {
  REQUIRE_GPU();
  const InrModel model = bench::sirenPaper();
  for (CudaEvaluatorPath path : {CudaEvaluatorPath::Fused, CudaEvaluatorPath::Generic}) {
    CudaEvaluatorOptions o;
    o.path = path;
    const CudaInrEvaluator gpu(model, o);
    for (const int bound : {3000, 70000}) {  // below and above the small-batch threshold
      const int count = bound - 777;
      const auto pts = randomQueryPoints(model, bound, 5);
      cuda::DeviceBuffer<float4> dPts(bound);
      cuda::DeviceBuffer<float> dOut(bound);
      cuda::DeviceBuffer<unsigned> dCount(1);
      INR_CUDA_CHECK(cudaMemcpy(dPts.get(), pts.data(), bound * sizeof(float4), cudaMemcpyHostToDevice));
      const unsigned c = unsigned(count);
      INR_CUDA_CHECK(cudaMemcpy(dCount.get(), &c, sizeof c, cudaMemcpyHostToDevice));
      INR_CUDA_CHECK(cudaMemset(dOut.get(), 0xff, bound * sizeof(float)));  // NaN poison
      gpu.evaluateDevice(dPts.get(), dCount.get(), bound, dOut.get(), nullptr, nullptr);
      std::vector<float> got(bound), direct(count);
      INR_CUDA_CHECK(cudaMemcpy(got.data(), dOut.get(), bound * sizeof(float), cudaMemcpyDeviceToHost));
      gpu.evaluate(pts.data(), count, direct.data());
      for (int i = 0; i < count; ++i) ASSERT_EQ(got[i], direct[i]) << i << " bound " << bound;
      for (int i = count; i < bound; ++i) ASSERT_TRUE(std::isnan(got[i])) << "wrote past the count at " << i;
    }
  }
}

// The kernels generated for each model (issue 50: the mma.sync kernel with the program as
// compile-time constants, compiled by NVRTC at construction) in two configurations (tile 128 x
// K 64 and tile 32 x K 32: four and one warp row groups, both weight chunks) and, for a fused
// Fourier encoding, both forms: the same code as the interpreter with constants, so the same
// bits as the interpreter in the same configuration (values, and values with gradients), within
// the interpreter's bounds of the fp16 emulation and of the CPU reference.
TEST(CudaInrEvaluator, GeneratedKernelsMatchTheInterpreterBitForBit) {
  REQUIRE_GPU();
  for (const auto& [name, model] : allModels()) {
    const MlpProgram program = MlpProgram::compile(model.architecture);
    if (!program.fusable) continue;
    bool fusedFourier = false;
    for (const MlpInstr& in : program.instrs) fusedFourier |= in.fourierInput >= 0;
    const auto pts = randomQueryPoints(model, 20011, 3);  // not a multiple of the tile
    constexpr std::size_t kEmulated = 4001;
    std::vector<float> ref(pts.size());
    CpuInrEvaluator(model).evaluate(pts.data(), pts.size(), ref.data());
    const std::vector<float> emu = emulated(model, pts, kEmulated);
    const float lo = *std::min_element(ref.begin(), ref.end()), hi = *std::max_element(ref.begin(), ref.end());
    const double scale = std::max(1.0, double(hi - lo));
    int configurationsRun = 0;
    for (const auto& [tile, kc] : {std::pair<int, int>{128, 64}, {32, 32}})
      for (const int stored : {0, 1}) {
        if (stored && !fusedFourier) continue;
        auto options = [&](GeneratedKernelUse use) {
          CudaEvaluatorOptions o = fixedFused(FusedMma::MmaSync);
          o.tileQueries = tile;
          o.weightChunk = kc;
          o.generatedKernels = use;
          o.tangentAutotuneBatch = 0;
          if (fusedFourier) o.storedEncoding = stored;
          return o;
        };
        const std::string which = name + " tile " + std::to_string(tile) + " x K " + std::to_string(kc) +
                                  (stored ? " stored encoding" : "");
        // A configuration the model's shared memory does not fit is impossible for the interpreter
        // too (the constructor says so): it is left out, said, and each model must run one.
        std::unique_ptr<CudaInrEvaluator> interpreted;
        try {
          interpreted = std::make_unique<CudaInrEvaluator>(model, options(GeneratedKernelUse::Off));
        } catch (const std::runtime_error& e) {
          // Only that refusal: any other failure of the interpreter fails the test.
          if (std::string(e.what()).find("impossible for this model") == std::string::npos) throw;
          std::printf("%-30s not built for this model (the interpreter neither): %s\n", which.c_str(), e.what());
          continue;
        }
        const CudaInrEvaluator& interpreter = *interpreted;
        ++configurationsRun;
        std::unique_ptr<CudaInrEvaluator> made;
        try {
          made = std::make_unique<CudaInrEvaluator>(model, options(GeneratedKernelUse::Only));
        } catch (const std::runtime_error& e) {
          FAIL() << which << ": no generated kernel: " << e.what();
        }
        const CudaInrEvaluator& generated = *made;
        ASSERT_TRUE(generated.usesGeneratedKernel()) << which << ": " << generated.launchReport();
        ASSERT_FALSE(interpreter.usesGeneratedKernel()) << which << ": " << interpreter.launchReport();
        std::vector<float> a(pts.size(), NAN), b(pts.size(), NAN);
        interpreter.evaluate(pts.data(), pts.size(), a.data());
        generated.evaluate(pts.data(), pts.size(), b.data());
        for (std::size_t q = 0; q < pts.size(); ++q) ASSERT_EQ(a[q], b[q]) << which << " query " << q;
        const Err e = compare(b, ref), em = compare(std::vector<float>(b.begin(), b.begin() + kEmulated), emu);
        std::printf("%-30s %s: vs fp32 max %.3g mean %.3g; vs emulation mean %.3g [%s]\n", which.c_str(),
                    generated.launchReport().substr(0, 60).c_str(), e.maxAbs, e.meanAbs, em.meanAbs,
                    generated.generatedKernelReport().c_str());
        EXPECT_LT(e.meanAbs, 2e-3 * scale) << which;
        EXPECT_LT(e.maxAbs, 3e-2 * scale) << which;
        EXPECT_LT(em.meanAbs, 5e-4) << which;
        // Value + gradient (the tangent rows), where the model runs them.
        if (!interpreter.usesFusedTangents()) continue;
        ASSERT_TRUE(generated.usesFusedTangents()) << which << ": " << generated.gradientPath();
        ASSERT_NE(generated.gradientPath().find("generated tile"), std::string::npos) << which << ": " << generated.gradientPath();
        const std::size_t n = 5003;
        std::vector<float> va(n), vb(n), ga(3 * n), gb(3 * n);
        interpreter.evaluateWithGradient(pts.data(), n, va.data(), ga.data());
        generated.evaluateWithGradient(pts.data(), n, vb.data(), gb.data());
        for (std::size_t q = 0; q < n; ++q) {
          ASSERT_EQ(va[q], vb[q]) << which << " value with gradient, query " << q;
          for (int k = 0; k < 3; ++k) ASSERT_EQ(ga[3 * q + k], gb[3 * q + k]) << which << " gradient " << k << ", query " << q;
        }
      }
    EXPECT_GE(configurationsRun, 1) << name << ": no configuration of the test fits the model";
  }
}

// The default (GeneratedKernelUse::Auto): the constructor returns without waiting for NVRTC, the
// generated twins of the chosen configuration compile in the background, the built-in kernel
// answers meanwhile, and once they are ready they are timed against it and the faster kept: the
// same bits before, during and after, values and gradients. From the disk cache the next
// evaluator adopts them in its constructor; an evaluator destroyed while they compile neither
// waits nor leaves anything that hangs the next.
TEST(CudaInrEvaluator, GeneratedKernelsInTheBackground) {
  REQUIRE_GPU();
  const std::filesystem::path cache =
      std::filesystem::temp_directory_path() / ("inr-background-kernels-" + std::to_string(::getpid()));
  std::filesystem::remove_all(cache);
  for (const auto& [name, model] : {std::pair<std::string, InrModel>{"SIREN 4-256x5-1", bench::sirenPaper()},
                                    {"HashGrid 3D + 2x64", hashGrid3d()}}) {
    CudaEvaluatorOptions o;
    o.path = CudaEvaluatorPath::Fused;
    o.mma = FusedMma::MmaSync;  // one configuration, so the interpreter's and the twin's bits are one
    o.tileQueries = 128;
    o.weightChunk = 64;
    o.hashGridPairs = 1;
    o.kernelCacheDir = (cache / "a").string();
    CudaEvaluatorOptions off = o;
    off.generatedKernels = GeneratedKernelUse::Off;
    o.generatedKernels = GeneratedKernelUse::Auto;
    const CudaInrEvaluator interpreter(model, off);
    const CudaInrEvaluator background(model, o);
    ASSERT_TRUE(background.generatedKernelsPending()) << name << ": " << background.generatedKernelReport();
    EXPECT_NE(background.generatedKernelReport().find("compiling in the background"), std::string::npos)
        << background.generatedKernelReport();
    EXPECT_FALSE(background.usesGeneratedKernel());
    const auto pts = randomQueryPoints(model, 20011, 5);
    const std::size_t n = 5003;
    std::vector<float> a(pts.size()), b(pts.size()), va(n), vb(n), ga(3 * n), gb(3 * n);
    interpreter.evaluate(pts.data(), pts.size(), a.data());
    interpreter.evaluateWithGradient(pts.data(), n, va.data(), ga.data());
    auto sameBits = [&](const char* when) {
      std::fill(b.begin(), b.end(), NAN);
      background.evaluate(pts.data(), pts.size(), b.data());
      for (std::size_t q = 0; q < pts.size(); ++q) ASSERT_EQ(a[q], b[q]) << name << ", " << when << ", query " << q;
      background.evaluateWithGradient(pts.data(), n, vb.data(), gb.data());
      for (std::size_t q = 0; q < n; ++q) {
        ASSERT_EQ(va[q], vb[q]) << name << ", " << when << ", value with gradient " << q;
        for (int k = 0; k < 3; ++k) ASSERT_EQ(ga[3 * q + k], gb[3 * q + k]) << name << ", " << when << ", gradient " << q;
      }
    };
    sameBits("while compiling");
    background.waitForGeneratedKernels();
    EXPECT_FALSE(background.generatedKernelsPending());
    const std::string report = background.generatedKernelReport();
    EXPECT_NE(report.find("2 kernels for sm_"), std::string::npos) << report;  // values and tangent rows
    EXPECT_NE(report.find("in the background"), std::string::npos) << report;
    EXPECT_NE(background.launchReport().find("generated kernels ready: "), std::string::npos) << background.launchReport();
    sameBits("after the adoption");
    std::printf("%-22s %s\n    %s\n    gradients: %s\n", name.c_str(), background.usesGeneratedKernel() ? "generated kernel kept" : "built-in kept",
                background.launchReport().c_str(), background.gradientPath().c_str());
    // The disk cache: adopted before the constructor returns.
    const CudaInrEvaluator cached(model, o);
    EXPECT_FALSE(cached.generatedKernelsPending());
    EXPECT_NE(cached.generatedKernelReport().find("2 from the cache"), std::string::npos) << cached.generatedKernelReport();
    EXPECT_NE(cached.launchReport().find("generated kernels ready: "), std::string::npos) << cached.launchReport();
    // Destroyed while compiling (a cold cache of its own), then built again.
    o.kernelCacheDir = (cache / "b").string();
    { const CudaInrEvaluator dropped(model, o); }
    const CudaInrEvaluator again(model, o);
    again.waitForGeneratedKernels();
    EXPECT_NE(again.generatedKernelReport().find("2 kernels for sm_"), std::string::npos) << again.generatedKernelReport();
  }
  std::filesystem::remove_all(cache);
}

// Turned off, or impossible to build, the generated kernels leave the built-in ones running and
// the report says why.
TEST(CudaInrEvaluator, GeneratedKernelsOffLeaveTheInterpreter) {
  REQUIRE_GPU();
  CudaEvaluatorOptions o;
  o.generatedKernels = GeneratedKernelUse::Off;
  o.autotuneBatch = 0;
  const CudaInrEvaluator gpu(bench::sirenPaper(), o);
  EXPECT_FALSE(gpu.usesGeneratedKernel());
  EXPECT_NE(gpu.name().find("generated kernels: off"), std::string::npos) << gpu.name();
}

}  // namespace
}  // namespace inr
