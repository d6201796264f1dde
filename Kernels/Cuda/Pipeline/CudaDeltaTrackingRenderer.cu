#include "Cuda/Pipeline/CudaDeltaTrackingRenderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "Cuda/CudaInrEvaluator.h"
#include "Cuda/Pipeline/CudaPerThreadMlp.h"
#include "Cuda/Pipeline/DeviceBuffer.h"
#include "Cuda/Pipeline/DeviceRefine.cuh"
#include "Cuda/Pipeline/PerThreadMlp.cuh"
#include "Render/AccumulationImage.h"
#include "Render/Evaluate.h"
#include "Render/Finalize.h"
#include "Render/RayInit.h"
#include "Render/Shadows.h"
#include "Render/Traverse.h"

namespace inr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

constexpr int kThreads = 256;
int blocksFor(long long n) { return int(std::max<long long>(1, (n + kThreads - 1) / kThreads)); }

// Per-frame device counters (one read-back at the end of the frame).
enum StatSlot { kStatRays = 0, kStatShadowRays = 1, kStatRefinements = 2, kStatNaiveQueries = 3,
                kStatNaiveShadowQueries = 4, kStatNaiveCut = 5, kStatCount = 8 };

// ---- kernels: thin wrappers around the shared INR_HD per-ray functions ----

__global__ void initKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, unsigned long long* stats) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= rs.count) return;
  initPrimaryRay(fc, grid, rs, i);
  if (rs.flags[i] & kRayActive) atomicAdd(&stats[kStatRays], 1ull);
}

// Ghost passes trace every stride-th pixel in x and y.
__global__ void ghostInitKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, int stride) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= rs.count) return;
  const int px = i % fc.camera.width, py = i / fc.camera.width;
  if (px % stride == 0 && py % stride == 0)
    initPrimaryRay(fc, grid, rs, i);
  else
    rs.flags[i] = 0;
}

__global__ void spawnShadowKernel(FrameConstants fc, MajorantGridView grid, RayStateView rs, unsigned long long* stats) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= rs.count) return;
  spawnShadowRay(fc, grid, rs, i);
  if (rs.flags[i] & kRayActive) atomicAdd(&stats[kStatShadowRays], 1ull);
}

// Stage II over `n` rays: all rays (list == null) or the rays that queued a query in the last
// pass. For the latter, first the evaluation's result is completed (NaN/Inf flag, exactly
// storeQueryResult) and fed to macrocell refinement, then the ray resumes tracking. A ray that
// emits a new candidate appends its query point and index to the output buffers.
// `listCount` (device), when given, is the number of listed rays; n is then its upper bound.
// Occupancy: with the empty-space skip inlined (Render/MajorantGrid.h) ptxas would take 67
// registers on sm_90 (3 blocks of 256 per SM; 44 and 5 blocks without the skip). Bounded to 5
// blocks it fits 48 registers without spills (ptxas -v, sm_86 and sm_90); sm_75 holds 4 blocks.
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
#define INR_TRAVERSE_MIN_BLOCKS 4
#else
#define INR_TRAVERSE_MIN_BLOCKS 5
#endif
__global__ void __launch_bounds__(kThreads, INR_TRAVERSE_MIN_BLOCKS) traverseKernel(FrameConstants fc, TrackingMedium medium, RayStateView rs, const int* list,
                               const unsigned* listCount, int n, int resolvePrevious, int refine,
                               DeviceRefineView refineView, float4* outPoints, int* outRays, unsigned* outCount) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n || (listCount && k >= int(*listCount))) return;
  const int i = list ? list[k] : k;
  if (resolvePrevious) {
    const float v = rs.sample[i];
    storeQueryResult(rs, i, v);
    if (refine) cuda::refineCell(refineView, linearCellIndex(medium.grid.dims, rs.cell[i]), v);
  }
  traverseRay(fc, medium, rs, i);
  if (rs.flags[i] & kRayPending) {
    const unsigned slot = cuda::appendSlot(outCount);
    const QueryPoint q = pendingQuery(rs, i, fc.time);
    outPoints[slot] = make_float4(q.x, q.y, q.z, q.t);
    outRays[slot] = i;
  }
}

