// The mma.sync kernel's instantiations for values, weight chunks of 64 (FusedMlpKernel.cuh).
#include "Evaluator/Cuda/FusedMlpKernel.cuh"

namespace inr::cuda {
template FusedKernel mmaSyncKernelFor<false, 64>(int tile);
}  // namespace inr::cuda
