#pragma once
// The seam between the GPU pipeline and its traversal: one launch of Stage II over a set of
// rays. The pipeline fills a TraversalLaunch and calls traverse(); what walks the rays through
// the majorant grid is the implementation's business: the DDA over the grid (DdaTraversal.cu,
// always available) or, later, an OptiX GAS over non-empty macrocells. Every implementation runs
// the same per-ray stage code (Render/Traverse.h: resolveCandidate, candidateDistance, emitCandidate), honours
// the contract below and appends its queries exactly as the DDA does, so the evaluation stage
// and everything after it do not know which traversal ran.
#include <cuda_runtime.h>

#include <memory>

#include "Cuda/Pipeline/CudaMacrocellGrid.h"
#include "Render/RayState.h"

namespace inr {

struct TraversalLaunch {
  FrameConstants fc;
  TrackingMedium medium;  // majorant grid (device arrays) and transfer function
  RayStateView rs;
  // Rays to traverse: all rays (list == null) or list[0 .. *listCount), at most n of them.
  const int* list = nullptr;
  const unsigned* listCount = nullptr;
  int n = 0;
  // With a list: the listed rays' previous queries were evaluated into rs.sample; complete them
  // (storeQueryResult) and, when `refine`, refine their macrocells through refineView first;
  // with pruning on (medium.prune.expected) they also feed the cells' expected scalars
  // (expectedAfterQuery, Render/Evaluate.h).
  bool resolvePrevious = false;
  bool refine = false;
  DeviceRefineView refineView;
  // Output: every ray that emits a candidate appends its query point and index here.
  float4* outPoints = nullptr;
  int* outRays = nullptr;
  unsigned* outCount = nullptr;
  // Work distribution: a device counter, zero at the launch, that the implementation may use to
  // hand out rays to its threads (the DDA's persistent warps take them 32 at a time).
  unsigned* workCounter = nullptr;
};

class DeviceTraversal {
public:
  virtual ~DeviceTraversal() = default;
  virtual const char* name() const = 0;
  // Enqueues the traversal on `stream` (asynchronous).
  virtual void traverse(const TraversalLaunch& launch, cudaStream_t stream) const = 0;
};

// The 3D DDA over the majorant grid with empty-space skipping.
std::unique_ptr<DeviceTraversal> makeDdaTraversal();

}  // namespace inr
