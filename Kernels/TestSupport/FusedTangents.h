#pragma once
// Test-only: values and world-space gradients of a model at world points through the CPU
// emulation of the fused kernel's tangent rows (emulateFusedTangents), mapped to world space as
// the kernel maps them (the domain's input slopes, the output mapping at each point's time), for
// the emulation's CPU test and the fused kernel's GPU test. No GoogleTest here.
#include <filesystem>
#include <string>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Evaluator/MlpProgram.h"
#include "Model/InrModel.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

namespace inr::test {

// fp16 bounds for the fused kernel's (and its emulation's) gradient against the fp32 reference,
// on relativeErrors (TestSupport/GradientErrors.h). Every value and tangent is stored in fp16
// between layers (relative rounding up to 2^-11 = 4.9e-4) and the GEMMs read fp16 weights: one
// layer's tangent then carries a relative error of a few 2^-11 (its own rounding, the weights',
// and act'(z) evaluated at a pre-activation z that the rounded inputs moved by ~2^-11 |W||x|,
// which for a sine with w0 = 30 moves cos(z) by as much), and the errors of the layers add up,
// in quadrature for the independent roundings: on the paper-size and shipped networks the
// emulation's median is 4e-4 to 3e-3, on the deepest one (coordnet_cylinder_u, 2026-11-27)
// 8.8e-3 with a 90th percentile of 3.4e-2. A ReLU whose fp16 pre-activation lands on the other
// side of 0 than the fp32 one switches its derivative between 0 and 1, so single points
// (hash-grid models: ReLU after fp16 features) may be off by order 1: the bounds are on the
// median and the 90th percentile, per point as vector norms with relativeErrors' floor (5% of
// the RMS gradient).
constexpr double kTangentMedianBound = 2e-2, kTangentQuantile90Bound = 6e-2;

struct NamedModel {
  std::string name;
  InrModel model;
};

// Every architecture family the tangent tests run: the paper-size synthetic SIREN, FFN and
// CoordNet, a hash grid, and every shipped model (Testing/Data/models and real).
inline std::vector<NamedModel> tangentTestModels() {
  std::vector<NamedModel> out;
  out.push_back({"siren_paper", bench::sirenPaper()});
  out.push_back({"ffn_paper", bench::ffnPaper()});
  out.push_back({"coordnet_paper", bench::coordNetPaper()});
  out.push_back({"hashgrid_3d", hashGridModel(hashGridMlp(3, 16, 16, 16, 1.5, 64, 2))});
  for (const char* folder : {"models", "real"})
    for (const auto& path : shippedModels(folder))
      out.push_back({std::string(folder) + "/" + std::filesystem::path(path).stem().string(), InrModel::loadFile(path)});
  return out;
}

struct ValuesAndWorldGradients {
  std::vector<float> values, gradients;  // gradients: 3 per point, d/dx, d/dy, d/dz (world)
};

// `program` with its tangentScale set (chooseTangentScale(program, model.domain), as the evaluator does).
inline ValuesAndWorldGradients emulatedWorldGradients(const InrModel& model, const MlpProgram& program,
                                                      const std::vector<QueryPoint>& pts) {
  const int dim = model.architecture.inputDim;
  const std::size_t n = pts.size();
  std::vector<float> inputs(n * dim), net(n), tangents(3 * n);
  for (std::size_t q = 0; q < n; ++q) {
    const double w[4] = {pts[q].x, pts[q].y, pts[q].z, pts[q].t};
    for (int i = 0; i < dim; ++i) {
      const int c = model.domain.inputOrder[std::size_t(i)];
      inputs[q * dim + i] = float(model.domain.toNetwork[c].apply(w[c]));
    }
  }
  int tangentInput[3];
  tangentInputsOf(model.domain, model.architecture.inputDim, tangentInput);
  emulateFusedTangents(program, inputs.data(), n, tangentInput, net.data(), tangents.data());
  ValuesAndWorldGradients r{std::vector<float>(n), std::vector<float>(3 * n)};
  for (std::size_t q = 0; q < n; ++q) {
    float a, b;
    model.output.affineAt(pts[q].t, a, b);
    r.values[q] = a * net[q] + b;
    for (int axis = 0; axis < 3; ++axis)
      r.gradients[3 * q + axis] = a * (float(model.domain.toNetwork[axis].scale) * tangents[3 * q + axis]);
  }
  return r;
}

// The CPU reference's values and world gradients (evaluateWithGradient).
inline ValuesAndWorldGradients referenceWorldGradients(const FieldEvaluator& e, const std::vector<QueryPoint>& pts) {
  ValuesAndWorldGradients r{std::vector<float>(pts.size()), std::vector<float>(3 * pts.size())};
  e.evaluateWithGradient(pts.data(), pts.size(), r.values.data(), r.gradients.data());
  return r;
}

}  // namespace inr::test
