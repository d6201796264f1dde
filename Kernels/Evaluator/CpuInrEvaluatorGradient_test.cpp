// CpuInrEvaluator::evaluateWithGradient: values identical to evaluate, gradients against central
// differences (of the graph in double, and of evaluate) on every shipped architecture family and
// on a synthetic graph holding every layer kind, batch edge cases, the refusal of a layer kind
// without a derivative, and the per-element activation derivatives of Common/Activation.h.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <vector>

#include "Common/Activation.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "TestSupport/GradientErrors.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestModelBuilder.h"

namespace inr {
namespace {

using nlohmann::json;
using test::buildSafeTensors;
using test::modelMetadata;

using test::GradientError;
using test::load;
using test::relativeErrors;
using test::randomValues;

struct ValuesAndGradients {
  std::vector<float> values, gradients;
};

ValuesAndGradients withGradient(const CpuInrEvaluator& e, const std::vector<QueryPoint>& pts) {
  ValuesAndGradients r{std::vector<float>(pts.size()), std::vector<float>(3 * pts.size())};
  e.evaluateWithGradient(pts.data(), pts.size(), r.values.data(), r.gradients.data());
  return r;
}

std::vector<float> valuesOf(const CpuInrEvaluator& e, const std::vector<QueryPoint>& pts) {
  std::vector<float> v(pts.size());
  e.evaluate(pts.data(), pts.size(), v.data());
  return v;
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

float& coordinate(QueryPoint& p, int axis) { return axis == 0 ? p.x : axis == 1 ? p.y : p.z; }

// Central differences of evaluate along world axis `axis`, in double from the fp32 values, over
// the steps actually taken (the shifted coordinates are fp32 too), Richardson-extrapolated from
// steps h and h/2 so the truncation error is O(h^4) rather than O(h^2): that lets h be large
// enough for fp32 rounding in the values to stay small against the difference.
std::vector<double> centralDifferences(const CpuInrEvaluator& e, const std::vector<QueryPoint>& pts, int axis,
                                       double worldStep) {
  auto difference = [&](double h) {
    std::vector<QueryPoint> plus = pts, minus = pts;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      coordinate(plus[i], axis) = static_cast<float>(coordinate(plus[i], axis) + h);
      coordinate(minus[i], axis) = static_cast<float>(coordinate(minus[i], axis) - h);
    }
    const std::vector<float> fp = valuesOf(e, plus), fm = valuesOf(e, minus);
    std::vector<double> d(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i)
      d[i] = (double(fp[i]) - double(fm[i])) / (double(coordinate(plus[i], axis)) - double(coordinate(minus[i], axis)));
    return d;
  };
  const std::vector<double> coarse = difference(worldStep), fine = difference(worldStep / 2);
  std::vector<double> r(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) r[i] = (4 * fine[i] - coarse[i]) / 3;
  return r;
}

// The field in double precision, written here from the format's definitions (Docs/FORMAT.md)
// and independent of the evaluator: the layer graph on one query's inputs. reluMargin, where
// given, gets the smallest |input| of any ReLU (how far the point is from a kink, where the
// field has no derivative); gridMargin the smallest distance to a hash-grid cell face (the
// encoding's kinks, test::hashGridInDouble).
std::vector<double> runInDouble(const std::vector<Layer>& layers, std::vector<double> x, double* reluMargin = nullptr,
                                double* gridMargin = nullptr) {
  for (const Layer& L : layers) {
    std::vector<double> y;
    switch (L.kind) {
      case LayerKind::Linear:
        y.assign(L.outWidth, 0.0);
        for (int o = 0; o < L.outWidth; ++o) {
          double s = L.bias.empty() ? 0.0 : L.bias[o];
          for (int i = 0; i < L.inWidth; ++i) s += double(L.weight[o * L.inWidth + i]) * x[i];
          y[o] = s;
        }
        break;
      case LayerKind::Fourier: {
        const int m = static_cast<int>(L.weight.size()) / L.inWidth;
        std::vector<double> sines(m), cosines(m);
        for (int j = 0; j < m; ++j) {
          double p = 0;
          for (int i = 0; i < L.inWidth; ++i) p += double(L.weight[j * L.inWidth + i]) * x[i];
          sines[j] = std::sin(double(L.param) * p);
          cosines[j] = std::cos(double(L.param) * p);
        }
        if (L.includeInput == IncludeInput::First) y = x;
        y.insert(y.end(), sines.begin(), sines.end());
        y.insert(y.end(), cosines.begin(), cosines.end());
        if (L.includeInput == IncludeInput::Last) y.insert(y.end(), x.begin(), x.end());
        break;
      }
      case LayerKind::HashGrid: y = test::hashGridInDouble(L, x, gridMargin); break;
      case LayerKind::Residual: {
        const std::vector<double> body = runInDouble(L.body, x, reluMargin, gridMargin);
        const std::vector<double> shortcut = L.shortcut.empty() ? x : runInDouble(L.shortcut, x, reluMargin, gridMargin);
        y.resize(body.size());
        for (std::size_t i = 0; i < y.size(); ++i) y[i] = double(L.residualScale) * (body[i] + shortcut[i]);
        break;
      }
      default:
        y = x;
        for (double& v : y) {
          switch (L.kind) {
            case LayerKind::Sine: v = std::sin(double(L.param) * v); break;
            case LayerKind::SiLU: v = v / (1 + std::exp(-v)); break;
            case LayerKind::ReLU:
              if (reluMargin) *reluMargin = std::min(*reluMargin, std::abs(v));
              v = v > 0 ? v : 0;
              break;
            case LayerKind::Sigmoid: v = 1 / (1 + std::exp(-v)); break;
            case LayerKind::Tanh: v = std::tanh(v); break;
            case LayerKind::Scale: v *= double(L.param); break;
            default: break;
          }
        }
    }
    x = std::move(y);
  }
  return x;
}

double valueInDouble(const InrModel& model, const double world[4], double* reluMargin = nullptr,
                     double* gridMargin = nullptr) {
  std::vector<double> x(model.architecture.inputDim);
  for (int i = 0; i < model.architecture.inputDim; ++i) {
    const int w = model.domain.inputOrder[i];
    x[i] = model.domain.toNetwork[w].apply(world[w]);
  }
  float a, b;
  model.output.affineAt(world[3], a, b);
  return double(a) * runInDouble(model.architecture.layers, x, reluMargin, gridMargin)[0] + double(b);
}

// The gradient of valueInDouble by central differences in double (Richardson-extrapolated from
// steps h and h/2). In double the rounding of the values is ~1e-16, so a step of 1e-5 network
// units leaves a rounding term near 1e-11 and, even for frequencies of a few hundred radians
// per unit, a truncation term (h w)^4 below 1e-8: far below the fp32 gradient's own error.
std::vector<double> gradientInDouble(const InrModel& model, const QueryPoint& p) {
  std::vector<double> g(3);
  for (int axis = 0; axis < 3; ++axis) {
    const double h = 1e-5 / std::abs(model.domain.toNetwork[axis].scale);
    auto difference = [&](double step) {
      double plus[4] = {p.x, p.y, p.z, p.t}, minus[4] = {p.x, p.y, p.z, p.t};
      plus[axis] += step;
      minus[axis] -= step;
      return (valueInDouble(model, plus) - valueInDouble(model, minus)) / (2 * step);
    };
    g[axis] = (4 * difference(h / 2) - difference(h)) / 3;
  }
  return g;
}

// Central differences of evaluate (fp32) at every point, 3 per point; networkStep in network
// units (what the network's frequencies are measured in), mapped to world units by the domain's
// slope along each axis.
std::vector<double> centralDifferencesOfEvaluate(const CpuInrEvaluator& e, const InrModel& model,
                                                 const std::vector<QueryPoint>& pts, double networkStep) {
  std::vector<double> fd(3 * pts.size());
  for (int axis = 0; axis < 3; ++axis) {
    const double slope = std::abs(model.domain.toNetwork[axis].scale);
    const std::vector<double> d = centralDifferences(e, pts, axis, networkStep / slope);
    for (std::size_t i = 0; i < pts.size(); ++i) fd[3 * i + axis] = d[i];
  }
  return fd;
}

std::vector<double> centralDifferencesInDouble(const InrModel& model, const std::vector<QueryPoint>& pts) {
  std::vector<double> fd(3 * pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const std::vector<double> g = gradientInDouble(model, pts[i]);
    for (int a = 0; a < 3; ++a) fd[3 * i + a] = g[a];
  }
  return fd;
}

// The target for fp32 gradients (issue 33).
constexpr double kMaxRelativeError = 1e-3;

// The gradient is checked twice. Against central differences of the graph evaluated in double
// (gradientInDouble): these are exact to far below fp32, so the target, a relative error
// of at most kMaxRelativeError, is held at every point. And against central differences of
// evaluate itself, the function the renderer samples (this ties the double reference to the
// evaluator: input order, domain and output mappings): there the fp32 rounding of the values,
// amplified by 1/h, limits what the differences can resolve (to around the target at the median
// on the largest SIREN-based models, at best), so that comparison is held at the median to
// kFp32DifferenceBound: loose, but a wrong factor, axis or mapping gives errors of order 1.
constexpr double kFp32DifferenceBound = 1e-2;

// The step for a model's central differences of evaluate, in network units. Two errors bound
// it: the Richardson-extrapolated difference's truncation error grows as (h w)^4 with w the
// field's highest angular frequency in network units, and the fp32 rounding of the values,
// amplified by 1/h, shrinks with h. The SIREN-based families (SIREN, CoordNet, neurcomp: sine
// with w0 = 30 at every layer) have frequencies of tens of radians per unit and more, so h =
// 3e-3 keeps h w below 1 at most points; the Fourier-feature networks (B from a normal of
// frequency scale 2 pi, through SiLU) are smoother, so a wider step, 5e-3, shrinks the rounding
// term further.
double networkStepFor(const InrModel& model) {
  for (const Layer& L : model.architecture.layers) {
    if (L.kind == LayerKind::Fourier) return 5e-3;
    // A hash grid is piecewise smooth between its cells' faces: a step inside the kink margin
    // the points keep (kMinGridMargin).
    if (L.kind == LayerKind::HashGrid) return 1e-4;
  }
  return 3e-3;
}

// Points closer than these to a kink (a ReLU's zero, a hash-grid cell face; runInDouble) are
// left out of the shipped-model comparison: central differences straddling a kink do not
// estimate the derivative there. The grid margin exceeds both gradientInDouble's step and the
// hash grids' networkStepFor (which is as large as that allows: fp32 positions at the finest
// levels, x * scale in the hundreds, resolve a smaller step coarsely).
constexpr double kMinReluMargin = 1e-3, kMinGridMargin = 1.5e-4;

// The points of pts at least the margins above from every kink of the model (all of them for
// models without ReLUs and hash grids).
std::vector<QueryPoint> awayFromKinks(const InrModel& model, const std::vector<QueryPoint>& pts) {
  std::vector<QueryPoint> kept;
  for (const QueryPoint& p : pts) {
    const double world[4] = {p.x, p.y, p.z, p.t};
    double relu = 1e30, grid = 1e30;
    valueInDouble(model, world, &relu, &grid);
    if (relu > kMinReluMargin && grid > kMinGridMargin) kept.push_back(p);
  }
  return kept;
}

class ShippedModelGradient : public ::testing::TestWithParam<std::string> {};

TEST_P(ShippedModelGradient, MatchesCentralDifferencesAndValuesMatchEvaluate) {
  const InrModel model = InrModel::loadFile(GetParam());
  const CpuInrEvaluator e(model);
  const std::vector<QueryPoint> pts = awayFromKinks(model, test::randomQueryPoints(model, 300, 11));
  ASSERT_GE(pts.size(), 150u) << "points away from every kink";

  const ValuesAndGradients got = withGradient(e, pts);
  const std::vector<float> values = valuesOf(e, pts);
  for (std::size_t i = 0; i < pts.size(); ++i)
    ASSERT_TRUE(sameBits(got.values[i], values[i])) << "point " << i << ": " << got.values[i] << " vs " << values[i];

  const std::string name = std::filesystem::path(GetParam()).filename().string();
  const GradientError inDouble = relativeErrors(got.gradients, centralDifferencesInDouble(model, pts));
  const GradientError ofEvaluate =
      relativeErrors(got.gradients, centralDifferencesOfEvaluate(e, model, pts, networkStepFor(model)));
  std::printf("  %-40s relative gradient error vs double differences: max %.3g (p90 %.3g, |g|/rms %.2g); vs differences of "
              "evaluate: median %.3g, p90 %.3g, max %.3g\n",
              name.c_str(), inDouble.maxRelative, inDouble.quantile90, inDouble.worstNormOverRms, ofEvaluate.median, ofEvaluate.quantile90,
              ofEvaluate.maxRelative);
  EXPECT_LE(inDouble.maxRelative, kMaxRelativeError) << "worst point " << inDouble.worst;
  EXPECT_LE(ofEvaluate.median, kFp32DifferenceBound);
}

std::vector<std::string> everyShippedModel() {
  std::vector<std::string> all = test::shippedModels("models");
  for (const auto& f : test::shippedModels("real")) all.push_back(f);
  return all;
}

INSTANTIATE_TEST_SUITE_P(AllFamilies, ShippedModelGradient, ::testing::ValuesIn(everyShippedModel()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = std::filesystem::path(info.param).parent_path().filename().string() +
                                              "_" + std::filesystem::path(info.param).stem().string();
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

// The parameterised test above covers every architecture family the repository ships: a family
// dropped from Testing/Data must not leave its gradient untested unnoticed.
TEST(CpuInrEvaluatorGradient, ShippedModelsCoverEveryFamily) {
  for (const std::string family : {"siren_", "ffn_", "coordnet_", "neurcomp_", "hashgrid_"}) {
    const auto models = everyShippedModel();
    EXPECT_TRUE(std::any_of(models.begin(), models.end(), [&](const std::string& f) {
      return std::filesystem::path(f).filename().string().rfind(family, 0) == 0;
    })) << "no shipped model of family " << family;
  }
}

// Every layer kind in one graph (Fourier with its input first and last, every activation, scale,
// residual blocks with and without shortcut), with permuted inputs that include time, a domain
// with a different slope per axis, and a per-time output mapping.
InrModel everyLayerKindModel(const std::string& include) {
  std::mt19937 rng(5);
  const int m = 6, in = 4, hidden = 12;
  const int enc = 2 * m + (include == "none" ? 0 : in);
  json arch = {{"input_dim", 4},
               {"layers",
                {{{"type", "fourier"}, {"B", "B"}, {"include_input", include}, {"frequency_scale", 2.0}},
                 {{"type", "linear"}, {"weight", "W1"}, {"bias", "b1"}},
                 {{"type", "tanh"}},
                 {{"type", "residual"},
                  {"scale", 0.7},
                  {"body", {{{"type", "scale"}, {"factor", 1.5}}, {{"type", "linear"}, {"weight", "W2"}, {"bias", "b2"}},
                            {{"type", "silu"}}}},
                  {"shortcut", {{{"type", "linear"}, {"weight", "W3"}}, {{"type", "identity"}}}}},
                 {{"type", "residual"},
                  {"body", {{{"type", "linear"}, {"weight", "W4"}, {"bias", "b4"}}, {{"type", "sine"}, {"w0", 3.0}},
                            {{"type", "linear"}, {"weight", "W5"}, {"bias", "b5"}}, {{"type", "relu"}}}}},
                 {{"type", "linear"}, {"weight", "Wo"}, {"bias", "bo"}},
                 {{"type", "sigmoid"}}}}};
  json dom = {{"bounds", {0, 2, -3, 5, 10, 10.5}}, {"time_range", {0, 4}}, {"input_order", {"z", "t", "x", "y"}}};
  json out = {{"per_time", {{"times", {0, 2, 4}}, {"min", {-1, 0, 2}}, {"max", {1, 5, 3}}}}};
  return load(buildSafeTensors({{"B", {m, in}, randomValues(m * in, rng, 1.f)},
                                {"W1", {hidden, enc}, randomValues(hidden * enc, rng)},
                                {"b1", {hidden}, randomValues(hidden, rng)},
                                {"W2", {hidden, hidden}, randomValues(hidden * hidden, rng)},
                                {"b2", {hidden}, randomValues(hidden, rng)},
                                {"W3", {hidden, hidden}, randomValues(hidden * hidden, rng)},
                                {"W4", {hidden, hidden}, randomValues(hidden * hidden, rng)},
                                {"b4", {hidden}, randomValues(hidden, rng)},
                                {"W5", {hidden, hidden}, randomValues(hidden * hidden, rng)},
                                {"b5", {hidden}, randomValues(hidden, rng)},
                                {"Wo", {1, hidden}, randomValues(hidden, rng, 2.f)},
                                {"bo", {1}, randomValues(1, rng)}},
                               modelMetadata(arch, dom, out)));
}

TEST(CpuInrEvaluatorGradient, EveryLayerKindMatchesCentralDifferences) {
  for (const std::string include : {"none", "first", "last"}) {
    SCOPED_TRACE("fourier include_input " + include);
    const InrModel model = everyLayerKindModel(include);
    const CpuInrEvaluator e(model);
    // Points at least 1e-3 from a ReLU kink: closer, the central differences straddle it (and
    // fp32 may put the point on the other side than double does).
    std::vector<QueryPoint> pts;
    for (const QueryPoint& p : test::randomQueryPoints(model, 500, 3)) {
      const double world[4] = {p.x, p.y, p.z, p.t};
      double margin = 1e30;
      valueInDouble(model, world, &margin);
      if (margin > 1e-3) pts.push_back(p);
    }
    ASSERT_GT(pts.size(), 400u);
    const ValuesAndGradients got = withGradient(e, pts);
    const std::vector<float> values = valuesOf(e, pts);
    for (std::size_t i = 0; i < pts.size(); ++i) ASSERT_TRUE(sameBits(got.values[i], values[i])) << i;
    const GradientError inDouble = relativeErrors(got.gradients, centralDifferencesInDouble(model, pts));
    EXPECT_LE(inDouble.maxRelative, kMaxRelativeError) << "worst point " << inDouble.worst;
    // Low frequencies (scale 2, w0 3): a wide step, 1e-2; it straddles the kinks of a few points,
    // so again the median is held, here to the target itself.
    const GradientError ofEvaluate = relativeErrors(got.gradients, centralDifferencesOfEvaluate(e, model, pts, 1e-2));
    std::printf("  include_input %-5s: vs double differences max %.3g; vs differences of evaluate median %.3g, "
                "max %.3g\n",
                include.c_str(), inDouble.maxRelative, ofEvaluate.median, ofEvaluate.maxRelative);
    EXPECT_LE(ofEvaluate.median, kMaxRelativeError);
  }
}

TEST(CpuInrEvaluatorGradient, AffineModelHasTheChainRuleGradientExactly) {
  // value = 3 * (w . network input) - 1 with network input = slope * world + offset per axis:
  // gradient_k = 3 * w_k * slope_k, constant, and the time input adds nothing to it.
  json arch = {{"input_dim", 4}, {"layers", {{{"type", "linear"}, {"weight", "w"}, {"bias", "b"}}}}};
  json dom = {{"bounds", {0, 2, 0, 4, -1, 1}}, {"time_range", {0, 10}}, {"input_order", {"t", "z", "y", "x"}}};
  json out = {{"scale", 3.0}, {"offset", -1.0}};
  const InrModel model =
      load(buildSafeTensors({{"w", {1, 4}, {0.5f, 0.25f, -2.f, 1.f}}, {"b", {1}, {0.125f}}}, modelMetadata(arch, dom, out)));
  const CpuInrEvaluator e(model);
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 10, 1);
  const ValuesAndGradients got = withGradient(e, pts);
  // input order t, z, y, x; slopes onto [-1, 1]: x 1, y 0.5, z 1
  const float want[3] = {3.f * 1.f * 1.f, 3.f * -2.f * 0.5f, 3.f * 0.25f * 1.f};
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (int a = 0; a < 3; ++a) EXPECT_FLOAT_EQ(got.gradients[3 * i + a], want[a]) << i << " axis " << a;
}

TEST(CpuInrEvaluatorGradient, EmptyBatchAndBatchesNotAMultipleOfTheChunk) {
  const InrModel model = everyLayerKindModel("last");
  CpuEvaluatorOptions opts;
  opts.chunkSize = 64;
  opts.threads = 4;
  const CpuInrEvaluator e(model, opts);
  e.evaluateWithGradient(nullptr, 0, nullptr, nullptr);  // n = 0 touches nothing

  // 1000 = 15 chunks of 64 and one of 40 (enough chunks for the threaded loop).
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 1000, 9);
  const ValuesAndGradients batch = withGradient(e, pts);
  const std::vector<float> values = valuesOf(e, pts);
  CpuEvaluatorOptions oneThread = opts;
  oneThread.threads = 1;
  const ValuesAndGradients serial = withGradient(CpuInrEvaluator(model, oneThread), pts);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_TRUE(sameBits(batch.values[i], values[i])) << i;
    for (int a = 0; a < 3; ++a)  // the thread count changes nothing
      ASSERT_TRUE(sameBits(batch.gradients[3 * i + a], serial.gradients[3 * i + a])) << i << " axis " << a;
  }
  // Each point alone (a chunk of one) gives its value and, up to the GEMMs' summation order, its
  // gradient; in particular the last, partial chunk's.
  for (std::size_t i : {std::size_t(0), std::size_t(63), std::size_t(64), std::size_t(959), std::size_t(960),
                        std::size_t(999)}) {
    float v, g[3];
    e.evaluateWithGradient(&pts[i], 1, &v, g);
    EXPECT_NEAR(v, batch.values[i], 1e-6f * std::max(1.f, std::abs(v))) << i;
    for (int a = 0; a < 3; ++a)
      EXPECT_NEAR(g[a], batch.gradients[3 * i + a], 1e-5f * std::max(1.f, std::abs(g[a]))) << i << " axis " << a;
  }
}

TEST(CpuInrEvaluatorGradient, LayerKindWithoutDerivativeIsRefusedByName) {
  // No LayerKind lacks a derivative today, so the test stands one in: a kind past the last
  // enumerator, as a kind added to the model without its Jacobian would be to this evaluator.
  InrModel model = everyLayerKindModel("none");
  const auto unknown = static_cast<LayerKind>(static_cast<int>(LayerKind::HashGrid) + 1);
  model.architecture.layers[4].body[1].kind = unknown;
  const CpuInrEvaluator e(model);
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 300, 2);
  std::vector<float> values(pts.size(), -7.f), gradients(3 * pts.size(), -7.f);
  try {
    e.evaluateWithGradient(pts.data(), pts.size(), values.data(), gradients.data());
    FAIL() << "expected an error naming the layer without a derivative";
  } catch (const std::runtime_error& err) {
    const std::string what = err.what();
    EXPECT_NE(what.find("layers[4].body[1]"), std::string::npos) << what;
    EXPECT_NE(what.find("LayerKind " + std::to_string(static_cast<int>(unknown))), std::string::npos) << what;
    EXPECT_NE(what.find("no derivative"), std::string::npos) << what;
  }
  EXPECT_TRUE(std::all_of(values.begin(), values.end(), [](float v) { return v == -7.f; }));
  EXPECT_TRUE(std::all_of(gradients.begin(), gradients.end(), [](float v) { return v == -7.f; }));
}