// Iteration cap reached: the listed rays stop where they are (no real collision recorded).
__global__ void cutoffKernel(RayStateView rs, const int* list, int n) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const int i = list[k];
  rs.flags[i] &= std::uint8_t(~(kRayActive | kRayPending | kRayBadSample));
  rs.sample[i] = NAN;
}

__global__ void finalizeKernel(FrameConstants fc, RayStateView rs, AccumulationView acc) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < rs.count) finalizePixel(fc, rs, acc, i);
}

// The naive baseline: one thread per ray, the network evaluated inside the tracking loop.
__device__ bool naiveTrack(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs, int i,
                           const PerThreadMlpView& net, int tid, int refine, const DeviceRefineView& refineView,
                           unsigned long long& queries, int maxSteps) {
  for (int step = 0;; ++step) {
    traverseRay(fc, medium, rs, i);
    if (!(rs.flags[i] & kRayPending)) return true;
    if (step >= maxSteps) {
      rs.flags[i] &= std::uint8_t(~(kRayActive | kRayPending));
      return false;
    }
    const QueryPoint q = pendingQuery(rs, i, fc.time);
    const float v = cuda::perThreadEvaluate(net, q.x, q.y, q.z, q.t, tid);
    storeQueryResult(rs, i, v);
    ++queries;
    if (refine) cuda::refineCell(refineView, linearCellIndex(medium.grid.dims, rs.cell[i]), v);
  }
}

__global__ void naiveKernel(FrameConstants fc, TrackingMedium medium, RayStateView rs, AccumulationView acc,
                            PerThreadMlpView net, int first, int count, int refine, DeviceRefineView refineView,
                            unsigned long long* stats, int maxSteps) {
  const int tid = blockIdx.x * blockDim.x + threadIdx.x;
  if (tid >= count) return;
  const int i = first + tid;
  unsigned long long q = 0, sq = 0;
  bool complete = true;
  initPrimaryRay(fc, medium.grid, rs, i);
  if (rs.flags[i] & kRayActive) {
    atomicAdd(&stats[kStatRays], 1ull);
    complete &= naiveTrack(fc, medium, rs, i, net, tid, refine, refineView, q, maxSteps);
    if (fc.shadows) {
      spawnShadowRay(fc, medium.grid, rs, i);
      if (rs.flags[i] & kRayActive) {
        atomicAdd(&stats[kStatShadowRays], 1ull);
        complete &= naiveTrack(fc, medium, rs, i, net, tid, refine, refineView, sq, maxSteps);
      }
    }
  }
  finalizePixel(fc, rs, acc, i);
  if (q) atomicAdd(&stats[kStatNaiveQueries], q);
  if (sq) atomicAdd(&stats[kStatNaiveShadowQueries], sq);
  if (!complete) atomicAdd(&stats[kStatNaiveCut], 1ull);
}

bool sameCamera(const Camera& a, const Camera& b) {
  return a.position == b.position && a.focalPoint == b.focalPoint && a.viewUp == b.viewUp &&
         a.viewAngle == b.viewAngle && a.parallelProjection == b.parallelProjection &&
         a.parallelScale == b.parallelScale;
}

bool sameTransferFunction(const TransferFunction& a, const TransferFunction& b) {
  if (a.unitDistance != b.unitDistance || a.colorSpace != b.colorSpace || a.color.size() != b.color.size() ||
      a.opacity.size() != b.opacity.size())
    return false;
  for (std::size_t i = 0; i < a.color.size(); ++i) {
    const auto &p = a.color[i], &q = b.color[i];
    if (p.x != q.x || p.r != q.r || p.g != q.g || p.b != q.b) return false;
  }
  for (std::size_t i = 0; i < a.opacity.size(); ++i) {
    const auto &p = a.opacity[i], &q = b.opacity[i];
    if (p.x != q.x || p.alpha != q.alpha || p.midpoint != q.midpoint || p.sharpness != q.sharpness) return false;
  }
  return true;
}


