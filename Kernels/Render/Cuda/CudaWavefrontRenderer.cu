#include "Render/Cuda/CudaWavefrontRenderer.h"

#include <cub/block/block_reduce.cuh>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "Common/DeviceMemory.h"
#include "Common/Stopwatch.h"
#include "Evaluator/Cuda/DeviceFieldEvaluator.h"
#include "Render/Cuda/CudaWavefrontRendererImpl.cuh"
#include "Render/Cuda/DeviceRefine.cuh"
#include "Render/Evaluate.h"
#include "Render/Finalize.h"
#include "Render/RayInit.h"
#include "Render/Reproject.h"
#include "Render/Shade.h"
#include "Render/Shadows.h"

namespace inr {

using namespace pipeline;

namespace {


// ---- kernels: thin wrappers around the shared INR_HD per-ray functions ----

__global__ void initKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, AccumulationView acc,
                           unsigned long long* stats) {
  using Count = cub::BlockReduce<int, kThreads>;
  __shared__ typename Count::TempStorage scratch;
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  int active = 0, skipped = 0;
  if (i < rs.count) {
    initBudgetedRay(fc, grid, rs, acc, i);
    active = (rs.flags[i] & kRayActive) ? 1 : 0;
    skipped = (rs.flags[i] & kRayBudgetSkipped) ? 1 : 0;
  }
  active = Count(scratch).Sum(active);
  __syncthreads();
  skipped = Count(scratch).Sum(skipped);
  if (threadIdx.x == 0) {
    if (active) atomicAdd(&stats[kStatRays], (unsigned long long)active);
    if (skipped) atomicAdd(&stats[kStatBudgetSkipped], (unsigned long long)skipped);
  }
}

// Gradient shading (Render/Shade.h): lists the rays whose colour is lit, with their points; the
// shading-query statistic doubles as the list's counter.
__global__ void gatherShadingKernel(FrameConstants fc, RayStateView rs, float4* points, int* rays,
                                    unsigned long long* stats) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= rs.count || !needsShading(fc, rs, i)) return;
  const int k = int(atomicAdd(&stats[kStatShadingQueries], 1ull));
  const QueryPoint q = shadingQuery(fc, rs, i);
  points[k] = make_float4(q.x, q.y, q.z, q.t);
  rays[k] = i;
}

__global__ void shadeKernel(FrameConstants fc, RayStateView rs, const float4* results, const int* rays,
                            const unsigned long long* count) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= int(*count)) return;
  const float4 r = results[k];
  shadeRay(fc, rs, rays[k], Vec3f{r.y, r.z, r.w});
}

// The list's length for the evaluator (32 bits, as its deviceCount).
__global__ void shadingCountKernel(const unsigned long long* stats, unsigned* count) {
  *count = unsigned(stats[kStatShadingQueries]);
}

// Reprojection pass 1: old pixel j offers itself to the new pixels around its hit point.
__global__ void reprojectScatterKernel(CameraView oldView, CameraView newView, Box3f box, AccumulationView history,
                                       unsigned long long* keys) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= history.count) return;
  reprojectionOffers(oldView, newView, box, history, j,
                     [&](int i, std::uint64_t key) { atomicMin(&keys[i], (unsigned long long)key); });
}

__global__ void reprojectGatherKernel(CameraView oldView, CameraView newView, Box3f box, AccumulationView history,
                                      AccumulationView acc, const unsigned long long* keys,
                                      std::uint32_t maxHistory, Vec3f background) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < acc.count) reprojectionGather(oldView, newView, box, history, acc, i, keys[i], maxHistory, background);
}

__global__ void ghostInitKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, int stride) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < rs.count) initGhostRay(fc, grid, rs, i, stride);
}

__global__ void spawnShadowKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, unsigned long long* stats) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= rs.count) return;
  spawnShadowRay(fc, grid, rs, i);
  if (rs.flags[i] & kRayActive) atomicAdd(&stats[kStatShadowRays], 1ull);
}

// Iteration cap reached: the listed rays stop where they are (no real collision recorded); the
// list holds min(n, *count) rays (count null: n).
__global__ void cutoffKernel(RayStateView rs, const int* list, const unsigned* count, int n) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= (count ? min(n, int(*count)) : n)) return;
  const int i = list[k];
  rs.flags[i] &= std::uint8_t(~(kRayActive | kRayPending | kRayBadSample));
  rs.sample[i] = NAN;
  rs.pointCount[i] = 0;
}

