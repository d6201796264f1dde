#pragma once
// The fused kernels' entry points, for the host: each kernel's instantiations live in its own
// translation unit (FusedMlpKernel.cu, FusedMlpKernelHopper.cu), and the evaluator launches them
// through these pointers.
#include <cuda_runtime.h>

#include "Evaluator/Cuda/FusedMlpParams.cuh"

namespace inr::cuda {

using FusedKernel = void (*)(FusedParams, const float4*, int, const unsigned*, float*, const int*);
// The Hopper kernel (FusedMlpKernelHopper.cuh) for weight chunks of 64 or 128 output columns
// with one or two consumer warpgroups (64 queries per consumer and round, or with splitColumns
// two consumers on one 64-query tile; FusedMlpKernelHopper.cu, built for sm_90a when the CUDA
// architectures include 90); nullptr when not built. splitEncoding: the instantiation for a
// program with a split encoding (FusedParams::hopperSplitGemm). nullptr also for the forms not
// instantiated: split encoding with two consumers and 128-column chunks (they never fit it) or
// with the columns split, and one consumer with the columns split.
FusedKernel hopperKernel(int chunkColumns, int consumers, bool splitEncoding = false, bool splitColumns = false);
// The mma.sync kernel for tiles of `tile` queries (128, 64 or 32) and weight K-chunks of `kc`
// columns (64 or 32).
FusedKernel mmaSyncKernel(int tile, int kc);
// The same kernel with tangent rows (value + gradient in one pass; FusedMlpKernel.cu): a tile of
// `tile` rows holds tile / 4 queries, `out` is a float4 per query (value, d/dx, d/dy, d/dz in
// world units, FusedParams' tangent fields), no scatter.
FusedKernel mmaSyncTangentKernel(int tile, int kc);
// The instantiations behind them, per tangent rows and weight chunk (one translation unit each,
// FusedMlpKernel.cuh).
template <bool kTangents, int KC>
FusedKernel mmaSyncKernelFor(int tile);

}  // namespace inr::cuda