enum Stage { kUpdate, kInit, kTraverse, kEvaluate, kShadowTraverse, kShadowEvaluate, kFinalize, kStages };

// CUDA-event stage timer: pairs of events per stage interval, summed after the frame's sync.
class StageTimer {
public:
  ~StageTimer() {
    for (cudaEvent_t e : pool_) cudaEventDestroy(e);
  }
  void reset(bool enabled) {
    enabled_ = enabled;
    used_ = 0;
    intervals_.clear();
  }
  void begin(Stage s, cudaStream_t stream) {
    if (!enabled_) return;
    open_ = s;
    openEvent_ = record(stream);
  }
  void end(cudaStream_t stream) {
    if (!enabled_) return;
    intervals_.push_back({open_, openEvent_, record(stream)});
  }
  // Call after the stream is synchronised.
  void collect(double (&ms)[kStages]) {
    for (double& m : ms) m = 0.0;
    for (const Interval& iv : intervals_) {
      float t = 0.f;
      INR_CUDA_CHECK(cudaEventElapsedTime(&t, pool_[iv.start], pool_[iv.stop]));
      ms[iv.stage] += t;
    }
  }

private:
  struct Interval {
    Stage stage;
    int start, stop;
  };
  int record(cudaStream_t stream) {
    if (used_ == int(pool_.size())) {
      cudaEvent_t e;
      INR_CUDA_CHECK(cudaEventCreate(&e));
      pool_.push_back(e);
    }
    INR_CUDA_CHECK(cudaEventRecord(pool_[used_], stream));
    return used_++;
  }
  bool enabled_ = true;
  std::vector<cudaEvent_t> pool_;
  int used_ = 0;
  Stage open_ = kUpdate;
  int openEvent_ = 0;
  std::vector<Interval> intervals_;
};

}  // namespace

struct CudaDeltaTrackingRenderer::Impl {
  ~Impl() {
    for (cudaEvent_t e : countReady)
      if (e) cudaEventDestroy(e);
  }
  cudaStream_t stream = nullptr;
  CameraView cameraView{};
  std::unique_ptr<TransferFunctionTable> tfTable;
  cuda::DeviceTransferFunction tf, ghostTf;
  cuda::DeviceBuffer<float> majorants, ghostMajorants, depth;
  // Coarse levels of the two majorant grids (empty-space skipping); null when skipping is off.
  cuda::DeviceBuffer<float> blockMajorants, ghostBlockMajorants;
  float* blocks() const { return blockMajorants.empty() ? nullptr : blockMajorants.get(); }
  float* ghostBlocks() const { return ghostBlockMajorants.empty() ? nullptr : ghostBlockMajorants.get(); }
  // Persistent ray state (struct of arrays).
  cuda::DeviceBuffer<Vec3f> origin, direction, tNext;
  cuda::DeviceBuffer<float> t, tEnd, sample, collisionProduct, visibility;
  cuda::DeviceBuffer<std::uint32_t> rngCounter;
  cuda::DeviceBuffer<std::uint8_t> flags;
  cuda::DeviceBuffer<Int3> cell;
  cuda::DeviceBuffer<Vec4f> radiance;
  // Query buffers (double-buffered: a pass reads the previous pass's ray list and appends to the other).
  cuda::DeviceBuffer<float4> points[2];
  cuda::DeviceBuffer<int> rays[2];
  cuda::DeviceBuffer<unsigned> counter;         // per iteration parity: queries appended
  cuda::PinnedHost<unsigned> hostCounter{2};
  cudaEvent_t countReady[2] = {nullptr, nullptr};  // hostCounter[parity] is valid
  // Accumulation.
  cuda::DeviceBuffer<Vec4f> accum;
  cuda::DeviceBuffer<std::uint32_t> sampleCount;
  cuda::DeviceBuffer<float> residual;
  // Frame statistics.
  cuda::DeviceBuffer<unsigned long long> stats;
  cuda::PinnedHost<unsigned long long> hostStats{kStatCount};
  StageTimer timer;
  bool truncated = false;