// Stage IV, the convergence sums (block reductions, one atomic each per block) and the count of
// rays the collision cap cut off.
// With the residual histogram of the histogram scheme (block-local bins in shared memory, one
// global atomic per non-empty bin and block); `histogram` is null for the other schemes.
__global__ void finalizeKernel(FrameConstants fc, RayStateView rs, AccumulationView acc, double* sums,
                               unsigned long long* stats, unsigned* histogram) {
  using Reduce = cub::BlockReduce<float, kThreads>;
  using Count = cub::BlockReduce<int, kThreads>;
  __shared__ union {
    typename Reduce::TempStorage sum;
    typename Count::TempStorage count;
  } scratch;
  __shared__ unsigned bins[kResidualBins];
  if (histogram) {
    for (int b = threadIdx.x; b < kResidualBins; b += blockDim.x) bins[b] = 0u;
    __syncthreads();
  }
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  PixelConvergence pc{0.f, 0.f, 0, -1};
  if (i < rs.count) {
    if (rs.flags[i] & kRayCapped) atomicAdd(&stats[kStatCapped], 1ull);
    pc = finalizePixel(fc, rs, acc, i);
    if (histogram && pc.residualBin >= 0) atomicAdd(&bins[pc.residualBin], 1u);
  }
  const float residual = Reduce(scratch.sum).Sum(pc.residual);
  __syncthreads();
  const float variance = Reduce(scratch.sum).Sum(pc.meanVariance);
  __syncthreads();
  const int covered = Count(scratch.count).Sum(pc.covered);
  if (threadIdx.x == 0) {
    atomicAdd(&sums[kSumResidual], double(residual));
    atomicAdd(&sums[kSumVariance], double(variance));
    if (covered) atomicAdd(&stats[kStatCovered], (unsigned long long)covered);
  }
  if (histogram) {
    __syncthreads();
    for (int b = threadIdx.x; b < kResidualBins; b += blockDim.x)
      if (bins[b]) atomicAdd(&histogram[b], bins[b]);
  }
}

// Candidates pruned this frame (RayStateView::pruned, both legs): one atomic per block.
__global__ void sumPrunedKernel(RayStateView rs, unsigned long long* stats) {
  using Reduce = cub::BlockReduce<unsigned, kThreads>;
  __shared__ typename Reduce::TempStorage scratch;
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  const unsigned sum = Reduce(scratch).Sum(i < rs.count ? rs.pruned[i] : 0u);
  if (threadIdx.x == 0 && sum) atomicAdd(&stats[kStatPruned], (unsigned long long)sum);
}

// Gradient opacity (Render/Evaluate.h), after the values of the first min(*count, maxN) queries
// landed in samples[slots[k]]: lists the queries whose outcome the gradient term can change (their
// point and slot, *listed of them) for a value + gradient batch, and gives the others the empty
// term (factor 0). 2D transfer functions take the same path (the term is |grad f|).
// points: ratio / march points (slots are point slots); else delta-tracking candidates (rays).
__global__ void listOpacityQueriesKernel(FrameConstants fc, TransferFunctionView tf, RayStateView rs, bool points,
                                         const unsigned* count, int maxN, const float4* queries, const int* slots,
                                         const float* samples, float* opacityScales, float4* listedPoints,
                                         int* listedSlots, unsigned* listed) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= maxN || k >= int(*count)) return;
  const int slot = slots[k];
  const float v = samples[slot];
  const bool needs = points ? sampleNeedsOpacityScale(tf, v) : candidateNeedsOpacityScale(fc, tf, rs, slot, v);
  if (!needs) {
    opacityScales[slot] = emptyGradientTerm(tf);
    return;
  }
  const unsigned j = atomicAdd(listed, 1u);
  listedPoints[j] = queries[k];
  listedSlots[j] = slot;
}

// The factor of each listed query (`results`: its value and gradient) to opacityScales[slots[j]];
// thread 0 adds the listed queries (at most maxN) to the frame's count of them.
__global__ void scatterOpacityKernel(const unsigned* listed, int maxN, const int* slots, const float4* results,
                                     TransferFunctionView tf, float* opacityScales, unsigned long long* stats) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  const int n = min(int(*listed), maxN);
  if (j == 0) stats[kStatGradientOpacityQueries] += (unsigned long long)n;
  if (j >= n) return;
  const float4 r = results[j];
  opacityScales[slots[j]] = gradientTermOf(tf, Vec3f{r.y, r.z, r.w});
}

__global__ void resetPixelsKernel(AccumulationView acc) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < acc.count) resetPixel(acc, i);
}

}  // namespace

