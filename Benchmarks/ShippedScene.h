#pragma once
// The scene a user gets from `inr render MODEL --tf MODEL.tf.json` for a shipped real model:
// ParaView's reset-camera framing of the world box, the model's suggested transfer function (the
// preset over the value range when there is no MODEL.tf.json beside it), opacity unit distance =
// box diagonal / 64, black background, no shadows. Benchmarks that report image quality use it so
// their numbers describe the picture a user would look at, not a test scene.
#include <array>
#include <cmath>
#include <filesystem>
#include <string>

#include "Evaluator/FieldEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/ModelBox.h"
#include "Render/SceneInputs.h"

namespace inr::bench {

// MODEL.tf.json beside MODEL.inr, or "" when there is none.
inline std::string suggestedTransferFunctionPath(const std::string& modelPath) {
  std::filesystem::path p(modelPath);
  p.replace_extension(".tf.json");
  return std::filesystem::exists(p) ? p.string() : std::string();
}

// `time`: world time; NaN = the middle of the model's time range (the flows are still starting up
// at its beginning, the CLI's default).
inline RenderScene shippedScene(const InrModel& model, const std::string& modelPath, const FieldEvaluator& evaluator,
                                double time = NAN) {
  const Box3f box = modelWorldBox(model);
  RenderScene scene;
  scene.camera = Camera::framing(box);
  scene.time = std::isnan(time) ? 0.5 * (model.domain.timeBegin + model.domain.timeEnd) : time;
  const std::string tf = suggestedTransferFunctionPath(modelPath);
  if (!tf.empty()) {
    scene.transferFunction = TransferFunction::fromParaViewJsonFile(tf);
  } else {
    const auto range = valueRangeFor(model, evaluator);
    scene.transferFunction = TransferFunction::preset(range[0], range[1]);
  }
  scene.transferFunction.unitDistance = length(box.hi - box.lo) / 64.0;
  return scene;
}

// The camera turned by `degrees` about the axis through its focal point along its view-up
// (a turntable orbit; position and view-up rotate together, so the view stays upright).
inline Camera orbitCamera(const Camera& c, double degrees) {
  const double a = degrees * 3.14159265358979323846 / 180.0, ca = std::cos(a), sa = std::sin(a);
  std::array<double, 3> k = c.viewUp;
  const double n = std::sqrt(k[0] * k[0] + k[1] * k[1] + k[2] * k[2]);
  for (double& v : k) v /= n;
  auto rotate = [&](const std::array<double, 3>& v) {  // Rodrigues
    const double d = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
    const std::array<double, 3> x{k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]};
    std::array<double, 3> r;
    for (int i = 0; i < 3; ++i) r[i] = v[i] * ca + x[i] * sa + k[i] * d * (1.0 - ca);
    return r;
  };
  Camera out = c;
  std::array<double, 3> rel;
  for (int i = 0; i < 3; ++i) rel[i] = c.position[i] - c.focalPoint[i];
  rel = rotate(rel);
  for (int i = 0; i < 3; ++i) out.position[i] = c.focalPoint[i] + rel[i];
  out.viewUp = rotate(c.viewUp);
  return out;
}

}  // namespace inr::bench
