// The mma.sync kernel's instantiations for values, weight chunks of 32 (FusedMlpKernel.cuh).
#include "Evaluator/Cuda/FusedMlpKernel.cuh"

namespace inr::cuda {
template FusedKernel mmaSyncKernelFor<false, 32>(int tile);
}  // namespace inr::cuda