  RayStateView rayView() const {
    RayStateView v;
    v.count = int(flags.size());
    v.origin = origin.get();
    v.direction = direction.get();
    v.t = t.get();
    v.tEnd = tEnd.get();
    v.rngCounter = rngCounter.get();
    v.flags = flags.get();
    v.sample = sample.get();
    v.collisionProduct = collisionProduct.get();
    v.cell = cell.get();
    v.tNext = tNext.get();
    v.radiance = radiance.get();
    v.visibility = visibility.get();
    return v;
  }
  AccumulationView accumulationView() const { return AccumulationView{accum.get(), sampleCount.get(), residual.get()}; }

  // The traverse-evaluate loop: returns when no query is pending (or at the iteration cap).
  // The host never waits on the GPU mid-loop: iteration i + 1's traversal and evaluation read
  // iteration i's query count on the device, with grids sized by the last count the host knows
  // (an upper bound: counts never grow), while the host reads count i from pinned memory. When
  // count i is zero, the already queued iteration i + 1 is empty and costs two idle launches.
  void track(const CudaInrEvaluator& evaluator, const FrameConstants& fc, const TrackingMedium& medium, bool refine,
             const DeviceRefineView& refineView, int maxIterations, Stage traverseStage, Stage evaluateStage,
             int& iterations, std::size_t& queries) {
    const RayStateView rs = rayView();
    int bound = rs.count;  // upper bound of the rays the next traversal lists
    auto enqueueTraverse = [&](int it) {
      const int cur = it & 1, prev = cur ^ 1;
      INR_CUDA_CHECK(cudaMemsetAsync(counter.get() + cur, 0, sizeof(unsigned), stream));
      timer.begin(traverseStage, stream);
      traverseKernel<<<blocksFor(bound), kThreads, 0, stream>>>(
          fc, medium, rs, it ? rays[prev].get() : nullptr, it ? counter.get() + prev : nullptr, bound, it ? 1 : 0,
          refine ? 1 : 0, refineView, points[cur].get(), rays[cur].get(), counter.get() + cur);
      INR_CUDA_CHECK_LAUNCH("traverseKernel");
      timer.end(stream);
      INR_CUDA_CHECK(
          cudaMemcpyAsync(hostCounter.get() + cur, counter.get() + cur, sizeof(unsigned), cudaMemcpyDeviceToHost, stream));
      INR_CUDA_CHECK(cudaEventRecord(countReady[cur], stream));
    };
    enqueueTraverse(0);
    for (int it = 0;; ++it) {
      const int cur = it & 1;
      if (it < maxIterations) {  // speculatively: evaluate iteration it, traverse iteration it + 1
        timer.begin(evaluateStage, stream);
        evaluator.evaluateDevice(points[cur].get(), counter.get() + cur, bound, rs.sample, rays[cur].get(), stream);
        timer.end(stream);
        enqueueTraverse(it + 1);
      }
      INR_CUDA_CHECK(cudaEventSynchronize(countReady[cur]));
      const int k = int(hostCounter[cur]);
      if (k == 0) break;
      if (it >= maxIterations) {
        cutoffKernel<<<blocksFor(k), kThreads, 0, stream>>>(rs, rays[cur].get(), k);
        INR_CUDA_CHECK_LAUNCH("cutoffKernel");
        truncated = true;
        break;
      }
      ++iterations;
      queries += std::size_t(k);
      bound = k;
    }
  }
};

