#include "Evaluator/CpuInrEvaluator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "Evaluator/ValueRange.h"
#include "TestSupport/TestModelBuilder.h"

namespace inr {
namespace {

using nlohmann::json;
using test::buildSafeTensors;
using test::modelMetadata;

using test::load;
using test::randomValues;

// Straightforward double-precision reference for the layers exercised below.
double silu(double x) { return x / (1 + std::exp(-x)); }

TEST(CpuInrEvaluator, FourierResidualSiluMatchesHandComputation) {
  std::mt19937 rng(7);
  const int m = 3, in = 4, hidden = 5;
  const int enc = 2 * m + in;  // include_input "last"
  auto B = randomValues(m * in, rng, 2.f), W1 = randomValues(hidden * enc, rng), b1 = randomValues(hidden, rng),
       Wr = randomValues(hidden * hidden, rng), br = randomValues(hidden, rng), Wo = randomValues(hidden, rng),
       bo = randomValues(1, rng);
  json arch = {{"input_dim", 4},
               {"layers",
                {{{"type", "fourier"}, {"B", "B"}, {"include_input", "last"}, {"frequency_scale", 3.0}},
                 {{"type", "linear"}, {"weight", "W1"}, {"bias", "b1"}},
                 {{"type", "silu"}},
                 {{"type", "residual"},
                  {"scale", 0.5},
                  {"body", {{{"type", "scale"}, {"factor", 2.0}}, {{"type", "linear"}, {"weight", "Wr"}, {"bias", "br"}},
                            {{"type", "tanh"}}}}},
                 {{"type", "linear"}, {"weight", "Wo"}, {"bias", "bo"}}}}};
  json dom = {{"bounds", {0, 2, 0, 4, -1, 1}}, {"time_range", {0, 10}}, {"input_order", {"t", "z", "y", "x"}}};
  json out = {{"scale", 3.0}, {"offset", -1.0}};
  const InrModel model = load(buildSafeTensors(
      {{"B", {m, in}, B}, {"W1", {hidden, enc}, W1}, {"b1", {hidden}, b1}, {"Wr", {hidden, hidden}, Wr},
       {"br", {hidden}, br}, {"Wo", {1, hidden}, Wo}, {"bo", {1}, bo}},
      modelMetadata(arch, dom, out)));
  const CpuInrEvaluator eval(model);

  std::vector<QueryPoint> pts;
  std::uniform_real_distribution<float> u(0, 1);
  for (int i = 0; i < 1000; ++i) pts.push_back({2 * u(rng), 4 * u(rng), 2 * u(rng) - 1, 10 * u(rng)});
  std::vector<float> got(pts.size());
  eval.evaluate(pts.data(), pts.size(), got.data());

  for (std::size_t q = 0; q < pts.size(); ++q) {
    const auto& p = pts[q];
    // network inputs in order t, z, y, x, each mapped to [-1, 1]
    const double x[4] = {p.t / 5.0 - 1, p.z, p.y / 2.0 - 1, p.x - 1};
    std::vector<double> e(enc);
    for (int k = 0; k < m; ++k) {
      double d = 0;
      for (int j = 0; j < in; ++j) d += B[k * in + j] * x[j];
      e[k] = std::sin(3.0 * d);
      e[m + k] = std::cos(3.0 * d);
    }
    for (int j = 0; j < in; ++j) e[2 * m + j] = x[j];
    std::vector<double> h(hidden), r(hidden);
    for (int o = 0; o < hidden; ++o) {
      double s = b1[o];
      for (int j = 0; j < enc; ++j) s += W1[o * enc + j] * e[j];
      h[o] = silu(s);
    }
    for (int o = 0; o < hidden; ++o) {
      double s = br[o];
      for (int j = 0; j < hidden; ++j) s += Wr[o * hidden + j] * 2.0 * h[j];
      r[o] = 0.5 * (std::tanh(s) + h[o]);
    }
    double y = bo[0];
    for (int j = 0; j < hidden; ++j) y += Wo[j] * r[j];
    const double want = 3.0 * y - 1.0;
    ASSERT_NEAR(got[q], want, 1e-5 * std::max(1.0, std::abs(want))) << "query " << q;
  }
}

TEST(CpuInrEvaluator, ActivationsAndSineW0) {
  // A 1-wide chain: each activation applied to a known pre-activation.
  auto run = [](const std::string& act, float pre) {
    json arch = {{"input_dim", 3},
                 {"layers",
                  {{{"type", "linear"}, {"weight", "w"}, {"bias", "b"}},
                   act == "sine" ? json{{"type", "sine"}, {"w0", 2.5}} : json{{"type", act}}}}};
    const InrModel model =
        load(buildSafeTensors({{"w", {1, 3}, {0, 0, 0}}, {"b", {1}, {pre}}},
                              modelMetadata(arch, {{"bounds", {0, 1, 0, 1, 0, 1}}, {"time_range", {0, 1}}})));
    const CpuInrEvaluator e(model);
    QueryPoint p{0.5f, 0.5f, 0.5f, 0.f};
    float v;
    e.evaluate(&p, 1, &v);
    return v;
  };
  EXPECT_NEAR(run("relu", -0.7f), 0.f, 1e-7);
  EXPECT_NEAR(run("relu", 0.7f), 0.7f, 1e-7);
  EXPECT_NEAR(run("sigmoid", 0.3f), 1 / (1 + std::exp(-0.3)), 1e-6);
  EXPECT_NEAR(run("tanh", 0.3f), std::tanh(0.3), 1e-6);
  EXPECT_NEAR(run("silu", -1.2f), silu(-1.2), 1e-6);
  EXPECT_NEAR(run("sine", 0.4f), std::sin(2.5 * 0.4), 1e-6);
  EXPECT_NEAR(run("identity", 0.4f), 0.4f, 1e-7);
}

TEST(CpuInrEvaluator, ResultsDoNotDependOnThreadCountOrBatchSplit) {
  std::mt19937 rng(3);
  const int w = 64;
  json arch = {{"input_dim", 4},
               {"layers",
                {{{"type", "linear"}, {"weight", "a"}, {"bias", "ab"}}, {{"type", "sine"}},
                 {{"type", "linear"}, {"weight", "b"}, {"bias", "bb"}}, {{"type", "sine"}},
                 {{"type", "linear"}, {"weight", "c"}, {"bias", "cb"}}}}};
  const InrModel model = load(buildSafeTensors({{"a", {w, 4}, randomValues(w * 4, rng)},
                                                {"ab", {w}, randomValues(w, rng)},
                                                {"b", {w, w}, randomValues(w * w, rng, 0.05f)},
                                                {"bb", {w}, randomValues(w, rng)},
                                                {"c", {1, w}, randomValues(w, rng)},
                                                {"cb", {1}, randomValues(1, rng)}},
                                               modelMetadata(arch)));
  std::vector<QueryPoint> pts(5000);
  std::uniform_real_distribution<float> u(-1, 1);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng), u(rng)};
  CpuEvaluatorOptions one;
  one.threads = 1;
  CpuEvaluatorOptions many;
  many.threads = 4;
  std::vector<float> a(pts.size()), b(pts.size());
  CpuInrEvaluator(model, one).evaluate(pts.data(), pts.size(), a.data());
  CpuInrEvaluator(model, many).evaluate(pts.data(), pts.size(), b.data());
  EXPECT_EQ(a, b);
  // The same points evaluated in a smaller batch give the same bits.
  std::vector<float> c(300);
  CpuInrEvaluator(model, many).evaluate(pts.data() + 256, c.size(), c.data());
  for (std::size_t i = 0; i < c.size(); ++i) EXPECT_EQ(c[i], a[256 + i]) << i;
}

TEST(ValueRange, SamplesTheField) {
  // value = x (identity of the first input) over x in [2, 5]
  json arch = {{"input_dim", 3}, {"layers", {{{"type", "linear"}, {"weight", "w"}}}}};
  json dom = {{"bounds", {2, 5, 0, 1, 0, 1}}, {"time_range", {0, 1}}, {"input_range", {2, 5}}};
  const InrModel model = load(buildSafeTensors({{"w", {1, 3}, {1, 0, 0}}}, modelMetadata(arch, dom)));
  const CpuInrEvaluator e(model);
  const SampledRange r = sampleValueRange(e, model.domain, 8, 3);
  EXPECT_NEAR(r.min, 2.f, 1e-6);
  EXPECT_NEAR(r.max, 5.f, 1e-6);
  EXPECT_EQ(r.samples, 512u);  // static model: one time sample
}

}  // namespace
}  // namespace inr
