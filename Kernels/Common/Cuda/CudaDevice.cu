#include "Common/Cuda/CudaDevice.h"

#include <cuda_runtime.h>

#include <atomic>
#include <cstdlib>

#include "Common/Cuda/DeviceBuffer.h"

namespace inr {

CudaDeviceInfo queryCudaDevice(int device) {
  CudaDeviceInfo info;
  info.device = device;
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    info.reason = std::string("no usable CUDA device (") + cudaGetErrorName(e) + ": " + cudaGetErrorString(e) + ")";
    cudaGetLastError();
    return info;
  }
  if (device < 0 || device >= count) {
    info.reason = "CUDA device " + std::to_string(device) + " does not exist (" + std::to_string(count) + " found)";
    return info;
  }
  cudaDeviceProp p{};
  if (cudaGetDeviceProperties(&p, device) != cudaSuccess) {
    info.reason = "cudaGetDeviceProperties failed";
    cudaGetLastError();
    return info;
  }
  info.name = p.name;
  info.major = p.major;
  info.minor = p.minor;
  info.multiprocessors = p.multiProcessorCount;
  info.sharedMemPerBlockOptin = p.sharedMemPerBlockOptin;
  info.globalMemory = p.totalGlobalMem;
  if (p.major < 7 || (p.major == 7 && p.minor < 5)) {
    info.reason = std::string(p.name) + " is sm_" + std::to_string(p.major) + std::to_string(p.minor) +
                  "; the CUDA backend needs sm_75 or newer";
    return info;
  }
  info.usable = true;
  info.reason = std::string(p.name) + " (sm_" + std::to_string(p.major) + std::to_string(p.minor) + ", " +
                std::to_string(p.multiProcessorCount) + " SMs)";
  return info;
}

int countCudaDevices() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();
    return 0;
  }
  return count;
}

}  // namespace inr

// ------------------------------------------------------------------ allocation fault hook
// (Common/Cuda/DeviceBuffer.h). One countdown for the process: -1 = not read from the
// environment yet, 0 = off, n > 0 = the n-th allocation from now fails.
namespace inr::cuda {
namespace {
std::atomic<long long> gAllocationFaultCountdown{-1};

long long allocationFaultFromEnvironment() {
  const char* text = std::getenv("INR_TEST_DEVICE_ALLOCATION_FAULT");
  if (!text || !*text) return 0;
  char* end = nullptr;
  const long long n = std::strtoll(text, &end, 10);
  return (end && *end == '\0' && n > 0) ? n : 0;
}
}  // namespace

void setDeviceAllocationFault(long long n) { gAllocationFaultCountdown.store(n > 0 ? n : 0); }

bool deviceAllocationFaultDue() {
  long long c = gAllocationFaultCountdown.load();
  if (c < 0) {
    long long unread = -1;
    gAllocationFaultCountdown.compare_exchange_strong(unread, allocationFaultFromEnvironment());
    c = gAllocationFaultCountdown.load();
  }
  while (c > 0) {
    if (gAllocationFaultCountdown.compare_exchange_weak(c, c - 1)) return c == 1;
  }
  return false;
}

}  // namespace inr::cuda
