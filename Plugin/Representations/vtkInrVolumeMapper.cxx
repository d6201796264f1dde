#include "vtkInrVolumeMapper.h"

#include "vtkActor.h"
#include "vtkActor2D.h"
#include "vtkCallbackCommand.h"
#include "vtkDataSet.h"
#include "vtkDualDepthPeelingPass.h"
#include "vtkMath.h"
#include "vtkWeakPointer.h"
#include "vtkFieldData.h"
#include "vtkInformation.h"
#include "vtkInformationObjectBaseVectorKey.h"
#include "vtkObjectFactory.h"
#include "vtkOpenGLRenderPass.h"
#include "vtkOpenGLRenderWindow.h"
#include "vtkPropCollection.h"
#include "vtkRenderer.h"
#include "vtkUnsignedCharArray.h"
#include "vtkVolume.h"
#include "vtk_glew.h"

#include "InrEngineSlots.h"
#include "InrFramebufferCompositor.h"
#include "InrParallelRendering.h"
#include "InrSceneTranslator.h"

#include "Backends/Refinement.h"
#include "Backends/RenderSession.h"
#include "Model/InrModel.h"
#include "Render/MacrocellLayout.h"
#include "Render/QueryReduction.h"
#include "Render/SceneChange.h"
#include "Render/SceneInputs.h"
#include "Render/WavefrontRenderer.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

namespace
{
std::uint64_t hashBytes(const unsigned char* p, std::size_t n)
{
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a
  for (std::size_t i = 0; i < n; ++i)
  {
    h = (h ^ p[i]) * 1099511628211ull;
  }
  return h ^ n;
}

// The renderer's tile in the window (the image the engine renders).
struct Viewport
{
  int width = 0, height = 0, x0 = 0, y0 = 0;
};

// True while VTK's dual depth peeling renders the volume inside its peels (translucent geometry
// with UseDepthPeelingForVolumes): the pass registers itself in the props' keys.
bool insideDepthPeeling(vtkVolume* vol)
{
  vtkInformation* keys = vol->GetPropertyKeys();
  if (!keys || !keys->Has(vtkOpenGLRenderPass::RenderPasses()))
  {
    return false;
  }
  for (int i = 0; i < keys->Length(vtkOpenGLRenderPass::RenderPasses()); ++i)
  {
    if (vtkDualDepthPeelingPass::SafeDownCast(keys->Get(vtkOpenGLRenderPass::RenderPasses(), i)))
    {
      return true;
    }
  }
  return false;
}

bool debugReport()
{
  return std::getenv("INR_VOLUME_DEBUG") != nullptr;
}

// Whether the renderer draws anything that can write depth before its volumes: a visible prop
// with data (ParaView keeps empty actors visible, e.g. the selection's) that is neither a volume
// nor a 2D overlay (those are drawn after the volumes).
bool geometryDrawnBeforeVolumes(vtkRenderer* ren)
{
  vtkPropCollection* props = ren->GetViewProps();
  vtkCollectionSimpleIterator it;
  props->InitTraversal(it);
  while (vtkProp* prop = props->GetNextProp(it))
  {
    if (!prop->GetVisibility() || vtkVolume::SafeDownCast(prop) || vtkActor2D::SafeDownCast(prop))
    {
      continue;
    }
    const double* bounds = prop->GetBounds();
    if (!bounds || vtkMath::AreBoundsInitialized(bounds))
    {
      return true;  // no bounds (e.g. a widget): assume it draws
    }
  }
  return false;
}

bool lodReport()
{
  const char* v = std::getenv("INR_VOLUME_LOD_LOG");
  return v && v[0] && std::string(v) != "0";
}

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Level of detail: the linear scale of the reduced image is a multiple of 1/kScaleSteps (so small
// cost fluctuations do not change the resolution, which would restart the accumulation and lose
// the reprojected history during a drag), never below kMinScale (bounded blur).
constexpr int kScaleSteps = 16;
constexpr double kMinScale = 1.0 / kScaleSteps;
// Re-choose the scale only when the measured render time leaves this band around the budget, and
// grow it by at most this factor at a time.
constexpr double kKeepScaleAbove = 0.5, kKeepScaleBelow = 1.0;
constexpr double kMaxGrowth = 1.25;
// Aim below the budget: per-frame cost varies with the view (coverage, collisions).
constexpr double kBudgetMargin = 0.8;
// The level of detail is judged on the engine's time (the part that scales with the image's
// pixels). The rest of the window's frame (depth read, upload, drawing the image over the whole
// viewport, the view's own passes, swap: on a software OpenGL 40-110 ms at ~1280x768, varying
// with the machine's load, whatever the image's resolution) is measured and left to the engine's
// budget, but at most this share of the budget: counted in full it drove the scale to its minimum
// (a 1/16 mosaic with a 2 ms engine) although no resolution could make it cheaper.
constexpr double kMaxFixedShare = 0.5;

// The depth limits (engine row order) of a width x height image, sampled at the centres of the
// pixels of a w x h image covering the same view.
std::vector<float> resampleDepthLimit(
  const std::vector<float>& full, int width, int height, int w, int h)
{
  if (full.empty())
  {
    return {};
  }
  std::vector<float> out(std::size_t(w) * std::size_t(h));
  for (int j = 0; j < h; ++j)
  {
    const int sj = std::min(height - 1, int((j + 0.5) * height / h));
    for (int i = 0; i < w; ++i)
    {
      const int si = std::min(width - 1, int((i + 0.5) * width / w));
      out[std::size_t(j) * w + i] = full[std::size_t(sj) * width + si];
    }
  }
  return out;
}

// For the refusal messages of CheckOptions.
std::ostream& operator<<(std::ostream& os, inr::PrimaryEstimator e)
{
  return os << inr::primaryEstimatorName(e) << " (" << static_cast<int>(e) << ")";
}

// Macrocell builds (inside the engine's setScene or buildAllSlices during Render) become VTK
// progress, `prefix` + the engine's phase as ProgressText: the representation forwards it to
// ParaView's progress bar.
//
// A view that prepares each render (vtkInrVolumeMapper::PrepareRender: ParaView's representation)
// gets the builds done there, before the GL render; a build that still happens inside the GL
// render reports nothing then (`*muted`): a GUI handles a progress event by repainting its
// progress bar at once, and Qt composes the window with another OpenGL context and repaints the
// view widget in the middle of VTK's render (the GL state VTK caches is then wrong: "Error in
// cache state" warnings, GL errors, a blank view).
inr::MacrocellProgress progressHandler(
  vtkInrVolumeMapper* self, const std::string& prefix, const bool* muted)
{
  return [self, prefix, muted](double fraction, const std::string& phase)
  {
    if (muted && *muted)
    {
      return;
    }
    self->SetProgressText((prefix + phase).c_str());
    self->UpdateProgress(fraction);
    self->SetProgressText(nullptr);  // observers read it during the event; later events (the
                                     // executive's own) are not the build's
  };
}

}

struct vtkInrVolumeMapper::Internals
{
  // Model identity (bytes array pointer / mtime, then content hash).
  vtkUnsignedCharArray* bytesPtr = nullptr;
  vtkMTimeType bytesMTime = 0;
  std::uint64_t hash = 0;
  bool modelOk = false;
  std::uint64_t reportedBadHash = 0;
  inr::InrModel model;

  // The engine session: evaluator + macrocells + renderer on the chosen backend.
  InrEngineSlot fine;
  int engineBuilds = 0;
  std::string backendInUse = "none (no model rendered yet)";
  bool warnedCuda = false;
  // Query reduction: what the user asked for and what the engine shown last holds.
  inr::QueryReductionSettings queryReduction;
  std::string queryReductionInUse;
  bool haveRefusedQueryReduction = false;  // the last set the engine refused (reported once,
  inr::QueryReductionSettings refusedQueryReduction;  // not again by a rebuilt session)

  // Macrocell and tracking options: as asked (the setters), the last valid values (what the engine
  // is built or updated with; initially the engine's defaults) and the last value refused per
  // option (each refusal is reported once).
  inr::MacrocellOptions macrocellsAsked, macrocellsValid, macrocellsRefused;
  // The estimator starts as inr render's (TrackingOptions::recommended()); the XML declares the
  // same defaults (test cli.estimator_xml_defaults).
  inr::TrackingOptions trackingAsked = inr::TrackingOptions::recommended();
  inr::TrackingOptions trackingValid = trackingAsked, trackingRefused = trackingAsked;
  std::string macrocellsInUse;
  std::string estimateText, refinementState;  // GetConvergenceEstimateText, GetRefinementState