// Ratio tracking's slot buffers for `slots` points and `rays` listed rays, all or nothing: the new
// ones are allocated beside the current ones and swapped in only when every one fits, so that a
// lack of memory leaves the buffers (and the device memory in use) as they were.
void CudaWavefrontRenderer::Impl::growSlots(std::size_t slots, std::size_t rays) {
  const DeviceAllocationPurpose purpose(
      "ratio tracking's query slots (" + std::to_string(rays) + " rays x " + std::to_string(slots / std::max<std::size_t>(1, rays)) +
          " points per iteration)",
      "lower Points Per Batch (InrPointsPerIteration; inr render --points-per-iteration) or the image resolution");
  const bool newState = pointState.count != slots;
  bool growPoints[2], growQueries[2], growList[2];
  bool any = newState;
  for (int b = 0; b < 2; ++b) {
    growPoints[b] = points[b].size() < slots;
    growQueries[b] = queryRays[b].size() < slots;
    growList[b] = rayList[b].size() < rays;
    any = any || growPoints[b] || growQueries[b] || growList[b];
  }
  if (!any) return;
  PointStateArrays<cuda::DeviceBuffer> state;
  cuda::DeviceBuffer<float4> newPoints[2];
  cuda::DeviceBuffer<int> newQueries[2], newList[2];
  if (newState) state.resize(slots);
  for (int b = 0; b < 2; ++b) {
    if (growPoints[b]) newPoints[b].resize(slots);
    if (growQueries[b]) newQueries[b].resize(slots);
    if (growList[b]) newList[b].resize(rays);
  }
  if (newState) std::swap(pointState, state);
  for (int b = 0; b < 2; ++b) {
    if (growPoints[b]) points[b].swap(newPoints[b]);
    if (growQueries[b]) queryRays[b].swap(newQueries[b]);
    if (growList[b]) rayList[b].swap(newList[b]);
  }
}

// Gradient opacity's buffers for `slots` queries, all or nothing (as growSlots).
void CudaWavefrontRenderer::Impl::growGradientOpacity(std::size_t slots) {
  const DeviceAllocationPurpose purpose(
      "gradient opacity's value-and-gradient queries (" + std::to_string(slots) + " slots)",
      "turn Gradient Opacity off, lower Points Per Batch (InrPointsPerIteration) or the image resolution");
  cuda::DeviceBuffer<float4> newGradients, newPoints;
  cuda::DeviceBuffer<int> newSlots;
  cuda::DeviceBuffer<unsigned> newListed;
  const bool grow = valueGradients.size() < slots, growListed = opacityListed.size() < 1;
  if (grow) {
    newGradients.resize(slots);
    newPoints.resize(slots);
    newSlots.resize(slots);
  }
  if (growListed) newListed.resize(1);
  if (grow) {
    valueGradients.swap(newGradients);
    opacityPoints.swap(newPoints);
    opacitySlots.swap(newSlots);
  }
  if (growListed) opacityListed.swap(newListed);
}

// Gradient shading's results for `rays` rays (one buffer: resize keeps it as it was on failure).
void CudaWavefrontRenderer::Impl::growShading(std::size_t rays) {
  const DeviceAllocationPurpose purpose(
      "gradient shading's values and gradients (" + std::to_string(rays) + " rays)",
      "turn Shade off (inr render without --shade) or lower the image resolution");
  shadingResults.growTo(rays);
}

// The traverse-evaluate loop's steps on the GPU. The host never waits on the GPU mid-loop:
// listedQueries(i) first queues iteration i's evaluation and iteration i + 1's traversal (below the
// iteration cap), which read iteration i's query count on the device, with grids sized by the last count
// the host knows (an upper bound: the rays a pass lists never outnumber the previous pass's
// queries, and a ray has at most pointsPerIteration queries), and only then reads count i from
// pinned memory. When count i is zero, the already queued iteration i + 1 is empty and costs two
// idle launches.
class CudaWavefrontRenderer::Impl::TrackingSteps final : public TrackingLoopSteps {
public:
  // `ratio`: the leg is a ratio-tracked or marched primary leg (fc.pointsPerIteration points per
  // ray); `refine`: evaluated samples widen under-estimated macrocells.
  TrackingSteps(Impl& impl, const DeviceFieldEvaluator& evaluator, const FrameConstants& fc,
                const TrackingMedium& medium, bool refine, const DeviceRefineView& refineView,
                cuda::Stage traverseStage, cuda::Stage evaluateStage, bool ratio)
      : I(impl), evaluator_(evaluator), fc_(fc), traverseStage_(traverseStage), evaluateStage_(evaluateStage),
        ratio_(ratio) {
    const RayStateView rs = I.rays.view();
    perRay_ = ratio ? fc.pointsPerIteration : 1;
    slots_ = std::size_t(rs.count) * std::size_t(perRay_);
    if (ratio) {
      const auto tSetup = Clock::now();
      I.growSlots(slots_, std::size_t(rs.count));
      if (!I.traversal->supportsRatioTracking() && !I.ratioTraversal) I.ratioTraversal = makeDdaTraversal();
      I.setupMs += msSince(tSetup);
    }
    walker_ = ratio && !I.traversal->supportsRatioTracking() ? I.ratioTraversal.get() : I.traversal.get();
    launch_.fc = fc;
    launch_.medium = medium;
    launch_.rs = rs;
    launch_.refine = refine;
    launch_.refineView = refineView;
    launch_.ratio = ratio;
    if (ratio) {
      launch_.points = I.pointState.view();
      launch_.points.perRay = fc.pointsPerIteration;  // by ray (pointSlot)
    }
    launch_.n = rs.count;  // upper bound of the rays the next traversal lists
    sampleOut_ = ratio ? launch_.points.sample : rs.sample;
    opacityScaleOut_ = ratio ? launch_.points.opacityScale : rs.opacityScale;
    gradientOpacity_ = usesGradient(medium.tf);  // (or a 2D TF)
    if (gradientOpacity_) I.growGradientOpacity(slots_);
    enqueueTraverse(0);
  }

