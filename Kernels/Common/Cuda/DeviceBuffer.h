#pragma once
// RAII helpers for device memory, shared by the CUDA evaluator, the GPU pipeline, tests and
// benchmarks (host code, no kernels): a typed device array, page-locked host memory for small
// read-backs, and a stream. Every CUDA call is checked.
#include <cuda_runtime.h>

#include <cstddef>
#include <utility>
#include <vector>

#include "Common/Cuda/CudaCheck.h"
#include "Common/DeviceMemory.h"

namespace inr::cuda {

// Test hook (fault injection): the n-th device allocation from now on fails as if the device
// were out of memory (n = 1: the next one), once; 0 turns it off. The environment variable
// INR_TEST_DEVICE_ALLOCATION_FAULT=N sets it before the process's first device allocation. For
// tests and the GPU stress script only: a real failure takes the same path.
void setDeviceAllocationFault(long long n);
// Whether the allocation being made now is the one the hook makes fail (counts it).
bool deviceAllocationFaultDue();

// cudaMalloc of `bytes`; a lack of memory (real or injected) throws DeviceOutOfMemory naming the
// bytes, the device's free memory and the current DeviceAllocationPurpose, and leaves no CUDA
// error pending; other errors throw as INR_CUDA_CHECK does.
inline void* allocateDevice(std::size_t bytes) {
  void* p = nullptr;
  const bool injected = deviceAllocationFaultDue();
  const cudaError_t e = injected ? cudaErrorMemoryAllocation : cudaMalloc(&p, bytes);
  if (e == cudaErrorMemoryAllocation) {
    (void)cudaGetLastError();  // not sticky: clear it so that no later check reports it
    std::size_t freeBytes = 0, totalBytes = 0;
    if (cudaMemGetInfo(&freeBytes, &totalBytes) != cudaSuccess) {
      (void)cudaGetLastError();
      freeBytes = totalBytes = 0;
    }
    throw deviceOutOfMemory(bytes, freeBytes, totalBytes, injected);
  }
  INR_CUDA_CHECK(e);
  return p;
}

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
  // Exactly n elements afterwards (contents lost when reallocated). The new storage is
  // allocated before the old is freed, so that a size that does not fit throws DeviceOutOfMemory
  // with the buffer as it was (its size and contents): no caller is left holding an empty
  // buffer it would launch kernels on.
  void resize(std::size_t n) {
    if (n == size_ && ptr_) return;
    T* fresh = static_cast<T*>(allocateDevice((n ? n : 1) * sizeof(T)));
    const cudaError_t freed = ptr_ ? cudaFree(ptr_) : cudaSuccess;
    ptr_ = fresh;
    size_ = n;
    INR_CUDA_CHECK(freed);
  }
  // At least n elements afterwards: reallocates (contents lost) only when n exceeds size(), so a
  // staging buffer reused by calls of varying size is allocated once for the largest.
  void growTo(std::size_t n) {
    if (n > size_) resize(n);
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
