#pragma once
// Which fused-kernel configuration runs a model's launches. The candidates are every mma.sync
// configuration (tile x weight chunk, a Fourier encoding fused into the GEMM or stored in a
// buffer) whose shared memory fits the device, then on Hopper every wgmma configuration (chunk
// width, as many ring slots as fit, two consumers with and without ping-pong turns and on one
// tile with its columns split, one consumer; a Fourier encoding fused, stored or stored split,
// where it fits). Each is timed on the same
// random queries in the model's domain, on a large batch (throughput) and on a small one
// (latency: the pipeline's late traverse-evaluate iterations hold a few thousand queries, where a
// 128-query tile leaves most SMs idle); the fastest of each runs launches of its size.
#include <cuda_runtime.h>

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "Common/Cuda/CudaDevice.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/Cuda/GeneratedKernels.h"
#include "Model/InrModel.h"

namespace inr::cuda {

struct FusedConfig {
  bool wgmma = false;  // the Hopper kernel (`tile` queries per round: consumers x 64, or 64 with splitColumns)
  int tile = 0, kc = 0;  // kc: mma.sync's weight K-chunk; wgmma: output columns per weight chunk
  int stages = 0;         // wgmma: weight ring slots
  bool pingPong = false;  // wgmma: the consumers take turns issuing a chunk's MMAs
  // A fused Fourier encoding in the program: run it as a stored buffer instead (the unfused
  // program, on either kernel: the encoding computed once per tile by a row instruction, where
  // the fused form computes it in the GEMM's operand load, for every weight chunk on the wgmma
  // kernel; faster where its buffer fits; figures: Benchmarks/RESULTS.md, "Warp-specialised
  // Hopper kernel" and "Hopper kernel in column chunks").
  bool storedEncoding = false;
  // wgmma with storedEncoding: the encoding split for its GEMM (FusedParams::hopperSplitGemm).
  bool splitEncoding = false;
  std::size_t sharedBytes = 0;
  int gridBlocks = 0;  // resident blocks per SM x SMs (the persistent grid)
  double measuredQps = 0.0;
  // A program with a hash grid: its gathers with a pair of lanes per row and level (splitting
  // the corners) or one lane (FusedParams::hashGridPairs); the same bits either way. -1: no grid.
  int hashGridPairs = -1;
  // The mma.sync kernel with tangent rows (value + gradient; a tile of `tile` rows holds tile / 4
  // queries).
  bool tangents = false;
  int consumers = 2;  // wgmma: consumer warpgroups per block (tile = 64 x consumers, or 64 with splitColumns)
  bool splitColumns = false;  // wgmma, two consumers: both on one tile, splitting its column chunks
  // mma.sync: the kernel generated for this model (GeneratedKernels.h) instead of the interpreter.
  bool generated = false;
};

// Whether two configurations launch the same kernel the same way (measuredQps aside).
bool sameConfig(const FusedConfig& a, const FusedConfig& b);

// "tile 128 x K 64" (mma.sync) or "wgmma 2x64 x N 128, 2 slots, ping-pong" (1x64: one consumer), with ", hash lane
// pairs" or ", hash lane per row" for a program with a hash grid.
std::string configName(const FusedConfig& config);

class FusedLaunchAutotuner {
public:
  // Launches under this many queries run the small-batch choice.
  static constexpr int kSmallBatchThreshold = 1 << 15;
  // The small batch the candidates are timed on, in runs of this many launches.
  static constexpr int kSmallBatch = 1 << 13;
  static constexpr int kSmallBatchLaunches = 10;

  // Runs `config` on n points into out (device memory), on the default stream.
  using Launch = std::function<void(const FusedConfig& config, const float4* points, int n, float* out)>;

  FusedLaunchAutotuner(const CudaDeviceInfo& device, const CudaEvaluatorOptions& options);

  // The configurations options allow whose shared memory fits, in the order that runs without
  // timing: mma.sync first (the stored encoding before the fused one: the kernel of earlier
  // versions), then wgmma when `wgmmaRuns` (the fused encoding, then stored, then stored split); each twice for a program with a hash grid (lane pairs
  // first, then a lane per row). `params`: the program as compiled; `storedParams`:
  // the same with any Fourier encoding stored; `splitParams`: stored with one split for the
  // wgmma kernel (hopperSplitGemm -1: none). Sets each kernel's dynamic shared-memory limit.
  // `generated`: the kernels generated for the model (null: none), each mma.sync configuration's
  // after all the interpreter's (CudaEvaluatorOptions::generatedKernels Only: those alone).
  std::vector<FusedConfig> candidates(const FusedParams& params, const FusedParams& storedParams,
                                      const FusedParams& splitParams, bool wgmmaRuns,
                                      const GeneratedKernels* generated = nullptr) const;

  // The value + gradient configurations: each mma.sync candidate as the kernel with tangent rows
  // (the same shared memory; its own register count, so its own resident blocks), its dynamic
  // shared-memory limit set; once per tile, chunk and encoding (a hash grid's two gather lane
  // arrangements are one for the tangent rows). Empty when no candidate is mma.sync (wgmma
  // requested).
  std::vector<FusedConfig> tangentCandidates(const std::vector<FusedConfig>& candidates,
                                             const GeneratedKernels* generated = nullptr) const;

  struct Choice {
    FusedConfig large;  // launches of kSmallBatchThreshold queries or more
    FusedConfig small;  // smaller launches
    std::string report;  // what launchReport() says
    // The fastest of the interpreter's mma.sync candidates, large and small (whose generated
    // twins may beat the winners); hasMmaSync false where there was none.
    FusedConfig mmaSyncLarge, mmaSyncSmall;
    bool hasMmaSync = false;
  };
  // Times every candidate (best of 3 after a warm-up, CUDA events) on largeBatch (-1:
  // options.autotuneBatch) and on min(largeBatch, kSmallBatch) random queries in `domain`
  // (kSmallBatchLaunches in a row per timing) and keeps the fastest of each; with one candidate
  // or a large batch of 0 the first runs every launch.
  Choice choose(const std::vector<FusedConfig>& candidates, const Domain& domain, const Launch& launch,
                int largeBatch = -1) const;
  // options.autotuneBatch: the large batch choose() times on by default (0: no timing).
  int candidatesBatch() const { return options_.autotuneBatch; }

private:
  CudaDeviceInfo device_;
  CudaEvaluatorOptions options_;
};

}  // namespace inr::cuda
