#include "Render/Cuda/CudaSurfaceRenderer.h"

#include <cub/device/device_scan.cuh>
#include <cub/device/device_select.cuh>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "Common/Cuda/DeviceBuffer.h"
#include "Common/Stopwatch.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/DeviceFieldEvaluator.h"
#include "Render/Cuda/DeviceTransferFunction.h"
#include "Render/Finalize.h"
#include "Render/RayMarch.h"
#include "Render/SurfaceMarch.h"

namespace inr {

namespace {

constexpr int kThreads = 128;
// Refinement points per round when the options leave it to the backend: from a bracket one step
// long, 33 parts and then the rest reach the default tolerance (step / 1000) in two rounds.
constexpr int kGpuRefinePoints = 32;
int blocksFor(int n) { return (n + kThreads - 1) / kThreads; }

// ---- Slice ----

// Pixel i's plane point, appended to the batch when the plane is hit there (slot[i] = its place,
// -1 when not hit).
__global__ void slicePointsKernel(SliceConstants sc, int n, float4* points, int* slot, unsigned* count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  Vec3f p;
  if (!slicePixelPoint(sc, i, p)) {
    slot[i] = -1;
    return;
  }
  const int k = int(atomicAdd(count, 1u));
  slot[i] = k;
  points[k] = make_float4(p.x, p.y, p.z, sc.time);
}

// Colours and accumulates every pixel: values[k] (no shading) or valueGradients[k] (shading) of
// its slot; depth: the world distance to the plane where it took colour.
__global__ void sliceColourKernel(SliceConstants sc, int n, const float4* points, const int* slot, const float* values,
                                  const float4* valueGradients, Vec4f* accum, float* depth, int frameIndex) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const int k = slot[i];
  Vec4f c{0.f, 0.f, 0.f, 0.f};
  float d = INFINITY;
  if (k >= 0) {
    const float4 q = points[k];
    const Vec3f p{q.x, q.y, q.z};
    float v;
    Vec3f g{0.f, 0.f, 0.f};
    if (valueGradients) {
      const float4 vg = valueGradients[k];
      v = vg.x;
      g = Vec3f{vg.y, vg.z, vg.w};
    } else {
      v = values[k];
    }
    c = sliceColour(sc, p, v, g);
    if (c.w > 0.f) {
      const Vec3f fromEye = modelToWorld(sc.camera, p) - sc.camera.position;
      d = sc.camera.parallel ? dot(fromEye, sc.camera.forward) : length(fromEye);
    }
  }
  accum[i] = accumulateMean(accum[i], c, frameIndex);
  depth[i] = d;
}

// ---- Isosurface ----

// Pixel i's ray; index[i] = i (the input of the first active-ray selection).
__global__ void surfaceInitKernel(SurfaceConstants sc, int n, SurfaceRay* rays, int* index) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  SurfaceRay r;
  surfaceInitRay(sc, i, r);
  rays[i] = r;
  index[i] = i;
}

// Selects the rays that still march (DeviceSelect::If over a list of ray indices).
struct SurfaceRayActive {
  const SurfaceRay* rays;
  __device__ bool operator()(int i) const { return rays[i].phase != kSurfaceDone; }
};

// Each active ray's samples into its M slots and its count. The launch covers `bound` entries, an
// upper bound of the active count *activeCount known on the host (the last one it read); count has
// bound + 1 entries, those from *activeCount on 0, so the exclusive scan's entry `bound` is the
// batch's size.
__global__ void surfaceEmitKernel(SurfaceConstants sc, int bound, const unsigned* activeCount, const int* active,
                                  SurfaceRay* rays, int M, float* ts, std::uint8_t* breaks, int* count) {
  const int a = blockIdx.x * blockDim.x + threadIdx.x;
  if (a > bound) return;
  if (a >= int(*activeCount)) {
    count[a] = 0;
    return;
  }
  const int i = active[a];
  SurfaceRay r = rays[i];
  count[a] = surfaceEmit(sc, r, ts + std::size_t(a) * M, breaks + std::size_t(a) * M, M);
  rays[i] = r;
}

