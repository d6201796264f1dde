#include "Evaluator/Cuda/CudaPerThreadMlp.h"

#include <algorithm>
#include <stdexcept>

#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.cuh"
#include "Evaluator/MlpProgram.h"

namespace inr {

namespace {
__global__ void perThreadEvaluateKernel(PerThreadMlpView N, const float4* points, int n, float* out) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float4 p = points[i];
  out[i] = cuda::perThreadEvaluate(N, p.x, p.y, p.z, p.w, i);
}

// Gradient shading's batch: a grid-stride loop of a bounded number of threads (their scratch).
__global__ void perThreadGradientKernel(PerThreadMlpView N, const float4* points, const unsigned* deviceCount,
                                        int maxN, float4* out) {
  const int n = deviceCount ? min(int(*deviceCount), maxN) : maxN;
  const int threads = gridDim.x * blockDim.x;
  const int tid = blockIdx.x * blockDim.x + threadIdx.x;
  for (int i = tid; i < n; i += threads) {
    const float4 p = points[i];
    float g[3];
    const float v = cuda::perThreadForward<true>(N, p.x, p.y, p.z, p.w, tid, g);
    out[i] = make_float4(v, g[0], g[1], g[2]);
  }
}

// Threads of the gradient kernel: enough to fill a large GPU, few enough that four planes of
// scratch per thread stay small.
constexpr int kGradientThreads = 1 << 15;
}  // namespace

struct CudaPerThreadMlp::Impl {
  MlpProgram program;
  OutputMapping output;
  PerThreadMlpView base;
  cuda::DeviceBuffer<MlpInstr> instrs;
  cuda::DeviceBuffer<float> weights;
  mutable cuda::DeviceBuffer<float> scratch;
  mutable cuda::DeviceBuffer<float4> stagePoints;
  mutable cuda::DeviceBuffer<float> stageOut;
};

CudaPerThreadMlp::CudaPerThreadMlp(const InrModel& model) : impl_(std::make_unique<Impl>()) {
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) throw std::runtime_error("CUDA backend unavailable: " + dev.reason);
  Impl& I = *impl_;
  I.program = MlpProgram::compile(model.architecture);
  I.output = model.output;
  I.instrs.upload(I.program.instrs, nullptr);
  I.weights.upload(I.program.floatWeights, nullptr);
  INR_CUDA_CHECK(cudaDeviceSynchronize());
  I.base = perThreadMlpBase(model, I.program, I.instrs.get(), I.weights.get());
}

PerThreadMlpView perThreadMlpBase(const InrModel& model, const MlpProgram& program, const MlpInstr* instrs,
                                  const float* weights) {
  PerThreadMlpView v;
  v.inputDim = model.architecture.inputDim;
  if (v.inputDim < 1 || v.inputDim > 4) throw std::runtime_error("per-thread MLP: input dimension must be 1..4");
  for (int i = 0; i < v.inputDim; ++i) {
    const int w = model.domain.inputOrder[i];
    v.inputCoord[i] = w;
    v.inScale[i] = float(model.domain.toNetwork[w].scale);
    v.inOffset[i] = float(model.domain.toNetwork[w].offset);
  }
  v.instrs = instrs;
  v.numInstrs = int(program.instrs.size());
  v.weights = weights;
  v.numBuffers = std::max(1, program.numBuffers);
  v.width = std::max(16, program.maxWidthPad);
  return v;
}

CudaPerThreadMlp::~CudaPerThreadMlp() = default;

std::size_t CudaPerThreadMlp::scratchBytesPerThread() const {
  return std::size_t(impl_->base.numBuffers) * impl_->base.width * sizeof(float);
}

PerThreadMlpView CudaPerThreadMlp::view(int threads, float time, bool tangents) const {
  Impl& I = *impl_;
  const std::size_t need = std::size_t(I.base.numBuffers) * I.base.width * std::size_t(std::max(threads, 1)) *
                           (tangents ? 4 : 1);
  I.scratch.growTo(need);
  PerThreadMlpView v = I.base;
  v.scratch = I.scratch.get();
  v.stride = threads;
  I.output.affineAt(time, v.outA, v.outB);
  return v;
}

