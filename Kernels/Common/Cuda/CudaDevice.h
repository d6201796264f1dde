#pragma once
// Whether the CUDA backend can run here, and what the device is. Never throws: machines without
// a GPU (CI) get `usable == false` and a reason to print.
#include <string>

namespace inr {

struct CudaDeviceInfo {
  bool usable = false;
  std::string reason;  // why not usable, or a one-line description when usable
  std::string name;
  int device = 0;
  int major = 0, minor = 0;
  int multiprocessors = 0;
  std::size_t sharedMemPerBlockOptin = 0;
  std::size_t globalMemory = 0;
};

CudaDeviceInfo queryCudaDevice(int device = 0);
// The number of CUDA devices visible to this process (0 without a driver or device).
int countCudaDevices();

}  // namespace inr
