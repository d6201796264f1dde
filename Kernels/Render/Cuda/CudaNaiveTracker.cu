// The naive GPU baseline of the CUDA backend (CudaWavefrontRenderer::renderFrameNaive): one
// thread per ray runs ray initialisation, delta tracking with the network evaluated inside its
// own loop (a per-thread fp32 MLP, CudaPerThreadMlp), shadows and finalisation — what a GPU delta
// tracker written for voxel data does when its texture fetch becomes a network inference. Same
// stage code, random streams and estimator as the wavefront pipeline, so it converges to the
// same image (test: CudaPipeline.NaiveTrackerConvergesToWavefrontImage).
#include <chrono>
#include <cstdio>

#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.cuh"
#include "Render/Cuda/CudaWavefrontRendererImpl.cuh"
#include "Render/Cuda/DeviceRefine.cuh"
#include "Render/Evaluate.h"
#include "Render/Finalize.h"
#include "Render/RayInit.h"
#include "Render/Shade.h"
#include "Render/Shadows.h"
#include "Render/Traverse.h"

namespace inr {

using namespace pipeline;

namespace {

__device__ bool naiveTrack(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs, int i,
                           const PerThreadMlpView& net, int tid, int refine, const DeviceRefineView& refineView,
                           unsigned long long& queries, unsigned long long& gradientQueries, int maxSteps) {
  for (int step = 0;; ++step) {
    traverseRay(fc, medium, rs, i);
    if (!(rs.flags[i] & kRayPending)) return true;
    if (step >= maxSteps) {
      rs.flags[i] &= std::uint8_t(~(kRayActive | kRayPending));
      return false;
    }
    const QueryPoint q = pendingQuery(rs, i, fc.time);
    const float v = cuda::perThreadEvaluate(net, q.x, q.y, q.z, q.t, tid);
    // As the wavefront's evaluation stage (Render/Evaluate.h); the view holds tangent planes then.
    if (usesGradient(medium.tf) && storeCandidateOpacityScale(fc, medium.tf, rs, i, v, [&](float* g) {
          cuda::perThreadForward<true>(net, q.x, q.y, q.z, q.t, tid, g);
        }))
      ++gradientQueries;
    storeQueryResult(rs, i, v);
    ++queries;
    if (refine) cuda::refineCell(refineView, linearCellIndex(medium.grid.dims, rs.cell[i]), v);
  }
}

__global__ void naiveKernel(FrameConstants fc, TrackingMedium medium, RayStateView rs, AccumulationView acc,
                            PerThreadMlpView net, int first, int count, int refine, DeviceRefineView refineView,
                            unsigned long long* stats, double* sums, int maxSteps) {
  const int tid = blockIdx.x * blockDim.x + threadIdx.x;
  if (tid >= count) return;
  const int i = first + tid;
  unsigned long long q = 0, sq = 0, gq = 0;
  bool complete = true;
  initPrimaryRay(fc, medium.grid, rs, i);
  if (rs.flags[i] & kRayActive) {
    atomicAdd(&stats[kStatRays], 1ull);
    complete &= naiveTrack(fc, medium, rs, i, net, tid, refine, refineView, q, gq, maxSteps);
    if (fc.shadows) {
      spawnShadowRay(fc, medium.grid, rs, i);
      if (rs.flags[i] & kRayActive) {
        atomicAdd(&stats[kStatShadowRays], 1ull);
        complete &= naiveTrack(fc, medium, rs, i, net, tid, refine, refineView, sq, gq, maxSteps);
      }
    }
    if (needsShading(fc, rs, i)) {  // the view holds tangent planes when shading
      const QueryPoint p = shadingQuery(fc, rs, i);
      float g[3];
      cuda::perThreadForward<true>(net, p.x, p.y, p.z, p.t, tid, g);
      shadeRay(fc, rs, i, Vec3f{g[0], g[1], g[2]});
      atomicAdd(&stats[kStatShadingQueries], 1ull);
    }
  }
  if (rs.flags[i] & kRayCapped) atomicAdd(&stats[kStatCapped], 1ull);
  const PixelConvergence pc = finalizePixel(fc, rs, acc, i);
  atomicAdd(&sums[kSumResidual], double(pc.residual));
  if (pc.covered) {
    atomicAdd(&sums[kSumVariance], double(pc.meanVariance));
    atomicAdd(&stats[kStatCovered], 1ull);
  }
  if (q) atomicAdd(&stats[kStatNaiveQueries], q);
  if (sq) atomicAdd(&stats[kStatNaiveShadowQueries], sq);
  if (gq) atomicAdd(&stats[kStatGradientOpacityQueries], gq);
  if (!complete) atomicAdd(&stats[kStatNaiveCut], 1ull);
}

}  // namespace

FrameStats CudaWavefrontRenderer::renderFrameNaive(const CudaPerThreadMlp& network) {
  FrameStats st = beginFrame("naive", "renderFrameNaive");
  const double updateBeforeFrame = st.updateMs;
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const auto tFrame = std::chrono::steady_clock::now();
  I.clearStats();
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  const FrameSetup f = frameSetup(frameKey());
  FrameConstants fc = f.fc;
  fc.jitterControl = 0;  // a thread finalizes its pixel before its neighbours are traced
  TrackingMedium medium = f.medium;
  medium.prune = PruneView{};  // the baseline runs without query reduction (as the CPU's does)
  const RayStateView& rs = f.rs;
  const int n = rs.count;
  // Threads per launch: the option, bounded so the per-thread scratch stays under 2 GiB.
  const bool shading = fc.shading.enabled != 0 || usesGradient(medium.tf);  // gradients
  const std::size_t perThread = network.scratchBytesPerThread() * (shading ? 4 : 1);
  int chunk = std::min(n, std::max(1, pipeline_.naiveRaysPerLaunch));
  chunk = int(std::max<std::size_t>(1024, std::min<std::size_t>(chunk, (std::size_t(2) << 30) / perThread)));
  chunk = std::min(chunk, n);
  const PerThreadMlpView net = network.view(chunk, fc.time, shading);
  const int maxSteps = 1 << 16;
  for (int first = 0; first < n; first += chunk) {
    const int count = std::min(chunk, n - first);
    naiveKernel<<<blocksFor(count), kThreads, 0, s>>>(fc, medium, rs, I.pixels.view(), net, first, count,
                                                      options_.refineMacrocells ? 1 : 0, f.refine, I.stats.get(),
                                                      I.sums.get(), maxSteps);
    INR_CUDA_CHECK_LAUNCH("naiveKernel");
  }
  readFrameStats(st);
  st.queries = std::size_t(I.hostStats[kStatNaiveQueries]);
  st.shadowQueries = std::size_t(I.hostStats[kStatNaiveShadowQueries]);
  if (I.hostStats[kStatNaiveCut]) {
    std::fprintf(stderr, "CudaWavefrontRenderer (naive): %llu rays hit the step cap and were cut off\n",
                 I.hostStats[kStatNaiveCut]);
  }
  endFrame(st, I.hostStats[kStatNaiveCut] != 0);
  // Traversal and evaluation are interleaved, not separable: the frame's time is the traversal's
  // (its majorant update included: it is not timed apart here).
  const double frameMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tFrame).count();
  st.traverseMs = frameMs;
  st.closeTiming(updateBeforeFrame, frameMs);
  return st;
}

}  // namespace inr