  std::size_t listedQueries(int it, bool belowCap) override {
    const int cur = it & 1;
    if (belowCap) {  // speculatively: evaluate iteration it, traverse iteration it + 1
      enqueueEvaluate(cur);
      enqueueTraverse(it + 1);
    }
    INR_CUDA_CHECK(cudaEventSynchronize(I.countReady[cur]));
    return std::size_t(I.hostCounter[cur]);
  }

  bool consume(int /*it*/, std::size_t k) override {  // (its evaluation is already queued)
    launch_.n = int(k);
    return true;
  }

  void cutOff(int it) override {
    const int cur = it & 1;
    const int k = int(I.hostCounter[cur]);
    // Delta: the listed queries' rays; ratio: the listed rays.
    cutoffKernel<<<blocksFor(k), kThreads, 0, I.stream>>>(launch_.rs, ratio_ ? I.rayList[cur].get() : I.queryRays[cur].get(),
                                                          ratio_ ? I.rayCount(cur) : nullptr, k);
    INR_CUDA_CHECK_LAUNCH("cutoffKernel");
  }

private:
  void enqueueTraverse(int it) {
    const cudaStream_t stream = I.stream;
    const int cur = it & 1, prev = cur ^ 1;
    // The parity's counts and the traversal's work counter, zeroed together.
    INR_CUDA_CHECK(cudaMemsetAsync(I.queryCount(cur), 0, 3 * sizeof(unsigned), stream));
    launch_.list = it ? (ratio_ ? I.rayList[prev].get() : I.queryRays[prev].get()) : nullptr;
    launch_.listCount = it ? (ratio_ ? I.rayCount(prev) : I.queryCount(prev)) : nullptr;
    launch_.resolvePrevious = it != 0;
    launch_.outPoints = I.points[cur].get();
    launch_.outRays = I.queryRays[cur].get();
    launch_.outCount = I.queryCount(cur);
    launch_.outRayList = ratio_ ? I.rayList[cur].get() : nullptr;
    launch_.outRayCount = ratio_ ? I.rayCount(cur) : nullptr;
    launch_.workCounter = I.queryCount(cur) + 1;
    I.timer.begin(traverseStage_, stream);
    walker_->traverse(launch_, stream);
    I.timer.end(stream);
    INR_CUDA_CHECK(cudaMemcpyAsync(I.hostCounter.get() + cur, I.queryCount(cur), sizeof(unsigned),
                                   cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaEventRecord(I.countReady[cur], stream));
  }

  void enqueueEvaluate(int cur) {
    const cudaStream_t stream = I.stream;
    const long long bound = std::min<long long>((long long)slots_, (long long)launch_.n * perRay_);
    I.timer.begin(evaluateStage_, stream);
    evaluator_.evaluateDevice(I.points[cur].get(), I.queryCount(cur), int(bound), sampleOut_, I.queryRays[cur].get(),
                              stream);
    if (gradientOpacity_) {  // gradients where the factor can change the outcome (Render/Evaluate.h)
      INR_CUDA_CHECK(cudaMemsetAsync(I.opacityListed.get(), 0, sizeof(unsigned), stream));
      listOpacityQueriesKernel<<<blocksFor(bound), kThreads, 0, stream>>>(
          fc_, launch_.medium.tf, launch_.rs, ratio_, I.queryCount(cur), int(bound), I.points[cur].get(),
          I.queryRays[cur].get(), sampleOut_, opacityScaleOut_, I.opacityPoints.get(), I.opacitySlots.get(),
          I.opacityListed.get());
      INR_CUDA_CHECK_LAUNCH("listOpacityQueriesKernel");
      evaluator_.evaluateWithGradientDevice(I.opacityPoints.get(), I.opacityListed.get(), int(bound), fc_.time,
                                            I.valueGradients.get(), stream);
      scatterOpacityKernel<<<blocksFor(bound), kThreads, 0, stream>>>(I.opacityListed.get(), int(bound),
                                                                       I.opacitySlots.get(), I.valueGradients.get(),
                                                                       launch_.medium.tf, opacityScaleOut_, I.stats.get());
      INR_CUDA_CHECK_LAUNCH("scatterOpacityKernel");
    }
    I.timer.end(stream);
  }

  Impl& I;
  const DeviceFieldEvaluator& evaluator_;
  const FrameConstants fc_;
  const cuda::Stage traverseStage_, evaluateStage_;
  const bool ratio_;
  int perRay_ = 1;
  std::size_t slots_ = 0;
  const DeviceTraversal* walker_ = nullptr;
  TraversalLaunch launch_;
  float* sampleOut_ = nullptr;
  float* opacityScaleOut_ = nullptr;
  bool gradientOpacity_ = false;
};

CudaWavefrontRenderer::CudaWavefrontRenderer(const DeviceFieldEvaluator& evaluator, CudaMacrocellGrid& macrocells,
                                                     TrackingOptions options, CudaPipelineOptions pipeline)
    : WavefrontRenderer(options), evaluator_(evaluator), macrocells_(macrocells), pipeline_(pipeline),
      impl_(std::make_unique<Impl>()) {
  Impl& I = *impl_;
  I.stream = macrocells.stream();
  I.traversal = makeDdaTraversal();
  I.counter.resize(6);
  for (cudaEvent_t& e : I.countReady) INR_CUDA_CHECK(cudaEventCreateWithFlags(&e, cudaEventDisableTiming));
  I.stats.resize(kStatCount);
  I.sums.resize(kSumCount);
  I.histogram.resize(kResidualBins);
  const DeviceAllocationPurpose purpose(
      "the majorant grid of " + std::to_string(macrocells.cellCount()) + " macrocells",
      "lower the macrocell resolution (Macrocell Resolution; inr render --macrocells)");
  I.majorants.resize(std::size_t(macrocells.cellCount()));
  I.majorants.zero(I.stream);
  if (macrocells.blockCount() > 0) {
    I.blockMajorants.resize(std::size_t(macrocells.blockCount()));
    I.blockMajorants.zero(I.stream);
  }
  allocatePixels();
}

CudaWavefrontRenderer::~CudaWavefrontRenderer() = default;

const DeviceTraversal& CudaWavefrontRenderer::traversal() const { return *impl_->traversal; }

void CudaWavefrontRenderer::setTraversal(const TraversalOptions& options) {
  std::string reason;
  std::unique_ptr<DeviceTraversal> t = makeDeviceTraversal(options, reason);
  if (!t->supportsRatioTracking()) reason += "; ratio-tracked primary rays run through the DDA";
  impl_->traversal = std::move(t);
  impl_->traversalStale = true;
  traversalChoice_ = reason;
}

void CudaWavefrontRenderer::rebuildTraversal() {
  Impl& I = *impl_;
  I.traversal->majorantsChanged(macrocells_.view(I.majorants.get(), I.blocks()), I.stream);
  I.pendingBuildMs += I.traversal->buildInfo().lastBuildMs;
  I.traversalStale = false;
}

void CudaWavefrontRenderer::reservePixels(int width, int height) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("image size must be positive");
  stagePixels(std::size_t(width) * std::size_t(height), std::to_string(width) + "x" + std::to_string(height));
}

