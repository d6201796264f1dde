#pragma once
// CUDA error handling for host code: every runtime call is checked; failures throw
// std::runtime_error naming the call, the file/line and the CUDA error string, and a lack of
// device memory throws DeviceOutOfMemory (Common/DeviceMemory.h), so that callers can fall back.
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "Common/DeviceMemory.h"

namespace inr {

inline void cudaCheck(cudaError_t e, const char* what, const char* file, int line) {
  if (e == cudaErrorMemoryAllocation) {
    (void)cudaGetLastError();  // not sticky: clear it so that no later check reports it
    throw deviceOutOfMemoryIn(std::string(what) + " (" + file + ":" + std::to_string(line) + ")");
  }
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("CUDA error in ") + what + " (" + file + ":" + std::to_string(line) +
                             "): " + cudaGetErrorName(e) + ": " + cudaGetErrorString(e));
}

}  // namespace inr

#define INR_CUDA_CHECK(call) ::inr::cudaCheck((call), #call, __FILE__, __LINE__)
#define INR_CUDA_CHECK_LAUNCH(name) ::inr::cudaCheck(cudaGetLastError(), name, __FILE__, __LINE__)
