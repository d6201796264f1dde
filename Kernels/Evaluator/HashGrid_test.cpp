// Hash-grid encodings (Docs/FORMAT.md "hashgrid"): loading, the CPU reference against an
// independent double-precision reading of tiny-cuda-nn's definition written here, its gradient,
// and the GPU program's CPU emulation. The numpy and PyTorch cross-checks are in
// Testing/Python/test_hashgrid.py.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <type_traits>
#include <utility>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Encodings.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/HashGridModels.h"

namespace inr {
namespace {

using test::HashGridOptions;

// The whole network (hash grid, then linear/relu layers) in double.
double networkInDouble(const InrModel& m, std::vector<double> x) {
  for (const Layer& L : m.architecture.layers) {
    if (L.kind == LayerKind::HashGrid) {
      x = test::hashGridInDouble(L, x);
    } else if (L.kind == LayerKind::Linear) {
      std::vector<double> y(L.outWidth);
      for (int o = 0; o < L.outWidth; ++o) {
        y[o] = L.bias.empty() ? 0.0 : L.bias[o];
        for (int i = 0; i < L.inWidth; ++i) y[o] += double(L.weight[o * L.inWidth + i]) * x[i];
      }
      x = y;
    } else if (L.kind == LayerKind::ReLU) {
      for (double& v : x) v = std::max(v, 0.0);
    }
  }
  return x[0];
}

std::vector<float> randomInputs(std::size_t n, int dims, unsigned seed, float lo = 0.f, float hi = 1.f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  std::vector<float> x(n * dims);
  for (float& v : x) v = u(rng);
  return x;
}

TEST(HashGrid, LoadsTheControlFileWithTinyCudaNnLevels) {
  const InrModel m = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/malformed/valid_hashgrid_control.inr");
  const Layer& L = m.architecture.layers[0];
  ASSERT_EQ(L.kind, LayerKind::HashGrid);
  // Level 0: scale 2 * 1 - 1 = 1, resolution 2, 2^3 = 8 entries (dense); level 1: scale 3,
  // resolution 4, 64 vertices > 2^4 entries (hashed).
  EXPECT_EQ(L.hashGrid.levelScale, (std::vector<float>{1.f, 3.f}));
  EXPECT_EQ(L.hashGrid.levelResolution, (std::vector<std::uint32_t>{2, 4}));
  EXPECT_EQ(L.hashGrid.levelOffset, (std::vector<std::uint32_t>{0, 8}));
  EXPECT_EQ(L.hashGrid.levelSize, (std::vector<std::uint32_t>{8, 16}));
  EXPECT_EQ(L.outWidth, 4);
  EXPECT_EQ(m.architecture.parameterCount(), 48u + 4u);
  EXPECT_NE(m.architecture.summary().find("hashgrid(3->4: 2x2, 2^4, base 2, x2)"), std::string::npos)
      << m.architecture.summary();
}

TEST(HashGrid, DenseLevelsInterpolateALinearTableExactly) {
  // A dense level whose entries hold a linear function of their vertex reproduces that function
  // of x * scale + 0.5 anywhere the cell's upper vertices stay inside the grid (x < 0.8 here).
  HashGridOptions o;
  o.levels = 2;
  o.featuresPerLevel = 1;
  o.log2TableSize = 12;
  o.baseResolution = 4;  // scales 3 and 7: 4^3 and 8^3 vertices, both dense
  o.hiddenLayers = 0;
  InrModel m = test::hashGridModel(o);
  Layer& L = m.architecture.layers[0];
  for (int l = 0; l < 2; ++l) {
    const std::uint32_t res = L.hashGrid.levelResolution[l];
    ASSERT_LE(res * res * res, L.hashGrid.levelSize[l]);
    for (std::uint32_t i = 0; i < res * res * res; ++i)
      L.weight[L.hashGrid.levelOffset[l] + i] = 0.25f * (i % res) + 0.5f * (i / res % res) - 0.125f * (i / res / res);
  }
  m.architecture.layers[1].weight = {1.f, 10.f};  // level 0 plus 10 x level 1
  m.architecture.layers[1].bias = {0.f};
  const CpuInrEvaluator e(m);
  const std::vector<float> x = randomInputs(500, 3, 5, 0.f, 0.8f);
  std::vector<float> got(500);
  e.evaluateNetwork(x.data(), 500, got.data());
  for (int q = 0; q < 500; ++q) {
    double want = 0;
    for (int l = 0; l < 2; ++l) {
      const double s = L.hashGrid.levelScale[l];
      const double p[3] = {s * x[3 * q] + 0.5, s * x[3 * q + 1] + 0.5, s * x[3 * q + 2] + 0.5};
      want += (l ? 10 : 1) * (0.25 * p[0] + 0.5 * p[1] - 0.125 * p[2]);
    }
    ASSERT_NEAR(got[q], want, 2e-5 * (1 + std::abs(want))) << q;
  }
}

TEST(HashGrid, HashedLevelReadsTheInstantNgpHashEntry) {
  // Scale 4 (base 5, one level) puts vertex v at the exact input (v - 0.5) / 4, where the
  // interpolation weight is all on v: the value is the entry the hash names. 5^3 vertices do not
  // fit 2^4 entries, so the level is hashed; entry i holds i.
  HashGridOptions o;
  o.levels = 1;
  o.featuresPerLevel = 1;
  o.log2TableSize = 4;
  o.baseResolution = 5;
  o.hiddenLayers = 0;
  InrModel m = test::hashGridModel(o);
  Layer& L = m.architecture.layers[0];
  ASSERT_EQ(L.hashGrid.levelSize[0], 16u);
  for (int i = 0; i < 16; ++i) L.weight[i] = float(i);
  m.architecture.layers[1].weight = {1.f};
  m.architecture.layers[1].bias = {0.f};
  const CpuInrEvaluator e(m);
  for (std::uint32_t vx : {0u, 1u, 3u})
    for (std::uint32_t vy : {0u, 2u, 4u})
      for (std::uint32_t vz : {1u, 3u}) {
        const float x[3] = {(vx - 0.5f) / 4, (vy - 0.5f) / 4, (vz - 0.5f) / 4};
        float got;
        e.evaluateNetwork(x, 1, &got);
        const std::uint32_t hash = (vx * 1u) ^ (vy * 2654435761u) ^ (vz * 805459861u);
        EXPECT_EQ(got, float(hash % 16)) << vx << " " << vy << " " << vz;
      }
}

TEST(HashGrid, CornerEntriesMatchTheVertexHash) {
  // The fused kernels' per-axis form (HashGridCorners) against hashGridEntry, vertex by vertex:
  // dense and hashed levels, power-of-2 and other sizes, cells inside, at the edge and far out
  // of the grid (the wrapped uint32 arithmetic).
  std::mt19937 rng(3);
  auto check = [&](auto dimsTag) {
    constexpr int D = decltype(dimsTag)::value;
    for (const std::uint32_t res : {3u, 16u, 25u, 1000u})
      for (const std::uint32_t entries : {24u, 4096u, 65536u, 1u << 19})
        for (int trial = 0; trial < 200; ++trial) {
          std::uint32_t lower[4];
          for (int d = 0; d < D; ++d)
            lower[d] = trial < 100 ? rng() % res : trial < 150 ? res - 1 : std::uint32_t(rng());
          const HashGridCorners<D> corners(lower, res, entries);
          for (int c = 0; c < (1 << D); ++c) {
            std::uint32_t v[4];
            for (int d = 0; d < D; ++d) v[d] = lower[d] + ((c >> d) & 1);
            ASSERT_EQ(corners.entry(c), hashGridEntry(v, D, res, entries)) << D << "D res " << res << " entries " << entries;
          }
        }
  };
  check(std::integral_constant<int, 3>{});
  check(std::integral_constant<int, 4>{});
}

// Issue 34's parity target with fp16 tables: the fused kernels' arithmetic (emulated: fp16 table,
// features and activations, fp32 accumulation) within 1e-3 of the value range of the fp32
// reference on random points, on the issue's network shape with fp32 tables (not
// fp16-representable) and on the shipped hash-grid model.
TEST(HashGrid, FusedArithmeticMeetsTheParityTarget) {
  std::vector<std::pair<std::string, InrModel>> models;
  InrModel issue = test::hashGridModel(test::hashGridMlp(4, 16, 14, 16, 1.5, 64, 2));
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> jitter(-1e-3f, 1e-3f);
  for (float& v : issue.architecture.layers[0].weight) v += jitter(rng);
  models.emplace_back("issue network, 2^14 entries, fp32 table", std::move(issue));
  models.emplace_back("hashgrid_mri_head_small",
                      InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/real/hashgrid_mri_head_small.inr"));
  for (const auto& [name, m] : models) {
    const MlpProgram program = MlpProgram::compile(m.architecture);
    const std::size_t n = 20000;
    const std::vector<float> x = randomInputs(n, m.architecture.inputDim, 23);
    std::vector<float> ref(n), emu(n);
    CpuInrEvaluator(m).evaluateNetwork(x.data(), n, ref.data());
    emulateFusedProgram(program, x.data(), n, emu.data());
    const auto [lo, hi] = std::minmax_element(ref.begin(), ref.end());
    double worst = 0, mean = 0;
    for (std::size_t q = 0; q < n; ++q) {
      worst = std::max(worst, double(std::abs(emu[q] - ref[q])));
      mean += std::abs(emu[q] - ref[q]) / double(n);
    }
    const double range = double(*hi - *lo);
    std::printf("%-40s fused (emulated) vs fp32: max %.3g mean %.3g, range %.3g (max %.2e of the range)\n", name.c_str(),
                worst, mean, range, worst / range);
    EXPECT_LT(worst, 1e-3 * range) << name;
  }
}

class HashGridVariants : public ::testing::TestWithParam<HashGridOptions> {};

TEST_P(HashGridVariants, CpuEvaluatorMatchesTheDoubleReading) {
  const InrModel m = test::hashGridModel(GetParam());
  const int D = m.architecture.inputDim;
  const CpuInrEvaluator e(m);
  const std::size_t n = 3001;
  // Inputs a little beyond [0, 1] too: vertices past the grid wrap, as in tiny-cuda-nn.
  const std::vector<float> x = randomInputs(n, D, 11, -0.05f, 1.05f);
  std::vector<float> got(n);
  e.evaluateNetwork(x.data(), n, got.data());
  std::vector<double> want(n);
  for (std::size_t q = 0; q < n; ++q) want[q] = networkInDouble(m, std::vector<double>(x.begin() + q * D, x.begin() + (q + 1) * D));
  const auto [lo, hi] = std::minmax_element(want.begin(), want.end());
  const double range = std::max(*hi - *lo, 1e-3);
  double worst = 0;
  for (std::size_t q = 0; q < n; ++q) worst = std::max(worst, std::abs(got[q] - want[q]));
  EXPECT_LT(worst, 1e-4 * range) << "range " << range;
}

TEST_P(HashGridVariants, GradientMatchesFiniteDifferencesOfTheDoubleReading) {
  const InrModel m = test::hashGridModel(GetParam());
  const CpuInrEvaluator e(m);
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> u(-0.9f, 0.9f);
  int checked = 0;
  for (int q = 0; q < 300; ++q) {
    const QueryPoint p{u(rng), u(rng), u(rng), 0.37f};
    float value, g[3];
    e.evaluateWithGradient(&p, 1, &value, g);
    // World [-1, 1] maps onto network [0, 1]: d input / d world = 1/2.
    const double in[4] = {(p.x + 1) / 2.0, (p.y + 1) / 2.0, (p.z + 1) / 2.0, 0.37};
    for (int a = 0; a < 3; ++a) {
      const double h = 1e-7;
      auto at = [&](double dx) {
        std::vector<double> x(in, in + m.architecture.inputDim);
        x[a] += dx;
        return networkInDouble(m, x);
      };
      // One-sided differences that disagree: a cell boundary (or ReLU kink) lies within h.
      const double left = (at(0) - at(-h)) / h, right = (at(h) - at(0)) / h;
      if (std::abs(left - right) > 1e-3 * (1 + std::abs(left))) continue;
      ++checked;
      EXPECT_NEAR(g[a], 0.5 * (left + right) / 2, 2e-3 * (1 + std::abs(left))) << "query " << q << " axis " << a;
    }
  }
  EXPECT_GT(checked, 600);  // most points are nowhere near a kink
}

TEST_P(HashGridVariants, GpuProgramEmulationMatchesTheCpuReference) {
  // The program the fused kernels run (encoding from fp16 tables in fp32, stored as fp16, GEMMs in
  // fp16 with fp32 accumulation), emulated on the CPU: the fp16 error stays well below the value
  // range.
  const InrModel m = test::hashGridModel(GetParam());
  const MlpProgram program = MlpProgram::compile(m.architecture);
  EXPECT_NE(program.describe().find("hashgrid"), std::string::npos) << program.describe();
  const int D = m.architecture.inputDim;
  const std::size_t n = 2000;
  const std::vector<float> x = randomInputs(n, D, 17);
  std::vector<float> ref(n), emu(n);
  CpuInrEvaluator(m).evaluateNetwork(x.data(), n, ref.data());
  emulateFusedProgram(program, x.data(), n, emu.data());
  const auto [lo, hi] = std::minmax_element(ref.begin(), ref.end());
  double worst = 0;
  for (std::size_t q = 0; q < n; ++q) worst = std::max(worst, double(std::abs(emu[q] - ref[q])));
  EXPECT_LT(worst, 5e-3 * std::max(double(*hi - *lo), 1e-3));
}

HashGridOptions variant(int dims, bool smoothstep, int features, std::string include, int levels, double scale) {
  HashGridOptions o;
  o.dims = dims;
  o.smoothstep = smoothstep;
  o.featuresPerLevel = features;
  o.includeInput = std::move(include);
  o.levels = levels;
  o.perLevelScale = scale;
  o.log2TableSize = 10;
  o.baseResolution = 3;
  o.seed = unsigned(dims * 100 + features * 10 + levels);
  return o;
}

INSTANTIATE_TEST_SUITE_P(Configs, HashGridVariants,
                         ::testing::Values(variant(3, false, 2, "none", 8, 1.7),   // dense and hashed levels
                                           variant(3, true, 4, "last", 6, 2.0),    // smoothstep, inputs after
                                           variant(4, false, 2, "first", 6, 1.5),  // 4D, inputs first
                                           variant(4, true, 1, "none", 12, 1.38),
                                           variant(3, false, 8, "none", 4, 3.0)));

}  // namespace
}  // namespace inr
