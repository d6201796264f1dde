// The OptiX traversal's device programs (compiled by nvcc to PTX at build time, embedded, and
// loaded with optixModuleCreate by OptixTraversal.cu). Stage II as the DDA runs it — complete the
// previous query, traverseRayWith (Render/Traverse.h) with its resolve and pruning loop, append
// the next query — except that the walk to the next candidate collision is one optixTrace
// through a GAS whose custom primitives are the macrocells with a positive majorant:
//   - the intersection program runs delta tracking inside its cell over the part of [tmin, tmax)
//     the ray spends there, with the cell's local majorant, through trackInSegment (the DDA's own
//     per-segment step), and reports the candidate collision if the free flight ends inside;
//   - the closest hit is the first candidate along the ray.
// Why this is delta tracking: cells do not overlap, and each draws its free flight from its own
// entry with an independent random number, so the first cell whose flight ends inside it is
// where front-to-back tracking (restarting at each boundary: flights are memoryless) would stop.
// Cells are visited in whatever order the BVH hands them out, so a cell's random number cannot
// come from the ray's sequential stream: it is keyed by (ray stream, draw index, cell), with one
// draw index per trace reserved from the ray's stream. The images therefore differ from the
// DDA's sample by sample and agree in expectation (tests: optix_traversal_tests).
#include <optix.h>

#include "Render/Cuda/ListedRay.cuh"
#include "Render/Cuda/OptixLaunchParams.h"
#include "Render/Traverse.h"

// The launch parameters, as bytes: OptixTraversalParams has default member initialisers, which a
// __constant__ variable cannot have; OptiX only needs the name and the size.
extern "C" {
__constant__ __align__(16) unsigned char params[sizeof(inr::OptixTraversalParams)];
}

namespace inr {
namespace {

__device__ __forceinline__ const OptixTraversalParams& launchParams() {
  return *reinterpret_cast<const OptixTraversalParams*>(params);
}

// Cell `cell`'s own stream for the draw with index `draw` of the ray stream `ray`: the cell
// index goes into the seed word, whose mixing (counterHash) makes the streams independent.
__device__ __forceinline__ RngStream cellStream(const RngStream& ray, std::uint32_t draw, int cell) {
  return RngStream{ray.pixel, ray.frame, ray.seed ^ (0x9e3779b9u * (std::uint32_t(cell) + 1u)), draw};
}

// The GAS as a traversal walker: traverseRayWith builds one per tracking step and asks it, after
// a candidate, for the candidate's cell (pruning).
struct GasWalker {
  Vec3f origin, direction;
  int cell = -1;
  __device__ GasWalker(const MajorantGridView&, const RayStateView& rs, int i)
      : origin(rs.origin[i]), direction(rs.direction[i]) {}
  __device__ int cellIndex() const { return cell; }
};

__device__ __forceinline__ void debugCount(OptixDebugCount c) {
  if (launchParams().debugCounts) atomicAdd(&launchParams().debugCounts[c], 1ull);
}

}  // namespace

// traverseRayWith<GasWalker>'s tracking step (found by argument-dependent lookup instead of the
// segment walkers' template): the next candidate collision in [t, tEnd), or false when the ray
// leaves its segment or its draw budget is spent. Two draws per candidate, as in the DDA: the
// trace's reserved index and emitCandidate's acceptance draw.
__device__ bool trackSegments(const FrameConstants& fc, const RayStateView& rs, int i, std::uint8_t& flags,
                              RngStream& rng, GasWalker& walker, float t, float tEnd) {
  if (!(t < tEnd)) return false;
  if (rng.counter >= fc.maxRngDraws) {  // bounded work per frame
    flags |= kRayCapped;
    return false;
  }
  // In: the ray's stream key, the reserved draw index, ~0u; out (closest hit): the cell, its
  // majorant, the candidate's parameter (never ~0u, a NaN pattern, so ~0u still there = no hit).
  unsigned p0 = rng.pixel, p1 = rng.counter, p2 = ~0u;
  ++rng.counter;
  debugCount(kDbgTrace);
  optixTrace(launchParams().gas, make_float3(walker.origin.x, walker.origin.y, walker.origin.z),
             make_float3(walker.direction.x, walker.direction.y, walker.direction.z), t, tEnd, 0.f,
             OptixVisibilityMask(0xff), OPTIX_RAY_FLAG_DISABLE_ANYHIT, 0, 1, 0, p0, p1, p2);
  if (i == launchParams().debugRay)
    printf("OptiX debug ray %d: trace [%g, %g) from (%g %g %g) dir (%g %g %g) -> cell %d t %g\n", i, t, tEnd,
           walker.origin.x, walker.origin.y, walker.origin.z, walker.direction.x, walker.direction.y,
           walker.direction.z, p2 == ~0u ? -1 : int(p0), p2 == ~0u ? -1.f : __uint_as_float(p2));
  if (p2 == ~0u) return false;  // no candidate before tEnd
  debugCount(kDbgHit);
  walker.cell = int(p0);
  rs.cell[i] = cellCoordinates(launchParams().launch.medium.grid.dims, walker.cell);  // refinement's and pruning's cell
  emitCandidate(fc, rs, i, flags, rng, __uint_as_float(p1), __uint_as_float(p2));
  return true;
}

}  // namespace inr

