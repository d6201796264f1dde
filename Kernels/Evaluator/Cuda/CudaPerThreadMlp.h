#pragma once
// The naive baseline's network: every GPU thread evaluates the whole network for its own query,
// in fp32, instruction by instruction from the MlpProgram (no batching, no tensor cores, no
// shared weights tiles). Deliberately the straightforward per-thread implementation a delta
// tracker written for voxel textures gets when its texture fetch becomes a network inference —
// the baseline of benchmark 4c. Activations live in a global scratch array, one slice per thread
// (coalesced: consecutive threads read consecutive words).
#include <cuda_runtime.h>

#include <functional>
#include <memory>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr {

struct MlpInstr;

// What a kernel needs to evaluate the network per thread (device pointers).
struct PerThreadMlpView {
  const MlpInstr* instrs = nullptr;
  int numInstrs = 0;
  const float* weights = nullptr;  // MlpProgram::floatWeights
  int inputDim = 4;
  int inputCoord[4] = {0, 1, 2, 3};
  float inScale[4] = {1, 1, 1, 1}, inOffset[4] = {0, 0, 0, 0};
  float outA = 1.f, outB = 0.f;  // value = outA * net + outB at the frame's time
  float* scratch = nullptr;      // numBuffers * width * stride floats
  int numBuffers = 1, width = 16, stride = 0;  // stride = threads sharing the scratch
};

struct MlpProgram;

// The view of `program` compiled from `model` with its instructions and fp32 weights at `instrs`
// and `weights` (device memory, or host memory for the host form of the code): input mapping,
// buffers; no scratch, output mapping at no time yet (view() adds them).
PerThreadMlpView perThreadMlpBase(const InrModel& model, const MlpProgram& program, const MlpInstr* instrs,
                                  const float* weights);

// FieldEvaluator::evaluateWithGradient's host arrays through a device value + gradient batch:
// the points staged in chunks of one output-mapping time (runs of equal times where `output`
// depends on time), launch(devicePoints, m, time, deviceResults) writing (value, d/dx, d/dy,
// d/dz) per point, on the default stream.
void gradientsThroughDevice(const OutputMapping& output, const QueryPoint* points, std::size_t n, float* values,
                            float* gradients, const std::function<void(const float4*, int, float, float4*)>& launch);

class CudaPerThreadMlp final : public FieldEvaluator {
public:
  explicit CudaPerThreadMlp(const InrModel& model);
  ~CudaPerThreadMlp() override;

  // View for `threads` concurrent threads at world time `time` (the output mapping may depend on
  // time). Grows the scratch array as needed; the view is valid until the next call. With
  // `tangents` the scratch also holds three tangent planes (perThreadForward<true>).
  PerThreadMlpView view(int threads, float time, bool tangents = false) const;
  // Scratch bytes one thread needs (values only).
  std::size_t scratchBytesPerThread() const;

  // FieldEvaluator (host arrays; for tests): one thread per query through the same device code.
  void evaluate(const QueryPoint* points, std::size_t n, float* out) const override;
  std::string name() const override { return "cuda-per-thread-fp32"; }
  // Values and gradients in fp32 forward mode (perThreadForward<true>), host arrays.
  bool providesGradient() const override { return true; }
  void evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values, float* gradients) const override;
  // The same on the device: for min(*deviceCount, maxN) points (the count in device memory; null:
  // maxN), all at world time `time`, out[i] = (value, d/dx, d/dy, d/dz). A bounded number of
  // threads loops over the points, so the tangents' scratch stays bounded whatever the batch.
  // Asynchronous on `stream`.
  void evaluateWithGradientDevice(const float4* points, const unsigned* deviceCount, int maxN, float time, float4* out,
                                  cudaStream_t stream) const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