  // Interactive frames caused by a time change render with a second session on a coarse
  // majorant grid (InteractiveMacrocellResolution): its slices build about 50x faster than the
  // fine grid's, so the first visit of a time stays interactive; the fine session builds its
  // slices in the still render that follows. Built with the fine session's other options,
  // lazily or ahead (InteractiveMacrocellsAhead).
  InrEngineSlot coarse;
  bool coarseFailed = false;  // creation failed once for coarse.built: reported, not retried
  bool shownCoarse = false;     // the last Render drew the coarse session's image
  bool uploadedCoarse = false;  // the uploaded texture came from the coarse session
  bool UpdateCoarseEngine(vtkInrVolumeMapper* self);
  // Whether a reduced interactive frame renders on the coarse session: a time change (its fine
  // slices may not be built yet), or a camera drag with Reproject on (the fine session's image
  // stays at full resolution, so the still render after the drag reprojects it instead of
  // restarting: a different resolution would restart the accumulation).
  bool RendersCoarse(vtkInrVolumeMapper* self, bool interactive, bool timeChange)
  {
    return interactive && (timeChange || this->queryReduction.reproject) &&
      this->UpdateCoarseEngine(self);
  }
  void BuildCoarseAhead(vtkInrVolumeMapper* self);
  inr::RenderSession* Shown() const
  {
    return this->shownCoarse && this->coarse.session ? this->coarse.session.get()
                                                     : this->fine.session.get();
  }

  // The fine session's macrocell slices for a new time, built on a worker thread in the GUI
  // (PrepareRender: CPU backend, one rank, FramesPerRender 1, not capturing) while renders draw
  // reduced frames of the coarse session, so the event loop never waits seconds for them. While
  // fineBusy nothing touches the fine session but the worker; JoinFineBuild waits for it.
  std::thread fineBuilder;
  bool fineBusy = false;
  std::atomic<bool> fineBuildDone{ false };
  std::atomic<double> fineBuildProgress{ 0.0 };
  void JoinFineBuild(vtkInrVolumeMapper* self);
  bool StartFineBuild(vtkInrVolumeMapper* self, double time);

  // Renders prepared outside the GL render (PrepareRender): once a view does that, progress is
  // reported only there (quietRenders), never from inside Render (insideRender).
  bool quietRenders = false;
  bool insideRender = false;
  bool muteProgress = false;  // quietRenders && insideRender: read by the progress handlers
  void SetInsideRender(bool inside)
  {
    this->insideRender = inside;
    this->muteProgress = this->quietRenders && inside;
  }

  // VTK -> engine (transfer-function cache), progressive refinement, drawing.
  InrSceneTranslator translator;
  std::vector<float> depth;
  inr::RefinementDriver::Step lastStep;
  InrFramebufferCompositor compositor;

  // Level of detail: the current scale, the measured cost of recent frames (exponential moving
  // averages; 0 = not measured yet), what the last render did.
  double lodScale = 1.0;
  double msPerPixelFrame = 0.0;  // engine time per pixel per frame, without macrocell updates
  double overheadMs = 0.0;       // the rest of a render: depth read, scene, upload, blend
  double interactiveMs = 0.0;    // engine time of interactive frames at lodScale (no macrocell
                                 // update: it depends on the time change, not on the scale)
  double lodCeiling = 2.0;       // smallest scale found too slow in this interaction
  int framesAtScale = 0;         // interactive frames measured at lodScale
  // The budget is for the whole window render: what the window spends outside this mapper
  // (other props, clear, swap; ParaView's view) is measured by observing the window's render.
  double outsideMs = 0.0;
  vtkWeakPointer<vtkRenderWindow> observedWindow;
  vtkNew<vtkCallbackCommand> windowObserver;
  Clock::time_point windowStart;
  double aheadMs = 0.0;  // of this window render, spent building coarse slices ahead (not a cost
                         // of the window's frames: left out of outsideMs)
  bool renderedInWindow = false;
  void ObserveWindow(vtkRenderWindow* window);
  void StopObserving();
  static void OnWindowEvent(vtkObject*, unsigned long event, void* clientData, void*);
  bool lastInteractive = false;
  bool haveLastTime = false;
  double lastTime = 0.0;
  int imageWidth = 0, imageHeight = 0;
  double lastRenderMs = 0.0;
  int interactiveFrames = 0;

  // For the INR_VOLUME_DEBUG report of what changed.
  bool haveLastScene = false;
  inr::RenderScene lastScene;

  // Tiled rendering: where this render's image lies in the full picture (whole: fullWidth 0).
  inr::ImageWindow window;
  // Sub-domain rendering under MPI (InrParallelRendering.h): this rank's place, the refinement
  // state reduced over all ranks after each render (what the getters report with several ranks).
  InrParallelRendering::Ranks ranks = InrParallelRendering::GlobalRanks();
  InrParallelRendering::Refinement reduced;
  std::string rankInUse;  // appended to the backend description
  int localRank = -1;     // this rank's index on its node (-1: unknown), and where it came from
  std::string localRankSource;
  int cudaDevices = 0;    // CUDA devices this process sees
  bool haveDevice = false;
  std::string engineOptionsText, interactiveOptionsText;  // GetEngineOptionsInUse and co.
  std::string ranksInUse;  // one line per rank after each render (several ranks only)
  // With several ranks: this rank's pixel share (image-space split).
  void RankSettings(inr::RenderSettings& settings) const;
  // Reduces the refinement state over the ranks (ReduceRefinement) once per Render, on every exit
  // path: every rank must take part in the collective or the others wait forever.
  void ReduceOverRanks(vtkInrVolumeMapper* self, bool rendered);
  // Once-per-mapper warnings: translucent geometry in the renderer, camera features ignored.
  bool warnedTranslucent = false, warnedPeeling = false;
  int uploadedEpoch = -1;  // the session's resets + reprojections when the image was uploaded
  std::string warnedCamera;
  void WarnAboutScene(vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, int width, int height);

