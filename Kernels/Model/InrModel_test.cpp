#include "Model/InrModel.h"

#include <gtest/gtest.h>

#include "TestSupport/TestModelBuilder.h"

namespace inr {
namespace {

using nlohmann::json;
using test::buildSafeTensors;
using test::modelMetadata;

const json kTinyArch = {{"input_dim", 4},
                        {"layers",
                         {{{"type", "linear"}, {"weight", "l0.w"}, {"bias", "l0.b"}},
                          {{"type", "sine"}, {"w0", 30}},
                          {{"type", "linear"}, {"weight", "l1.w"}, {"bias", nullptr}}}}};

std::vector<test::TensorSpec> tinyTensors() {
  return {{"l0.w", {2, 4}, {1, 0, 0, 0, 0, 1, 0, 0}}, {"l0.b", {2}, {0.5f, -0.5f}}, {"l1.w", {1, 2}, {1, 1}}};
}

using test::load;

TEST(InrModel, LoadsArchitectureAndCountsParameters) {
  const InrModel m = load(buildSafeTensors(tinyTensors(), modelMetadata(kTinyArch)));
  ASSERT_EQ(m.architecture.layers.size(), 3u);
  EXPECT_EQ(m.architecture.parameterCount(), 8u + 2u + 2u);
  EXPECT_EQ(m.architecture.layers[0].outWidth, 2);
  EXPECT_EQ(m.architecture.layers[1].param, 30.f);
  EXPECT_TRUE(m.architecture.layers[2].bias.empty());
  EXPECT_EQ(m.architecture.summary(), "linear(4->2) sine(30) linear(2->1)");
  EXPECT_TRUE(m.domain.usesTime());
}

TEST(InrModel, NodeAndCellCentredMappings) {
  json dom = {{"bounds", {0, 2, 10, 20, -1, 1}}, {"time_range", {0, 10}}, {"input_range", {0, 1}},
              {"time_input_range", {-1, 1}}};
  InrModel m = load(buildSafeTensors(tinyTensors(), modelMetadata(kTinyArch, dom)));
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kX].apply(0), 0);
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kX].apply(2), 1);
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kY].apply(15), 0.5);
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kT].apply(0), -1);
  EXPECT_NEAR(m.domain.toNetwork[kT].apply(5), 0, 1e-12);
  dom["centering"] = "cell";
  dom["resolution"] = {4, 10, 2};
  m = load(buildSafeTensors(tinyTensors(), modelMetadata(kTinyArch, dom)));
  // x: 4 cells of 0.5, first centre 0.25 -> 0, last centre 1.75 -> 1
  EXPECT_NEAR(m.domain.toNetwork[kX].apply(0.25), 0, 1e-12);
  EXPECT_NEAR(m.domain.toNetwork[kX].apply(1.75), 1, 1e-12);
  EXPECT_NEAR(m.domain.toNetwork[kZ].apply(-0.5), 0, 1e-12);
  EXPECT_NEAR(m.domain.toNetwork[kZ].apply(0.5), 1, 1e-12);
}

TEST(InrModel, InputOrderAndPerAxisRanges) {
  json dom = {{"bounds", {0, 1, 0, 1, 0, 1}},
              {"time_range", {0, 1}},
              {"input_order", {"t", "z", "y", "x"}},
              {"input_range", {{0, 1}, {-1, 1}, {0, 2}}}};
  const InrModel m = load(buildSafeTensors(tinyTensors(), modelMetadata(kTinyArch, dom)));
  EXPECT_EQ(m.domain.inputOrder, (std::vector<int>{kT, kZ, kY, kX}));
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kY].apply(1), 1);
  EXPECT_DOUBLE_EQ(m.domain.toNetwork[kZ].apply(1), 2);
}

TEST(InrModel, PerTimeOutputMappingInterpolates) {
  json out = {{"per_time", {{"times", {0, 10}}, {"min", {0, 2}}, {"max", {1, 6}}, {"network_range", {-1, 1}}}}};
  const InrModel m = load(buildSafeTensors(tinyTensors(), modelMetadata(kTinyArch, json(), out)));
  float a, b;
  m.output.affineAt(5, a, b);  // min 1, max 3.5: net -1 -> 1, net 1 -> 3.5
  EXPECT_FLOAT_EQ(a * -1 + b, 1.f);
  EXPECT_FLOAT_EQ(a * 1 + b, 3.5f);
  m.output.affineAt(-3, a, b);  // clamped to the first entry
  EXPECT_FLOAT_EQ(a * 1 + b, 1.f);
}

TEST(InrModel, ResidualWithShortcutAndFourier) {
  json arch = {{"input_dim", 3},
               {"layers",
                {{{"type", "fourier"}, {"B", "B"}, {"include_input", "first"}},
                 {{"type", "residual"},
                  {"scale", 0.5},
                  {"body", {{{"type", "linear"}, {"weight", "r.w"}, {"bias", "r.b"}}, {{"type", "silu"}}}},
                  {"shortcut", {{{"type", "linear"}, {"weight", "s.w"}}}}},
                 {{"type", "linear"}, {"weight", "o.w"}}}}};
  std::vector<test::TensorSpec> t = {{"B", {2, 3}, std::vector<float>(6, 0.1f)},
                                     {"r.w", {5, 7}, std::vector<float>(35, 0.1f)},
                                     {"r.b", {5}, std::vector<float>(5, 0.f)},
                                     {"s.w", {5, 7}, std::vector<float>(35, 0.2f)},
                                     {"o.w", {1, 5}, std::vector<float>(5, 1.f)}};
  json dom = {{"bounds", {-1, 1, -1, 1, -1, 1}}, {"time_range", {0, 1}}};
  const InrModel m = load(buildSafeTensors(t, modelMetadata(arch, dom)));
  EXPECT_FALSE(m.domain.usesTime());
  EXPECT_EQ(m.architecture.layers[0].outWidth, 7);
  EXPECT_EQ(m.architecture.layers[1].outWidth, 5);
  EXPECT_EQ(m.architecture.maxWidth(), 7);
}

}  // namespace
}  // namespace inr
