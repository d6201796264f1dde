#pragma once
// Small RAII helpers for the GPU pipeline's device memory (host code, no kernels): a typed
// device array that grows on demand, a pinned host scalar for the per-iteration counter
// read-back, and a device copy of a TransferFunctionTable. Every CUDA call is checked.
#include <cuda_runtime.h>

#include <cstddef>
#include <utility>
#include <vector>

#include "Cuda/CudaCheck.h"
#include "Render/SceneInputs.h"

namespace inr::cuda {

template <typename T>
class DeviceBuffer {
public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t n) { resize(n); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept { swap(o); }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    swap(o);
    return *this;
  }
  ~DeviceBuffer() {
    if (ptr_) cudaFree(ptr_);  // no throw from a destructor; errors surface at the next check
  }
  void swap(DeviceBuffer& o) noexcept {
    std::swap(ptr_, o.ptr_);
    std::swap(size_, o.size_);
  }
  // Exactly n elements afterwards (contents lost when reallocated).
  void resize(std::size_t n) {
    if (n == size_ && ptr_) return;
    if (ptr_) INR_CUDA_CHECK(cudaFree(ptr_));
    ptr_ = nullptr;
    size_ = 0;
    INR_CUDA_CHECK(cudaMalloc(&ptr_, (n ? n : 1) * sizeof(T)));
    size_ = n;
  }
  void upload(const T* host, std::size_t n, cudaStream_t s) {
    resize(n);
    if (n) INR_CUDA_CHECK(cudaMemcpyAsync(ptr_, host, n * sizeof(T), cudaMemcpyHostToDevice, s));
  }
  void upload(const std::vector<T>& v, cudaStream_t s) { upload(v.data(), v.size(), s); }
  // Synchronous download of the first n elements.
  std::vector<T> download(cudaStream_t s, std::size_t n = std::size_t(-1)) const {
    if (n > size_) n = size_;
    std::vector<T> out(n);
    if (n) {
      INR_CUDA_CHECK(cudaMemcpyAsync(out.data(), ptr_, n * sizeof(T), cudaMemcpyDeviceToHost, s));
      INR_CUDA_CHECK(cudaStreamSynchronize(s));
    }
    return out;
  }
  void zero(cudaStream_t s) {
    if (ptr_) INR_CUDA_CHECK(cudaMemsetAsync(ptr_, 0, (size_ ? size_ : 1) * sizeof(T), s));
  }
  T* get() const { return ptr_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

private:
  T* ptr_ = nullptr;
  std::size_t size_ = 0;
};

// Page-locked host memory for small read-backs (counters, stats).
template <typename T>
class PinnedHost {
public:
  explicit PinnedHost(std::size_t n = 1) : n_(n) { INR_CUDA_CHECK(cudaMallocHost(&ptr_, n * sizeof(T))); }
  PinnedHost(const PinnedHost&) = delete;
  PinnedHost& operator=(const PinnedHost&) = delete;
  ~PinnedHost() {
    if (ptr_) cudaFreeHost(ptr_);
  }
  T* get() const { return ptr_; }
  T& operator[](std::size_t i) const { return ptr_[i]; }

private:
  T* ptr_ = nullptr;
  std::size_t n_ = 0;
};

// A TransferFunctionTable's arrays in device memory, and the view the per-ray code reads.
class DeviceTransferFunction {
public:
  void upload(const TransferFunctionTable& table, cudaStream_t s) {
    const TransferFunctionView h = table.view();
    rgba_.upload(h.rgba, std::size_t(h.size), s);
    opacityMax_.upload(h.opacityMax, std::size_t(h.size) * std::size_t(h.levels), s);
    view_ = h;
    view_.rgba = rgba_.get();
    view_.opacityMax = opacityMax_.get();
    // The host table must stay alive until the copies ran (they are asynchronous from pageable
    // memory only in name: the runtime stages them before returning). Synchronise anyway.
    INR_CUDA_CHECK(cudaStreamSynchronize(s));
  }
  const TransferFunctionView& view() const { return view_; }
  bool valid() const { return view_.size > 0; }

private:
  DeviceBuffer<Vec4f> rgba_;
  DeviceBuffer<float> opacityMax_;
  TransferFunctionView view_{};
};

// RAII stream.
class Stream {
public:
  Stream() { INR_CUDA_CHECK(cudaStreamCreateWithFlags(&s_, cudaStreamNonBlocking)); }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  ~Stream() {
    if (s_) cudaStreamDestroy(s_);
  }
  cudaStream_t get() const { return s_; }

private:
  cudaStream_t s_ = nullptr;
};

}  // namespace inr::cuda
