#pragma once
// The fused mma.sync kernels generated for one model (Evaluator/MlpKernelSource.h: the program as
// compile-time constants), compiled by NVRTC for the present GPU (a cubin per kernel, compiled in
// parallel), kept in a disk cache keyed by a hash of the kernel's source, the embedded device
// headers, the GPU architecture, NVRTC's version and the options, loaded with
// cudaLibraryLoadData. The evaluator's autotuner takes them as candidates beside the
// interpreter's (FusedConfig::generated). Where NVRTC fails (a missing header, a compiler error)
// nothing is thrown: report() says why, with the first lines of NVRTC's log, and the evaluator
// runs the built-in kernels.
//
// Two ways to build them: at once (the constructor: every tile x chunk asked for, the caller
// waits for NVRTC), or in the background (startInBackground: the kernels of a few chosen
// configurations compiled on the process's compile threads while the caller goes on with the
// built-in kernels; the evaluator loads and times them when they are ready).
#include <memory>
#include <string>
#include <vector>

#include "Evaluator/Cuda/FusedMlpKernels.h"
#include "Evaluator/MlpProgram.h"

namespace inr::cuda {

// The cache folder when none is given: INR_KERNEL_CACHE_DIR, else $XDG_CACHE_HOME/inr-volume/kernels,
// else $HOME/.cache/inr-volume/kernels; empty (no disk cache) when none of them is set.
std::string defaultKernelCacheDir();

// How many threads compile in the background, for the whole process: the environment variable
// INR_COMPILE_THREADS (1..64), else half the hardware threads (at least 1, at most 8), so a
// compilation leaves the rest of the machine to the renderer and the user interface.
int backgroundCompileThreads();

// A launch configuration whose generated kernels are wanted: values and tangent rows of the
// program (storedEncoding false) or of its stored-encoding form.
struct GeneratedKernelConfig {
  int tile = 128;
  int kc = 64;
  bool storedEncoding = false;
};

class GeneratedKernels {
public:
  // Every tile of `tiles` (128, 64, 32) and weight chunk of `chunks` (64, 32), values and tangent
  // rows, of `program` and, where it fuses a Fourier encoding, of its stored form, for compute
  // capability major.minor; compiled before the constructor returns. cacheDir: "" =
  // defaultKernelCacheDir(), "none" = no disk cache.
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

  struct Job;    // one kernel: its source, name, cache file and image (GeneratedKernels.cu)
  struct Batch;  // the jobs of one model compiled in the background
  // A background compilation: its kernels compile on the process's compile threads
  // (backgroundCompileThreads); nothing touches the GPU until take(). Destroying it drops the
  // kernels not yet begun and does not wait for the ones compiling (their cubins still reach the
  // disk cache).
  class Pending {
  public:
    Pending(std::shared_ptr<Batch> batch, std::string what);
    ~Pending();
    Pending(const Pending&) = delete;
    Pending& operator=(const Pending&) = delete;
    // Every kernel compiled (or failed): take() will not wait.
    bool ready() const;
    void wait() const;
    // The kernels loaded on the calling thread's current device (waits for them first); seconds
    // since the start, for the report. Call once.
    std::unique_ptr<GeneratedKernels> take();
    // "4 kernels for sm_90 compiling in the background on 8 threads (1 from the cache)".
    const std::string& what() const { return what_; }

  private:
    std::shared_ptr<Batch> batch_;
    std::string what_;
  };
  // The values and tangent-row kernels of `configs` (duplicates taken once). Those in the disk
  // cache are read now; the rest start compiling. Null where the program cannot be generated
  // (`why` says so).
  static std::unique_ptr<Pending> startInBackground(const MlpProgram& program, int major, int minor,
                                                    const std::string& cacheDir,
                                                    const std::vector<GeneratedKernelConfig>& configs, std::string& why);

private:
  GeneratedKernels() = default;
  // Loads the compiled jobs (the report counts `seconds` since the start and the cache hits).
  void load(std::vector<Job>& jobs, const std::string& arch, const std::string& cacheDir, double seconds,
            const char* how);

  struct Loaded;
  std::vector<std::unique_ptr<Loaded>> loaded_;
  bool available_ = false;
  std::string report_;
};

}  // namespace inr::cuda