__global__ void surfacePointsKernel(SurfaceConstants sc, int m, const int* active, const SurfaceRay* rays, int M,
                                    const float* ts, const int* count, const int* offsets, float4* points) {
  const int a = blockIdx.x * blockDim.x + threadIdx.x;
  if (a >= m) return;
  const int c = count[a];
  if (c == 0) return;
  const SurfaceRay& r = rays[active[a]];
  const int refinePoints = surfaceRefinePointsAsked(sc, r);
  for (int j = 0; j < c; ++j) {
    const Vec3f p = surfacePoint(r, surfaceSampleT(r, ts + std::size_t(a) * M, j, refinePoints));
    points[offsets[a] + j] = make_float4(p.x, p.y, p.z, sc.time);
  }
}

// Consumes each active ray's values; a hit that needs lighting is appended to the gradient batch.
__global__ void surfaceConsumeKernel(SurfaceConstants sc, int m, const int* active, SurfaceRay* rays, int M,
                                     const float* ts, const std::uint8_t* breaks, const int* count, const int* offsets,
                                     const float* values, float4* hitPoints, int* hitRay, unsigned* hitCount) {
  const int a = blockIdx.x * blockDim.x + threadIdx.x;
  if (a >= m) return;
  const int c = count[a];
  if (c == 0) return;
  const int i = active[a];
  SurfaceRay r = rays[i];
  surfaceConsume(sc, r, ts + std::size_t(a) * M, breaks + std::size_t(a) * M, values + offsets[a], c);
  if (r.pendingShade) {
    const int k = int(atomicAdd(hitCount, 1u));
    const Vec3f p = surfacePoint(r, r.hitT);
    hitPoints[k] = make_float4(p.x, p.y, p.z, sc.time);
    hitRay[k] = i;
  }
  rays[i] = r;
}

// The hits of the gradient batch, lit and composited (their count read on the device, and added
// to the frame's gradient queries).
__global__ void surfaceShadeKernel(SurfaceConstants sc, int maxHits, SurfaceRay* rays, const int* hitRay,
                                   const float4* valueGradients, const unsigned* hitCount, unsigned* gradientQueries) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k == 0) atomicAdd(gradientQueries, *hitCount);
  if (k >= maxHits || k >= int(*hitCount)) return;
  const float4 vg = valueGradients[k];
  SurfaceRay& r = rays[hitRay[k]];
  surfaceShadeHit(sc, r, Vec3f{vg.y, vg.z, vg.w});
}

__global__ void surfaceFinalizeKernel(int n, const SurfaceRay* rays, Vec4f* accum, float* depth, int frameIndex) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  accum[i] = accumulateMean(accum[i], surfaceEstimate(rays[i]), frameIndex);
  depth[i] = rays[i].firstHitWorld;
}

}  // namespace

struct CudaSurfaceRenderer::Impl {
  cuda::Stream stream;
  cuda::DeviceTransferFunction tf;
  cuda::DeviceBuffer<float> depthLimit;
  cuda::DeviceBuffer<Vec4f> accum;
  cuda::DeviceBuffer<float> depth;
  // Candidate mask (cells, blocks) and isovalues.
  cuda::DeviceBuffer<float> cells, blocks, isovalues;
  // Slice.
  cuda::DeviceBuffer<float4> points;
  cuda::DeviceBuffer<int> slot;
  cuda::DeviceBuffer<float> values;
  cuda::DeviceBuffer<float4> valueGradients;
  // Isosurface.
  cuda::DeviceBuffer<SurfaceRay> rays;
  cuda::DeviceBuffer<float> ts;
  cuda::DeviceBuffer<std::uint8_t> breaks;
  cuda::DeviceBuffer<int> count, offsets, hitRay;
  cuda::DeviceBuffer<int> active, selected;  // the rays still marching, and the next selection's
  cuda::DeviceBuffer<unsigned char> scanTemp;  // the scan's and the selection's
  cuda::DeviceBuffer<float4> hitPoints;
  cuda::DeviceBuffer<unsigned> counters;  // [0] hits of the iteration, [1] active rays, [2] gradient queries
  cuda::PinnedHost<int> total{1};
  cuda::PinnedHost<unsigned> countersHost{2};
};

CudaSurfaceRenderer::CudaSurfaceRenderer(const CudaInrEvaluator& evaluator, const Box3f& box, double timeBegin,
                                         double timeEnd, SurfaceOptions options)
    : CudaSurfaceRenderer(evaluator, evaluator, box, timeBegin, timeEnd, options) {}

CudaSurfaceRenderer::CudaSurfaceRenderer(const FieldEvaluator& hostField, const DeviceFieldEvaluator& deviceField,
                                         const Box3f& box, double timeBegin, double timeEnd, SurfaceOptions options)
    : evaluator_(deviceField), host_(hostField, box, timeBegin, timeEnd, options), impl_(std::make_unique<Impl>()) {
  impl_->counters.resize(3);
}