void CudaPerThreadMlp::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  if (n == 0) return;
  static_assert(sizeof(QueryPoint) == sizeof(float4), "QueryPoint must match float4");
  Impl& I = *impl_;
  constexpr int kChunk = 1 << 16;
  I.stagePoints.resize(std::min<std::size_t>(n, kChunk));
  I.stageOut.resize(std::min<std::size_t>(n, kChunk));
  for (std::size_t first = 0; first < n; first += kChunk) {
    const int m = int(std::min<std::size_t>(kChunk, n - first));
    // The output mapping depends on time: group by the chunk's first time is wrong in general,
    // so evaluate query by query's time through a per-chunk view only when times agree.
    float t0 = points[first].t;
    bool sameTime = true;
    for (int i = 1; i < m; ++i) sameTime &= points[first + i].t == t0;
    if (!sameTime && I.output.perTime) {
      // Rare (tests only): fall back to one chunk per distinct time run.
      for (int i = 0; i < m;) {
        int j = i + 1;
        while (j < m && points[first + j].t == points[first + i].t) ++j;
        evaluate(points + first + i, std::size_t(j - i), out + first + i);
        i = j;
      }
      continue;
    }
    INR_CUDA_CHECK(cudaMemcpy(I.stagePoints.get(), points + first, m * sizeof(float4), cudaMemcpyHostToDevice));
    const PerThreadMlpView v = view(m, t0);
    perThreadEvaluateKernel<<<(m + 127) / 128, 128>>>(v, I.stagePoints.get(), m, I.stageOut.get());
    INR_CUDA_CHECK_LAUNCH("perThreadEvaluateKernel");
    INR_CUDA_CHECK(cudaMemcpy(out + first, I.stageOut.get(), m * sizeof(float), cudaMemcpyDeviceToHost));
  }
}

void CudaPerThreadMlp::evaluateWithGradientDevice(const float4* points, const unsigned* deviceCount, int maxN,
                                                  float time, float4* out, cudaStream_t stream) const {
  if (maxN <= 0) return;
  const int threads = std::min(maxN, kGradientThreads);
  const PerThreadMlpView v = view(threads, time, true);
  perThreadGradientKernel<<<(threads + 127) / 128, 128, 0, stream>>>(v, points, deviceCount, maxN, out);
  INR_CUDA_CHECK_LAUNCH("perThreadGradientKernel");
}

void gradientsThroughDevice(const OutputMapping& output, const QueryPoint* points, std::size_t n, float* values,
                            float* gradients, const std::function<void(const float4*, int, float, float4*)>& launch) {
  static_assert(sizeof(QueryPoint) == sizeof(float4), "QueryPoint must match float4");
  constexpr int kChunk = 1 << 16;
  cuda::DeviceBuffer<float4> stagePoints, stageResults;
  std::vector<float4> results;
  for (std::size_t first = 0; first < n;) {
    // One output mapping per launch: a run of equal times where the mapping depends on time.
    std::size_t end = first + 1;
    while (end < n && end - first < std::size_t(kChunk) && (!output.perTime || points[end].t == points[first].t)) ++end;
    const int m = int(end - first);
    stagePoints.growTo(std::size_t(m));
    stageResults.growTo(std::size_t(m));
    INR_CUDA_CHECK(cudaMemcpy(stagePoints.get(), points + first, m * sizeof(float4), cudaMemcpyHostToDevice));
    launch(stagePoints.get(), m, points[first].t, stageResults.get());
    results.resize(std::size_t(m));
    INR_CUDA_CHECK(cudaMemcpy(results.data(), stageResults.get(), m * sizeof(float4), cudaMemcpyDeviceToHost));
    for (int i = 0; i < m; ++i) {
      values[first + i] = results[i].x;
      gradients[3 * (first + i)] = results[i].y;
      gradients[3 * (first + i) + 1] = results[i].z;
      gradients[3 * (first + i) + 2] = results[i].w;
    }
    first = end;
  }
}

void CudaPerThreadMlp::evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values,
                                            float* gradients) const {
  gradientsThroughDevice(impl_->output, points, n, values, gradients, [&](const float4* p, int m, float time, float4* out) {
    evaluateWithGradientDevice(p, nullptr, m, time, out, nullptr);
  });
}

}  // namespace inr
