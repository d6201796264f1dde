// The Hopper (wgmma) instantiations of the fused kernel. This file is compiled for sm_90a only
// (Kernels/Cuda/CMakeLists.txt), so on an H100/H200 the driver can only load the wgmma code, and
// on any other GPU the kernels report no image and the evaluator keeps the mma.sync kernel.
#include "Cuda/FusedMlpKernel.cuh"

namespace inr::cuda {

HopperKernel hopperKernelFor(int tile, int kc) {
  if (kc == 32) return tile == 128 ? fusedMlpKernel<4, 32, true> : fusedMlpKernel<2, 32, true>;
  return tile == 128 ? fusedMlpKernel<4, 64, true> : fusedMlpKernel<2, 64, true>;
}

}  // namespace inr::cuda
