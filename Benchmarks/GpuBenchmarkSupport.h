#pragma once
// What the GPU benchmark programs share on top of BenchmarkSupport.h: CUDA-event timing and the
// evaluator throughput measurement.
#include <cuda_profiler_api.h>
#include <cuda_runtime.h>

#include <optional>
#include <string>
#include <vector>

#include "BenchmarkSupport.h"
#include "Common/Cuda/CudaCheck.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"

namespace inr::bench {

// The value of a `--mma` option (wgmma or mma.sync); prints why and returns nothing for another
// (`program` names the benchmark in the message).
inline std::optional<FusedMma> parseMmaOption(const std::string& value, const char* program) {
  if (value == "wgmma") return FusedMma::Wgmma;
  if (value == "mma.sync") return FusedMma::MmaSync;
  std::fprintf(stderr, "%s: --mma takes wgmma or mma.sync, not '%s'\n", program, value.c_str());
  return std::nullopt;
}

// Milliseconds of GPU work between start() and stop() on one stream, from CUDA events.
class EventTimer {
public:
  EventTimer() {
    INR_CUDA_CHECK(cudaEventCreate(&e0_));
    INR_CUDA_CHECK(cudaEventCreate(&e1_));
  }
  EventTimer(const EventTimer&) = delete;
  EventTimer& operator=(const EventTimer&) = delete;
  ~EventTimer() {
    cudaEventDestroy(e0_);
    cudaEventDestroy(e1_);
  }
  void start(cudaStream_t s = nullptr) { INR_CUDA_CHECK(cudaEventRecord(e0_, s)); }
  // Waits for the work queued since start().
  void stop(cudaStream_t s = nullptr) {
    INR_CUDA_CHECK(cudaEventRecord(e1_, s));
    INR_CUDA_CHECK(cudaEventSynchronize(e1_));
  }
  float ms() const {
    float ms = 0;
    INR_CUDA_CHECK(cudaEventElapsedTime(&ms, e0_, e1_));
    return ms;
  }

private:
  cudaEvent_t e0_ = nullptr, e1_ = nullptr;
};

// Queries per second of launch() over n queries, one value per launch of `reps` after a
// warm-up launch (CUDA events on the default stream). The timed launches run between
// cudaProfilerStart and cudaProfilerStop, so a profiler started with collection off (`ncu
// --profile-from-start off`) sees them and not the autotuner's trial launches before them
// (Benchmarks/run_evaluator_summary.sh); without a profiler both calls do nothing.
// inRow > 1 times inRow launches queued back to back per value instead of one: a launch alone
// on an idle GPU also times the host's launch latency (the start event completes at once, the
// kernel starts when the host's launch call reaches the GPU), which a small batch feels; the
// frame's wavefront queues its evaluator launches behind the traversal's, as inRow does.
template <class Launch>
std::vector<double> launchRates(int n, int reps, const Launch& launch, int inRow = 1) {
  EventTimer timer;
  launch();  // warm-up
  INR_CUDA_CHECK(cudaDeviceSynchronize());
  std::vector<double> rates;
  INR_CUDA_CHECK(cudaProfilerStart());
  for (int r = 0; r < reps; ++r) {
    timer.start();
    for (int i = 0; i < inRow; ++i) launch();
    timer.stop();
    rates.push_back(double(n) * inRow / (timer.ms() * 1e-3));
  }
  INR_CUDA_CHECK(cudaProfilerStop());
  return rates;
}

// Queries per second of `eval` over n points already on the device (launchRates).
inline std::vector<double> evaluatorRates(const CudaInrEvaluator& eval, const float4* points, int n, float* out,
                                          int reps, int inRow = 1) {
  return launchRates(n, reps, [&] { eval.evaluateDevice(points, n, out, nullptr, nullptr); }, inRow);
}

// Value + gradient queries per second of `eval` over n points on the device, all at world time
// `time` (launchRates).
inline std::vector<double> gradientRates(const CudaInrEvaluator& eval, const float4* points, int n, float time,
                                         float4* out, int reps) {
  return launchRates(n, reps, [&] { eval.evaluateWithGradientDevice(points, nullptr, n, time, out, nullptr); });
}

}  // namespace inr::bench