CudaSurfaceRenderer::~CudaSurfaceRenderer() = default;

void CudaSurfaceRenderer::setSettings(const RenderSettings& settings) {
  host_.setSettings(settings);
  const std::size_t n = std::size_t(settings.width) * settings.height;
  impl_->accum.resize(n);
  impl_->depth.resize(n);
  resetAccumulation();
}

void CudaSurfaceRenderer::setScene(const RenderScene& scene, const BlendScene& blend) {
  if (scene.shading.enabled && !evaluator_.providesDeviceGradient())
    throw std::invalid_argument("shading: the evaluator " + evaluator_.name() + " computes no gradients on the GPU");
  host_.setScene(scene, blend);
  Impl& I = *impl_;
  const cudaStream_t s = I.stream.get();
  I.tf.upload(host_.transferFunctionTable(), s);
  if (scene.depthLimit.empty())
    I.depthLimit.resize(0);
  else
    I.depthLimit.upload(scene.depthLimit, s);
  if (blend.mode == BlendMode::Isosurface) {
    I.cells.upload(host_.candidates().cell, s);
    I.blocks.upload(host_.candidates().block, s);
    I.isovalues.upload(host_.isovalues(), s);
  }
  INR_CUDA_CHECK(cudaStreamSynchronize(s));  // the host arrays may change after this returns
  resetAccumulation();
}

void CudaSurfaceRenderer::resetAccumulation() {
  host_.resetAccumulation();
  impl_->accum.zero(impl_->stream.get());
  INR_CUDA_CHECK(cudaStreamSynchronize(impl_->stream.get()));
}

FrameStats CudaSurfaceRenderer::renderFrame() {
  const double updateMs = host_.takePendingUpdateMs();
  FrameStats st = host_.blendScene().mode == BlendMode::Slice ? renderSlice() : renderIsosurface();
  st.updateMs = updateMs;
  st.closeTiming(updateMs, st.totalMs);
  host_.frameRenderedElsewhere();
  return st;
}

