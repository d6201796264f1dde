#pragma once
// The model's world box (Domain::bounds) as the renderers take it.
#include "Model/InrModel.h"
#include "Render/RenderMath.h"

namespace inr {

inline Box3f modelWorldBox(const InrModel& model) {
  const auto& b = model.domain.bounds;
  return {{float(b[0]), float(b[2]), float(b[4])}, {float(b[1]), float(b[3]), float(b[5])}};
}

}  // namespace inr
