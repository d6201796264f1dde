#pragma once
// Query points in device memory, as the GPU evaluators' device interface reads them (float4
// x, y, z, t).
#include <cuda_runtime.h>

#include <vector>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/FieldEvaluator.h"

namespace inr::test {

inline cuda::DeviceBuffer<float4> devicePoints(const std::vector<QueryPoint>& pts) {
  static_assert(sizeof(QueryPoint) == sizeof(float4), "QueryPoint must match float4");
  cuda::DeviceBuffer<float4> d(pts.size());
  if (!pts.empty())
    INR_CUDA_CHECK(cudaMemcpy(d.get(), pts.data(), pts.size() * sizeof(float4), cudaMemcpyHostToDevice));
  return d;
}

}  // namespace inr::test
