// The Hopper (wgmma) kernel's instantiations. This file is compiled for sm_90a only
// (Kernels/Cuda/CMakeLists.txt), so on an H100/H200 the driver can only load the wgmma code, and
// on any other GPU the kernels report no image and the evaluator keeps the mma.sync kernel.
#include "Cuda/FusedMlpKernelHopper.cuh"

namespace inr::cuda {

FusedKernel hopperKernelFor(int kc) { return kc == 32 ? hopperMlpKernel<32> : hopperMlpKernel<64>; }

}  // namespace inr::cuda