FrameStats CudaSurfaceRenderer::renderSlice() {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream.get();
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "slice";
  st.frame = host_.accumulatedFrames();
  SliceConstants sc = host_.sliceConstants();
  sc.tf = I.tf.view();
  sc.depthLimit = host_.scene().depthLimit.empty() ? nullptr : I.depthLimit.get();
  const int n = host_.settings().width * host_.settings().height;
  st.pixels = std::size_t(n);
  I.points.growTo(std::size_t(n));
  I.slot.growTo(std::size_t(n));
  I.counters.zero(s);
  auto t0 = Clock::now();
  slicePointsKernel<<<blocksFor(n), kThreads, 0, s>>>(sc, n, I.points.get(), I.slot.get(), I.counters.get());
  INR_CUDA_CHECK_LAUNCH("slicePointsKernel");
  st.initMs += msSince(t0);
  t0 = Clock::now();
  const float4* valueGradients = nullptr;
  if (sc.shade) {
    I.valueGradients.growTo(std::size_t(n));
    evaluator_.evaluateWithGradientDevice(I.points.get(), I.counters.get(), n, sc.time, I.valueGradients.get(), s);
    valueGradients = I.valueGradients.get();
  } else {
    I.values.growTo(std::size_t(n));
    evaluator_.evaluateDevice(I.points.get(), I.counters.get(), n, I.values.get(), nullptr, s);
  }
  st.evaluateMs += msSince(t0);
  t0 = Clock::now();
  sliceColourKernel<<<blocksFor(n), kThreads, 0, s>>>(sc, n, I.points.get(), I.slot.get(), I.values.get(),
                                                      valueGradients, I.accum.get(), I.depth.get(),
                                                      host_.accumulatedFrames());
  INR_CUDA_CHECK_LAUNCH("sliceColourKernel");
  INR_CUDA_CHECK(cudaMemcpyAsync(I.countersHost.get(), I.counters.get(), sizeof(unsigned), cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.finalizeMs += msSince(t0);
  const std::size_t q = I.countersHost[0];
  st.queries = q;
  st.rays = q;
  if (sc.shade) st.shadingQueries = q;
  st.iterations = q > 0 ? 1 : 0;
  st.closeTiming(0.0, msSince(tFrame));
  return st;
}

FrameStats CudaSurfaceRenderer::renderIsosurface() {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream.get();
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "isosurface";
  st.frame = host_.accumulatedFrames();
  SurfaceConstants sc = host_.surfaceConstants();
  sc.tf = I.tf.view();
  sc.depthLimit = host_.scene().depthLimit.empty() ? nullptr : I.depthLimit.get();
  sc.cells.majorant = I.cells.get();
  sc.cells.blockMajorant = sc.cells.blockMajorant ? I.blocks.get() : nullptr;
  sc.isovalues = I.isovalues.get();
  // The GPU's choices (SurfaceOptions): an iteration costs launches and a host round trip.
  if (host_.options().maxMarchSamples == 0) sc.maxMarchSamples = kMaxSurfaceSamples;
  if (host_.options().refinePoints == 0) sc.refinePoints = kGpuRefinePoints;
  const int n = host_.settings().width * host_.settings().height;
  const int K = sc.samplesPerIteration;
  st.pixels = std::size_t(n);
  if (I.rays.size() < std::size_t(n)) {
    I.rays.resize(std::size_t(n));
    I.ts.resize(std::size_t(n) * K);
    I.breaks.resize(std::size_t(n) * K);
    I.count.resize(std::size_t(n) + 1);
    I.offsets.resize(std::size_t(n) + 1);
    I.hitRay.resize(std::size_t(n));
    I.hitPoints.resize(std::size_t(n));
    I.active.resize(std::size_t(n));
    I.selected.resize(std::size_t(n));
    std::size_t scanBytes = 0, selectBytes = 0;
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, scanBytes, I.count.get(), I.offsets.get(), n + 1, s));
    INR_CUDA_CHECK(cub::DeviceSelect::If(nullptr, selectBytes, I.selected.get(), I.active.get(), I.counters.get() + 1, n,
                                         SurfaceRayActive{I.rays.get()}, s));
    I.scanTemp.resize(std::max(scanBytes, selectBytes));
  } else if (I.ts.size() < std::size_t(n) * K) {
    I.ts.resize(std::size_t(n) * K);
    I.breaks.resize(std::size_t(n) * K);
  }
  I.counters.zero(s);
  // The rays of `from` still marching, in their order, into `to` (their count in counters[1]).
  auto select = [&](const int* from, int items, int* to) {
    std::size_t bytes = I.scanTemp.size();
    INR_CUDA_CHECK(cub::DeviceSelect::If(I.scanTemp.get(), bytes, from, to, I.counters.get() + 1, items,
                                         SurfaceRayActive{I.rays.get()}, s));
  };
  auto t0 = Clock::now();
  surfaceInitKernel<<<blocksFor(n), kThreads, 0, s>>>(sc, n, I.rays.get(), I.selected.get());
  INR_CUDA_CHECK_LAUNCH("surfaceInitKernel");
  select(I.selected.get(), n, I.active.get());
  st.initMs += msSince(t0);
  // Each iteration: the active rays' samples (M per ray, growing as rays finish), one batch, the
  // values consumed, the rays still marching selected. One host round trip per iteration (the
  // batch's size and the active count); the emit launch covers the last active count the host
  // read, an upper bound of the current one.
  int bound = n;
  for (;;) {
    t0 = Clock::now();
    const int M = surfaceMarchSamples(K, sc.maxMarchSamples, n, bound);
    surfaceEmitKernel<<<blocksFor(bound + 1), kThreads, 0, s>>>(sc, bound, I.counters.get() + 1, I.active.get(),
                                                                I.rays.get(), M, I.ts.get(), I.breaks.get(),
                                                                I.count.get());
    INR_CUDA_CHECK_LAUNCH("surfaceEmitKernel");
    std::size_t bytes = I.scanTemp.size();
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(I.scanTemp.get(), bytes, I.count.get(), I.offsets.get(), bound + 1, s));
    INR_CUDA_CHECK(cudaMemcpyAsync(I.total.get(), I.offsets.get() + bound, sizeof(int), cudaMemcpyDeviceToHost, s));
    INR_CUDA_CHECK(cudaMemcpyAsync(I.countersHost.get() + 1, I.counters.get() + 1, sizeof(unsigned),
                                   cudaMemcpyDeviceToHost, s));
    INR_CUDA_CHECK(cudaStreamSynchronize(s));
    const int total = I.total[0];
    const int m = int(I.countersHost[1]);
    if (st.iterations == 0) st.rays = std::size_t(m);  // the rays that entered a candidate cell
    st.traverseMs += msSince(t0);
    if (total == 0) break;  // every ray has finished
    t0 = Clock::now();
    if (I.points.size() < std::size_t(total)) {
      I.points.resize(std::size_t(total));
      I.values.resize(std::size_t(total));
    }
    surfacePointsKernel<<<blocksFor(m), kThreads, 0, s>>>(sc, m, I.active.get(), I.rays.get(), M, I.ts.get(),
                                                          I.count.get(), I.offsets.get(), I.points.get());
    INR_CUDA_CHECK_LAUNCH("surfacePointsKernel");
    evaluator_.evaluateDevice(I.points.get(), total, I.values.get(), nullptr, s);
    st.queries += std::size_t(total);
    st.iterations += 1;
    st.evaluateMs += msSince(t0);  // launch time: the stream runs on
    t0 = Clock::now();
    INR_CUDA_CHECK(cudaMemsetAsync(I.counters.get(), 0, sizeof(unsigned), s));
    surfaceConsumeKernel<<<blocksFor(m), kThreads, 0, s>>>(sc, m, I.active.get(), I.rays.get(), M, I.ts.get(),
                                                           I.breaks.get(), I.count.get(), I.offsets.get(),
                                                           I.values.get(), I.hitPoints.get(), I.hitRay.get(),
                                                           I.counters.get());
    INR_CUDA_CHECK_LAUNCH("surfaceConsumeKernel");
    st.traverseMs += msSince(t0);
    if (sc.shade) {
      t0 = Clock::now();
      // At most one hit per active ray: launches sized for m, not for the image.
      I.valueGradients.growTo(std::size_t(n));
      evaluator_.evaluateWithGradientDevice(I.hitPoints.get(), I.counters.get(), m, sc.time, I.valueGradients.get(), s);
      surfaceShadeKernel<<<blocksFor(m), kThreads, 0, s>>>(sc, m, I.rays.get(), I.hitRay.get(), I.valueGradients.get(),
                                                           I.counters.get(), I.counters.get() + 2);
      INR_CUDA_CHECK_LAUNCH("surfaceShadeKernel");
      st.shadingMs += msSince(t0);  // launch time: the stream runs on
    }
    t0 = Clock::now();
    select(I.active.get(), m, I.selected.get());  // the rays still marching, in their order
    I.active.swap(I.selected);
    bound = m;
    st.traverseMs += msSince(t0);
  }
  t0 = Clock::now();
  surfaceFinalizeKernel<<<blocksFor(n), kThreads, 0, s>>>(n, I.rays.get(), I.accum.get(), I.depth.get(),
                                                          host_.accumulatedFrames());
  INR_CUDA_CHECK_LAUNCH("surfaceFinalizeKernel");
  INR_CUDA_CHECK(cudaMemcpyAsync(I.countersHost.get(), I.counters.get() + 2, sizeof(unsigned), cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.shadingQueries = I.countersHost[0];
  st.finalizeMs += msSince(t0);
  st.closeTiming(0.0, msSince(tFrame));
  return st;
}

ImageRGBA CudaSurfaceRenderer::premultipliedImage() const {
  const std::vector<Vec4f> acc = impl_->accum.download(impl_->stream.get());
  ImageRGBA img(host_.settings().width, host_.settings().height);
  for (std::size_t i = 0; i < acc.size(); ++i) {
    img.data[4 * i + 0] = acc[i].x;
    img.data[4 * i + 1] = acc[i].y;
    img.data[4 * i + 2] = acc[i].z;
    img.data[4 * i + 3] = acc[i].w;
  }
  return img;
}

ImageRGBA CudaSurfaceRenderer::image() const {
  const std::vector<Vec4f> acc = impl_->accum.download(impl_->stream.get());
  ImageRGBA img(host_.settings().width, host_.settings().height);
  const auto& b = host_.scene().background;
  const Vec3f bg{b[0], b[1], b[2]};
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const Vec3f c = overBackground(acc[i], bg);
    img.data[4 * i + 0] = c.x;
    img.data[4 * i + 1] = c.y;
    img.data[4 * i + 2] = c.z;
    img.data[4 * i + 3] = acc[i].w;
  }
  return img;
}

std::vector<float> CudaSurfaceRenderer::surfaceDepth() const { return impl_->depth.download(impl_->stream.get()); }

}  // namespace inr
