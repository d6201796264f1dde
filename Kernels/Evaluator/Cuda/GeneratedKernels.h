#pragma once
// The fused mma.sync kernels generated for one model (Evaluator/MlpKernelSource.h: the program as
// compile-time constants), compiled at model load by NVRTC for the present GPU (a cubin per
// kernel, compiled in parallel), kept in a disk cache keyed by a hash of the kernel's source, the
// embedded device headers, the GPU architecture, NVRTC's version and the options, loaded with
// cudaLibraryLoadData. The evaluator's autotuner takes them as candidates beside the
// interpreter's (FusedConfig::generated). Where NVRTC fails (a missing header, a compiler error)
// nothing is thrown: report() says why, with the first lines of NVRTC's log, and the evaluator
// runs the built-in kernels.
#include <memory>
#include <string>
#include <vector>

#include "Evaluator/Cuda/FusedMlpKernels.h"
#include "Evaluator/MlpProgram.h"

namespace inr::cuda {

// The cache folder when none is given: INR_KERNEL_CACHE_DIR, else $XDG_CACHE_HOME/inr-volume/kernels,
// else $HOME/.cache/inr-volume/kernels; empty (no disk cache) when none of them is set.
std::string defaultKernelCacheDir();

class GeneratedKernels {
public:
  // Every tile of `tiles` (128, 64, 32) and weight chunk of `chunks` (64, 32), values and tangent
  // rows, of `program` and, where it fuses a Fourier encoding, of its stored form, for compute
  // capability major.minor. cacheDir: "" = defaultKernelCacheDir(), "none" = no disk cache.
  GeneratedKernels(const MlpProgram& program, int major, int minor, const std::string& cacheDir,
                   const std::vector<int>& tiles = {128, 64, 32}, const std::vector<int>& chunks = {64, 32});
  ~GeneratedKernels();
  GeneratedKernels(const GeneratedKernels&) = delete;
  GeneratedKernels& operator=(const GeneratedKernels&) = delete;

  bool available() const { return available_; }
  // "N kernels for sm_90: compiled by NVRTC 13.0 in 2.1 s (k cached)" or why there are none.
  const std::string& report() const { return report_; }
  // The kernel for a configuration (storedEncoding: the program's stored form), nullptr where
  // none was built.
  FusedKernel kernel(int tile, int kc, bool storedEncoding, bool tangents) const;

private:
  struct Loaded;
  std::vector<std::unique_ptr<Loaded>> loaded_;
  bool available_ = false;
  std::string report_;
};

}  // namespace inr::cuda
