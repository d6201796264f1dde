#pragma once
// An analytic field with both interfaces, for GPU tests that need no network: the smooth
// time-varying field of test::smoothField (TestSupport/TestFields.h), written once as an INR_HD
// function and evaluated on the host (FieldEvaluator) or by a kernel (DeviceFieldEvaluator).
// Host and device values differ from test::smoothField's only by rounding: the ulps of sinf /
// cosf / expf (the pipeline is built without fast math) and the host compiler's contractions.
#include <math.h>

#include "Common/HostDevice.h"
#include "Evaluator/Cuda/DeviceFieldEvaluator.h"
#include "Evaluator/FieldEvaluator.h"

namespace inr::test {

// test::smoothField: values in about [0, 1] on [-1, 1]^3.
INR_HD float smoothFieldValue(float x, float y, float z, float t) {
  return 0.5f + 0.35f * sinf(2.2f * x + 0.7f * t) * cosf(1.7f * y - 0.4f * t) * sinf(1.9f * z + 1.1f) +
         0.15f * expf(-4.f * ((x - 0.3f) * (x - 0.3f) + y * y + (z + 0.2f) * (z + 0.2f)));
}

class AnalyticDeviceField final : public FieldEvaluator, public DeviceFieldEvaluator {
public:
  void evaluate(const QueryPoint* points, std::size_t n, float* out) const override;
  using DeviceFieldEvaluator::evaluateDevice;
  void evaluateDevice(const float4* points, const unsigned* deviceCount, int maxN, float* out, const int* scatter,
                      cudaStream_t stream) const override;
  std::string name() const override { return "analytic smooth field"; }
};

}  // namespace inr::test