void CudaWavefrontRenderer::stagePixels(std::size_t n, const std::string& imageSize) {
  if (n > (std::size_t(1) << 30))
    throw std::invalid_argument("image too large for the GPU pipeline (more than 2^30 pixels)");
  Impl& I = *impl_;
  if (I.staged.ready && I.staged.count == n) return;
  I.staged = Impl::PixelBuffers{};  // a size staged before and not used: freed first
  if (I.rays.count == n && I.pixels.count == n) return;  // the current buffers fit
  Impl::PixelBuffers next;
  {
    const DeviceAllocationPurpose purpose(
        "the per-pixel ray, accumulation and query state of a " + imageSize + " image (" + std::to_string(n) +
            " pixels, while the current image's is kept)",
        "lower the image resolution (the view or screenshot size; inr render --size)");
    next.rays.resize(n);
    next.pixels.resize(n);
    for (int b = 0; b < 2; ++b) {
      next.points[b].resize(n);
      next.queryRays[b].resize(n);
    }
  }  // a throw above frees what `next` holds and leaves the current buffers untouched
  next.count = n;
  next.ready = true;
  I.staged = std::move(next);
}

std::string CudaWavefrontRenderer::takeMemoryNote() {
  std::string note;
  std::swap(note, impl_->memoryNote);
  return note;
}

void CudaWavefrontRenderer::resizePixels(std::size_t n) {
  Impl& I = *impl_;
  stagePixels(n, std::to_string(n) + "-pixel");
  if (I.staged.ready && I.staged.count == n) {
    std::swap(I.rays, I.staged.rays);
    std::swap(I.pixels, I.staged.pixels);
    for (int b = 0; b < 2; ++b) {
      std::swap(I.points[b], I.staged.points[b]);
      std::swap(I.queryRays[b], I.staged.queryRays[b]);
    }
    I.staged = Impl::PixelBuffers{};  // the old size's buffers are freed
  }
  I.rays.flags.zero(I.stream);
}

void CudaWavefrontRenderer::clearAccumulation() {
  Impl& I = *impl_;
  const AccumulationView acc = I.pixels.view();
  resetPixelsKernel<<<blocksFor(acc.count), kThreads, 0, I.stream>>>(acc);
  INR_CUDA_CHECK_LAUNCH("resetPixelsKernel");
  INR_CUDA_CHECK(cudaStreamSynchronize(I.stream));
}

