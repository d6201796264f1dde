// The mma.sync kernel's instantiations for value + gradient (tangent rows), weight chunks of 32 (FusedMlpKernel.cuh).
#include "Evaluator/Cuda/FusedMlpKernel.cuh"

namespace inr::cuda {
template FusedKernel mmaSyncKernelFor<true, 32>(int tile);
}  // namespace inr::cuda
