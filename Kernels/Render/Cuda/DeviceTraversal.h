#pragma once
// The seam between the GPU pipeline and its traversal: one launch of Stage II over a set of
// rays. The pipeline fills a TraversalLaunch and calls traverse(); what walks the rays through
// the majorant grid is the implementation's business: the DDA over the grid (DdaTraversal.cu,
// always available) or an OptiX GAS over non-empty macrocells (OptixTraversal.cu). Every one runs
// the same per-ray stage code (Render/Traverse.h: resolveCandidate, candidateDistance, emitCandidate), honours
// the contract below and appends its queries exactly as the DDA does, so the evaluation stage
// and everything after it do not know which traversal ran.
#include <cuda_runtime.h>

#include <cstddef>
#include <memory>
#include <string>

#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/RatioTracking.h"
#include "Render/RayState.h"
#include "Render/TraversalOptions.h"

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
  // Ratio tracking's primary leg (RatioTracking.h): the rays draw up to
  // fc.pointsPerIteration points each; every point that needs the network is appended to
  // outPoints / outRays with its slot in `points` (the evaluator writes points.sample[slot]), and
  // every ray left waiting is appended once to outRayList (the next pass's list).
  bool ratio = false;
  PointStateView points;
  int* outRayList = nullptr;
  unsigned* outRayCount = nullptr;
  // Work distribution: a device counter, zero at the launch, that the implementation may use to
  // hand out rays to its threads (the DDA's persistent warps take them 32 at a time).
  unsigned* workCounter = nullptr;
};

// What a traversal keeps over the majorants (the OptiX GAS), for the frame statistics.
struct TraversalBuildInfo {
  double lastBuildMs = 0;      // wall time of the last update (selection check, build, compaction)
  bool lastRebuilt = false;    // the last update built the structure (false: the selection was unchanged)
  std::size_t primitives = 0;  // macrocells in the structure
  std::size_t bytes = 0;       // its device size (compacted)
  std::size_t reservedBytes = 0;  // device memory held for it (sized once per grid shape for the worst case)
  std::size_t builds = 0;      // builds so far
  std::size_t reuses = 0;      // updates that kept the structure (same cells selected: refinements, most edits)
  std::size_t reservations = 0;  // device allocations of its buffers (once per grid shape)
};

class DeviceTraversal {
public:
  virtual ~DeviceTraversal() = default;
  virtual const char* name() const = 0;
  // Enqueues the traversal on `stream` (asynchronous).
  virtual void traverse(const TraversalLaunch& launch, cudaStream_t stream) const = 0;
  // The majorants behind `grid` (device arrays) changed: a time step, a transfer-function edit,
  // refinements. Rebuilds what the traversal keeps over them before returning; traverse() calls
  // over another majorant array (ghost passes) must still work. The DDA reads the grid directly.
  virtual void majorantsChanged(const MajorantGridView& grid, cudaStream_t stream) {
    (void)grid;
    (void)stream;
  }
  virtual TraversalBuildInfo buildInfo() const { return {}; }
  // Whether traverse() runs ratio-tracked primary legs (TraversalLaunch::ratio); the pipeline
  // runs those through the DDA otherwise.
  virtual bool supportsRatioTracking() const { return false; }
};

// The 3D DDA over the majorant grid with empty-space skipping.
std::unique_ptr<DeviceTraversal> makeDdaTraversal();

// The OptiX GAS traversal (OptixTraversal.cu) on the current device; throws std::runtime_error
// saying why when this build has no OptiX or it does not initialise. `rtCores` (optional) says
// whether the GPU has RT cores (otherwise OptiX traverses in software).
std::unique_ptr<DeviceTraversal> makeOptixTraversal(const TraversalOptions& options, bool* rtCores = nullptr);

// The traversal `options` ask for; `reason` says what was chosen and why (auto's choice, or why
// OptiX is unavailable). Dda never fails; Optix throws when OptiX cannot run.
std::unique_ptr<DeviceTraversal> makeDeviceTraversal(const TraversalOptions& options, std::string& reason);

}  // namespace inr