CudaDeltaTrackingRenderer::CudaDeltaTrackingRenderer(const CudaInrEvaluator& evaluator, CudaMacrocellGrid& macrocells,
                                                     TrackingOptions options, CudaPipelineOptions pipeline)
    : evaluator_(evaluator), macrocells_(macrocells), options_(options), pipeline_(pipeline),
      impl_(std::make_unique<Impl>()) {
  if (pipeline_.maxIterations < 1) throw std::invalid_argument("maxIterations must be >= 1");
  impl_->stream = macrocells.stream();
  impl_->counter.resize(2);
  for (cudaEvent_t& e : impl_->countReady) INR_CUDA_CHECK(cudaEventCreateWithFlags(&e, cudaEventDisableTiming));
  impl_->stats.resize(kStatCount);
  impl_->majorants.resize(std::size_t(macrocells.cellCount()));
  impl_->majorants.zero(impl_->stream);
  if (macrocells.blockCount() > 0) {
    impl_->blockMajorants.resize(std::size_t(macrocells.blockCount()));
    impl_->blockMajorants.zero(impl_->stream);
  }
  resize();
}

CudaDeltaTrackingRenderer::~CudaDeltaTrackingRenderer() = default;

void CudaDeltaTrackingRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  if ((long long)settings.width * settings.height > (1ll << 30))
    throw std::invalid_argument("image too large for the GPU pipeline (more than 2^30 pixels)");
  const bool sizeChanged = settings.width != settings_.width || settings.height != settings_.height;
  settings_ = settings;
  if (sizeChanged) resize();
  if (haveScene_) impl_->cameraView = scene_.camera.view(settings_.width, settings_.height);
  resetAccumulation();
}

void CudaDeltaTrackingRenderer::resize() {
  Impl& I = *impl_;
  const std::size_t n = std::size_t(settings_.width) * settings_.height;
  I.origin.resize(n);
  I.direction.resize(n);
  I.tNext.resize(n);
  I.t.resize(n);
  I.tEnd.resize(n);
  I.sample.resize(n);
  I.collisionProduct.resize(n);
  I.visibility.resize(n);
  I.rngCounter.resize(n);
  I.flags.resize(n);
  I.flags.zero(I.stream);
  I.cell.resize(n);
  I.radiance.resize(n);
  for (int b = 0; b < 2; ++b) {
    I.points[b].resize(n);
    I.rays[b].resize(n);
  }
  I.accum.resize(n);
  I.sampleCount.resize(n);
  I.residual.resize(n);
  if (haveScene_ && !scene_.depthLimit.empty() && scene_.depthLimit.size() != n) {
    scene_.depthLimit.clear();  // stale: the next setScene must bring one of the new size
    I.depth.resize(0);
  }
}

void CudaDeltaTrackingRenderer::resetAccumulation() {
  Impl& I = *impl_;
  I.accum.zero(I.stream);
  I.sampleCount.zero(I.stream);
  // residual = 1 everywhere ("maximally unstable"): float 1.0 is 0x3f800000, not a byte pattern.
  std::vector<float> ones(I.residual.size(), 1.f);
  I.residual.upload(ones, I.stream);
  INR_CUDA_CHECK(cudaStreamSynchronize(I.stream));
  frameIndex_ = 0;
  ++counters_.accumulationResets;
}

