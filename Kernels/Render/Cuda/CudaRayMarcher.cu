#include "Render/Cuda/CudaRayMarcher.h"

#include <cub/device/device_scan.cuh>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Common/Cuda/DeviceBuffer.h"
#include "Common/Stopwatch.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Render/Cuda/DeviceTransferFunction.h"
#include "Render/Finalize.h"
#include "Render/RayMarch.h"

namespace inr {

namespace {


struct MarchParams {
  CameraView cam;
  Box3f box;
  const float* depth;  // world distance per pixel, or null
  float step, time;
  std::uint32_t frame, seed;
  int jitter;
  int windowX, windowY, fullWidth;  // the image as a window of a larger one (fullWidth 0: none)
  int chunk0, chunkN;
};

// Each ray of the chunk (Render/RayMarch.h) and its sample count; count has chunkN + 1 entries
// (the last 0, so the exclusive scan's last entry is the total). hitRays counts the rays with
// samples (FrameStats::rays, as the CPU marcher counts them).
__global__ void marchRaysKernel(MarchParams p, MarchRay* rays, int* count, int* hitRays) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k > p.chunkN) return;
  if (k == p.chunkN) {
    count[k] = 0;
    return;
  }
  const int i = p.chunk0 + k;
  const MarchRay r = marchCameraRay(p.cam, p.box, i, marchPixelKey(i, p.cam.width, p.windowX, p.windowY, p.fullWidth),
                                    p.frame, p.seed, p.jitter != 0, p.depth ? p.depth[i] : INFINITY, p.step);
  rays[k] = r;
  count[k] = r.count;
  if (r.count > 0) atomicAdd(hitRays, 1);
}

__global__ void pointsKernel(MarchParams p, const MarchRay* rays, const int* offsets, float4* points) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.chunkN) return;
  const MarchRay r = rays[k];
  for (int j = 0; j < r.count; ++j) {
    const Vec3f q = marchSample(r, j);
    points[offsets[k] + j] = make_float4(q.x, q.y, q.z, p.time);
  }
}

__global__ void compositeKernel(MarchParams p, const MarchRay* rays, const int* offsets, const float* values,
                                TransferFunctionView tf, Vec4f* accum, int frameIndex) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.chunkN) return;
  const MarchRay r = rays[k];
  MarchCompositor<float> ray;
  for (int j = 0; j < r.count; ++j) ray.add(tf, values[offsets[k] + j], r.ds, 1.f);
  const int i = p.chunk0 + k;
  accum[i] = accumulateMean(accum[i], ray.estimate(), frameIndex);
}

}  // namespace

struct CudaRayMarcher::Impl {
  cuda::Stream stream;
  std::unique_ptr<TransferFunctionTable> tfTable;
  cuda::DeviceTransferFunction tf;
  cuda::DeviceBuffer<float> depth;
  cuda::DeviceBuffer<Vec4f> accum;
  cuda::DeviceBuffer<MarchRay> rays;
  cuda::DeviceBuffer<int> count, offsets;
  cuda::DeviceBuffer<unsigned char> scanTemp;
  cuda::DeviceBuffer<float4> points;
  cuda::DeviceBuffer<float> values;
  cuda::DeviceBuffer<int> hitRays;
  cuda::PinnedHost<int> total{1};
  cuda::PinnedHost<int> hitRaysHost{1};
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
  validateImageWindow(settings.window, settings.width, settings.height);
  settings_ = settings;
  impl_->accum.resize(std::size_t(settings_.width) * settings_.height);
  resetAccumulation();
}

void CudaRayMarcher::setScene(const RenderScene& scene) {
  // Its samples take no gradients: SessionRayMarcher gives shaded scenes the CPU marcher.
  if (scene.shading.enabled)
    throw std::invalid_argument("shading: the GPU ray marcher does not shade (the CPU marcher does)");
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
  p.frame = sampleShareFrame(settings_.sampleShare, std::uint32_t(frameIndex_));
  p.seed = settings_.seed;
  p.jitter = settings_.pixelJitter ? 1 : 0;
  p.windowX = settings_.window.x;
  p.windowY = settings_.window.y;
  p.fullWidth = settings_.window.fullWidth;
  // Pixels per chunk: at most 2^24 samples (the longest ray has ceil(diagonal / step) + 1).
  const long long maxPerRay = (long long)std::ceil(length(box_.hi - box_.lo) / step_) + 2;
  const int chunk = int(std::max<long long>(1, std::min<long long>(n, (1ll << 24) / maxPerRay)));
  if (I.count.size() < std::size_t(chunk + 1)) {
    I.rays.resize(chunk);
    I.count.resize(chunk + 1);
    I.offsets.resize(chunk + 1);
    std::size_t bytes = 0;
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, I.count.get(), I.offsets.get(), chunk + 1, s));
    I.scanTemp.resize(bytes);
  }
  const TransferFunctionView tf = I.tf.view();
  I.hitRays.resize(1);
  I.hitRays.zero(s);
  for (int c0 = 0; c0 < n; c0 += chunk) {
    p.chunk0 = c0;
    p.chunkN = std::min(chunk, n - c0);
    const int blocks = (p.chunkN + 1 + 127) / 128;
    marchRaysKernel<<<blocks, 128, 0, s>>>(p, I.rays.get(), I.count.get(), I.hitRays.get());
    INR_CUDA_CHECK_LAUNCH("marchRaysKernel");
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
      pointsKernel<<<blocks, 128, 0, s>>>(p, I.rays.get(), I.offsets.get(), I.points.get());
      INR_CUDA_CHECK_LAUNCH("pointsKernel");
      evaluator_.evaluateDevice(I.points.get(), total, I.values.get(), nullptr, s);
      st.queries += std::size_t(total);
      st.iterations += 1;
    }
    compositeKernel<<<blocks, 128, 0, s>>>(p, I.rays.get(), I.offsets.get(), I.values.get(), tf, I.accum.get(), frameIndex_);
    INR_CUDA_CHECK_LAUNCH("compositeKernel");
  }
  INR_CUDA_CHECK(cudaMemcpyAsync(I.hitRaysHost.get(), I.hitRays.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.rays = std::size_t(I.hitRaysHost[0]);
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
