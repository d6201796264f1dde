// Stage II on the GPU with the DDA walker (Render/Traverse.h), behind the DeviceTraversal seam.
#include <algorithm>

#include "Cuda/CudaCheck.h"
#include "Cuda/Pipeline/DeviceRefine.cuh"
#include "Cuda/Pipeline/DeviceTraversal.h"
#include "Render/Evaluate.h"
#include "Render/Traverse.h"

namespace inr {
namespace {

constexpr int kThreads = 256;

// One thread per listed ray: complete and refine the previous query, resume tracking, append
// the next candidate's query.
// Occupancy: with the empty-space skip inlined (Render/MajorantGrid.h) ptxas would take 67
// registers on sm_90 (3 blocks of 256 per SM; 44 and 5 blocks without the skip). Bounded to 5
// blocks it fits 48 registers; since the DDA walker (Render/Traverse.h) it spills 10 bytes of
// stores and 16 of loads on sm_90, 20 of loads with the pruning hook (ptxas -v). sm_75 holds 4
// blocks.
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
#define INR_TRAVERSE_MIN_BLOCKS 4
#else
#define INR_TRAVERSE_MIN_BLOCKS 5
#endif
__global__ void __launch_bounds__(kThreads, INR_TRAVERSE_MIN_BLOCKS) ddaTraverseKernel(TraversalLaunch p) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.n || (p.listCount && k >= int(*p.listCount))) return;
  const int i = p.list ? p.list[k] : k;
  const RayStateView& rs = p.rs;
  if (p.resolvePrevious) {
    const float v = rs.sample[i];
    storeQueryResult(rs, i, v);
    if (p.refine) cuda::refineCell(p.refineView, linearCellIndex(p.medium.grid.dims, rs.cell[i]), v);
    int cell;
    float estimate;
    // Pruning's EMA (Eq. ev_ema). Threads of a pass update hot cells concurrently; a benign race
    // by design: read, then one atomic store of the new estimate. A lost update only drops a
    // sample (every stored value is still a convex mix of the mean and real samples); a CAS
    // loop would serialise the many rays in a hot cell for no visible gain.
    if (p.medium.prune.expected && expectedAfterQuery(p.medium, rs, i, v, cell, estimate))
      atomicExch(&p.medium.prune.expected[cell], estimate);
  }
  traverseRay(p.fc, p.medium, rs, i);
  if (rs.flags[i] & kRayPending) {
    const unsigned slot = cuda::appendSlot(p.outCount);
    const QueryPoint q = pendingQuery(rs, i, p.fc.time);
    p.outPoints[slot] = make_float4(q.x, q.y, q.z, q.t);
    p.outRays[slot] = i;
  }
}

class DdaTraversal final : public DeviceTraversal {
public:
  const char* name() const override { return "dda"; }
  void traverse(const TraversalLaunch& launch, cudaStream_t stream) const override {
    const int blocks = int(std::max<long long>(1, (launch.n + kThreads - 1) / kThreads));
    ddaTraverseKernel<<<blocks, kThreads, 0, stream>>>(launch);
    INR_CUDA_CHECK_LAUNCH("ddaTraverseKernel");
  }
};

}  // namespace

std::unique_ptr<DeviceTraversal> makeDdaTraversal() { return std::make_unique<DdaTraversal>(); }

}  // namespace inr