using namespace inr;

extern "C" __global__ void __raygen__traverse() {
  const TraversalLaunch& p = launchParams().launch;
  const uint3 idx = optixGetLaunchIndex();
  const uint3 dims = optixGetLaunchDimensions();
  int i;
  if (p.list) {
    const int n = p.listCount ? min(p.n, int(*p.listCount)) : p.n;
    if (int(idx.x) >= n) return;
    i = p.list[idx.x];
  } else {
    i = int(idx.y * dims.x + idx.x);  // a 2D launch over the image when rays are its pixels
    if (i >= p.n) return;
  }
  debugCount(kDbgRaygen);
  if (i == launchParams().debugRay)
    printf("OptiX debug ray %d at raygen: flags %u t %g tEnd %g draws %u (cap %u)\n", i, unsigned(p.rs.flags[i]),
           p.rs.t[i], p.rs.tEnd[i], p.rs.rngCounter[i], p.fc.maxRngDraws);
  if (p.resolvePrevious) inr::cuda::completeListedQuery(p, i);
  traverseRayWith<GasWalker>(p.fc, p.medium, p.rs, i);
  // One atomic per query (no warp aggregation: OptiX does not keep a warp's threads together).
  if (p.rs.flags[i] & kRayPending) inr::cuda::writeListedQuery(p, i, atomicAdd(p.outCount, 1u));
}

extern "C" __global__ void __intersection__macrocell() {
  debugCount(kDbgIntersect);
  const int cell = launchParams().cellOfPrimitive[optixGetPrimitiveIndex()];
  const MajorantGridView& g = launchParams().launch.medium.grid;
  const Int3 c = cellCoordinates(g.dims, cell);
  const float3 o = optixGetObjectRayOrigin(), d = optixGetObjectRayDirection();
  const Vec3f origin{o.x, o.y, o.z}, dir{d.x, d.y, d.z};
  // The ray's interval in the cell, from its face planes exactly as the DDA computes crossings
  // (faceCrossing), so neighbouring cells share their boundary parameters: no gap, no overlap.
  float t0 = optixGetRayTmin(), t1 = optixGetRayTmax();
  for (int a = 0; a < 3; ++a) {
    const float da = component(dir, a);
    const int ca = component(c, a);
    if (da == 0.f) {
      const float lo = component(g.box.lo, a) + float(ca) * component(g.cellSize, a);
      const float hi = component(g.box.lo, a) + float(ca + 1) * component(g.cellSize, a);
      const float x = component(origin, a);
      if (!(x >= lo && x < hi)) return;
      continue;
    }
    const float tFar = faceCrossing(g, origin, dir, ca, a);                 // far face along the ray
    const float tNear = faceCrossing(g, origin, dir, ca + (da > 0.f ? -1 : 1), a);  // near face
    t0 = fmaxf(t0, tNear);
    t1 = fminf(t1, tFar);
  }
  if (!(t0 < t1)) return;
  debugCount(kDbgInterval);
  const float m = g.majorant[cell];
  const RngStream ray{optixGetPayload_0(), launchParams().launch.fc.frame, launchParams().launch.fc.seed, 0u};
  RngStream rng = cellStream(ray, optixGetPayload_1(), cell);
  float tCandidate;
  if (trackInSegment(launchParams().launch.fc, rng, m, t0, t1, tCandidate) == SegmentOutcome::Candidate) {
    debugCount(kDbgReport);
    optixReportIntersection(tCandidate, 0, unsigned(cell), __float_as_uint(m));
  }
}

extern "C" __global__ void __closesthit__macrocell() {
  debugCount(kDbgClosestHit);
  optixSetPayload_0(optixGetAttribute_0());
  optixSetPayload_1(optixGetAttribute_1());
  optixSetPayload_2(__float_as_uint(optixGetRayTmax()));
}

extern "C" __global__ void __miss__none() {}