std::vector<Vec4f> CudaWavefrontRenderer::accumulation() const { return impl_->pixels.accum.download(impl_->stream); }

void CudaWavefrontRenderer::copyAccumulation(cudaArray* target) const {
  const std::size_t w = std::size_t(settings().width), h = std::size_t(settings().height);
  if (!target) throw std::invalid_argument("CudaWavefrontRenderer::copyAccumulation: no target array");
  if (impl_->pixels.accum.size() < w * h)
    throw std::logic_error("CudaWavefrontRenderer::copyAccumulation: no image of the current size yet");
  const std::size_t row = w * sizeof(Vec4f);
  INR_CUDA_CHECK(cudaMemcpy2DToArrayAsync(target, 0, 0, impl_->pixels.accum.get(), row, row, h,
                                          cudaMemcpyDeviceToDevice, impl_->stream));
  INR_CUDA_CHECK(cudaStreamSynchronize(impl_->stream));
}

void CudaWavefrontRenderer::transferFunctionChanged() { impl_->tf.upload(*tfTable_, impl_->stream); }

void CudaWavefrontRenderer::recomputeMajorants() {
  macrocells_.computeMajorants(impl_->tf.view(), impl_->majorants.get(), impl_->blocks());
  rebuildTraversal();  // part of the scene update (time step, transfer-function edit)
}

void CudaWavefrontRenderer::depthLimitChanged(const std::vector<float>& depthLimit) {
  const DeviceAllocationPurpose purpose(
      "the opaque geometry's depth limit (" + std::to_string(depthLimit.size()) + " pixels)",
      "lower the image resolution");
  if (depthLimit.empty())
    impl_->depth.resize(0);
  else
    impl_->depth.upload(depthLimit, impl_->stream);
}

void CudaWavefrontRenderer::sceneUpdateDone() { INR_CUDA_CHECK(cudaStreamSynchronize(impl_->stream)); }

CudaWavefrontRenderer::FrameSetup CudaWavefrontRenderer::frameSetup(int frame) {
  Impl& I = *impl_;
  FrameSetup f;
  f.fc = WavefrontRenderer::frameConstants(std::uint32_t(frame), I.depth.get());
  const PruneView prune = pruningActive() ? macrocells_.pruneView(pruneThresholds()) : PruneView{};
  f.medium = TrackingMedium{macrocells_.view(I.majorants.get(), I.blocks()), I.tf.view(), prune};
  f.refine = macrocells_.refineView();
  f.refine.frameRefinements = I.stats.get() + kStatRefinements;
  f.rs = I.rays.view();
  return f;
}

void CudaWavefrontRenderer::readFrameStats(FrameStats& st) {
  Impl& I = *impl_;
  I.downloadStats();
  st.rays = std::size_t(I.hostStats[kStatRays]);
  st.shadowRays = std::size_t(I.hostStats[kStatShadowRays]);
  st.refinements = std::size_t(I.hostStats[kStatRefinements]);
  st.residualSum = I.hostSums[kSumResidual];
  st.varianceSum = I.hostSums[kSumVariance];
  st.coveredPixels = std::size_t(I.hostStats[kStatCovered]);
  st.cappedRays = std::size_t(I.hostStats[kStatCapped]);
  st.budgetSkipped = std::size_t(I.hostStats[kStatBudgetSkipped]);
  st.pruned = std::size_t(I.hostStats[kStatPruned]);
  st.shadingQueries = std::size_t(I.hostStats[kStatShadingQueries]);
  st.gradientOpacityQueries = std::size_t(I.hostStats[kStatGradientOpacityQueries]);
  // Refinement raised majorants: the next frame's updateDirtyMajorants applies them, and the
  // traversal's structure is rebuilt over them.
  if (st.refinements > 0) I.traversalStale = true;
}

FrameConstants CudaWavefrontRenderer::prepareFrame(FrameStats& /*st*/) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  I.setupMs = 0.0;
  I.timer.reset(pipeline_.stageTiming);
  I.clearStats();

  I.timer.begin(cuda::kUpdate, s);
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  if (I.traversalStale) rebuildTraversal();
  I.timer.end(s);

  frame_ = frameSetup(frameKey());
  const FrameConstants& fc = frame_.fc;
  const int n = frame_.rs.count;
  // Every buffer this frame grows is allocated before any of its work: a lack of GPU memory then
  // leaves the frame undone with the image, its accumulation and the ray state as they were.
  const bool ratio = fc.estimator != PrimaryEstimator::Delta;
  const std::size_t slots = std::size_t(n) * std::size_t(ratio ? fc.pointsPerIteration : 1);
  const auto tSetup = Clock::now();
  if (ratio) I.growSlots(slots, std::size_t(n));
  if (usesGradient(frame_.medium.tf)) I.growGradientOpacity(slots);
  if (fc.shading.enabled) I.growShading(std::size_t(n));
  I.setupMs += msSince(tSetup);  // (I.setupMs was reset above: this frame's allocations)
  return fc;
}

