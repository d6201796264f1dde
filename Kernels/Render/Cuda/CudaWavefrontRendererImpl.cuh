#pragma once
// Private to the CUDA backend's translation units (CudaWavefrontRenderer.cu, the naive
// baseline in CudaNaiveTracker.cu): the renderer's device state and the small launch helpers.
#include <algorithm>
#include <memory>
#include <string>

#include "Common/Cuda/DeviceBuffer.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/DeviceTransferFunction.h"
#include "Render/Cuda/DeviceTraversal.h"
#include "Render/Cuda/StageTimer.h"
#include "Render/RayStateArrays.h"

namespace inr {

namespace cuda {
// RayStateArrays / PixelStateArrays storage hooks for device arrays (found by argument-dependent
// lookup).
template <typename T>
void resizeArray(DeviceBuffer<T>& a, std::size_t n) {
  a.resize(n);
}
template <typename T>
T* arrayData(DeviceBuffer<T>& a) {
  return a.get();
}
}  // namespace cuda

namespace pipeline {
constexpr int kThreads = 256;
inline int blocksFor(long long n) { return int(std::max<long long>(1, (n + kThreads - 1) / kThreads)); }

// Per-frame device counters (one read-back at the end of the frame).
enum StatSlot { kStatRays = 0, kStatShadowRays = 1, kStatRefinements = 2, kStatNaiveQueries = 3,
                kStatNaiveShadowQueries = 4, kStatNaiveCut = 5, kStatCapped = 6, kStatCovered = 7, kStatPruned = 8, kStatBudgetSkipped = 9,
                kStatShadingQueries = 10, kStatGradientOpacityQueries = 11, kStatCount = 12 };
// Per-frame device sums of the convergence estimate (doubles).
enum SumSlot { kSumResidual = 0, kSumVariance = 1, kSumCount = 2 };
}  // namespace pipeline

struct CudaWavefrontRenderer::Impl {
  ~Impl() {
    for (cudaEvent_t e : countReady)
      if (e) cudaEventDestroy(e);
  }
  cudaStream_t stream = nullptr;
  std::unique_ptr<DeviceTraversal> traversal;
  // The traversal's structure no longer matches the displayed majorants (refinements of the last
  // frame, a new traversal); build time not yet reported in a frame's statistics.
  bool traversalStale = false;
  double pendingBuildMs = 0;
  cuda::DeviceTransferFunction tf, ghostTf;
  cuda::DeviceBuffer<float> majorants, ghostMajorants, depth;
  // Coarse levels of the two majorant grids (empty-space skipping); null when skipping is off.
  cuda::DeviceBuffer<float> blockMajorants, ghostBlockMajorants;
  float* blocks() const { return blockMajorants.empty() ? nullptr : blockMajorants.get(); }
  float* ghostBlocks() const { return ghostBlockMajorants.empty() ? nullptr : ghostBlockMajorants.get(); }
  RayStateArrays<cuda::DeviceBuffer> rays;
  PixelStateArrays<cuda::DeviceBuffer> pixels;
  // The per-pixel buffers of the next image size, allocated in full before they replace the
  // current ones (reservePixels): a size that does not fit leaves the image as it was.
  struct PixelBuffers {
    RayStateArrays<cuda::DeviceBuffer> rays;
    PixelStateArrays<cuda::DeviceBuffer> pixels;
    cuda::DeviceBuffer<float4> points[2];
    cuda::DeviceBuffer<int> queryRays[2];
    std::size_t count = 0;
    bool ready = false;
  };
  PixelBuffers staged;
  // Reprojection: the old accumulation and the per-pixel minimum offers (allocated on first use).
  PixelStateArrays<cuda::DeviceBuffer> history;
  cuda::DeviceBuffer<unsigned long long> reprojectKeys;
  bool reprojectionSkipped = false;  // once for lack of memory (memoryNote said so)
  std::string memoryNote;            // a warning for the session to pass on (takeMemoryNote)
  cuda::DeviceBuffer<std::uint8_t> blueNoise;  // the shipped STBN mask (uploaded on first use)
  // The histogram scheme's residual histogram of the last frame (device, and its pinned copy).
  cuda::DeviceBuffer<unsigned> histogram;
  cuda::PinnedHost<unsigned> hostHistogram{kResidualBins};
  // Query buffers (double-buffered: a pass reads the previous pass's ray list and appends to the
  // other). Delta tracking: one query per listed ray, queryRays doubling as the next list;
  // ratio tracking: up to pointsPerIteration queries per ray (queryRays hold point slots, grown
  // on first use) and a list of rays of its own (rayList).
  cuda::DeviceBuffer<float4> points[2];
  cuda::DeviceBuffer<int> queryRays[2];
  cuda::DeviceBuffer<int> rayList[2];
  PointStateArrays<cuda::DeviceBuffer> pointState;  // ratio tracking's pending points
  // The DDA for ratio-tracked legs when `traversal` cannot run them (OptiX).
  std::unique_ptr<DeviceTraversal> ratioTraversal;
  // [6]: per parity p, [3p] the queries appended, [3p + 1] the traversal's work counter,
  // [3p + 2] the rays listed for the next pass (ratio tracking).
  cuda::DeviceBuffer<unsigned> counter;
  unsigned* queryCount(int parity) const { return counter.get() + 3 * parity; }
  unsigned* rayCount(int parity) const { return counter.get() + 3 * parity + 2; }
  cuda::PinnedHost<unsigned> hostCounter{2};
  // Gradient shading: the lit rays' values and gradients (their points and ray indices reuse
  // points[0] and queryRays[0], free once the tracking loops are done).
  cuda::DeviceBuffer<float4> shadingResults;
  // Gradient opacity: the loop's queries that need their factor (points, slots, how many) and their
  // (value, gradient).
  cuda::DeviceBuffer<float4> opacityPoints, valueGradients;
  cuda::DeviceBuffer<int> opacitySlots;
  cuda::DeviceBuffer<unsigned> opacityListed;
  cudaEvent_t countReady[2] = {nullptr, nullptr};  // hostCounter[parity] is valid
  // Frame statistics: counters and the convergence sums.
  cuda::DeviceBuffer<unsigned long long> stats;
  cuda::PinnedHost<unsigned long long> hostStats{pipeline::kStatCount};
  cuda::DeviceBuffer<double> sums;
  cuda::PinnedHost<double> hostSums{pipeline::kSumCount};
  cuda::StageTimer timer;
  double setupMs = 0.0;  // this frame's buffer (re)allocations (FrameStats::setupMs)

  // Zeroes the frame statistics (asynchronous).
  void clearStats() {
    INR_CUDA_CHECK(cudaMemsetAsync(stats.get(), 0, pipeline::kStatCount * sizeof(unsigned long long), stream));
    INR_CUDA_CHECK(cudaMemsetAsync(sums.get(), 0, pipeline::kSumCount * sizeof(double), stream));
  }
  // Copies the frame statistics to the host and waits for the stream.
  void downloadStats() {
    INR_CUDA_CHECK(cudaMemcpyAsync(hostStats.get(), stats.get(), pipeline::kStatCount * sizeof(unsigned long long),
                                   cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaMemcpyAsync(hostSums.get(), sums.get(), pipeline::kSumCount * sizeof(double),
                                   cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaStreamSynchronize(stream));
  }

  // Buffers a frame grows, each group all or nothing (a lack of memory throws DeviceOutOfMemory
  // and leaves them as they were): ratio tracking's slots, gradient opacity's, shading's.
  void growSlots(std::size_t slots, std::size_t rays);
  void growGradientOpacity(std::size_t slots);
  void growShading(std::size_t rays);
  // A leg's traverse-evaluate loop steps (CudaWavefrontRenderer.cu).
  class TrackingSteps;
};

}  // namespace inr
