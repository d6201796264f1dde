#pragma once
// A TransferFunctionTable in device memory, for the GPU pipeline's per-ray code.
#include <cuda_runtime.h>

#include <cstddef>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Render/SceneInputs.h"

namespace inr::cuda {

// Its arrays in device memory, and the view the per-ray code reads.
class DeviceTransferFunction {
public:
  void upload(const TransferFunctionTable& table, cudaStream_t s) {
    const TransferFunctionView h = table.view();
    rgba_.upload(h.rgba, std::size_t(h.size), s);
    opacityMax_.upload(h.opacityMax, std::size_t(h.size) * std::size_t(h.levels), s);
    view_ = h;
    view_.rgba = rgba_.get();
    view_.opacityMax = opacityMax_.get();
    entryExtinction_.upload(h.entryExtinction, std::size_t(h.size), s);
    extinctionIntegral_.upload(h.extinctionIntegral, std::size_t(h.size), s);
    view_.entryExtinction = entryExtinction_.get();
    view_.extinctionIntegral = extinctionIntegral_.get();
    if (h.gradientOpacity) {
      gradientOpacity_.upload(h.gradientOpacity, std::size_t(h.gradientOpacitySize), s);
      gradientOpacityX_.upload(h.gradientOpacityX, std::size_t(h.gradientOpacitySize), s);
      view_.gradientOpacity = gradientOpacity_.get();
      view_.gradientOpacityX = gradientOpacityX_.get();
    }
    if (h.rgba2D) {
      rgba2D_.upload(h.rgba2D, std::size_t(h.size) * std::size_t(h.gradientSize), s);
      view_.rgba2D = rgba2D_.get();
    }
    // The host table must stay alive until the copies ran (they are asynchronous from pageable
    // memory only in name: the runtime stages them before returning). Synchronise anyway.
    INR_CUDA_CHECK(cudaStreamSynchronize(s));
  }
  const TransferFunctionView& view() const { return view_; }
  bool valid() const { return view_.size > 0; }

private:
  DeviceBuffer<Vec4f> rgba_;
  DeviceBuffer<float> opacityMax_;
  DeviceBuffer<float> entryExtinction_;
  DeviceBuffer<Vec4f> extinctionIntegral_;
  DeviceBuffer<float> gradientOpacity_, gradientOpacityX_;
  DeviceBuffer<Vec4f> rgba2D_;
  TransferFunctionView view_{};
};

}  // namespace inr::cuda
