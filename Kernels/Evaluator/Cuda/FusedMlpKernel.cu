// The mma.sync kernel's entry points (FusedMlpKernels.h): its instantiations, in the
// translation units FusedMlpKernel{Values,Tangents}K{64,32}.cu (the kernel: FusedMlpKernel.cuh).
#include "Evaluator/Cuda/FusedMlpKernels.h"

namespace inr::cuda {

FusedKernel mmaSyncKernel(int tile, int kc) {
  return kc == 32 ? mmaSyncKernelFor<false, 32>(tile) : mmaSyncKernelFor<false, 64>(tile);
}

FusedKernel mmaSyncTangentKernel(int tile, int kc) {
  return kc == 32 ? mmaSyncKernelFor<true, 32>(tile) : mmaSyncKernelFor<true, 64>(tile);
}

}  // namespace inr::cuda
