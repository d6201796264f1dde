#pragma once
// One model being rendered with delta tracking on one backend: the session owns the evaluator,
// the macrocell grid and the renderer, CPU or CUDA, behind one interface. This is what the CLI
// and the ParaView mapper hold; they never name a backend's classes.
//
// Backend choice: Auto takes CUDA when this build has it and a usable GPU is present, else the
// CPU; Cuda without a usable GPU either throws or, with allowFallback, runs on the CPU and says so
// in description(). A GPU without room for the session (DeviceOutOfMemory while creating it) is
// treated alike: Auto and Cuda with allowFallback run on the CPU, saying so in description().
//
// Out of GPU memory later (Common/DeviceMemory.h): a CUDA session's setSettings to a larger image,
// setScene to a time whose macrocell slices are not built, and renderFrame needing larger buffers
// throw DeviceOutOfMemory naming the bytes, their purpose and what to lower, with the session as
// it was (settings, scene, image and accumulated frames); a camera move without room for
// reprojection's history restarts the image instead, with one warning.
//
// Several sessions of one model on one backend and device can share one evaluator (the network's
// weights uploaded and, on CUDA, the fused kernel autotuned once): pass one session's
// sharedEvaluator() as RenderSessionOptions::evaluator when creating another (the ParaView
// mapper's fine and coarse level-of-detail sessions do). Ownership is shared: the evaluator lives
// as long as the last session holding it.
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "Common/ImageIO.h"
#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/GridField.h"
#include "Render/MacrocellGrid.h"
#include "Render/QueryReduction.h"
#include "Render/RenderStats.h"
#include "Render/SceneInputs.h"
#include "Render/TraversalOptions.h"

// The CUDA runtime's array type (cudaArray_t is a pointer to it), declared here so that callers
// need no CUDA headers.
struct cudaArray;

namespace inr {

enum class RenderBackend { Auto, Cpu, Cuda };

// "auto", "cpu", "cuda" (case-insensitive); throws std::invalid_argument naming the choices.
RenderBackend parseRenderBackend(const std::string& name);
const char* renderBackendName(RenderBackend backend);

// Whether this build has the CUDA backend and a usable GPU is present; `reason` says why not.
bool cudaBackendAvailable(std::string* reason = nullptr);
// How many CUDA devices this process sees (0 without the CUDA backend, a driver or a device):
// one process per GPU picks RenderSessionOptions::cudaDevice = local rank modulo this.
int cudaDeviceCount();

// An evaluator as sessions hold it: shared ownership plus what it was built for (a session of
// another backend or CUDA device cannot run it). Empty = none.
struct SharedEvaluator {
  std::shared_ptr<const FieldEvaluator> evaluator;  // CpuInrEvaluator or CudaInrEvaluator
  RenderBackend backend = RenderBackend::Cpu;       // Cpu or Cuda
  int cudaDevice = 0;                               // its device (Cuda)
  explicit operator bool() const { return evaluator != nullptr; }
};

struct RenderSessionOptions {
  RenderBackend backend = RenderBackend::Auto;
  bool allowFallback = true;  // Cuda requested but unusable: run on the CPU instead of throwing
  MacrocellOptions macrocells;
  TrackingOptions tracking;
  int cpuThreads = 0;  // CPU evaluator threads (0 = OpenMP default)
  int cudaDevice = 0;
  // GPU traversal (DDA or OptiX GAS; auto decides, description() says what runs and why). The
  // CPU backend always runs the DDA.
  TraversalOptions traversal;
  // Progress of macrocell builds from the start (with !macrocells.lazySlices every slice is built
  // while the session is created); RenderSession::setProgressHandler replaces it later.
  MacrocellProgress progress;
  // Run this evaluator instead of building one (another session's sharedEvaluator(), built from
  // the same model). The session then runs on the evaluator's backend and device: create()
  // throws std::invalid_argument when `backend` (unless Auto) or, on CUDA, `cudaDevice` differ.
  // The CPU evaluator may be used from several threads at once (it keeps no state between
  // calls); a CUDA one from one thread at a time.
  SharedEvaluator evaluator;
};

struct MacrocellInfo {
  Int3 dims{};
  int temporalSlices = 0;
  int skipBlockCells = 0;      // the grid's MacrocellOptions, as it was built
  double boundsPadding = 0.0;
  int slicesBuilt = 0;
  double buildSeconds = 0.0;
  std::size_t latticeQueries = 0;
  unsigned long long refinements = 0;
  double sliceSeconds() const { return slicesBuilt ? buildSeconds / slicesBuilt : 0.0; }
};

class RenderSession {
public:
  static std::unique_ptr<RenderSession> create(const InrModel& model, const RenderSessionOptions& options);
  virtual ~RenderSession() = default;

