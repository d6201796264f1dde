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
#include "Render/Evaluate.h"
#include "Render/Finalize.h"
#include "Render/RayMarch.h"
#include "Render/SceneInputs.h"
#include "Render/Shading.h"

namespace inr {

// Shadows, as the CPU marcher casts them (Render/RayMarch.h): from every primary sample that can
// emit, a ray towards the light cut into segments of at most `step`.
struct MarchShadowParams {
  Box3f box;
  Vec3f toLight;  // unit, model space
  float step, time, ambient;
};

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

__device__ __forceinline__ MarchShadowRay shadowRayOf(const MarchShadowParams& sp, const float4& q) {
  return marchShadowRay(sp.box, Vec3f{q.x, q.y, q.z}, sp.toLight, sp.step);
}

// Each primary sample's shadow-ray sample count (0 when it cannot emit); count has total + 1
// entries (the last 0, so that the exclusive scan's last entry is the chunk's shadow points).
// tau (the optical depth towards the light) starts at 0.
// Gradient opacity and 2D TFs (Render/Evaluate.h): sample j's gradient term from its (value,
// gradient), 1 without.
__device__ __forceinline__ float marchOpacityScale(const TransferFunctionView& tf, const float4* valueGradients, int j) {
  if (!valueGradients) return 1.f;
  const float4 vg = valueGradients[j];
  return gradientTermOf(tf, Vec3f{vg.y, vg.z, vg.w});
}

// gradients: each sample's (value, gradient) with gradient opacity, else null.
__global__ void shadowCountKernel(int total, const float4* points, const float* values, const float4* gradients,
                                  TransferFunctionView tf, MarchShadowParams sp, int* count, float* tau,
                                  int* shadowRays) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j > total) return;
  if (j == total) {
    count[j] = 0;
    return;
  }
  tau[j] = 0.f;
  const int c = marchSampleEmits(tf, values[j], marchOpacityScale(tf, gradients, j)) ? shadowRayOf(sp, points[j]).count : 0;
  count[j] = c;
  if (c > 0) atomicAdd(shadowRays, 1);
}

// The primary sample whose shadow points include point m: the last j with offsets[j] <= m (the
// offsets are non-decreasing; samples without shadow points share their successor's offset).
__device__ __forceinline__ int shadowOwner(const int* offsets, int total, int m) {
  int lo = 0, hi = total;  // offsets[lo] <= m < offsets[hi]
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (offsets[mid] <= m) lo = mid;
    else hi = mid;
  }
  return lo;
}

// Shadow points [first, first + n) of the chunk into points (from 0).
__global__ void shadowPointsKernel(int first, int n, int total, const float4* primary, const int* offsets,
                                   MarchShadowParams sp, float4* points) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const int m = first + k;
  const int j = shadowOwner(offsets, total, m);
  const float4 q = primary[j];
  const Vec3f s = marchShadowSample(Vec3f{q.x, q.y, q.z}, sp.toLight, shadowRayOf(sp, q), m - offsets[j]);
  points[k] = make_float4(s.x, s.y, s.z, sp.time);
}

// Adds each primary sample's share of the optical depth from shadow points [first, first + n)
// (values from 0; gradients: their (value, gradient) with gradient opacity, else null), in the
// order of its points, so that batches add up as one sum would.
__global__ void shadowDepthKernel(int first, int n, int total, const float4* primary, const int* offsets,
                                  const float* values, const float4* gradients, TransferFunctionView tf,
                                  MarchShadowParams sp, float* tau) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= total) return;
  const int a = max(offsets[j], first), b = min(offsets[j + 1], first + n);
  if (a >= b) return;
  const float ds = shadowRayOf(sp, primary[j]).ds;
  float sum = tau[j];
  for (int m = a; m < b; ++m)
    sum += marchExtinction(tf, values[m - first], marchOpacityScale(tf, gradients, m - first)) * ds;
  tau[j] = sum;
}

