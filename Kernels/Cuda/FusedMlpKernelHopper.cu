// The Hopper (wgmma) kernel. This file is compiled for sm_90a only (Kernels/Cuda/CMakeLists.txt),
// so on an H100/H200 the driver can only load the wgmma code, and on any other GPU the kernel
// reports no image and the evaluator keeps the mma.sync kernel.
#include "Cuda/FusedMlpKernelHopper.cuh"

namespace inr::cuda {

FusedKernel hopperKernel() { return hopperMlpKernel; }

}  // namespace inr::cuda
