// The mma.sync kernel's instantiations for value + gradient (tangent rows), weight chunks of 64 (FusedMlpKernel.cuh).
#include "Evaluator/Cuda/FusedMlpKernel.cuh"

namespace inr::cuda {
template FusedKernel mmaSyncKernelFor<true, 64>(int tile);
}  // namespace inr::cuda
