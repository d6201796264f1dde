#include "Cuda/Pipeline/CudaRayMarcher.h"

#include <cub/device/device_scan.cuh>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Cuda/CudaInrEvaluator.h"
#include "Cuda/DeviceBuffer.h"
#include "Cuda/Pipeline/DeviceTransferFunction.h"
#include "Render/CounterRng.h"
#include "Render/Finalize.h"

namespace inr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

struct MarchParams {
  CameraView cam;
  Box3f box;
  const float* depth;
  float step, time;
  std::uint32_t frame, seed;
  int jitter;
  int chunk0, chunkN;
};

struct Segments {
  Vec3f* o;
  Vec3f* d;
  float* t0;
  float* ds;
  int* count;  // chunkN + 1 entries (last = 0, so the exclusive scan's last entry is the total)
};

// RayMarchRenderer's per-pixel set-up: same draws (jitter u0, u1, then the shift).
__global__ void segmentKernel(MarchParams p, Segments s) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k > p.chunkN) return;
  if (k == p.chunkN) {
    s.count[k] = 0;
    return;
  }
  const int i = p.chunk0 + k;
  RngStream rng{std::uint32_t(i), p.frame, p.seed, 0u};
  const float u0 = rng.next(), u1 = rng.next();
  const float shift = p.jitter ? rng.next() : 0.5f;
  Vec3f o, d;
  cameraRay(p.cam, i % p.cam.width, i / p.cam.width, p.jitter ? u0 : 0.5f, p.jitter ? u1 : 0.5f, o, d);
  s.o[k] = o;
  s.d[k] = d;
  s.count[k] = 0;
  float tEnter, tExit;
  if (!intersectBox(p.box, o, d, tEnter, tExit)) return;
  if (p.depth) tExit = minf(tExit, p.depth[i]);
  if (!(tEnter < tExit)) return;
  const float len = tExit - tEnter;
  const int count = max(1, int(ceilf(len / p.step)));
  s.count[k] = count;
  s.ds[k] = len / float(count);
  s.t0[k] = tEnter + shift * s.ds[k];
}

__global__ void pointsKernel(MarchParams p, Segments s, const int* offsets, float4* points) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.chunkN) return;
  const int n = s.count[k], first = offsets[k];
  const Vec3f o = s.o[k], d = s.d[k];
  const float t0 = s.t0[k], ds = s.ds[k];
  for (int j = 0; j < n; ++j) {
    const Vec3f q = o + d * (t0 + float(j) * ds);
    points[first + j] = make_float4(q.x, q.y, q.z, p.time);
  }
}

__global__ void compositeKernel(MarchParams p, Segments s, const int* offsets, const float* values,
                                TransferFunctionView tf, Vec4f* accum, int frameIndex) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.chunkN) return;
  const int n = s.count[k], first = offsets[k];
  const float ds = n > 0 ? s.ds[k] : 0.f;
  float T = 1.f, r = 0.f, g = 0.f, b = 0.f;
  for (int j = 0; j < n; ++j) {
    const float v = values[first + j];
    if (!isFiniteValue(v)) continue;  // NaN output: empty space, as in the delta tracker
    const Vec4f c = lookupTransferFunction(tf, v);
    const float sigma = opacityToExtinction(c.w, tf.invUnitDistance);
    const float alpha = -expm1f(-sigma * ds);
    const float w = T * alpha;
    r += w * c.x;
    g += w * c.y;
    b += w * c.z;
    T *= 1.f - alpha;
  }
  const int i = p.chunk0 + k;
  const Vec4f prev = accum[i];
  const float wgt = 1.f / float(frameIndex + 1);
  accum[i] = Vec4f{prev.x + (r - prev.x) * wgt, prev.y + (g - prev.y) * wgt, prev.z + (b - prev.z) * wgt,
                   prev.w + ((1.f - T) - prev.w) * wgt};
}

}  // namespace

struct CudaRayMarcher::Impl {
  cuda::Stream stream;
  std::unique_ptr<TransferFunctionTable> tfTable;
  cuda::DeviceTransferFunction tf;
  cuda::DeviceBuffer<float> depth;
  cuda::DeviceBuffer<Vec4f> accum;
  cuda::DeviceBuffer<Vec3f> o, d;
  cuda::DeviceBuffer<float> t0, ds;
  cuda::DeviceBuffer<int> count, offsets;
  cuda::DeviceBuffer<unsigned char> scanTemp;
  cuda::DeviceBuffer<float4> points;
  cuda::DeviceBuffer<float> values;
  cuda::PinnedHost<int> total{1};
};

CudaRayMarcher::CudaRayMarcher(const CudaInrEvaluator& evaluator, const Box3f& box, RayMarchOptions options)
    : evaluator_(evaluator), box_(box), options_(options), impl_(std::make_unique<Impl>()) {
  const float diag = length(box.hi - box.lo);
  step_ = options.step > 0.f ? options.step : diag / 512.f;
  if (!(step_ > 0.f)) throw std::invalid_argument("ray-march step must be > 0");
  setSettings(settings_);
}

CudaRayMarcher::~CudaRayMarcher() = default;

