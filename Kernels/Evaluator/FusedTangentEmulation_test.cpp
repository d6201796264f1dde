// The fused kernel's tangent rows (value + gradient in one pass, issue 33) through their CPU
// emulation (emulateFusedTangents): the program logic of the GPU path, checked without a GPU on
// every architecture family against the fp32 CPU reference's forward-mode gradient.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/FusedTangents.h"
#include "TestSupport/GradientErrors.h"

namespace inr {
namespace {

TEST(FusedTangentEmulation, GradientMatchesFp32ReferenceWithinFp16Error) {
  for (const test::NamedModel& m : test::tangentTestModels()) {
    SCOPED_TRACE(m.name);
    MlpProgram program = MlpProgram::compile(m.model.architecture);
    program.tangentScale = chooseTangentScale(program, m.model.domain);
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
    EXPECT_LE(err.median, test::kTangentMedianBound);
    EXPECT_LE(err.quantile90, test::kTangentQuantile90Bound);
    for (float g : emu.gradients) ASSERT_TRUE(std::isfinite(g));
  }
}

// The tangents ride beside the value without touching it: the values are emulateFusedProgram's
// (the same code; up to the compiler's contraction of each instantiation into FMAs); and the tangent scale is a power of two that puts the largest stored tangent of
// its sample at kTangentTarget or below (within a factor 2 of it).
TEST(FusedTangentEmulation, ValuesAreTheValueEmulationsAndTheScaleFitsFp16) {
  for (const test::NamedModel& m : test::tangentTestModels()) {
    SCOPED_TRACE(m.name);
    MlpProgram program = MlpProgram::compile(m.model.architecture);
    program.tangentScale = chooseTangentScale(program, m.model.domain);
    int e = 0;
    EXPECT_EQ(std::frexp(program.tangentScale, &e), 0.5f) << program.tangentScale;
    const int dim = m.model.architecture.inputDim;
    std::vector<float> inputs(64 * dim);
    for (std::size_t i = 0; i < inputs.size(); ++i) inputs[i] = std::sin(0.37f * float(i));
    std::vector<float> values(64), plain(64), tangents(3 * 64);
    int tangentInput[3];
    ASSERT_TRUE(tangentInputsOf(m.model.domain, m.model.architecture.inputDim, tangentInput));
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
  program.tangentScale = chooseTangentScale(program, model.domain);
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
  const auto all = test::tangentTestModels();
  for (const std::string family : {"siren_", "ffn_", "coordnet_", "neurcomp_", "hashgrid_"}) {
    bool found = false;
    for (const test::NamedModel& m : all) found |= m.name.find(family) != std::string::npos;
    EXPECT_TRUE(found) << family;
  }
}

}  // namespace
}  // namespace inr