  virtual RenderBackend backend() const = 0;  // what actually runs (Cpu or Cuda)
  virtual std::string description() const = 0;  // backend, evaluator, device; fallback reason
  virtual const FieldEvaluator& evaluator() const = 0;
  // The same evaluator with shared ownership, for RenderSessionOptions::evaluator of another
  // session of this model.
  virtual SharedEvaluator sharedEvaluator() const = 0;
  // The options this session was created with (backend as asked; backend() says what runs).
  virtual const RenderSessionOptions& options() const = 0;

  virtual void setSettings(const RenderSettings& settings) = 0;
  virtual void setScene(const RenderScene& scene) = 0;  // does only the work the changes need
  // Ray budgeting, reprojection and pruning (QueryReduction.h). Validates first: throws
  // std::invalid_argument naming the parameter and its range, leaving the old settings in place.
  // A change of the pruning thresholds restarts the accumulation (the estimator changes).
  virtual void setQueryReduction(const QueryReductionSettings& settings) = 0;
  virtual const QueryReductionSettings& queryReduction() const = 0;
  virtual FrameStats renderFrame() = 0;
  virtual FrameStats renderFrameNaive() = 0;  // baseline: network evaluated inside each ray's loop
  virtual FrameStats runGhostPasses(int count) = 0;
  // Macrocell refinement and ghost passes on update, work caps (TrackingOptions): validated
  // (std::invalid_argument naming the option, the old options kept); they apply from the next
  // frame or scene change, the accumulation is kept.
  virtual void setTrackingOptions(const TrackingOptions& options) = 0;
  virtual const TrackingOptions& trackingOptions() const = 0;
  virtual void resetAccumulation() = 0;
  // A flag another thread may raise to stop the frame in progress (WavefrontRenderer::
  // setStopRequest: the CPU's frames stop, unaccumulated; the GPU's run to their end).
  virtual void setStopRequest(const std::atomic<bool>* stop) = 0;
  virtual int accumulatedFrames() const = 0;
  virtual ImageRGBA image() const = 0;               // composited over the background
  virtual ImageRGBA premultipliedImage() const = 0;  // volume only
  // The CUDA backend's premultiplied image without a trip through host memory: copied device to
  // device into `target`, a CUDA array of the image's size with four 32-bit float channels (for
  // instance an OpenGL texture mapped through CUDA-OpenGL interop), in premultipliedImage()'s
  // layout (row 0 at the top); returns once the copy is done. False, with nothing copied, where
  // the image is not on a GPU (the CPU backend): read premultipliedImage() then.
  virtual bool copyPremultipliedImage(cudaArray* target) const {
    (void)target;
    return false;
  }
  virtual std::vector<float> residual() const = 0;
  virtual MacrocellInfo macrocellInfo() const = 0;
  // The working macrocell grid's per-cell means at `time` (the field averaged over each cell's
  // lattice samples) as a field that costs no query: a stand-in of the network for an approximate
  // image (the plugin's camera drags on the CPU). Null where the grid is not on the host (CUDA)
  // or the working grid is not at `time` (no scene at that time set since).
  virtual std::shared_ptr<const GridField> workingMeanField(double time) const {
    (void)time;
    return nullptr;
  }
  virtual const RendererCounters& counters() const = 0;  // scene-change work, capped rays, truncated frames
  // Where the renderer's once-per-cause warnings go (work caps hit); default: stderr.
  virtual void setWarningHandler(std::function<void(const std::string&)> handler) = 0;
  // Where progress of long engine work goes: macrocell slice builds, on the first setScene (the
  // slices the first time needs), on a time change that needs slices not built yet, and on every
  // build after creating a session with another macrocell grid (MacrocellProgress: a fraction in
  // [0, 1] and a short phase text, a few calls per slice). Default: none.
  virtual void setProgressHandler(MacrocellProgress handler) = 0;
  // Builds every temporal macrocell slice not built yet (reporting progress as above), so that
  // later time changes find their slices built: for a caller that has time to spare now (the
  // mapper's coarse interactive grid, built ahead during a still render).
  virtual void buildAllSlices() = 0;
  // Builds the macrocell slices a later setScene at `time` needs (reporting progress as above),
  // and nothing else: the scene, the accumulation and the working grid are kept. For a caller
  // that must not be interrupted by progress later (the ParaView mapper, outside its GL render).
  virtual void buildSlicesFor(double time) = 0;
};

}  // namespace inr
