#pragma once
// Test-only: values and world-space gradients of a model at world points through the CPU
// emulation of the fused kernel's tangent rows (emulateFusedTangents), mapped to world space as
// the kernel maps them (the domain's input slopes, the output mapping at each point's time), for
// the emulation's CPU test and the fused kernel's GPU test. No GoogleTest here.
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Evaluator/MlpProgram.h"
#include "Model/InrModel.h"

namespace inr::test {

struct ValuesAndWorldGradients {
  std::vector<float> values, gradients;  // gradients: 3 per point, d/dx, d/dy, d/dz (world)
};

// `program` with its tangentScale set (chooseTangentScale(program, model), as the evaluator does).
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
  tangentInputsOf(model, tangentInput);
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
