#pragma once
// Device-side helpers shared by the pipeline kernels: float atomic min/max (order-independent,
// so refinement gives the same bounds whatever order the GPU runs the queries in), the
// macrocell refinement step (the device twin of MacrocellGrid::refine) and warp-aggregated
// atomic append.
#include <cooperative_groups.h>

#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/RenderMath.h"

namespace inr::cuda {

// IEEE floats order like sign-magnitude integers: non-negative values as signed ints, negative
// values reversed as unsigned ints. Correct for +-0, +-INF; NaN is never passed.
__device__ inline void atomicMinFloat(float* addr, float v) {
  if (v >= 0.f)
    atomicMin(reinterpret_cast<int*>(addr), __float_as_int(v));
  else
    atomicMax(reinterpret_cast<unsigned*>(addr), __float_as_uint(v));
}
__device__ inline void atomicMaxFloat(float* addr, float v) {
  if (v >= 0.f)
    atomicMax(reinterpret_cast<int*>(addr), __float_as_int(v));
  else
    atomicMin(reinterpret_cast<unsigned*>(addr), __float_as_uint(v));
}

// Widens an (possibly empty: min > max) interval to contain v.
__device__ inline void widenBounds(float* mn, float* mx, int cell, float v) {
  atomicMinFloat(&mn[cell], v);  // empty cells hold +INF / -INF, so this also initialises them
  atomicMaxFloat(&mx[cell], v);
}

// An evaluated sample `v` fell in macrocell `cell`: if it is outside the working bounds, widen
// them and the contributing slices, mark the cell dirty (its majorant is recomputed before the
// next frame). Same rule as MacrocellGrid::refine.
__device__ inline bool refineCell(const DeviceRefineView& r, int cell, float v) {
  if (!isFiniteValue(v) || cell < 0 || cell >= r.cells) return false;
  const float mn = r.workMin[cell], mx = r.workMax[cell];
  if (mn <= mx && v >= mn && v <= mx) return false;
  widenBounds(r.workMin, r.workMax, cell, v);
  widenBounds(r.slice0Min, r.slice0Max, cell, v);
  if (r.slice1Min) widenBounds(r.slice1Min, r.slice1Max, cell, v);
  atomicAdd(r.refinements, 1ull);
  if (r.frameRefinements) atomicAdd(r.frameRefinements, 1ull);
  if (atomicExch(&r.dirtyMask[cell], 1u) == 0u) r.dirtyList[atomicAdd(r.dirtyCount, 1u)] = cell;
  return true;
}

// Slot for this thread in an append buffer: one atomicAdd per group of converged threads that
// append together. Call only from threads that append.
__device__ inline unsigned appendSlot(unsigned* counter) {
  namespace cg = cooperative_groups;
  const cg::coalesced_group g = cg::coalesced_threads();
  unsigned base = 0;
  if (g.thread_rank() == 0) base = atomicAdd(counter, unsigned(g.size()));
  return g.shfl(base, 0) + g.thread_rank();
}

}  // namespace inr::cuda