void CudaDeltaTrackingRenderer::setScene(const RenderScene& scene) {
  Impl& I = *impl_;
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels)
    throw std::invalid_argument("depth limit must have one value per pixel (" + std::to_string(pixels) + "), got " +
                                std::to_string(scene.depthLimit.size()));
  const Vec3f light = toVec3(scene.toLight);
  if (scene.shadows && !(length(light) > 0.f)) throw std::invalid_argument("light direction must be non-zero");
  const CameraView view = scene.camera.view(settings_.width, settings_.height);  // validates
  const bool timeChanged = !haveScene_ || scene.time != scene_.time || macrocells_.time() != scene.time;
  const bool tfChanged = !haveScene_ || !sameTransferFunction(scene.transferFunction, scene_.transferFunction);
  const auto t0 = Clock::now();
  if (tfChanged) {
    I.tfTable = std::make_unique<TransferFunctionTable>(scene.transferFunction);
    I.tf.upload(*I.tfTable, I.stream);
    ++counters_.transferFunctionUploads;
  }
  if (timeChanged) {
    macrocells_.setTime(scene.time);
    ++counters_.workingGridUpdates;
  }
  if (timeChanged || tfChanged) {
    macrocells_.computeMajorants(I.tf.view(), I.majorants.get(), I.blocks());
    ++counters_.majorantUpdates;
  }
  const bool depthChanged = scene.depthLimit != scene_.depthLimit || !haveScene_;
  if (depthChanged) {
    if (scene.depthLimit.empty())
      I.depth.resize(0);
    else
      I.depth.upload(scene.depthLimit, I.stream);
  }
  INR_CUDA_CHECK(cudaStreamSynchronize(I.stream));
  pendingUpdateMs_ += msSince(t0);
  const bool viewChanged = !haveScene_ || !sameCamera(scene.camera, scene_.camera) ||
                           scene.background != scene_.background || depthChanged || scene.shadows != scene_.shadows ||
                           scene.toLight != scene_.toLight || scene.ambient != scene_.ambient ||
                           scene.shadowEstimator != scene_.shadowEstimator;
  scene_ = scene;
  I.cameraView = view;
  haveScene_ = true;
  if (timeChanged || tfChanged || viewChanged) resetAccumulation();
  if ((timeChanged || tfChanged) && options_.ghostPassesOnUpdate > 0) runGhostPasses(options_.ghostPassesOnUpdate);
}

namespace {
}  // namespace