void CudaRayMarcher::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  settings_ = settings;
  impl_->accum.resize(std::size_t(settings_.width) * settings_.height);
  resetAccumulation();
}

void CudaRayMarcher::setScene(const RenderScene& scene) {
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels)
    throw std::invalid_argument("depth limit must have one value per pixel");
  if (scene.shadows) throw std::invalid_argument("CudaRayMarcher: shadows are not implemented on the GPU");
  scene.camera.view(settings_.width, settings_.height);  // validates
  scene_ = scene;
  impl_->tfTable = std::make_unique<TransferFunctionTable>(scene.transferFunction);
  impl_->tf.upload(*impl_->tfTable, impl_->stream.get());
  if (scene.depthLimit.empty())
    impl_->depth.resize(0);
  else
    impl_->depth.upload(scene.depthLimit, impl_->stream.get());
  haveScene_ = true;
  resetAccumulation();
}

void CudaRayMarcher::resetAccumulation() {
  impl_->accum.zero(impl_->stream.get());
  INR_CUDA_CHECK(cudaStreamSynchronize(impl_->stream.get()));
  frameIndex_ = 0;
}

FrameStats CudaRayMarcher::renderFrame() {
  if (!haveScene_) throw std::logic_error("renderFrame: setScene first");
  Impl& I = *impl_;
  const cudaStream_t s = I.stream.get();
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "raymarch";
  st.frame = frameIndex_;
  const int n = settings_.width * settings_.height;
  st.pixels = std::size_t(n);
  MarchParams p;
  p.cam = scene_.camera.view(settings_.width, settings_.height);
  p.box = box_;
  p.depth = scene_.depthLimit.empty() ? nullptr : I.depth.get();
  p.step = step_;
  p.time = float(scene_.time);
  p.frame = std::uint32_t(frameIndex_);
  p.seed = settings_.seed;
  p.jitter = settings_.pixelJitter ? 1 : 0;
  // Pixels per chunk: at most 2^24 samples (the longest ray has ceil(diagonal / step) + 1).
  const long long maxPerRay = (long long)std::ceil(length(box_.hi - box_.lo) / step_) + 2;
  const int chunk = int(std::max<long long>(1, std::min<long long>(n, (1ll << 24) / maxPerRay)));
  if (I.count.size() < std::size_t(chunk + 1)) {
    I.o.resize(chunk);
    I.d.resize(chunk);
    I.t0.resize(chunk);
    I.ds.resize(chunk);
    I.count.resize(chunk + 1);
    I.offsets.resize(chunk + 1);
    std::size_t bytes = 0;
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, I.count.get(), I.offsets.get(), chunk + 1, s));
    I.scanTemp.resize(bytes);
  }
  const Segments seg{I.o.get(), I.d.get(), I.t0.get(), I.ds.get(), I.count.get()};
  const TransferFunctionView tf = I.tf.view();
  for (int c0 = 0; c0 < n; c0 += chunk) {
    p.chunk0 = c0;
    p.chunkN = std::min(chunk, n - c0);
    const int blocks = (p.chunkN + 1 + 127) / 128;
    segmentKernel<<<blocks, 128, 0, s>>>(p, seg);
    INR_CUDA_CHECK_LAUNCH("segmentKernel");
    std::size_t bytes = I.scanTemp.size();
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(I.scanTemp.get(), bytes, I.count.get(), I.offsets.get(),
                                                 p.chunkN + 1, s));
    INR_CUDA_CHECK(cudaMemcpyAsync(I.total.get(), I.offsets.get() + p.chunkN, sizeof(int), cudaMemcpyDeviceToHost, s));
    INR_CUDA_CHECK(cudaStreamSynchronize(s));
    const int total = I.total[0];
    if (total > 0) {
      if (I.points.size() < std::size_t(total)) {
        I.points.resize(std::size_t(total));
        I.values.resize(std::size_t(total));
      }
      pointsKernel<<<blocks, 128, 0, s>>>(p, seg, I.offsets.get(), I.points.get());
      INR_CUDA_CHECK_LAUNCH("pointsKernel");
      evaluator_.evaluateDevice(I.points.get(), total, I.values.get(), nullptr, s);
      st.queries += std::size_t(total);
      st.iterations += 1;
    }
    compositeKernel<<<blocks, 128, 0, s>>>(p, seg, I.offsets.get(), I.values.get(), tf, I.accum.get(), frameIndex_);
    INR_CUDA_CHECK_LAUNCH("compositeKernel");
  }
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  return st;
}

ImageRGBA CudaRayMarcher::image() const {
  const std::vector<Vec4f> acc = impl_->accum.download(impl_->stream.get());
  ImageRGBA img(settings_.width, settings_.height);
  const Vec3f bg{scene_.background[0], scene_.background[1], scene_.background[2]};
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const Vec3f c = overBackground(acc[i], bg);
    img.data[4 * i + 0] = c.x;
    img.data[4 * i + 1] = c.y;
    img.data[4 * i + 2] = c.z;
    img.data[4 * i + 3] = acc[i].w;
  }
  return img;
}

}  // namespace inr
