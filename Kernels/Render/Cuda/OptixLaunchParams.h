#pragma once
// What the OptiX traversal's programs (OptixPrograms.cu) read: the Stage II launch every
// DeviceTraversal gets, plus the GAS over the non-empty macrocells and its primitive -> cell map.
// Host code (OptixTraversal.cu) fills it; the device sees it as the pipeline's launch parameters.
#include <optix_types.h>

#include "Render/Cuda/DeviceTraversal.h"

namespace inr {

struct OptixTraversalParams {
  TraversalLaunch launch;
  OptixTraversableHandle gas = 0;
  // GAS primitive k is the macrocell cellOfPrimitive[k] (linear index, x fastest).
  const int* cellOfPrimitive = nullptr;
  // Diagnostics (INR_OPTIX_DEBUG=1 in the environment; null otherwise): counts of raygen calls,
  // traces, intersection calls, calls whose cell interval is not empty, reported candidates,
  // closest hits and traces that returned a hit (OptixDebugCount), and one ray whose trace is
  // printed (-1: none).
  unsigned long long* debugCounts = nullptr;
  int debugRay = -1;
};

enum OptixDebugCount { kDbgRaygen, kDbgTrace, kDbgIntersect, kDbgInterval, kDbgReport, kDbgClosestHit, kDbgHit,
                       kDbgCounts };

// Payload and attribute slots shared by the programs (and the pipeline's compile options).
constexpr unsigned kOptixPayloadValues = 3;
constexpr unsigned kOptixAttributeValues = 2;

}  // namespace inr
