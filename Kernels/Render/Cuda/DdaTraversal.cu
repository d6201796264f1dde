// Stage II on the GPU with the DDA walker (Render/Traverse.h), behind the DeviceTraversal seam.
#include <algorithm>
#include <stdexcept>

#include "Common/Cuda/CudaCheck.h"
#include "Render/Cuda/DeviceRefine.cuh"
#include "Render/Cuda/DeviceTraversal.h"
#include "Render/Cuda/ListedRay.cuh"
#include "Render/Traverse.h"

namespace inr {
namespace {

constexpr int kThreads = 128;
constexpr int kWarp = 32;
// In the pass over all rays a warp walks a kTileWidth x kTileHeight block of pixels rather than
// 32 pixels of one row: neighbouring rays cross nearly the same macrocells, so the lanes of a
// warp run nearly the same number of DDA steps (less divergence) and read the same majorants.
constexpr int kTileWidth = 8, kTileHeight = kWarp / kTileWidth;

// Stage II for ray i: complete and refine the previous query (when the launch says so), resume
// tracking, append the next candidate's query. kPruning: the medium has expected scalars (the
// kernel is compiled twice so the pass without pruning carries none of its registers). kPoints:
// kDeltaPass, or the point passes of ListedRay.cuh (cuda::kRatioPoints, kPreintegratedPoints,
// kDebiasedPoints).
constexpr int kDeltaPass = 0, kRatioPass = cuda::kRatioPoints, kPreintegratedPass = cuda::kPreintegratedPoints,
              kDebiasedPass = cuda::kDebiasedPoints;
template <bool kPruning, int kPoints>
__device__ __forceinline__ void traverseListedRay(const TraversalLaunch& p, int i) {
  if (kPoints != kDeltaPass) {  // these estimators resolve their own points (RatioTracking.h)
    cuda::traverseRatioListedRay<DdaWalker, kPruning, kPoints>(p, i);
    return;
  }
  if (p.resolvePrevious) cuda::completeListedQuery<kPruning>(p, i);
  traverseDdaRay<kPruning>(p.fc, p.medium, p.rs, i);
  if (p.rs.flags[i] & kRayPending) cuda::writeListedQuery(p, i, cuda::appendSlot(p.outCount));
}

// The pass over all rays: a persistent grid (as many blocks as the GPU holds) whose warps take 32 rays at a
// time from p.workCounter until none is left. Why: a ray's walk costs from nothing (it misses
// the box) to hundreds of DDA steps, and with one thread per ray and blocks handed out once, the
// SMs that drew heavy blocks ran on while the others idled. Warp-sized fetches balance to the
// last 32 rays; the list length is read here, so a launch sized by a stale upper bound costs
// nothing extra (Benchmarks/RESULTS.md, "GPU DDA traversal", has the before and after; what is
// left is the slowest rays' own walks).
// tilesX > 0: the pass over all rays, in 8 x 4 pixel tiles (tilesX tiles per image row).
// Occupancy: the bound below is the largest block count per SM at which ptxas (sm_90) keeps the
// delta pass free of spills; the bound of the pass before the persistent loop spilled. sm_75
// holds 8 blocks of 128 at its 1024 threads per SM.
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
#define INR_TRAVERSE_MIN_BLOCKS 8
#else
#define INR_TRAVERSE_MIN_BLOCKS 9
#endif
template <bool kPruning, int kPoints>
__device__ __forceinline__ void traversePass(const TraversalLaunch& p, int tilesX) {
  if (p.list) {
    // List passes: one thread per listed ray, as before the persistent loop (grid-stride when
    // the list outgrows the grid). They are short and bound by their slowest ray, and a warp's
    // two same-address atomics (its fetch and the empty fetch that ends it) lie on that path.
    const int n = p.listCount ? min(p.n, int(*p.listCount)) : p.n;
    const int stride = int(gridDim.x * blockDim.x);
    for (int k = int(blockIdx.x * blockDim.x + threadIdx.x); k < n; k += stride) traverseListedRay<kPruning, kPoints>(p, p.list[k]);
    return;
  }
  const int lane = int(threadIdx.x) & (kWarp - 1);
  const int width = p.fc.camera.width, height = p.fc.camera.height;
  int n = p.n;
  if (tilesX > 0) n = tilesX * ((height + kTileHeight - 1) / kTileHeight) * kWarp;
  for (;;) {
    unsigned base = 0;
    if (lane == 0) base = atomicAdd(p.workCounter, unsigned(kWarp));
    base = __shfl_sync(0xffffffffu, base, 0);
    if (base >= unsigned(n)) break;  // the same for every lane of the warp
    const int k = int(base) + lane;  // base is a multiple of 32, so k % 32 == lane
    if (k >= n) continue;
    int i = k;
    if (tilesX > 0) {
      const int tile = k / kWarp;
      const int px = (tile % tilesX) * kTileWidth + lane % kTileWidth;
      const int py = (tile / tilesX) * kTileHeight + lane / kTileWidth;
      if (px >= width || py >= height) continue;
      i = py * width + px;
    }
    traverseListedRay<kPruning, kPoints>(p, i);
  }
}

// Delta tracking's pass (one candidate per ray) at the occupancy above.
template <bool kPruning>
__global__ void __launch_bounds__(kThreads, INR_TRAVERSE_MIN_BLOCKS) ddaTraverseKernel(TraversalLaunch p, int tilesX) {
  traversePass<kPruning, kDeltaPass>(p, tilesX);
}
// Ratio tracking's pass (RatioTracking.h) carries the ray's estimate and a transfer-function
// lookup per point: at the delta kernel's bound it spilled, so it gets a lower bound of its own
// (the largest without spills for ratio and march, ptxas sm_90).
template <bool kPruning>
__global__ void __launch_bounds__(kThreads, 5) ddaRatioTraverseKernel(TraversalLaunch p, int tilesX) {
  traversePass<kPruning, kRatioPass>(p, tilesX);
}
// The pre-integrated march's pass (PreintegratedMarch.h), at ratio tracking's bound.
template <bool kPruning>
__global__ void __launch_bounds__(kThreads, 5) ddaPreintegratedTraverseKernel(TraversalLaunch p, int tilesX) {
  traversePass<kPruning, kPreintegratedPass>(p, tilesX);
}
// The debiased march's pass (DebiasedMarch.h), at ratio tracking's bound.
template <bool kPruning>
__global__ void __launch_bounds__(kThreads, 5) ddaDebiasedTraverseKernel(TraversalLaunch p, int tilesX) {
  traversePass<kPruning, kDebiasedPass>(p, tilesX);
}

class DdaTraversal final : public DeviceTraversal {
public:
  DdaTraversal() {
    int device = 0, sms = 0, perSm = 0;
    INR_CUDA_CHECK(cudaGetDevice(&device));
    INR_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    const void* kernels[kVariants] = {(const void*)ddaTraverseKernel<false>,
                                      (const void*)ddaTraverseKernel<true>,
                                      (const void*)ddaRatioTraverseKernel<false>,
                                      (const void*)ddaRatioTraverseKernel<true>,
                                      (const void*)ddaPreintegratedTraverseKernel<false>,
                                      (const void*)ddaPreintegratedTraverseKernel<true>,
                                      (const void*)ddaDebiasedTraverseKernel<false>,
                                      (const void*)ddaDebiasedTraverseKernel<true>};
    for (int k = 0; k < kVariants; ++k) {
      INR_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&perSm, kernels[k], kThreads, 0));
      residentBlocks_[k] = std::max(1, sms * std::max(1, perSm));
    }
  }
  bool supportsRatioTracking() const override { return true; }
  const char* name() const override { return "dda"; }
  void traverse(const TraversalLaunch& launch, cudaStream_t stream) const override {
    if (!launch.workCounter) throw std::invalid_argument("DdaTraversal: TraversalLaunch::workCounter is null");
    const long long needed = std::max<long long>(1, (launch.n + kThreads - 1) / kThreads);
    const bool pruning = launch.medium.prune.expected != nullptr;
    if (launch.ratio && (!launch.outRayList || !launch.outRayCount || !launch.points.t))
      throw std::invalid_argument("DdaTraversal: a ratio-tracking launch needs its point storage and ray list");
    const bool preintegrated = launch.ratio && launch.fc.estimator == PrimaryEstimator::Preintegrated;
    const bool debiased = launch.ratio && launch.fc.estimator == PrimaryEstimator::Debiased;
    const int variant = (debiased ? 6 : preintegrated ? 4 : launch.ratio ? 2 : 0) + (pruning ? 1 : 0);
    const int blocks = int(std::min<long long>(needed, residentBlocks_[variant]));
    // Pixel tiles only when the rays are exactly the image's pixels (ray i = pixel i).
    const CameraView& cam = launch.fc.camera;
    const bool tiled = !launch.list && cam.width > 0 && cam.height > 0 &&
                       (long long)cam.width * cam.height == (long long)launch.n;
    const int tilesX = tiled ? (cam.width + kTileWidth - 1) / kTileWidth : 0;
    switch (variant) {
      case 0: ddaTraverseKernel<false><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 1: ddaTraverseKernel<true><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 2: ddaRatioTraverseKernel<false><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 3: ddaRatioTraverseKernel<true><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 4: ddaPreintegratedTraverseKernel<false><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 5: ddaPreintegratedTraverseKernel<true><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      case 6: ddaDebiasedTraverseKernel<false><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
      default: ddaDebiasedTraverseKernel<true><<<blocks, kThreads, 0, stream>>>(launch, tilesX); break;
    }
    INR_CUDA_CHECK_LAUNCH("ddaTraverseKernel");
  }

private:
  static constexpr int kVariants = 8;  // delta / ratio / preintegrated / debiased x without / with pruning
  int residentBlocks_[kVariants] = {1, 1, 1, 1, 1, 1, 1, 1};
};

}  // namespace

std::unique_ptr<DeviceTraversal> makeDdaTraversal() { return std::make_unique<DdaTraversal>(); }

}  // namespace inr
