// The fused kernel's tangent rows (value + gradient in one pass, issue 33) through their CPU
// emulation (emulateFusedTangents): the program logic of the GPU path, checked without a GPU on
// every architecture family against the fp32 CPU reference's forward-mode gradient.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/FusedTangents.h"
#include "TestSupport/GradientErrors.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

namespace inr {
namespace {

// fp16 bounds for the emulated (and the kernel's) gradient against the fp32 reference. Every
// value and tangent is stored in fp16 between layers (relative rounding up to 2^-11 = 4.9e-4)
// and the GEMMs read fp16 weights: one layer's tangent then carries a relative error of a few
// 2^-11 (its own rounding, the weights', and act'(z) evaluated at a pre-activation z that the
// rounded inputs moved by ~2^-11 |W||x|, which for a sine with w0 = 30 moves cos(z) by as
// much), and the errors of the layers add up, in quadrature for the independent roundings: on
// the paper-size and shipped networks the median is 4e-4 to 3e-3, on the deepest one
// (coordnet_cylinder_u, 2026-11-27) 8.8e-3 with a 90th percentile of 3.4e-2. A ReLU whose fp16 pre-activation
// lands on the other side of 0 than the fp32 one switches its derivative between 0 and 1, so
// single points (hash-grid models: ReLU after fp16 features) may be off by order 1: the bounds
// are on the median and the 90th percentile, per point as vector norms with the floor of
// relativeErrors (5% of the RMS gradient).
constexpr double kMedianBound = 2e-2, kQuantile90Bound = 6e-2;

struct NamedModel {
  std::string name;
  InrModel model;
};

std::vector<NamedModel> everyFamily() {
  std::vector<NamedModel> out;
  out.push_back({"siren_paper", bench::sirenPaper()});
  out.push_back({"ffn_paper", bench::ffnPaper()});
  out.push_back({"coordnet_paper", bench::coordNetPaper()});
  out.push_back({"hashgrid_3d", test::hashGridModel(test::hashGridMlp(3, 16, 16, 16, 1.5, 64, 2))});
  for (const char* folder : {"models", "real"})
    for (const auto& path : test::shippedModels(folder))
      out.push_back({std::string(folder) + "/" + std::filesystem::path(path).stem().string(), InrModel::loadFile(path)});
  return out;
}

TEST(FusedTangentEmulation, GradientMatchesFp32ReferenceWithinFp16Error) {
  for (const NamedModel& m : everyFamily()) {
    SCOPED_TRACE(m.name);
    MlpProgram program = MlpProgram::compile(m.model.architecture);
    program.tangentScale = chooseTangentScale(program, m.model);
    const std::vector<QueryPoint> pts = test::randomQueryPoints(m.model, 160, 29);
    const test::ValuesAndWorldGradients emu = test::emulatedWorldGradients(m.model, program, pts);
    const test::ValuesAndWorldGradients ref = test::referenceWorldGradients(CpuInrEvaluator(m.model), pts);
    const test::GradientError err =
        test::relativeErrors(emu.gradients, std::vector<double>(ref.gradients.begin(), ref.gradients.end()));
    double valueErr = 0, valueRange = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      valueErr = std::max(valueErr, std::abs(double(emu.values[i]) - ref.values[i]));
      valueRange = std::max(valueRange, std::abs(double(ref.values[i])));
    }
    std::printf("  %-40s tangent scale 2^%d: emulated fp16 gradient vs fp32: median %.3g, p90 %.3g, max %.3g; value max "
                "abs %.3g\n",
                m.name.c_str(), int(std::log2(program.tangentScale)), err.median, err.quantile90, err.maxRelative,
                valueErr);
    EXPECT_LE(err.median, kMedianBound);
    EXPECT_LE(err.quantile90, kQuantile90Bound);
    for (float g : emu.gradients) ASSERT_TRUE(std::isfinite(g));
  }
}

// The tangents ride beside the value without touching it: the values are emulateFusedProgram's
// (the same code; up to the compiler's contraction of each instantiation into FMAs); and the tangent scale is a power of two that puts the largest stored tangent of
// its sample at kTangentTarget or below (within a factor 2 of it).
TEST(FusedTangentEmulation, ValuesAreTheValueEmulationsAndTheScaleFitsFp16) {
  for (const NamedModel& m : everyFamily()) {
    SCOPED_TRACE(m.name);
    MlpProgram program = MlpProgram::compile(m.model.architecture);
    program.tangentScale = chooseTangentScale(program, m.model);
    int e = 0;
    EXPECT_EQ(std::frexp(program.tangentScale, &e), 0.5f) << program.tangentScale;
    const int dim = m.model.architecture.inputDim;
    std::vector<float> inputs(64 * dim);
    for (std::size_t i = 0; i < inputs.size(); ++i) inputs[i] = std::sin(0.37f * float(i));
    std::vector<float> values(64), plain(64), tangents(3 * 64);
    int tangentInput[3];
    ASSERT_TRUE(tangentInputsOf(m.model, tangentInput));
    float largest = 0.f;
    emulateFusedTangents(program, inputs.data(), 64, tangentInput, values.data(), tangents.data(), &largest);
    emulateFusedProgram(program, inputs.data(), 64, plain.data());
    for (int q = 0; q < 64; ++q) ASSERT_NEAR(values[q], plain[q], 1e-5 * std::max(1.f, std::abs(plain[q]))) << q;
    // The sample here differs from the scale's, so allow the headroom the scale leaves.
    EXPECT_LE(largest, 64 * kTangentTarget);
    EXPECT_GT(largest, 0.f);
  }
}

// A model whose tangents would overflow fp16 unscaled: a SIREN with its hidden and output
// weights times 16 (each layer's tangent grows by 16 more) keeps finite
// gradients because the scale brings its tangents down.
TEST(FusedTangentEmulation, LargeTangentsAreScaledIntoFp16Range) {
  InrModel model = bench::sirenPaper();
  int linear = 0;
  for (Layer& L : model.architecture.layers)
    if (L.kind == LayerKind::Linear && linear++ > 0)
      for (float& w : L.weight) w *= 16.f;
  MlpProgram program = MlpProgram::compile(model.architecture);
  program.tangentScale = chooseTangentScale(program, model);
  EXPECT_LT(program.tangentScale, 1.f) << "these tangents exceed fp16's range unscaled";
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 64, 3);
  const test::ValuesAndWorldGradients emu = test::emulatedWorldGradients(model, program, pts);
  for (float g : emu.gradients) ASSERT_TRUE(std::isfinite(g));
  MlpProgram unscaled = program;
  unscaled.tangentScale = 1.f;
  const test::ValuesAndWorldGradients raw = test::emulatedWorldGradients(model, unscaled, pts);
  bool overflowed = false;
  for (float g : raw.gradients) overflowed |= !std::isfinite(g);
  EXPECT_TRUE(overflowed) << "the unscaled tangents were expected to overflow fp16";
}

TEST(FusedTangentEmulation, EveryShippedFamilyIsCovered) {
  const auto all = everyFamily();
  for (const std::string family : {"siren_", "ffn_", "coordnet_", "neurcomp_", "hashgrid_"}) {
    bool found = false;
    for (const NamedModel& m : all) found |= m.name.find(family) != std::string::npos;
    EXPECT_TRUE(found) << family;
  }
}

}  // namespace
}  // namespace inr