// Gradient shading and gradient opacity: each sample's value out of its (value, gradient) for the
// shadow and compositing kernels, which read values.
__global__ void valuesOfGradientsKernel(int total, const float4* valueGradients, float* values) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j < total) values[j] = valueGradients[j].x;
}

// The shaded composite's inputs (as the CPU marcher lights its samples): each sample's point and
// (value, gradient), the shading constants and the unit model-space direction towards the light.
struct MarchShading {
  const float4* points = nullptr;
  const float4* valueGradients = nullptr;  // null: no shading
  ShadingConstants constants;
  Vec3f toLight;
};

// tau: each sample's optical depth towards the light, or null without shadows; gradients: each
// sample's (value, gradient) with gradient opacity, else null.
__global__ void compositeKernel(MarchParams p, const MarchRay* rays, const int* offsets, const float* values,
                                const float4* gradients, const float* tau, float ambient, MarchShading shading,
                                TransferFunctionView tf, Vec4f* accum, int frameIndex) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= p.chunkN) return;
  const MarchRay r = rays[k];
  MarchCompositor<float> ray;
  for (int j = 0; j < r.count; ++j) {
    const int sample = offsets[k] + j;
    const float scale = marchOpacityScale(tf, gradients, sample);
    if (shading.valueGradients) {
      const float4 q = shading.points[sample], vg = shading.valueGradients[sample];
      const SampleLight light =
          sampleLightAt(p.cam, shading.constants, shading.toLight, Vec3f{q.x, q.y, q.z}, Vec3f{vg.y, vg.z, vg.w});
      ray.addLit(tf, values[sample], r.ds, ambient, light, tau ? expf(-tau[sample]) : 1.f, scale);
    } else {
      ray.add(tf, values[sample], r.ds, tau ? marchLightFactor<float>(ambient, expf(-tau[sample])) : 1.f, scale);
    }
  }
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
  cuda::DeviceBuffer<float4> valueGradients;  // gradient shading, gradient opacity: (value, gradient) per sample
  cuda::DeviceBuffer<int> hitRays;
  cuda::PinnedHost<int> total{1};
  cuda::PinnedHost<int> hitRaysHost{1};
  // Shadows: per primary sample its shadow points' count, offset and optical depth; the shadow
  // points and values of one evaluator call; the counter of shadow rays.
  cuda::DeviceBuffer<int> shadowCount, shadowOffsets, shadowRays;
  cuda::DeviceBuffer<unsigned char> shadowScanTemp;
  cuda::DeviceBuffer<float> tau;
  cuda::DeviceBuffer<float4> shadowPoints;
  cuda::DeviceBuffer<float> shadowValues;
  cuda::DeviceBuffer<float4> shadowValueGradients;  // gradient opacity: the shadow points' (value, gradient)
  cuda::PinnedHost<int> shadowRaysHost{1};
};