FrameStats CudaDeltaTrackingRenderer::renderFrame() {
  if (!haveScene_) throw std::logic_error("renderFrame: setScene first");
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "delta";
  st.frame = frameIndex_;
  I.timer.reset(pipeline_.stageTiming);
  I.truncated = false;
  INR_CUDA_CHECK(cudaMemsetAsync(I.stats.get(), 0, kStatCount * sizeof(unsigned long long), s));

  I.timer.begin(kUpdate, s);
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  I.timer.end(s);

  const FrameConstants fc = makeFrameConstants(I.cameraView, macrocells_.box(), scene_, settings_, I.depth.get(),
                                               std::uint32_t(frameIndex_));
  const TrackingMedium medium{macrocells_.view(I.majorants.get(), I.blocks()), I.tf.view()};
  DeviceRefineView refine = macrocells_.refineView();
  refine.refinements = I.stats.get() + kStatRefinements;
  const RayStateView rs = I.rayView();
  const int n = rs.count;
  st.pixels = std::size_t(n);

  I.timer.begin(kInit, s);
  initKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, medium.grid, rs, I.stats.get());
  INR_CUDA_CHECK_LAUNCH("initKernel");
  I.timer.end(s);

  I.track(evaluator_, fc, medium, options_.refineMacrocells, refine, pipeline_.maxIterations, kTraverse, kEvaluate,
          st.iterations, st.queries);

  if (fc.shadows) {
    I.timer.begin(kShadowTraverse, s);
    spawnShadowKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, medium.grid, rs, I.stats.get());
    INR_CUDA_CHECK_LAUNCH("spawnShadowKernel");
    I.timer.end(s);
    I.track(evaluator_, fc, medium, options_.refineMacrocells, refine, pipeline_.maxIterations, kShadowTraverse,
            kShadowEvaluate, st.shadowIterations, st.shadowQueries);
  }

  I.timer.begin(kFinalize, s);
  finalizeKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, rs, I.accumulationView());
  INR_CUDA_CHECK_LAUNCH("finalizeKernel");
  I.timer.end(s);
  INR_CUDA_CHECK(cudaMemcpyAsync(I.hostStats.get(), I.stats.get(), kStatCount * sizeof(unsigned long long),
                                 cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.rays = std::size_t(I.hostStats[kStatRays]);
  st.shadowRays = std::size_t(I.hostStats[kStatShadowRays]);
  st.refinements = std::size_t(I.hostStats[kStatRefinements]);
  double ms[kStages];
  I.timer.collect(ms);
  st.updateMs = pendingUpdateMs_ + ms[kUpdate];
  pendingUpdateMs_ = 0.0;
  st.initMs = ms[kInit];
  st.traverseMs = ms[kTraverse];
  st.evaluateMs = ms[kEvaluate];
  st.shadowTraverseMs = ms[kShadowTraverse];
  st.shadowEvaluateMs = ms[kShadowEvaluate];
  st.finalizeMs = ms[kFinalize];
  if (I.truncated) {
    if (counters_.truncatedFrames == 0)
      std::fprintf(stderr, "CudaDeltaTrackingRenderer: a frame hit the iteration cap (%d); remaining rays cut off\n",
                   pipeline_.maxIterations);
    ++counters_.truncatedFrames;
  }
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  return st;
}

FrameStats CudaDeltaTrackingRenderer::renderFrameNaive(const CudaPerThreadMlp& network) {
  if (!haveScene_) throw std::logic_error("renderFrameNaive: setScene first");
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "naive";
  st.frame = frameIndex_;
  INR_CUDA_CHECK(cudaMemsetAsync(I.stats.get(), 0, kStatCount * sizeof(unsigned long long), s));
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  const FrameConstants fc = makeFrameConstants(I.cameraView, macrocells_.box(), scene_, settings_, I.depth.get(),
                                               std::uint32_t(frameIndex_));
  const TrackingMedium medium{macrocells_.view(I.majorants.get(), I.blocks()), I.tf.view()};
  DeviceRefineView refine = macrocells_.refineView();
  refine.refinements = I.stats.get() + kStatRefinements;
  const RayStateView rs = I.rayView();
  const int n = rs.count;
  st.pixels = std::size_t(n);
  // Threads per launch: the option, bounded so the per-thread scratch stays under 2 GiB.
  const std::size_t perThread = network.scratchBytesPerThread();
  int chunk = std::min(n, std::max(1, pipeline_.naiveRaysPerLaunch));
  chunk = int(std::max<std::size_t>(1024, std::min<std::size_t>(chunk, (std::size_t(2) << 30) / perThread)));
  chunk = std::min(chunk, n);
  const PerThreadMlpView net = network.view(chunk, fc.time);
  const int maxSteps = 1 << 16;
  for (int first = 0; first < n; first += chunk) {
    const int count = std::min(chunk, n - first);
    naiveKernel<<<blocksFor(count), kThreads, 0, s>>>(fc, medium, rs, I.accumulationView(), net, first, count,
                                                      options_.refineMacrocells ? 1 : 0, refine, I.stats.get(),
                                                      maxSteps);
    INR_CUDA_CHECK_LAUNCH("naiveKernel");
  }
  INR_CUDA_CHECK(cudaMemcpyAsync(I.hostStats.get(), I.stats.get(), kStatCount * sizeof(unsigned long long),
                                 cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.rays = std::size_t(I.hostStats[kStatRays]);
  st.shadowRays = std::size_t(I.hostStats[kStatShadowRays]);
  st.refinements = std::size_t(I.hostStats[kStatRefinements]);
  st.queries = std::size_t(I.hostStats[kStatNaiveQueries]);
  st.shadowQueries = std::size_t(I.hostStats[kStatNaiveShadowQueries]);
  if (I.hostStats[kStatNaiveCut]) {
    std::fprintf(stderr, "CudaDeltaTrackingRenderer (naive): %llu rays hit the step cap and were cut off\n",
                 I.hostStats[kStatNaiveCut]);
    ++counters_.truncatedFrames;
  }
  st.updateMs = pendingUpdateMs_;
  pendingUpdateMs_ = 0.0;
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  st.traverseMs = st.totalMs;  // traversal and evaluation are interleaved; not separable
  return st;
}

FrameStats CudaDeltaTrackingRenderer::runGhostPasses(int count) {
  if (!haveScene_) throw std::logic_error("runGhostPasses: setScene first");
  Impl& I = *impl_;
  const cudaStream_t s = I.stream;
  FrameStats total;
  total.method = "ghost";
  if (count <= 0) return total;
  const auto tStart = Clock::now();
  I.timer.reset(false);
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  const auto range = macrocells_.workingValueRange();
  const double lo = range[0], span = std::max(double(range[1]) - range[0], 1e-6);
  const Vec3f cs = macrocells_.cellSize();
  const double meanCell = (double(cs.x) + cs.y + cs.z) / 3.0;
  const RayStateView rs = I.rayView();
  const int n = rs.count;
  const int stride = std::max(1, options_.ghostPixelStride);
  I.ghostMajorants.resize(std::size_t(macrocells_.cellCount()));
  if (macrocells_.blockCount() > 0) I.ghostBlockMajorants.resize(std::size_t(macrocells_.blockCount()));
  DeviceRefineView refine = macrocells_.refineView();
  refine.refinements = I.stats.get() + kStatRefinements;
  INR_CUDA_CHECK(cudaMemsetAsync(I.stats.get(), 0, kStatCount * sizeof(unsigned long long), s));
  for (int g = 0; g < count; ++g) {
    // Same sweep of cosine bumps as DeltaTrackingRenderer::runGhostPasses.
    const double centre = lo + (g + 0.5) / count * span;
    TransferFunction ghost = TransferFunction::cosineBump(lo, lo + span, centre, span / count, 0.5);
    ghost.unitDistance = meanCell;
    const TransferFunctionTable table(ghost);
    I.ghostTf.upload(table, s);
    macrocells_.computeMajorants(I.ghostTf.view(), I.ghostMajorants.get(), I.ghostBlocks());
    const TrackingMedium medium{macrocells_.view(I.ghostMajorants.get(), I.ghostBlocks()), I.ghostTf.view()};
    FrameConstants fc = makeFrameConstants(I.cameraView, macrocells_.box(), scene_, settings_, nullptr,
                                           0x80000000u + ghostFrame_++);
    fc.shadows = 0;
    fc.depthLimit = nullptr;  // refine what is hidden now too: it may show up after a camera move
    ghostInitKernel<<<blocksFor(n), kThreads, 0, s>>>(fc, medium.grid, rs, stride);
    INR_CUDA_CHECK_LAUNCH("ghostInitKernel");
    I.track(evaluator_, fc, medium, true, refine, pipeline_.maxIterations, kTraverse, kEvaluate, total.iterations,
            total.queries);
  }
  const auto tUpdate = Clock::now();
  macrocells_.updateDirtyMajorants(I.tf.view(), I.majorants.get(), I.blocks());
  INR_CUDA_CHECK(cudaMemcpyAsync(I.hostStats.get(), I.stats.get(), kStatCount * sizeof(unsigned long long),
                                 cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  total.refinements = std::size_t(I.hostStats[kStatRefinements]);
  total.updateMs = msSince(tUpdate);
  total.totalMs = msSince(tStart);
  return total;
}

ImageRGBA CudaDeltaTrackingRenderer::premultipliedImage() const {
  return accumulationImage(impl_->accum.download(impl_->stream), settings_.width, settings_.height, nullptr);
}

ImageRGBA CudaDeltaTrackingRenderer::image() const {
  return accumulationImage(impl_->accum.download(impl_->stream), settings_.width, settings_.height, &scene_.background);
}

std::vector<float> CudaDeltaTrackingRenderer::residual() const { return impl_->residual.download(impl_->stream); }

std::vector<float> CudaDeltaTrackingRenderer::majorants() const { return impl_->majorants.download(impl_->stream); }

std::vector<float> CudaDeltaTrackingRenderer::blockMajorants() const {
  return impl_->blockMajorants.download(impl_->stream);
}

}  // namespace inr