void CudaWavefrontRenderer::initRays(const FrameConstants& fc, FrameStats& /*st*/) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const RayStateView& rs = frame_.rs;
  I.timer.begin(cuda::kInit, s);
  initKernel<<<blocksFor(rs.count), kThreads, 0, s>>>(fc, frame_.medium.grid, rs, I.pixels.view(), I.stats.get());
  INR_CUDA_CHECK_LAUNCH("initKernel");
  I.timer.end(s);
}

std::unique_ptr<TrackingLoopSteps> CudaWavefrontRenderer::legSteps(const FrameConstants& fc, Leg leg,
                                                                   FrameStats& /*st*/) {
  const bool shadow = leg == Leg::Shadow;
  return std::make_unique<Impl::TrackingSteps>(
      *impl_, evaluator_, fc, frame_.medium, options_.refineMacrocells, frame_.refine,
      shadow ? cuda::kShadowTraverse : cuda::kTraverse, shadow ? cuda::kShadowEvaluate : cuda::kEvaluate,
      !shadow && fc.estimator != PrimaryEstimator::Delta);
}

void CudaWavefrontRenderer::spawnShadowRays(const FrameConstants& fc, FrameStats& /*st*/) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const RayStateView& rs = frame_.rs;
  I.timer.begin(cuda::kShadowTraverse, s);
  spawnShadowKernel<<<blocksFor(rs.count), kThreads, 0, s>>>(fc, frame_.medium.grid, rs, I.stats.get());
  INR_CUDA_CHECK_LAUNCH("spawnShadowKernel");
  I.timer.end(s);
}

const std::uint32_t* CudaWavefrontRenderer::finalizePixels(const FrameConstants& fc, FrameStats& st) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const RayStateView& rs = frame_.rs;
  const int n = rs.count;
  if (frame_.medium.prune.expected) {
    sumPrunedKernel<<<blocksFor(n), kThreads, 0, s>>>(rs, I.stats.get());
    INR_CUDA_CHECK_LAUNCH("sumPrunedKernel");
  }
  I.timer.begin(cuda::kFinalize, s);
  const bool histogram = queryReduction_.budget == BudgetScheme::Histogram;
  if (histogram) INR_CUDA_CHECK(cudaMemsetAsync(I.histogram.get(), 0, kResidualBins * sizeof(unsigned), s));
  finalizeKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, rs, I.pixels.view(), I.sums.get(), I.stats.get(),
                                                    histogram ? I.histogram.get() : nullptr);
  INR_CUDA_CHECK_LAUNCH("finalizeKernel");
  I.timer.end(s);
  if (histogram)
    INR_CUDA_CHECK(cudaMemcpyAsync(I.hostHistogram.get(), I.histogram.get(), kResidualBins * sizeof(unsigned),
                                   cudaMemcpyDeviceToHost, s));
  readFrameStats(st);  // synchronises
  double ms[cuda::kStages];
  I.timer.collect(ms);
  st.updateMs += ms[cuda::kUpdate];
  st.initMs = ms[cuda::kInit];
  st.traverseMs = ms[cuda::kTraverse];
  st.evaluateMs = ms[cuda::kEvaluate];
  st.shadowTraverseMs = ms[cuda::kShadowTraverse];
  st.shadowEvaluateMs = ms[cuda::kShadowEvaluate];
  st.shadingMs = ms[cuda::kShade];
  st.finalizeMs = ms[cuda::kFinalize];
  const TraversalBuildInfo built = I.traversal->buildInfo();
  st.traversalBuildMs = I.pendingBuildMs;
  st.traversalPrimitives = built.primitives;
  st.traversalBytes = built.bytes;
  I.pendingBuildMs = 0;
  st.setupMs = I.setupMs;
  return histogram ? I.hostHistogram.get() : nullptr;
}

BlueNoiseMaskView CudaWavefrontRenderer::blueNoiseMask() {
  Impl& I = *impl_;
  const BlueNoiseMask& mask = shippedBlueNoiseMask();
  if (I.blueNoise.empty()) I.blueNoise.upload(mask.texels, I.stream);
  return BlueNoiseMaskView{I.blueNoise.get(), mask.width, mask.height, mask.depth};
}