TEST(ActivationDerivative, MatchesTheClosedFormsInDouble) {
  auto sigmoid = [](double v) { return 1 / (1 + std::exp(-v)); };
  for (double v : {-6.0, -1.3, -0.2, 0.0, 0.4, 1.7, 5.0}) {
    SCOPED_TRACE(v);
    const float f = static_cast<float>(v);
    EXPECT_NEAR(activationDerivative(MlpAct::None, f), 1.0, 0);
    EXPECT_NEAR(activationDerivative(MlpAct::Sine, f), std::cos(v), 1e-6);
    EXPECT_NEAR(activationDerivative(MlpAct::SiLU, f), sigmoid(v) * (1 + v * (1 - sigmoid(v))), 1e-6);
    EXPECT_EQ(activationDerivative(MlpAct::ReLU, f), v > 0 ? 1.f : 0.f);
    EXPECT_NEAR(activationDerivative(MlpAct::Sigmoid, f), sigmoid(v) * (1 - sigmoid(v)), 1e-6);
    EXPECT_NEAR(activationDerivative(MlpAct::Tanh, f), 1 - std::tanh(v) * std::tanh(v), 1e-6);
    // Host code has no fast forms: FastDevice computes Exact.
    for (MlpAct a : {MlpAct::Sine, MlpAct::SiLU, MlpAct::Sigmoid, MlpAct::Tanh})
      EXPECT_EQ(activationDerivative<ActMath::FastDevice>(a, f), activationDerivative(a, f));
  }
}

}  // namespace
}  // namespace inr
