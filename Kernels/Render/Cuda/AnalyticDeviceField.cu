#include "Render/Cuda/AnalyticDeviceField.h"

#include "Common/Cuda/CudaCheck.h"

namespace inr::test {

namespace {

// out[scatter ? scatter[i] : i] = field(points[i]) for i < min(n, *count) (count: optional).
__global__ void smoothFieldKernel(const float4* points, int n, const unsigned* count, float* out,
                                  const int* scatter) {
  const int m = count ? min(n, int(*count)) : n;
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < m; i += gridDim.x * blockDim.x) {
    const float4 p = points[i];
    out[scatter ? scatter[i] : i] = smoothFieldValue(p.x, p.y, p.z, p.w);
  }
}

}  // namespace

void AnalyticDeviceField::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  for (std::size_t i = 0; i < n; ++i) out[i] = smoothFieldValue(points[i].x, points[i].y, points[i].z, points[i].t);
}

void AnalyticDeviceField::evaluateDevice(const float4* points, const unsigned* deviceCount, int maxN, float* out,
                                         const int* scatter, cudaStream_t stream) const {
  if (maxN <= 0) return;
  const int blocks = (maxN + 255) / 256 < 4096 ? (maxN + 255) / 256 : 4096;  // grid-strided beyond
  smoothFieldKernel<<<blocks, 256, 0, stream>>>(points, maxN, deviceCount, out, scatter);
  INR_CUDA_CHECK_LAUNCH("smoothFieldKernel");
}

}  // namespace inr::test
