#pragma once
// The device-side twin of FieldEvaluator: a batch of world-space (x, y, z, t) points in device
// memory in, one scalar per point out, written straight into device memory (optionally scattered
// through an index array), asynchronously on a stream. What the GPU pipeline (macrocell builds,
// the wavefront's evaluation stage) needs from a field: CudaInrEvaluator implements it for
// networks, tests implement it with analytic fields (Render/Cuda/AnalyticDeviceField.h).
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

namespace inr {

class DeviceFieldEvaluator {
public:
  virtual ~DeviceFieldEvaluator() = default;

  // points: n world-space (x, y, z, t) as float4 in device memory. out[scatter ? scatter[i] : i]
  // receives the value of points[i]. Asynchronous on `stream`.
  void evaluateDevice(const float4* points, int n, float* out, const int* scatter, cudaStream_t stream) const {
    evaluateDevice(points, nullptr, n, out, scatter, stream);
  }
  // The same for min(*deviceCount, maxN) points, the count in device memory (written by an
  // earlier kernel on `stream`; null: maxN points): implementations should avoid reading it back
  // to the host. (Implementations add `using DeviceFieldEvaluator::evaluateDevice;`.)
  virtual void evaluateDevice(const float4* points, const unsigned* deviceCount, int maxN, float* out,
                              const int* scatter, cudaStream_t stream) const = 0;
  virtual std::string name() const = 0;

  // Gradient shading's batch (Render/Shade.h): for min(*deviceCount, maxN) points at world time
  // `time`, out[i] = (value, d/dx, d/dy, d/dz). Evaluators without gradients say false and throw.
  virtual bool providesDeviceGradient() const { return false; }
  virtual void evaluateWithGradientDevice(const float4* /*points*/, const unsigned* /*deviceCount*/, int /*maxN*/,
                                          float /*time*/, float4* /*out*/, cudaStream_t /*stream*/) const {
    throw std::logic_error("the device evaluator " + name() + " computes no gradients (needed for shading)");
  }
};

}  // namespace inr
