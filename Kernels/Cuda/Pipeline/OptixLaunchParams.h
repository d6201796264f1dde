#pragma once
// What the OptiX traversal's programs (OptixPrograms.cu) read: the Stage II launch every
// DeviceTraversal gets, plus the GAS over the non-empty macrocells and its primitive -> cell map.
// Host code (OptixTraversal.cu) fills it; the device sees it as the pipeline's launch parameters.
#include <optix_types.h>

#include "Cuda/Pipeline/DeviceTraversal.h"

namespace inr {

struct OptixTraversalParams {
  TraversalLaunch launch;
  OptixTraversableHandle gas = 0;
  // GAS primitive k is the macrocell cellOfPrimitive[k] (linear index, x fastest).
  const int* cellOfPrimitive = nullptr;
};

// Payload and attribute slots shared by the programs (and the pipeline's compile options).
constexpr unsigned kOptixPayloadValues = 3;
constexpr unsigned kOptixAttributeValues = 2;

}  // namespace inr