  bool UpdateModel(vtkInrVolumeMapper* self, vtkUnsignedCharArray* bytes);
  void CheckOptions(vtkInrVolumeMapper* self);
  InrEngineRequest Request(vtkInrVolumeMapper* self);
  bool UpdateEngine(vtkInrVolumeMapper* self);
  inr::RenderScene TranslateScene(vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol,
    vtkDataSet* input, const Viewport& tile);
  void PushQueryReduction(vtkInrVolumeMapper* self, InrEngineSlot& slot);
  bool InteractiveRender(vtkInrVolumeMapper* self, vtkRenderer* ren, const inr::RenderScene& scene,
    double* budgetMs, bool* timeChange) const;
  double ChooseScale(double budgetMs, int width, int height);
  void MeasureFrame(double renderMs, double refineMs, int width, int height, bool interactive);
  bool Refine(vtkInrVolumeMapper* self, const inr::RenderScene& scene, int width, int height,
    bool interactive = false, bool useCoarse = false, int interactiveFrames = 1);
  void Composite(vtkInrVolumeMapper* self, vtkRenderer* ren, int width, int height);
};

vtkStandardNewMacro(vtkInrVolumeMapper);

vtkInrVolumeMapper::vtkInrVolumeMapper()
  : Internal(new Internals)
{
}

vtkInrVolumeMapper::~vtkInrVolumeMapper()
{
  this->Internal->JoinFineBuild(this);
  this->Internal->StopObserving();
  delete this->Internal;
}

int vtkInrVolumeMapper::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

void vtkInrVolumeMapper::ResetAccumulation()
{
  this->Internal->JoinFineBuild(this);
  for (InrEngineSlot* slot : { &this->Internal->fine, &this->Internal->coarse })
  {
    if (slot->session)
    {
      slot->session->resetAccumulation();
    }
    slot->refinement.restart();
  }
}

int vtkInrVolumeMapper::GetAccumulatedFrames()
{
  if (this->Internal->ranks.count > 1)
  {
    return this->Internal->reduced.frames;  // the fewest of all ranks
  }
  const inr::RenderSession* shown = this->Internal->Shown();
  return shown ? shown->accumulatedFrames() : 0;
}

int vtkInrVolumeMapper::GetConverged()
{
  if (this->Internal->ranks.count > 1)
  {
    return this->Internal->reduced.converged;  // every rank has converged
  }
  return this->GetLocalConverged();
}

int vtkInrVolumeMapper::GetLocalConverged()
{
  // Without progressive refinement nothing renders again by itself: "stopped" from the start.
  // A reduced interactive image is never the final one: a still render must follow.
  return !this->ProgressiveRefinement ||
      (!this->Internal->lastInteractive && this->Internal->fine.refinement.converged())
    ? 1
    : 0;
}

int vtkInrVolumeMapper::GetLastRenderInteractive()
{
  return this->Internal->lastInteractive ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastImageWidth()
{
  return this->Internal->imageWidth;
}

int vtkInrVolumeMapper::GetLastImageHeight()
{
  return this->Internal->imageHeight;
}

double vtkInrVolumeMapper::GetLastRenderMilliseconds()
{
  return this->Internal->lastRenderMs;
}

double vtkInrVolumeMapper::GetConvergenceEstimate()
{
  if (this->Internal->ranks.count > 1)
  {
    return this->Internal->reduced.estimate;  // the lowest of all ranks
  }
  return this->Internal->fine.refinement.estimate();
}

std::string vtkInrVolumeMapper::FormatConvergenceEstimate(double db)
{
  if (std::isnan(db) || db == -std::numeric_limits<double>::infinity())
  {
    return "\u2014";  // not known yet: a covered pixel has a single sample
  }
  if (db == std::numeric_limits<double>::infinity())
  {
    return "no noise left";  // no covered pixel, or no variance
  }
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f dB", db);
  return text;
}

const char* vtkInrVolumeMapper::GetConvergenceEstimateText()
{
  this->Internal->estimateText = FormatConvergenceEstimate(this->GetConvergenceEstimate());
  return this->Internal->estimateText.c_str();
}

const char* vtkInrVolumeMapper::GetRefinementState()
{
  Internals& I = *this->Internal;
  std::ostringstream s;
  const int frames = this->GetAccumulatedFrames();
  const double estimate = this->GetConvergenceEstimate();
  if (!I.fine.session || frames == 0)
  {
    s << "\u2014 (nothing rendered yet)";
  }
  else if (I.lastInteractive)
  {
    s << "interacting: reduced " << I.imageWidth << "x" << I.imageHeight << " image";
  }
  else if (!this->ProgressiveRefinement)
  {
    s << "one frame per render (Progressive Refinement off)";
  }
  else if (this->GetConverged())
  {
    if (this->ConvergenceTarget > 0.0 && estimate >= this->ConvergenceTarget)
    {
      s << "converged: " << frames << " frames, " << FormatConvergenceEstimate(estimate);
    }
    else
    {
      s << "stopped at " << frames << " frames (Maximum Frames " << this->MaximumFrames << ")";
      if (std::isfinite(estimate))
      {
        s << ", " << FormatConvergenceEstimate(estimate);
      }
    }
  }
  else
  {
    s << "refining: " << frames << " frames";
    if (std::isfinite(estimate))
    {
      s << ", " << FormatConvergenceEstimate(estimate);
      if (this->ConvergenceTarget > 0.0)
      {
        char target[32];
        std::snprintf(target, sizeof(target), " of %.0f dB", this->ConvergenceTarget);
        s << target;
      }
    }
  }
  I.refinementState = s.str();
  return I.refinementState.c_str();
}

const char* vtkInrVolumeMapper::GetBackendInUse()
{
  return this->Internal->backendInUse.c_str();
}

double* vtkInrVolumeMapper::GetBounds()
{
  vtkDataSet* input = this->GetInput();
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  vtkDataArray* domain = fd ? fd->GetArray("InrDomainBounds") : nullptr;
  if (domain && domain->GetNumberOfValues() == 6)
  {
    for (int k = 0; k < 6; ++k)
    {
      this->Bounds[k] = domain->GetTuple1(k);
    }
    return this->Bounds;
  }
  return this->Superclass::GetBounds();
}

const char* vtkInrVolumeMapper::GetRanksInUse()
{
  return this->Internal->ranksInUse.c_str();
}

double vtkInrVolumeMapper::GetLastUpdateMilliseconds()
{
  return this->Internal->lastStep.total.updateMs;
}

int vtkInrVolumeMapper::GetSlicesBuilt()
{
  this->Internal->JoinFineBuild(this);
  const auto& fine = this->Internal->fine.session;
  return fine ? fine->macrocellInfo().slicesBuilt : 0;
}

int vtkInrVolumeMapper::GetInteractiveSlicesBuilt()
{
  const auto& coarse = this->Internal->coarse.session;
  return coarse ? coarse->macrocellInfo().slicesBuilt : 0;
}

const char* vtkInrVolumeMapper::GetEngineOptionsInUse()
{
  this->Internal->JoinFineBuild(this);
  const auto& fine = this->Internal->fine.session;
  this->Internal->engineOptionsText = fine ? InrDescribeSession(*fine) : "";
  return this->Internal->engineOptionsText.c_str();
}

const char* vtkInrVolumeMapper::GetInteractiveEngineOptionsInUse()
{
  const auto& coarse = this->Internal->coarse.session;
  this->Internal->interactiveOptionsText = coarse ? InrDescribeSession(*coarse) : "";
  return this->Internal->interactiveOptionsText.c_str();
}

int vtkInrVolumeMapper::GetInteractiveSharesEvaluator()
{
  const auto& fine = this->Internal->fine.session;
  const auto& coarse = this->Internal->coarse.session;
  return fine && coarse && &fine->evaluator() == &coarse->evaluator() ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderCoarse()
{
  return this->Internal->shownCoarse ? 1 : 0;
}

// A time-change frame starts its image afresh (one frame of a thin medium is sparse speckle):
// up to `fresh` frames at a scale that keeps pixels x frames at most what one frame at `scale`
// costs, so the scale controller's measurement (taken as the render time of one frame at its
// scale) still holds. The scale is a step of 1/kScaleSteps, never below kMinScale.
double vtkInrVolumeMapper::InteractiveFreshFrameScale(double scale, int fresh)
{
  if (fresh <= 1)
  {
    return scale;
  }
  const double s = std::max(kMinScale,
    std::floor(scale / std::sqrt(double(fresh)) * kScaleSteps + 1e-9) / kScaleSteps);
  return std::floor(scale * scale / (s * s) + 1e-9) >= 2.0 ? s : scale;
}

int vtkInrVolumeMapper::InteractiveFreshFrameCount(double scale, int fresh)
{
  const double s = InteractiveFreshFrameScale(scale, fresh);
  return s == scale ? 1 : std::clamp(int(std::floor(scale * scale / (s * s) + 1e-9)), 1, fresh);
}

int vtkInrVolumeMapper::GetEngineBuilds()
{
  return this->Internal->engineBuilds;
}

double vtkInrVolumeMapper::GetLastQueries()
{
  return double(this->Internal->lastStep.total.totalQueries());
}

double vtkInrVolumeMapper::GetLastRays()
{
  return double(this->Internal->lastStep.total.rays);
}

double vtkInrVolumeMapper::GetLastBudgetSkipped()
{
  return double(this->Internal->lastStep.total.budgetSkipped);
}

double vtkInrVolumeMapper::GetLastPruned()
{
  return double(this->Internal->lastStep.total.pruned);
}

// Options kept in Internals as asked: query reduction (validated when pushed into the engine, so
// the error names the engine's parameter and range) and macrocell / tracking options (checked
// when the engine is updated, naming the property). Modified() makes ParaView render again.
#define INR_STORED_OPTION(Name, Type, member, toField, fromField)                                  \
  void vtkInrVolumeMapper::Set##Name(Type v)                                                      \
  {                                                                                                \
    if (this->Get##Name() != v)                                                                    \
    {                                                                                              \
      this->Internal->member = toField;                                                            \
      this->Modified();                                                                            \
    }                                                                                              \
  }                                                                                                \
  Type vtkInrVolumeMapper::Get##Name()                                                             \
  {                                                                                                \
    return fromField;                                                                              \
  }
INR_STORED_OPTION(RayBudget, int, queryReduction.budget, static_cast<inr::BudgetScheme>(v),
  static_cast<int>(this->Internal->queryReduction.budget))
INR_STORED_OPTION(BudgetFraction, double, queryReduction.budgetFraction, v,
  this->Internal->queryReduction.budgetFraction)
INR_STORED_OPTION(BudgetMaxSkip, int, queryReduction.budgetMaxSkip, v,
  this->Internal->queryReduction.budgetMaxSkip)
INR_STORED_OPTION(BudgetAlpha, double, queryReduction.budgetAlpha, v,
  this->Internal->queryReduction.budgetAlpha)
INR_STORED_OPTION(Reproject, int, queryReduction.reproject, v != 0,
  this->Internal->queryReduction.reproject ? 1 : 0)
INR_STORED_OPTION(PruneEpsilon, double, queryReduction.pruneEpsilon, v,
  this->Internal->queryReduction.pruneEpsilon)
INR_STORED_OPTION(PruneFalloff, double, queryReduction.pruneFalloff, v,
  this->Internal->queryReduction.pruneFalloff)

const char* vtkInrVolumeMapper::GetQueryReductionInUse()
{
  return this->Internal->queryReductionInUse.c_str();
}

INR_STORED_OPTION(SkipBlock, int, macrocellsAsked.skipBlockCells, v,
  this->Internal->macrocellsAsked.skipBlockCells)
INR_STORED_OPTION(BoundsPadding, double, macrocellsAsked.boundsPadding, v,
  this->Internal->macrocellsAsked.boundsPadding)
INR_STORED_OPTION(GhostPasses, int, trackingAsked.ghostPassesOnUpdate, v,
  this->Internal->trackingAsked.ghostPassesOnUpdate)
INR_STORED_OPTION(RefineMacrocells, int, trackingAsked.refineMacrocells, v != 0,
  this->Internal->trackingAsked.refineMacrocells ? 1 : 0)
INR_STORED_OPTION(Estimator, int, trackingAsked.estimator, static_cast<inr::PrimaryEstimator>(v),
  static_cast<int>(this->Internal->trackingAsked.estimator))
INR_STORED_OPTION(MajorantScale, double, trackingAsked.majorantScale, v,
  this->Internal->trackingAsked.majorantScale)
INR_STORED_OPTION(ResidualScale, double, trackingAsked.residualScale, v,
  this->Internal->trackingAsked.residualScale)
INR_STORED_OPTION(PointsPerIteration, int, trackingAsked.pointsPerIteration, v,
  this->Internal->trackingAsked.pointsPerIteration)
#undef INR_STORED_OPTION

const char* vtkInrVolumeMapper::GetMacrocellsInUse()
{
  return this->Internal->macrocellsInUse.c_str();
}

void vtkInrVolumeMapper::ReleaseGraphicsResources(vtkWindow* win)
{
  this->Internal->compositor.ReleaseGraphicsResources(win);
  this->Superclass::ReleaseGraphicsResources(win);
}

// The slow, GL-free part of the next Render, done before the view's GL render starts: the engine
// (re)built when its options changed, the macrocell slices the coming frame needs for the input's
// time (the fine grid's, or the coarse interactive grid's for a reduced time-change frame), and
// the coarse grid's slices built ahead once a still image is on screen. Their progress is reported
// here; from then on Render itself reports none (see progressHandler).
void vtkInrVolumeMapper::PrepareRender(vtkRenderer* ren, vtkVolume* vol)
{
  Internals& I = *this->Internal;
  if (!ren || !vol || ren->GetSelector() || I.insideRender)
  {
    return;
  }
  I.quietRenders = true;
  if (I.fineBusy && I.fineBuildDone)
  {
    I.JoinFineBuild(this);
  }
  if (vtkAlgorithm* producer = this->GetInputAlgorithm())
  {
    producer->Update();
  }
  vtkDataSet* input = this->GetInput();
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  auto* bytes = vtkUnsignedCharArray::SafeDownCast(fd ? fd->GetAbstractArray("InrModel") : nullptr);
  if (!bytes || bytes->GetNumberOfValues() == 0 || !I.UpdateModel(this, bytes) ||
    !I.UpdateEngine(this))
  {
    return;  // Render reports what is wrong
  }
  if (I.fineBusy)
  {
    // Still building on the worker: show how far (the render draws the coarse session).
    this->SetProgressText("INR Volume: building macrocells");
    this->UpdateProgress(I.fineBuildProgress.load());
    this->SetProgressText(nullptr);
    return;
  }
  inr::RenderScene next;
  next.time = InrSceneTranslator::Time(
    input, 0.5 * (I.model.domain.timeBegin + I.model.domain.timeEnd));
  double budgetMs = 0.0;
  bool timeChange = false;
  const bool interactive = I.InteractiveRender(this, ren, next, &budgetMs, &timeChange);
  const bool coarse = I.RendersCoarse(this, interactive, timeChange);
  try
  {
    if (coarse)
    {
      I.coarse.session->buildSlicesFor(next.time);
    }
    else if (!I.StartFineBuild(this, next.time))
    {
      I.fine.session->buildSlicesFor(next.time);
    }
  }
  catch (const std::exception&)
  {
    // The render's setScene meets the same failure and reports it.
  }
  if (I.fineBusy)
  {
    return;
  }
  // The coarse slices of later time-change frames, once a still image of the fine grid is shown
  // (the first image is not delayed by them).
  if (!interactive && !I.lastInteractive && I.fine.session->accumulatedFrames() > 0 &&
    this->InteractiveMacrocellsAhead &&
    this->InteractiveLevelOfDetail == LOD_INTERACTION_AND_TIME && this->FramesPerRender == 1 &&
    !this->Capturing)
  {
    I.BuildCoarseAhead(this);
  }
}

void vtkInrVolumeMapper::Render(vtkRenderer* ren, vtkVolume* vol)
{
  Internals& I = *this->Internal;
  if (!ren || !vol || ren->GetSelector())
  {
    return;  // no picking support: hardware-selection passes skip the volume
  }
  struct InsideRender
  {
    Internals& I;
    explicit InsideRender(Internals& i)
      : I(i)
    {
      I.SetInsideRender(true);
    }
    ~InsideRender() { I.SetInsideRender(false); }
  } inside(I);
  // Under MPI every rank reaches this point in every render (IceT composites all of them):
  // whatever happens below, the refinement state is reduced over the ranks once on the way out
  // (also where this rank draws nothing: depth peeling depends on its own geometry, and a rank
  // that skipped the reduction would leave the others waiting in it).
  struct RankReduction
  {
    Internals& I;
    vtkInrVolumeMapper* self;
    bool rendered = false;
    ~RankReduction() { I.ReduceOverRanks(self, rendered); }
  } reduction{ I, this };
  if (insideDepthPeeling(vol))
  {
    // Its peels expect the GPU ray-cast mapper's shaders; blending a finished image into them
    // (several times a frame) corrupts the picture. ParaView's representation avoids this path.
    if (!I.warnedPeeling)
    {
      vtkWarningMacro("INR Volume: not drawn while the renderer depth-peels volumes with "
                      "translucent geometry (UseDepthPeelingForVolumes, which only the GPU "
                      "ray-cast mapper supports): turn UseDepthPeelingForVolumes off to see it.");
      I.warnedPeeling = true;
    }
    return;
  }
  if (vtkAlgorithm* producer = this->GetInputAlgorithm())
  {
    producer->Update();
  }
  vtkDataSet* input = this->GetInput();
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  auto* bytes = vtkUnsignedCharArray::SafeDownCast(fd ? fd->GetAbstractArray("InrModel") : nullptr);
  if (!bytes || bytes->GetNumberOfValues() == 0)
  {
    return;  // e.g. an empty piece in a parallel run: nothing to draw here
  }
  if (!I.UpdateModel(this, bytes) || !I.UpdateEngine(this))
  {
    return;
  }
  Viewport tile;
  ren->GetTiledSizeAndOrigin(&tile.width, &tile.height, &tile.x0, &tile.y0);
  if (tile.width <= 0 || tile.height <= 0)
  {
    return;
  }
  // A tile of a larger picture (screenshot larger than the view, tile display): the camera is
  // already the tile's (window centre); the window keys the random streams by the full picture.
  {
    vtkRenderWindow* win = ren->GetRenderWindow();
    double tileViewport[4] = { 0, 0, 1, 1 };
    win->GetTileViewport(tileViewport);
    I.window = InrSceneTranslator::TileWindow(
      ren->GetViewport(), tileViewport, win->GetSize(), tile.width, tile.height);
  }
  I.WarnAboutScene(this, ren, vol, tile.width, tile.height);
  const auto renderStart = Clock::now();
  I.ObserveWindow(ren->GetRenderWindow());
  inr::RenderScene scene = I.TranslateScene(this, ren, vol, input, tile);
  // Level of detail: an interactive render draws one frame of a reduced image, upscaled. Tiles of
  // a larger picture are captures (still renders) and always render at full resolution.
  double budgetMs = 0.0;
  bool timeChange = false;
  int interactiveFrames = 1;
  bool interactive =
    I.window.fullWidth == 0 && I.InteractiveRender(this, ren, scene, &budgetMs, &timeChange);
  if (I.fineBusy && !interactive && I.window.fullWidth == 0 && !this->Capturing)
  {
    // The fine slices of this time are still building on the worker: a reduced frame of the
    // coarse session, as right after a time change (a fresh image).
    interactive = true;
    timeChange = true;
    budgetMs = this->InteractiveFrameTime;
  }
  int width = tile.width, height = tile.height;
  if (interactive)
  {
    if (!I.lastInteractive)
    {
      I.lodCeiling = 2.0;  // a new interaction: the view may have become cheaper or dearer
    }
    double s = I.ChooseScale(budgetMs, tile.width, tile.height);
    if (timeChange && s < 1.0)
    {
      interactiveFrames = InteractiveFreshFrameCount(s, this->InteractiveFreshFrames);
      s = InteractiveFreshFrameScale(s, this->InteractiveFreshFrames);
    }
    width = std::max(1, int(std::lround(tile.width * s)));
    height = std::max(1, int(std::lround(tile.height * s)));
    if (width != tile.width || height != tile.height)
    {
      scene.depthLimit =
        resampleDepthLimit(scene.depthLimit, tile.width, tile.height, width, height);
    }
    else
    {
      interactive = false;  // full resolution fits the budget: an ordinary (still) render
    }
  }
  I.haveLastTime = true;
  I.lastTime = scene.time;
  const auto refineStart = Clock::now();
  // A time change shown as a reduced frame: the coarse grid, unless it is off or not coarser.
  // and a camera drag with Reproject on: the fine session keeps its full-resolution accumulation,
  // which the still render after the drag reprojects to the new camera instead of restarting.
  const bool useCoarse = I.RendersCoarse(this, interactive, timeChange);
  if (I.fineBusy && !useCoarse)
  {
    I.JoinFineBuild(this);  // this frame needs the fine session: wait for the worker
  }
  if (!I.Refine(this, scene, width, height, interactive, useCoarse, interactiveFrames))
  {
    return;
  }
  reduction.rendered = true;
  const double refineMs = msSince(refineStart);
  const auto compositeStart = Clock::now();
  I.Composite(this, ren, width, height);
  if (interactive)
  {
    // The image must be drawn before the time is read (the GL pipeline is asynchronous).
    glFinish();
  }
  const double compositeMs = msSince(compositeStart);
  I.lastRenderMs = msSince(renderStart);
  I.lastInteractive = interactive;
  I.renderedInWindow = true;
  I.imageWidth = width;
  I.imageHeight = height;
  I.MeasureFrame(I.lastRenderMs, refineMs, width, height, interactive);
  if (lodReport())
  {
    std::fprintf(stderr,
      "INR Volume LOD: %s frame %dx%d of %dx%d (scale %.3f), %.1f ms (budget %.0f ms; macrocell "
      "update %.1f ms; scene %.1f ms, engine %.1f ms, composite %.1f ms), frames %d%s\n",
      interactive ? "interactive" : "still", width, height, tile.width, tile.height,
      double(width) / tile.width, I.lastRenderMs, budgetMs, I.lastStep.total.updateMs,
      std::chrono::duration<double, std::milli>(refineStart - renderStart).count(), refineMs,
      compositeMs, I.Shown()->accumulatedFrames(), useCoarse ? ", coarse macrocells" : "");
  }
  // A still render that time-change frames may follow: build the coarse slices they will need
  // now (after the frame is measured: it is no part of the frame's cost).
  // (A view that prepares its renders builds them in PrepareRender instead, outside the GL render.)
  if (!I.quietRenders && !interactive && I.window.fullWidth == 0 && this->InteractiveMacrocellsAhead &&
    this->InteractiveLevelOfDetail == LOD_INTERACTION_AND_TIME && this->FramesPerRender == 1 &&
    !this->Capturing)
  {
    I.BuildCoarseAhead(this);
  }
}

void vtkInrVolumeMapper::Internals::JoinFineBuild(vtkInrVolumeMapper* self)
{
  if (!this->fineBusy)
  {
    return;
  }
  this->fineBuilder.join();
  this->fineBusy = false;
  this->lodCeiling = 2.0;  // frames measured while the worker shared the CPU were slower
  if (this->fine.session)
  {
    this->fine.session->setProgressHandler(
      progressHandler(self, "INR Volume: ", &this->muteProgress));
  }
}

// Starts building the fine slices for `time` on a worker thread where that keeps the GUI
// responsive (CPU backend, one rank, GUI-like refinement, a coarse session to draw meanwhile);
// false where the caller builds them itself. Waits a few ms first: most calls find the slices
// built and finish at once, and then no coarse frame is drawn.
namespace
{
std::atomic<bool> backgroundBuilds{ false };
}

void vtkInrVolumeMapper::SetBackgroundMacrocellBuilds(bool on)
{
  backgroundBuilds = on;
}

bool vtkInrVolumeMapper::GetBackgroundMacrocellBuilds()
{
  return backgroundBuilds;
}

bool vtkInrVolumeMapper::Internals::StartFineBuild(vtkInrVolumeMapper* self, double time)
{
  if (!backgroundBuilds || this->fineBusy || !this->fine.session || self->Capturing || self->FramesPerRender != 1 ||
    !self->ProgressiveRefinement ||
    self->InteractiveLevelOfDetail != LOD_INTERACTION_AND_TIME || this->ranks.count > 1 ||
    this->fine.session->backend() != inr::RenderBackend::Cpu || !this->UpdateCoarseEngine(self))
  {
    return false;
  }
  inr::RenderSession* session = this->fine.session.get();
  this->fineBuildProgress = 0.0;
  this->fineBuildDone = false;
  session->setProgressHandler([this](double fraction, const std::string&)
    { this->fineBuildProgress = fraction; });
  this->fineBusy = true;
  this->fineBuilder = std::thread(
    [this, session, time]()
    {
      try
      {
        session->buildSlicesFor(time);
      }
      catch (const std::exception&)
      {
        // The render's setScene meets the same failure and reports it.
      }
      this->fineBuildDone = true;
    });
  const auto start = Clock::now();
  while (!this->fineBuildDone && msSince(start) < 20.0)
  {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (this->fineBuildDone)
  {
    this->JoinFineBuild(self);
  }
  return true;
}

void vtkInrVolumeMapper::Internals::ObserveWindow(vtkRenderWindow* window)
{
  if (window == this->observedWindow)
  {
    return;
  }
  this->StopObserving();
  this->windowObserver->SetCallback(&Internals::OnWindowEvent);
  this->windowObserver->SetClientData(this);
  window->AddObserver(vtkCommand::StartEvent, this->windowObserver);
  window->AddObserver(vtkCommand::EndEvent, this->windowObserver);
  this->observedWindow = window;
  this->windowStart = Clock::now();
  this->renderedInWindow = false;
}

void vtkInrVolumeMapper::Internals::StopObserving()
{
  if (this->observedWindow)
  {
    this->observedWindow->RemoveObserver(this->windowObserver);
  }
  this->observedWindow = nullptr;
}

void vtkInrVolumeMapper::Internals::OnWindowEvent(
  vtkObject*, unsigned long event, void* clientData, void*)
{
  auto* self = static_cast<Internals*>(clientData);
  if (event == vtkCommand::StartEvent)
  {
    self->windowStart = Clock::now();
    self->renderedInWindow = false;
    self->aheadMs = 0.0;
  }
  else if (event == vtkCommand::EndEvent && self->renderedInWindow)
  {
    const double outside =
      std::max(0.0, msSince(self->windowStart) - self->lastRenderMs - self->aheadMs);
    self->outsideMs = self->outsideMs > 0.0 ? 0.5 * (self->outsideMs + outside) : outside;
    self->renderedInWindow = false;
  }
}

// Whether this render is interactive (see InteractiveLevelOfDetail) and its budget in ms.
bool vtkInrVolumeMapper::Internals::InteractiveRender(vtkInrVolumeMapper* self, vtkRenderer* ren,
  const inr::RenderScene& scene, double* budgetMs, bool* timeChange) const
{
  *budgetMs = self->InteractiveFrameTime;
  *timeChange = false;
  // Under MPI with several ranks every frame is a full-resolution one: each rank would choose its
  // own reduced scale from its own timings, and images of different sizes do not composite.
  if (self->InteractiveLevelOfDetail == LOD_OFF || self->Capturing || this->ranks.count > 1)
  {
    return false;
  }
  const double rate = ren->GetRenderWindow() ? ren->GetRenderWindow()->GetDesiredUpdateRate() : 0;
  if (rate >= self->InteractiveUpdateRate)
  {
    *budgetMs = std::min(*budgetMs, 1000.0 / rate);
    return true;
  }
  *timeChange = self->InteractiveLevelOfDetail == LOD_INTERACTION_AND_TIME &&
    self->FramesPerRender == 1 && this->haveLastTime && scene.time != this->lastTime;
  return *timeChange;
}

// The linear scale of an interactive image, judged on the engine's time (which scales with the
// pixel count) against the budget left once the window's fixed cost is taken off (capped at
// kMaxFixedShare of the budget; see there). A stable resolution lets reprojection reuse the
// accumulation during a drag, so the scale is kept while the engine's measured time at it stays
// in a band around that budget; outside it the scale is re-chosen from that measurement, growing
// by at most kMaxGrowth per change because small images cost more per pixel (each wavefront
// iteration has a fixed cost). Before any interactive measurement: from the per-pixel cost of the
// frames rendered so far. Full resolution when the budget allows it.
double vtkInrVolumeMapper::Internals::ChooseScale(double budgetMs, int width, int height)
{
  const double pixels = double(width) * double(height);
  const double fixed = std::min(this->overheadMs + this->outsideMs, kMaxFixedShare * budgetMs);
  const double engineBudget = budgetMs - fixed;
  const double target = kBudgetMargin * engineBudget;
  const double measured = this->interactiveMs;
  double s = this->lodScale;
  if (measured > 0.0)
  {
    if (measured >= kKeepScaleAbove * engineBudget && measured <= kKeepScaleBelow * engineBudget)
    {
      return this->lodScale;
    }
    if (measured < kKeepScaleAbove * engineBudget && this->framesAtScale >= 4)
    {
      // Four frames at this scale well under the budget: the frame that barred the larger scale
      // was an outlier (a loaded machine, a background build): allow it again.
      this->lodCeiling = 2.0;
    }
    if (measured > kKeepScaleBelow * engineBudget && measured <= 2.0 * engineBudget &&
      this->framesAtScale < 2)
    {
      // One frame somewhat over the budget may be noise (a loaded machine): a second one decides
      // before the scale drops and is barred for the rest of the interaction.
      return this->lodScale;
    }
    s = std::min(this->lodScale * std::sqrt(target / std::max(measured, 1e-3)),
      this->lodScale * kMaxGrowth);
    if (measured > kKeepScaleBelow * engineBudget)
    {
      this->lodCeiling = std::min(this->lodCeiling, this->lodScale);  // measured too slow
    }
  }
  else if (this->msPerPixelFrame > 0.0)
  {
    s = std::sqrt(target / (this->msPerPixelFrame * pixels));
  }
  else
  {
    s = 0.25;  // nothing measured yet: a cautious first guess
  }
  s = std::clamp(std::floor(s * kScaleSteps) / kScaleSteps, kMinScale, 1.0);
  if (s == this->lodScale && measured > 0.0)
  {
    // Out of the band but rounded back to the same scale: one step in the needed direction.
    s = std::clamp(s + (measured > engineBudget ? -1.0 : 1.0) / kScaleSteps, kMinScale, 1.0);
  }
  if (s >= this->lodCeiling)
  {
    s = this->lodScale;  // never back up to a scale this interaction found too slow: no oscillation
  }
  if (s != this->lodScale)
  {
    this->lodScale = s;
    this->interactiveMs = 0.0;  // not measured at the new scale yet
    this->framesAtScale = 0;
  }
  return s;
}

// Updates the cost model from a render (exponential moving averages; macrocell/majorant update
// time is left out: it depends on the time change, not on the resolution): the engine's time per
// pixel per frame, the rest of the render (scene, depth read, upload, blend), and the engine time
// of interactive frames at the current scale.
void vtkInrVolumeMapper::Internals::MeasureFrame(
  double renderMs, double refineMs, int width, int height, bool interactive)
{
  const int frames = this->lastStep.framesRendered;
  if (frames <= 0)
  {
    return;
  }
  const double updateMs = this->lastStep.total.updateMs;
  const double engineMs = std::max(0.0, refineMs - updateMs);
  const double perPixel = engineMs / (double(frames) * double(width) * double(height));
  const double overhead = std::max(0.0, renderMs - refineMs);
  constexpr double kWeight = 0.5;  // recent frames dominate (the view changes during a drag)
  auto ema = [](double old, double now) { return old > 0.0 ? (1.0 - kWeight) * old + kWeight * now : now; };
  this->msPerPixelFrame = ema(this->msPerPixelFrame, perPixel);
  this->overheadMs = ema(this->overheadMs, overhead);
  if (interactive)
  {
    this->interactiveMs = ema(this->interactiveMs, engineMs);
    ++this->framesAtScale;
  }
}

// The model: loaded again only when its bytes changed (array, modification time, then hash).
bool vtkInrVolumeMapper::Internals::UpdateModel(vtkInrVolumeMapper* self, vtkUnsignedCharArray* bytes)
{
  if (bytes != this->bytesPtr || bytes->GetMTime() != this->bytesMTime)
  {
    this->bytesPtr = bytes;
    this->bytesMTime = bytes->GetMTime();
    const std::size_t n = static_cast<std::size_t>(bytes->GetNumberOfValues());
    const std::uint64_t h = hashBytes(bytes->GetPointer(0), n);
    if (h != this->hash || !this->modelOk)
    {
      this->JoinFineBuild(self);
      this->hash = h;
      this->modelOk = false;
      this->fine.session.reset();
      this->coarse.session.reset();
      this->coarseFailed = false;
      try
      {
        this->model = inr::InrModel::loadBytes(bytes->GetPointer(0), n, "INR model (field data)");
        this->modelOk = true;
      }
      catch (const std::exception& e)
      {
        if (this->reportedBadHash != h)
        {
          vtkErrorWithObjectMacro(self, << e.what());
          this->reportedBadHash = h;
        }
      }
    }
  }
  return this->modelOk;
}

// The options the engine is built or updated with: each asked value is checked as `inr render`
// checks it (the engine's validation and message: skipBlockShift, TrackingOptions::validate, the
// layout's padding rule); a refused one is reported once, naming the property, and the last valid
// value (at first the engine's default) stays in use.
void vtkInrVolumeMapper::Internals::CheckOptions(vtkInrVolumeMapper* self)
{
  auto accept = [self](const char* property, auto asked, auto& valid, auto& refused, auto check)
  {
    if (asked == valid)
    {
      return;
    }
    try
    {
      check(asked);
      valid = asked;
      refused = asked;  // a value refused before is reported again when asked again later
    }
    catch (const std::invalid_argument& e)
    {
      if (refused != asked)
      {
        refused = asked;
        vtkErrorWithObjectMacro(self, << "INR Volume: " << property << " = " << asked
                                      << " refused: " << e.what() << "; keeping " << valid);
      }
    }
  };
  accept("Skip Block (InrSkipBlock)", this->macrocellsAsked.skipBlockCells,
    this->macrocellsValid.skipBlockCells, this->macrocellsRefused.skipBlockCells,
    [](int cells) { inr::skipBlockShift(cells); });
  accept("Bounds Padding (InrBoundsPadding)", this->macrocellsAsked.boundsPadding,
    this->macrocellsValid.boundsPadding, this->macrocellsRefused.boundsPadding,
    [](double padding)
    {
      if (!(padding >= 0.0))
      {
        throw std::invalid_argument("bounds padding must be >= 0");
      }
    });
  accept("Ghost Passes (InrGhostPasses)", this->trackingAsked.ghostPassesOnUpdate,
    this->trackingValid.ghostPassesOnUpdate, this->trackingRefused.ghostPassesOnUpdate,
    [this](int passes)
    {
      inr::TrackingOptions t = this->trackingValid;
      t.ghostPassesOnUpdate = passes;
      t.validate();
    });
  // The estimator's options, each checked by TrackingOptions::validate on the valid set.
  auto trackingField = [&](const char* property, auto member)
  {
    accept(property, this->trackingAsked.*member, this->trackingValid.*member,
      this->trackingRefused.*member,
      [this, member](auto asked)
      {
        inr::TrackingOptions t = this->trackingValid;
        t.*member = asked;
        t.validate();
      });
  };
  trackingField("Estimator (InrEstimator)", &inr::TrackingOptions::estimator);
  trackingField("Majorant Scale (InrMajorantScale)", &inr::TrackingOptions::majorantScale);
  trackingField("Residual Scale (InrResidualScale)", &inr::TrackingOptions::residualScale);
  trackingField("Points Per Iteration (InrPointsPerIteration)", &inr::TrackingOptions::pointsPerIteration);
  this->trackingValid.refineMacrocells = this->trackingAsked.refineMacrocells;
}

// What the user asked of the engine (the properties, checked by CheckOptions), with the device
// of this rank: what both sessions are built from (InrSessionOptions).
InrEngineRequest vtkInrVolumeMapper::Internals::Request(vtkInrVolumeMapper* self)
{
  this->CheckOptions(self);
  InrEngineRequest r;
  r.backend = self->Backend == BACKEND_CUDA ? inr::RenderBackend::Cuda
    : self->Backend == BACKEND_CPU          ? inr::RenderBackend::Cpu
                                            : inr::RenderBackend::Auto;
  r.traversal = self->Traversal == TRAVERSAL_DDA ? inr::TraversalKind::Dda
    : self->Traversal == TRAVERSAL_OPTIX         ? inr::TraversalKind::Optix
                                                 : inr::TraversalKind::Auto;
  r.resolution = self->MacrocellResolution;
  r.temporalSlices = self->TemporalSlices;
  r.modelUsesTime = this->model.domain.usesTime();
  r.skipBlockCells = this->macrocellsValid.skipBlockCells;
  r.boundsPadding = this->macrocellsValid.boundsPadding;
  r.tracking = this->trackingValid;
  // One GPU per rank: the rank's index on its node picks the device (looked up once: neither
  // changes while the process runs).
  if (!this->haveDevice)
  {
    this->localRank = InrParallelRendering::LocalRank(&this->localRankSource);
    this->cudaDevices = inr::cudaDeviceCount();
    this->haveDevice = true;
  }
  if (this->localRank >= 0 && this->cudaDevices > 0)
  {
    r.cudaDevice = this->localRank % this->cudaDevices;
  }
  return r;
}

// The engine (evaluator, macrocells, renderer): rebuilt when the model, the macrocell grid or the
// backend change. Its macrocell builds report progress through the mapper's ProgressEvent.
bool vtkInrVolumeMapper::Internals::UpdateEngine(vtkInrVolumeMapper* self)
{
  const InrEngineRequest want = this->Request(self);
  InrEngineSlot& f = this->fine;
  if (this->fineBusy)
  {
    if (f.asked.SameBuild(want))
    {
      return true;  // the worker owns the session until its build is joined
    }
    this->JoinFineBuild(self);
  }
  if (!f.session || !f.asked.SameBuild(want))
  {
    try
    {
      // The coarse session runs the fine session's evaluator: it goes with it.
      this->coarse.session.reset();
      this->coarseFailed = false;
      f.session.reset();
      InrEngineRequest built = want;
      try
      {
        f.session = inr::RenderSession::create(this->model, InrSessionOptions(built, InrSessionLevel::Fine()));
      }
      catch (const std::exception& e)
      {
        if (built.traversal != inr::TraversalKind::Optix)
        {
          throw;
        }
        // OptiX asked for where it cannot run (no OptiX in this build, or the driver's): say why
        // and let auto choose, rather than leaving the view empty.
        vtkWarningWithObjectMacro(self,
          "INR Volume: the OptiX traversal is not available here (" << e.what()
                                                                     << "); using Traversal Auto.");
        built.traversal = inr::TraversalKind::Auto;
        f.session = inr::RenderSession::create(this->model, InrSessionOptions(built, InrSessionLevel::Fine()));
      }
      f.session->setProgressHandler(progressHandler(self, "INR Volume: ", &this->muteProgress));
      this->rankInUse.clear();
      if (this->ranks.count > 1 || this->localRank >= 0)
      {
        std::ostringstream note;
        note << "; rank " << this->ranks.rank << " of " << this->ranks.count;
        if (this->localRank >= 0)
        {
          note << " (local rank " << this->localRank << " from " << this->localRankSource << ")";
        }
        if (f.session->backend() == inr::RenderBackend::Cuda)
        {
          note << ", CUDA device " << built.cudaDevice << " of " << this->cudaDevices;
        }
        this->rankInUse = note.str();
      }
      // The engine's once-per-cause warnings (work caps hit) go to ParaView's output window.
      f.session->setWarningHandler([self](const std::string& message)
        { vtkWarningWithObjectMacro(self, "INR Volume: " << message); });
      if (want.backend == inr::RenderBackend::Cuda &&
        f.session->backend() != inr::RenderBackend::Cuda && !this->warnedCuda)
      {
        vtkWarningWithObjectMacro(self,
          "INR Volume: the CUDA backend was requested but is not usable here; "
          "rendering on the CPU (" << f.session->description() << ").");
        this->warnedCuda = true;
      }
      f.asked = want;
      f.built = built;
      f.Started();
      ++this->engineBuilds;
    }
    catch (const std::exception& e)
    {
      vtkErrorWithObjectMacro(self, << "INR Volume: cannot set up the renderer: " << e.what());
      f.session.reset();
      return false;
    }
  }
  InrSyncTrackingOptions(*f.session, this->trackingValid);  // valid: checked above
  f.built.tracking = this->trackingValid;
  this->backendInUse = f.session->description() + this->rankInUse;
  this->macrocellsInUse = InrDescribeMacrocells(*f.session);
  return true;
}

// The coarse session for reduced interactive frames (InteractiveMacrocellResolution: time changes,
// and camera drags with Reproject on), built on first use from what the fine session was built
// with (InrSessionOptions, coarse level: every user setting, on the fine session's evaluator);
// false (render with the fine session) when it is off, not coarser than the fine grid, or it
// cannot be created (reported once).
bool vtkInrVolumeMapper::Internals::UpdateCoarseEngine(vtkInrVolumeMapper* self)
{
  InrEngineSlot& c = this->coarse;
  const int n = self->InteractiveMacrocellResolution;
  if (n <= 0 || n >= this->fine.built.resolution || !this->fine.session)
  {
    return false;
  }
  InrEngineRequest want = this->fine.built;  // the fine session's request, as it was built
  want.resolution = n;
  if (!c.session || !c.asked.SameBuild(want))
  {
    if (this->coarseFailed && c.asked.SameBuild(want))
    {
      return false;
    }
    c.session.reset();
    c.asked = want;
    c.built = want;
    try
    {
      // No progress handler for its lazy builds (inside interactive frames, short); the build
      // ahead reports progress (BuildCoarseAhead).
      c.session = inr::RenderSession::create(
        this->model, InrSessionOptions(this->fine.built, InrSessionLevel::Coarse(n, *this->fine.session)));
      c.session->setWarningHandler([self](const std::string& message)
        { vtkWarningWithObjectMacro(self, "INR Volume (interactive macrocells): " << message); });
      c.Started();
      this->coarseFailed = false;
    }
    catch (const std::exception& e)
    {
      vtkErrorWithObjectMacro(self, << "INR Volume: Interactive Macrocell Resolution "
                                       "(InrInteractiveMacrocellResolution) = "
                                    << n << ": cannot set up the coarse renderer: " << e.what()
                                    << "; time changes render with the fine macrocells");
      c.session.reset();
      this->coarseFailed = true;
      return false;
    }
  }
  InrSyncTrackingOptions(*c.session, this->trackingValid);
  return true;
}

// Builds every coarse slice not built yet (InteractiveMacrocellsAhead), reporting progress; the
// coarse session reports none otherwise (its lazy builds happen inside interactive frames).
void vtkInrVolumeMapper::Internals::BuildCoarseAhead(vtkInrVolumeMapper* self)
{
  if (!this->UpdateCoarseEngine(self))
  {
    return;
  }
  inr::RenderSession& engine = *this->coarse.session;
  const inr::MacrocellInfo before = engine.macrocellInfo();
  if (before.slicesBuilt >= before.temporalSlices)
  {
    return;
  }
  const auto start = Clock::now();
  engine.setProgressHandler(
    progressHandler(self, "INR Volume (interactive macrocells): ", &this->muteProgress));
  try
  {
    engine.buildAllSlices();
  }
  catch (const std::exception& e)
  {
    vtkErrorWithObjectMacro(self, << "INR Volume: building the interactive macrocells ahead "
                                     "failed: " << e.what()
                                  << "; time changes build them when needed");
  }
  engine.setProgressHandler({});
  const double ms = msSince(start);
  this->aheadMs += ms;
  if (lodReport())
  {
    std::fprintf(stderr, "INR Volume LOD: built %d interactive macrocell slices ahead (%dx%dx%d "
                         "cells), %.1f ms\n",
      engine.macrocellInfo().slicesBuilt - before.slicesBuilt, before.dims.x, before.dims.y,
      before.dims.z, ms);
  }
}

// Camera, transfer function, time and depth limit from VTK; light and shadows from the mapper.
inr::RenderScene vtkInrVolumeMapper::Internals::TranslateScene(vtkInrVolumeMapper* self,
  vtkRenderer* ren, vtkVolume* vol, vtkDataSet* input, const Viewport& tile)
{
  const int width = tile.width, height = tile.height;
  vtkCamera* cam = ren->GetActiveCamera();
  inr::RenderScene scene;
  scene.camera = InrSceneTranslator::TranslateCamera(cam, width, height);
  scene.camera.modelToWorld = InrSceneTranslator::ModelToWorld(vol);
  // Depth limit: world distance to the opaque geometry rendered before the volume. Without any
  // such geometry the depth buffer holds only the clear value (no limit): skip the read, which
  // costs tens of ms per render on a software OpenGL.
  if (geometryDrawnBeforeVolumes(ren))
  {
    InrFramebufferCompositor::ReadDepth(
      ren->GetRenderWindow(), tile.x0, tile.y0, width, height, this->depth);
    scene.depthLimit = InrSceneTranslator::DepthToRayDistances(this->depth, width, height, cam);
  }
  double valueRange[2];
  InrSceneTranslator::ValueRange(input->GetFieldData(), valueRange);
  scene.transferFunction = this->translator.UpdateTransferFunction(
    vol->GetProperty(), self->UseDefaultTransferFunction != 0, valueRange);
  scene.time = InrSceneTranslator::Time(
    input, 0.5 * (this->model.domain.timeBegin + this->model.domain.timeEnd));
  scene.background = { 0.f, 0.f, 0.f };
  scene.shadows = self->Shadows != 0;
  const double* l = self->LightDirection;
  scene.toLight = (l[0] == 0.0 && l[1] == 0.0 && l[2] == 0.0)
    ? inr::defaultLightDirection(scene.camera)
    : std::array<double, 3>{ l[0], l[1], l[2] };
  scene.ambient = static_cast<float>(self->Ambient);
  scene.shadowEstimator =
    self->ShadowEstimator == 1 ? inr::ShadowEstimator::Ratio : inr::ShadowEstimator::Delta;
  return scene;
}

// Once per mapper: translucent polygonal geometry in the renderer (VTK draws it before volumes
// and this mapper blends over it without depth order: only VTK's GPU ray-cast mapper joins
// depth peeling), and camera features the engine ignores (named; warned again when they change).
void vtkInrVolumeMapper::Internals::WarnAboutScene(
  vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, int width, int height)
{
  if (!this->warnedTranslucent)
  {
    vtkPropCollection* props = ren->GetViewProps();
    vtkCollectionSimpleIterator it;
    props->InitTraversal(it);
    while (vtkProp* prop = props->GetNextProp(it))
    {
      auto* actor = vtkActor::SafeDownCast(prop);
      if (actor && prop != vol && actor->GetVisibility() && actor->HasTranslucentPolygonalGeometry())
      {
        vtkWarningWithObjectMacro(self,
          "INR Volume: translucent geometry (opacity < 1) is drawn before the volume and is not "
          "depth-sorted with it: translucent surfaces in front of the INR volume appear behind "
          "it (ParaView's non-GPU volume mappers do the same; only the GPU ray-cast mapper "
          "interleaves volumes with depth peeling). Opaque geometry is depth-composited "
          "correctly: set the surface's Opacity to 1 to have it hide the volume behind it.");
        this->warnedTranslucent = true;
        break;
      }
    }
  }
  const std::string ignored = InrSceneTranslator::UnsupportedCameraFeatures(
    ren->GetActiveCamera(), ren->GetRenderWindow(), width, height);
  if (!ignored.empty() && ignored != this->warnedCamera)
  {
    vtkWarningWithObjectMacro(self, "INR Volume: the volume is rendered with the camera's "
                                    "position, focal point, view up, angle/scale and window "
                                    "centre only; ignored here: "
        << ignored << ".");
  }
  this->warnedCamera = ignored;
}

// Hands the query-reduction settings to the engine when they changed. A rejected set is reported
// once and the engine keeps what it had; a pruning change restarts its accumulation, which the
// refinement driver notices (accumulated frames drop to 0).
void vtkInrVolumeMapper::Internals::PushQueryReduction(vtkInrVolumeMapper* self,
  InrEngineSlot& slot)
{
  inr::RenderSession& engine = *slot.session;
  if (!slot.haveQueryReduction || !InrSameQueryReduction(this->queryReduction, slot.queryReductionTried))
  {
    slot.haveQueryReduction = true;
    slot.queryReductionTried = this->queryReduction;
    try
    {
      engine.setQueryReduction(this->queryReduction);
      this->haveRefusedQueryReduction = false;
    }
    catch (const std::invalid_argument& e)
    {
      if (!this->haveRefusedQueryReduction ||
        !InrSameQueryReduction(this->queryReduction, this->refusedQueryReduction))
      {
        vtkErrorWithObjectMacro(self, << "INR Volume: " << e.what() << "; keeping "
                                      << InrDescribeQueryReduction(engine.queryReduction()));
      }
      this->haveRefusedQueryReduction = true;
      this->refusedQueryReduction = this->queryReduction;
    }
  }
  this->queryReductionInUse = InrDescribeQueryReduction(engine.queryReduction());
}

// Hands the scene to the engine (it decides what to redo: SceneChange), then accumulates frames
// as the refinement options allow (RefinementDriver). False when the engine failed.
bool vtkInrVolumeMapper::Internals::Refine(vtkInrVolumeMapper* self,
  const inr::RenderScene& scene, int width, int height, bool interactive, bool useCoarse,
  int interactiveFrames)
{
  // The session drawing this render: the fine one, or the coarse one for a time-change
  // interactive frame.
  InrEngineSlot& slot = useCoarse ? this->coarse : this->fine;
  inr::RenderSession& engine = *slot.session;
  inr::RefinementDriver& refinement = slot.refinement;
  this->shownCoarse = useCoarse;
  try
  {
    inr::RenderSettings settings;
    settings.width = width;
    settings.height = height;
    settings.seed = static_cast<std::uint32_t>(self->Seed);
    settings.window = this->window;
    this->RankSettings(settings);
    slot.SetSettings(settings);
    const bool debug = debugReport();
    if (debug)
    {
      const inr::SceneChange change =
        inr::diffScenes(this->haveLastScene ? &this->lastScene : nullptr, scene);
      std::fprintf(stderr, "INR Volume: render %dx%d%s, frames %d, changed:%s\n", width, height,
        useCoarse ? " (coarse macrocells)" : "", engine.accumulatedFrames(),
        change.describe().c_str());
      this->lastScene = scene;
      this->haveLastScene = true;
    }
    this->PushQueryReduction(self, slot);
    engine.setScene(scene);

    inr::RefinementOptions options;
    options.maximumFrames = self->MaximumFrames;
    options.convergenceTarget = self->ConvergenceTarget;
    options.framesPerRender =
      interactive ? interactiveFrames : self->ProgressiveRefinement ? self->FramesPerRender : 1;
    if (this->window.fullWidth > 0 && self->ProgressiveRefinement && !interactive)
    {
      // A tile is rendered once per capture, from a fresh accumulation: refine it to the still
      // image's quality (convergence target or frame limit) in this one render.
      options.framesPerRender = options.maximumFrames;
    }
    refinement.setOptions(options);
    this->lastStep = inr::RefinementDriver::Step{};
    this->lastStep = refinement.advance(engine);
    if (debug && this->lastStep.framesRendered > 0)
    {
      std::fprintf(stderr,
        "INR Volume: now %d frames, %.0f queries, update %.1f ms, converged %d; %s: %.0f rays, "
        "%.0f pixels skipped, %.0f pruned\n",
        engine.accumulatedFrames(), double(this->lastStep.total.totalQueries()),
        this->lastStep.total.updateMs, int(refinement.converged()),
        this->queryReductionInUse.c_str(), double(this->lastStep.total.rays),
        double(this->lastStep.total.budgetSkipped), double(this->lastStep.total.pruned));
    }
    return true;
  }
  catch (const std::exception& e)
  {
    vtkErrorWithObjectMacro(self, << "INR Volume: rendering failed: " << e.what());
    return false;
  }
}

// With several ranks, the image-space split: rank r of N traces the pixels (x + y) mod N = r of
// the picture at full depth (RenderSettings::pixelShare) with the same seed as one rank would,
// so the ranks' premultiplied images add up to the single-rank image (IceT blends them; disjoint
// pixels blend the same in any order).
void vtkInrVolumeMapper::Internals::RankSettings(inr::RenderSettings& settings) const
{
  if (this->ranks.count > 1)
  {
    settings.pixelShare = inr::PixelShare{ this->ranks.rank, this->ranks.count };
  }
}

void vtkInrVolumeMapper::Internals::ReduceOverRanks(vtkInrVolumeMapper* self, bool rendered)
{
  // What every rank did (GetRanksInUse): how a user checks that all of them render.
  std::ostringstream line;
  line << "rank " << this->ranks.rank << " of " << this->ranks.count << ": ";
  if (rendered)
  {
    line << this->lastStep.total.totalQueries() << " queries in the last render, "
         << (this->Shown() ? this->Shown()->accumulatedFrames() : 0) << " frames, "
         << (self->GetLocalConverged() ? "converged" : "refining") << "; "
         << this->backendInUse;
  }
  else
  {
    line << "nothing drawn in the last render";
  }
  if (this->ranks.count < 2)
  {
    this->ranksInUse = line.str();
    return;
  }
  // A rank that drew nothing (no model on its piece, a failed engine) neither holds back nor
  // speeds up the others: it reports "converged", the most frames and the highest estimate.
  InrParallelRendering::Refinement local;
  local.converged = rendered ? self->GetLocalConverged() : 1;
  local.frames = rendered && this->Shown() ? this->Shown()->accumulatedFrames()
                                           : std::numeric_limits<int>::max();
  local.estimate =
    rendered ? this->fine.refinement.estimate() : std::numeric_limits<double>::infinity();
  InrParallelRendering::Refinement all = InrParallelRendering::ReduceRefinement(local);
  if (all.frames == std::numeric_limits<int>::max())
  {
    all = InrParallelRendering::Refinement{ 0, 0, 0.0 };  // no rank drew anything
  }
  this->reduced = all;
  std::string text;
  for (const std::string& l : InrParallelRendering::GatherText(line.str()))
  {
    text += (text.empty() ? "" : "\n") + l;
  }
  this->ranksInUse = text;
}

// Draws the accumulated image over what is in the framebuffer; the texture is loaded again only
// when the image changed.
void vtkInrVolumeMapper::Internals::Composite(
  vtkInrVolumeMapper* self, vtkRenderer* ren, int width, int height)
{
  auto* window = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow());
  inr::RenderSession& shown = *this->Shown();
  const int frames = shown.accumulatedFrames();
  if (!window || frames == 0)
  {
    return;
  }
  // A reprojection (camera or volume moved) changes the image without rendering a frame when the
  // kept history already reaches the frame limit: upload on any new accumulation epoch too.
  const int epoch = shown.counters().accumulationResets + shown.counters().reprojections;
  if (this->compositor.NeedsUpload(window, width, height, frames,
        this->lastStep.framesRendered > 0 || epoch != this->uploadedEpoch ||
          this->shownCoarse != this->uploadedCoarse))
  {
    const inr::ImageRGBA image = shown.premultipliedImage();
    // A reduced (interactive) image is stretched over the viewport: filter it linearly.
    int viewport[2] = { width, height };
    ren->GetTiledSize(&viewport[0], &viewport[1]);
    const bool upscaled = viewport[0] != width || viewport[1] != height;
    this->compositor.Upload(window, width, height, frames, image.data.data(), upscaled);
    this->uploadedEpoch = epoch;
    this->uploadedCoarse = this->shownCoarse;
  }
  std::string error;
  if (!this->compositor.Blend(window, &error))
  {
    vtkErrorWithObjectMacro(self, << error);
  }
}

void vtkInrVolumeMapper::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Backend: " << this->Backend << " (" << this->GetBackendInUse() << ")\n";
  os << indent << "Traversal: " << this->Traversal << "\n";
  os << indent << "MacrocellResolution: " << this->MacrocellResolution << "\n";
  os << indent << "TemporalSlices: " << this->TemporalSlices << "\n";
  os << indent << "Shadows: " << this->Shadows << "\n";
  os << indent << "MaximumFrames: " << this->MaximumFrames << "\n";
  os << indent << "ConvergenceTarget: " << this->ConvergenceTarget << "\n";
  os << indent << "FramesPerRender: " << this->FramesPerRender << "\n";
  os << indent << "ProgressiveRefinement: " << this->ProgressiveRefinement << "\n";
  os << indent << "Macrocells in use: " << this->Internal->macrocellsInUse << "\n";
  os << indent << "Seed: " << this->Seed << "\n";
  os << indent << "InteractiveLevelOfDetail: " << this->InteractiveLevelOfDetail << "\n";
  os << indent << "InteractiveFrameTime: " << this->InteractiveFrameTime << " ms\n";
  os << indent << "InteractiveUpdateRate: " << this->InteractiveUpdateRate << "\n";
  os << indent << "InteractiveMacrocellResolution: " << this->InteractiveMacrocellResolution
     << "\n";
  os << indent << "InteractiveMacrocellsAhead: " << this->InteractiveMacrocellsAhead << "\n";
  os << indent << "InteractiveFreshFrames: " << this->InteractiveFreshFrames << "\n";
  os << indent << "QueryReduction: " << InrDescribeQueryReduction(this->Internal->queryReduction)
     << " (in use: " << this->Internal->queryReductionInUse << ")\n";
}