void CudaWavefrontRenderer::reprojectAccumulation(const CameraView& oldView, const CameraView& newView,
                                                      std::uint32_t maxHistory, const Vec3f& background) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const std::size_t n = I.pixels.count;
  // The history buffers are allocated before the accumulation becomes the history, so that a
  // lack of memory leaves the accumulation in place: the image then restarts instead (the camera
  // moved), as without reprojection, and says so once.
  try {
    const DeviceAllocationPurpose purpose(
        "reprojection's history of a " + std::to_string(n) + "-pixel image",
        "turn Reproject off (InrReproject; inr render --no-reproject) or lower the image resolution");
    I.history.resize(n);
    I.reprojectKeys.resize(n);
  } catch (const DeviceOutOfMemory& e) {
    I.history = PixelStateArrays<cuda::DeviceBuffer>{};
    I.reprojectKeys = cuda::DeviceBuffer<unsigned long long>{};
    clearAccumulation();
    if (!I.reprojectionSkipped) I.memoryNote = std::string("reprojection skipped, the image restarts: ") + e.what();
    I.reprojectionSkipped = true;
    return;
  }
  std::swap(I.history, I.pixels);  // the old accumulation becomes the history
  INR_CUDA_CHECK(cudaMemsetAsync(I.reprojectKeys.get(), 0xff, n * sizeof(unsigned long long), s));
  const AccumulationView history = I.history.view(), acc = I.pixels.view();
  reprojectScatterKernel<<<blocksFor(history.count), kThreads, 0, s>>>(oldView, newView, volumeBox(), history,
                                                                        I.reprojectKeys.get());
  INR_CUDA_CHECK_LAUNCH("reprojectScatterKernel");
  reprojectGatherKernel<<<blocksFor(acc.count), kThreads, 0, s>>>(oldView, newView, volumeBox(), history, acc,
                                                                  I.reprojectKeys.get(), maxHistory, background);
  INR_CUDA_CHECK_LAUNCH("reprojectGatherKernel");
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
}

void CudaWavefrontRenderer::beginGhostPasses() {
  Impl& I = *impl_;
  I.timer.reset(false);
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  const DeviceAllocationPurpose purpose(
      "the ghost passes' majorant grid (" + std::to_string(macrocells_.cellCount()) + " macrocells)",
      "lower the macrocell resolution or set Ghost Passes to 0");
  I.ghostMajorants.resize(std::size_t(macrocells_.cellCount()));
  if (macrocells_.blockCount() > 0) I.ghostBlockMajorants.resize(std::size_t(macrocells_.blockCount()));
  I.clearStats();
}

void CudaWavefrontRenderer::traceGhostPass(const TransferFunctionTable& table, const FrameConstants& fc, int stride,
                                               FrameStats& total) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  I.ghostTf.upload(table, s);
  macrocells_.computeMajorants(I.ghostTf.view(), I.ghostMajorants.get(), I.ghostBlocks());
  const TrackingMedium medium{macrocells_.view(I.ghostMajorants.get(), I.ghostBlocks()), I.ghostTf.view(), PruneView{}};
  DeviceRefineView refine = macrocells_.refineView();
  refine.frameRefinements = I.stats.get() + kStatRefinements;
  const RayStateView rs = I.rays.view();
  ghostInitKernel<<<blocksFor(rs.count), kThreads, 0, s>>>(fc, medium.grid, rs, stride);
  INR_CUDA_CHECK_LAUNCH("ghostInitKernel");
  Impl::TrackingSteps steps(I, evaluator_, fc, medium, true, refine, cuda::kTraverse, cuda::kEvaluate, false);
  runLeg(steps, Leg::Primary, total);
}

void CudaWavefrontRenderer::endGhostPasses(FrameStats& total) {
  Impl& I = *impl_;
  const auto tUpdate = Clock::now();
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  I.downloadStats();
  total.refinements = std::size_t(I.hostStats[kStatRefinements]);
  if (total.refinements > 0) rebuildTraversal();
  total.updateMs = msSince(tUpdate);
}

std::vector<float> CudaWavefrontRenderer::residual() const { return impl_->pixels.residual.download(impl_->stream); }

std::vector<float> CudaWavefrontRenderer::majorants() const { return impl_->majorants.download(impl_->stream); }

std::vector<float> CudaWavefrontRenderer::blockMajorants() const {
  return impl_->blockMajorants.download(impl_->stream);
}

bool CudaWavefrontRenderer::fieldHasGradient() const { return evaluator_.providesDeviceGradient(); }

void CudaWavefrontRenderer::shadeHits(const FrameConstants& fc, FrameStats& /*st*/) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const RayStateView rs = I.rays.view();
  const int n = rs.count;
  I.timer.begin(cuda::kShade, s);
  I.growShading(std::size_t(n));
  float4* points = I.points[0].get();
  int* rays = I.queryRays[0].get();
  gatherShadingKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, rs, points, rays, I.stats.get());
  INR_CUDA_CHECK_LAUNCH("gatherShadingKernel");
  unsigned* count = I.queryCount(0);  // free after the tracking loops
  shadingCountKernel<<<1, 1, 0, s>>>(I.stats.get(), count);
  INR_CUDA_CHECK_LAUNCH("shadingCountKernel");
  evaluator_.evaluateWithGradientDevice(points, count, n, fc.time, I.shadingResults.get(), s);
  shadeKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, rs, I.shadingResults.get(), rays, I.stats.get() + kStatShadingQueries);
  INR_CUDA_CHECK_LAUNCH("shadeKernel");
  I.timer.end(s);
}

}  // namespace inr
