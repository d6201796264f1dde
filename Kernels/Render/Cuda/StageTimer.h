#pragma once
// Per-stage GPU timing for the pipeline (pbrt-v4's per-kernel timing stats): pairs of CUDA
// events around each stage interval, summed per stage after the frame's stream synchronisation.
// Events come from a pool that grows to the frame's interval count and is reused.
#include <cuda_runtime.h>

#include <vector>

#include "Common/Cuda/CudaCheck.h"

namespace inr::cuda {

enum Stage { kUpdate, kInit, kTraverse, kEvaluate, kShadowTraverse, kShadowEvaluate, kShade, kFinalize, kStages };

class StageTimer {
public:
  StageTimer() = default;
  StageTimer(const StageTimer&) = delete;
  StageTimer& operator=(const StageTimer&) = delete;
  ~StageTimer() {
    for (cudaEvent_t e : pool_) cudaEventDestroy(e);
  }
  void reset(bool enabled) {
    enabled_ = enabled;
    used_ = 0;
    intervals_.clear();
  }
  void begin(Stage s, cudaStream_t stream) {
    if (!enabled_) return;
    open_ = s;
    openEvent_ = record(stream);
  }
  void end(cudaStream_t stream) {
    if (!enabled_) return;
    intervals_.push_back({open_, openEvent_, record(stream)});
  }
  // Call after the stream is synchronised.
  void collect(double (&ms)[kStages]) {
    for (double& m : ms) m = 0.0;
    for (const Interval& iv : intervals_) {
      float t = 0.f;
      INR_CUDA_CHECK(cudaEventElapsedTime(&t, pool_[iv.start], pool_[iv.stop]));
      ms[iv.stage] += t;
    }
  }

private:
  struct Interval {
    Stage stage;
    int start, stop;
  };
  int record(cudaStream_t stream) {
    if (used_ == int(pool_.size())) {
      cudaEvent_t e;
      INR_CUDA_CHECK(cudaEventCreate(&e));
      pool_.push_back(e);
    }
    INR_CUDA_CHECK(cudaEventRecord(pool_[used_], stream));
    return used_++;
  }
  bool enabled_ = true;
  std::vector<cudaEvent_t> pool_;
  int used_ = 0;
  Stage open_ = kUpdate;
  int openEvent_ = 0;
  std::vector<Interval> intervals_;
};

}  // namespace inr::cuda