CudaRayMarcher::CudaRayMarcher(const CudaInrEvaluator& evaluator, const Box3f& box, RayMarchOptions options)
    : evaluator_(evaluator), box_(box), options_(options), impl_(std::make_unique<Impl>()) {
  const float diag = length(box.hi - box.lo);
  step_ = options.step > 0.f ? options.step : diag / 512.f;
  shadowStep_ = options.shadowStep > 0.f ? options.shadowStep : 2.f * step_;  // as the CPU marcher
  if (!(step_ > 0.f) || !(shadowStep_ > 0.f)) throw std::invalid_argument("ray-march step must be > 0");
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
  validateLighting(scene);
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels)
    throw std::invalid_argument("depth limit must have one value per pixel");
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
  // Pixels per chunk: at most 2^24 samples (the longest ray has ceil(diagonal / step) + 1); with
  // shadows, few enough that the chunk's shadow points stay below 2^30 (int offsets).
  const double diag = length(box_.hi - box_.lo);
  const long long maxPerRay = (long long)std::ceil(diag / step_) + 2;
  const long long maxShadowPerSample = (long long)std::ceil(diag / shadowStep_) + 2;
  const long long maxSamples = scene_.shadows ? std::min(1ll << 24, (1ll << 30) / maxShadowPerSample) : (1ll << 24);
  const int chunk = int(std::max<long long>(1, std::min<long long>(n, maxSamples / maxPerRay)));
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
  MarchShadowParams sp;
  sp.box = box_;
  sp.toLight = normalize(Vec3f{float(scene_.toLight[0]), float(scene_.toLight[1]), float(scene_.toLight[2])});
  if (p.cam.transformed) sp.toLight = normalize(applyLinear(p.cam.modelFromWorld, sp.toLight));  // model space
  sp.step = shadowStep_;
  sp.time = p.time;
  sp.ambient = scene_.ambient;
  if (scene_.shadows) {
    I.shadowRays.resize(1);
    I.shadowRays.zero(s);
  }
  // Gradient shading and gradient opacity: every sample's value comes with its gradient, shadow
  // samples' too with gradient opacity, as in the CPU marcher.
  const bool gradientOpacity = usesGradient(tf);  // (or a 2D TF)
  MarchShading shading;
  shading.constants = shadingConstants(scene_.shading, p.cam);
  shading.toLight = sp.toLight;
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
      if (shading.constants.enabled || gradientOpacity) {
        if (I.valueGradients.size() < std::size_t(total)) I.valueGradients.resize(std::size_t(total));
        evaluator_.evaluateWithGradientDevice(I.points.get(), nullptr, total, p.time, I.valueGradients.get(), s);
        valuesOfGradientsKernel<<<(total + 127) / 128, 128, 0, s>>>(total, I.valueGradients.get(), I.values.get());
        INR_CUDA_CHECK_LAUNCH("valuesOfGradientsKernel");
        if (shading.constants.enabled) {
          shading.points = I.points.get();
          shading.valueGradients = I.valueGradients.get();
        }
      } else {
        evaluator_.evaluateDevice(I.points.get(), total, I.values.get(), nullptr, s);
      }
      st.queries += std::size_t(total);
      if (gradientOpacity) st.gradientOpacityQueries += std::size_t(total);
      st.iterations += 1;
    }
    const bool shadows = scene_.shadows && total > 0;
    if (shadows) castShadows(total, tf, sp, st);
    compositeKernel<<<blocks, 128, 0, s>>>(p, I.rays.get(), I.offsets.get(), I.values.get(),
                                           gradientOpacity ? I.valueGradients.get() : nullptr,
                                           shadows ? I.tau.get() : nullptr, sp.ambient, shading, tf, I.accum.get(),
                                           frameIndex_);
    INR_CUDA_CHECK_LAUNCH("compositeKernel");
  }
  INR_CUDA_CHECK(cudaMemcpyAsync(I.hitRaysHost.get(), I.hitRays.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  st.rays = std::size_t(I.hitRaysHost[0]);
  if (scene_.shadows) {
    INR_CUDA_CHECK(cudaMemcpyAsync(I.shadowRaysHost.get(), I.shadowRays.get(), sizeof(int), cudaMemcpyDeviceToHost, s));
    INR_CUDA_CHECK(cudaStreamSynchronize(s));
    st.shadowRays = std::size_t(I.shadowRaysHost[0]);
  }
  ++frameIndex_;
  st.closeTiming(0.0, msSince(tFrame));
  return st;
}

// The optical depth towards the light of the chunk's `total` primary samples (I.points, I.values)
// into I.tau: count each emitting sample's shadow points, place them by a prefix sum, then
// evaluate them in calls of at most options_.maxShadowBatch points, each adding its share.
void CudaRayMarcher::castShadows(int total, const TransferFunctionView& tf, const MarchShadowParams& sp, FrameStats& st) {
  Impl& I = *impl_;
  const cudaStream_t s = I.stream.get();
  const auto t0 = Clock::now();
  if (I.shadowCount.size() < std::size_t(total) + 1) {
    I.shadowCount.resize(std::size_t(total) + 1);
    I.shadowOffsets.resize(std::size_t(total) + 1);
    I.tau.resize(std::size_t(total));
    std::size_t bytes = 0;
    INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(nullptr, bytes, I.shadowCount.get(), I.shadowOffsets.get(), total + 1, s));
    I.shadowScanTemp.resize(bytes);
  }
  const int sampleBlocks = (total + 1 + 127) / 128;
  const bool gradientOpacity = usesGradient(tf);  // (or a 2D TF)
  shadowCountKernel<<<sampleBlocks, 128, 0, s>>>(total, I.points.get(), I.values.get(),
                                                 gradientOpacity ? I.valueGradients.get() : nullptr, tf, sp,
                                                 I.shadowCount.get(), I.tau.get(), I.shadowRays.get());
  INR_CUDA_CHECK_LAUNCH("shadowCountKernel");
  std::size_t bytes = I.shadowScanTemp.size();
  INR_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(I.shadowScanTemp.get(), bytes, I.shadowCount.get(), I.shadowOffsets.get(),
                                               total + 1, s));
  INR_CUDA_CHECK(cudaMemcpyAsync(I.total.get(), I.shadowOffsets.get() + total, sizeof(int), cudaMemcpyDeviceToHost, s));
  INR_CUDA_CHECK(cudaStreamSynchronize(s));
  const int shadowTotal = I.total[0];
  const int batch = int(std::max<std::size_t>(1, std::min<std::size_t>(options_.maxShadowBatch, std::size_t(shadowTotal))));
  if (shadowTotal > 0 && I.shadowPoints.size() < std::size_t(batch)) {
    I.shadowPoints.resize(std::size_t(batch));
    I.shadowValues.resize(std::size_t(batch));
  }
  // (Its own size check: a marcher that cast shadows without gradient opacity has its points sized.)
  if (shadowTotal > 0 && gradientOpacity) I.shadowValueGradients.growTo(std::size_t(batch));
  for (int first = 0; first < shadowTotal; first += batch) {
    const int m = std::min(batch, shadowTotal - first);
    shadowPointsKernel<<<(m + 127) / 128, 128, 0, s>>>(first, m, total, I.points.get(), I.shadowOffsets.get(), sp,
                                                        I.shadowPoints.get());
    INR_CUDA_CHECK_LAUNCH("shadowPointsKernel");
    const auto te = Clock::now();
    if (gradientOpacity) {
      evaluator_.evaluateWithGradientDevice(I.shadowPoints.get(), nullptr, m, sp.time, I.shadowValueGradients.get(), s);
      valuesOfGradientsKernel<<<(m + 127) / 128, 128, 0, s>>>(m, I.shadowValueGradients.get(), I.shadowValues.get());
      INR_CUDA_CHECK_LAUNCH("valuesOfGradientsKernel");
    } else {
      evaluator_.evaluateDevice(I.shadowPoints.get(), m, I.shadowValues.get(), nullptr, s);
    }
    shadowDepthKernel<<<(total + 127) / 128, 128, 0, s>>>(first, m, total, I.points.get(), I.shadowOffsets.get(),
                                                          I.shadowValues.get(),
                                                          gradientOpacity ? I.shadowValueGradients.get() : nullptr, tf,
                                                          sp, I.tau.get());
    INR_CUDA_CHECK_LAUNCH("shadowDepthKernel");
    st.shadowQueries += std::size_t(m);
    if (gradientOpacity) st.gradientOpacityQueries += std::size_t(m);
    st.shadowIterations += 1;
    st.shadowEvaluateMs += msSince(te);  // launch time only: the stream runs on
  }
  st.shadowTraverseMs += msSince(t0);
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
