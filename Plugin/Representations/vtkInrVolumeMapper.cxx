#include "vtkInrVolumeMapper.h"

#include "vtkActor.h"
#include "vtkActor2D.h"
#include "vtkCallbackCommand.h"
#include "vtkCamera.h"
#include "vtkDataSet.h"
#include "vtkDualDepthPeelingPass.h"
#include "vtkMath.h"
#include "vtkWeakPointer.h"
#include "vtkFieldData.h"
#include "vtkInformation.h"
#include "vtkInformationObjectBaseVectorKey.h"
#include "vtkMatrix4x4.h"
#include "vtkObjectFactory.h"
#include "vtkOpenGLRenderPass.h"
#include "vtkOpenGLRenderWindow.h"
#include "vtkPropCollection.h"
#include "vtkRenderer.h"
#include "vtkUnsignedCharArray.h"
#include "vtkVolume.h"
#include "vtk_glew.h"

#include "InrCudaGlInterop.h"
#include "InrEngineSlots.h"
#include "InrFramebufferCompositor.h"
#include "InrLevelOfDetail.h"
#include "InrMapperRanks.h"
#include "InrMapperReport.h"
#include "InrParallelRendering.h"
#include "InrRenderDecision.h"
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
#include <ctime>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>
#include "Common/Stopwatch.h"

namespace
{
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

// CPU time of the whole process (all its threads), ms: logged beside the engine's wall time
// (INR_VOLUME_LOD_LOG) to see how much of a frame's time a loaded machine adds.
double processCpuMs()
{
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * double(t.tv_sec) + 1e-6 * double(t.tv_nsec);
}

bool lodReport()
{
  const char* v = std::getenv("INR_VOLUME_LOD_LOG");
  return v && v[0] && std::string(v) != "0";
}

using inr::Clock;
using inr::msSince;

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
  // Model identity: the bytes array and its modification time (then the engines' content hash).
  vtkUnsignedCharArray* bytesPtr = nullptr;
  vtkMTimeType bytesMTime = 0;

  // The engine sessions (fine: the still image; coarse: reduced interactive frames of time changes
  // and drags with Reproject on), built from one request (InrEngineSlots.h); the options as asked,
  // valid and refused.
  InrEngines engines;
  InrBackgroundWorker& worker = engines.worker;
  InrEngineOptions options;
  // What the panel shows (InrMapperReport.h): written as the render goes; Report refreshes its
  // refinement figures from the engine, ReportEngineCounters its counters (joining the worker).
  InrMapperReport report;
  const InrMapperReport& Report(vtkInrVolumeMapper* self);
  const InrMapperReport& ReportEngineCounters(vtkInrVolumeMapper* self, bool joinFine);
  bool uploadedCoarse = false;  // the uploaded texture came from the coarse session
  bool warnedLightsLeftOut = false;  // Shade's lights the engine left out: said once
  inr::RenderSession* Shown() const
  {
    return this->report.shownCoarse && this->engines.coarse.session ? this->engines.coarse.session.get()
                                                             : this->engines.fine.session.get();
  }

  // Level of detail (InrLevelOfDetail.h): the policy and its cost model; the mapper's options
  // as the policy reads them.
  InrLevelOfDetail lod;
  // The cost model of camera drags drawn on the stand-in (InteractiveStandIn): far cheaper per
  // pixel than the network's frames, so its scale must not carry over to time changes and back.
  InrLevelOfDetail lodStandIn;
  InrLevelOfDetail::Settings LodSettings(vtkInrVolumeMapper* self) const;
  // Whether a reduced interactive frame renders on the coarse session (creating it if needed).
  bool RendersCoarse(vtkInrVolumeMapper* self, const InrLevelOfDetail::Decision& d)
  {
    return InrLevelOfDetail::RendersCoarse(d, this->options.queryReduction.reproject, true) &&
      this->engines.UpdateCoarse(self->InteractiveMacrocellResolution);
  }
  void BuildCoarseAhead(vtkInrVolumeMapper* self)
  {
    this->aheadMs += this->engines.BuildCoarseAhead(self->InteractiveMacrocellResolution, lodReport());
  }
  // Whether long macrocell builds go to the worker thread (the GUI: background builds on, CPU
  // backend, GUI-like refinement; InrLevelOfDetail::BuildsFineInBackground).
  bool BuildsInBackground(vtkInrVolumeMapper* self) const;
  // Whether this render is the GUI's first of this mapper, put off to the next one
  // (firstRender).
  bool DefersFirstRender(vtkInrVolumeMapper* self) const;
  // The GUI's still renders of the fine session refine it on the worker, one refinement step at
  // a time (InrBackgroundWorker.h); while the worker holds the fine session the panel reads what
  // was kept of it.
  vtkOpenGLRenderWindow* uploadedWindow = nullptr;  // the window the texture was loaded for
  int ShownFrames() const
  {
    return !this->report.shownCoarse && this->worker.FineRefining()
      ? this->worker.KeptFrames()
      : this->Shown() ? this->Shown()->accumulatedFrames() : 0;
  }

  // Renders prepared outside the GL render (PrepareRender): once a view does that, progress is
  // reported only there (quietRenders), never from inside Render (insideRender).
  bool quietRenders = false;
  bool insideRender = false;
  void SetInsideRender(bool inside)
  {
    this->insideRender = inside;
    this->engines.muteProgress = this->quietRenders && inside;
  }

  // VTK -> engine (transfer-function cache), progressive refinement, drawing.
  InrSceneTranslator translator;
  // The window's depth over the render tile (GL rows) where `depthValid`: the nearest opaque
  // geometry drawn before the volume, under MPI of every rank (CompositeDepth).
  std::vector<float> depth;
  bool depthValid = false;
  InrFramebufferCompositor compositor;
  // The CUDA image into the compositor's texture on the GPU; after a failure (`imageTransfer`
  // says why) the image goes through host memory for the rest of the mapper's life.
  InrCudaGlInterop interop;
  bool interopFailed = false;
  std::string imageTransfer;

  // The budget is for the whole window render: what the window spends outside this mapper
  // (other props, clear, swap; ParaView's view) is measured by observing the window's render.
  vtkWeakPointer<vtkRenderWindow> observedWindow;
  vtkNew<vtkCallbackCommand> windowObserver;
  Clock::time_point windowStart;
  double aheadMs = 0.0;  // of this window render, spent building coarse slices ahead (not a cost
                         // of the window's frames: left out of the window's fixed cost)
  bool renderedInWindow = false;
  // The GUI's first render of this mapper is put off to the next turn of the event loop
  // (DefersFirstRender): not reached yet, put off (the next render does the work), or done.
  enum class FirstRender
  {
    NotReached,
    PutOff,
    Done
  };
  FirstRender firstRender = FirstRender::NotReached;
  // The refinement budget is for the view's whole render: where it began (the view's update, when
  // MarkViewUpdate came after the last render, else the window's render) and what the window
  // spends after this mapper's Render (measured: drawing, swap).
  Clock::time_point viewUpdateStart;
  bool viewUpdatePending = false;
  Clock::time_point framesEnd;  // this render's last frame (compositing and the window follow)
  double afterMs = 0.0;
  double lastEngineBudgetMs = -1.0;  // the frames' share of the last still render (for the log)
  double EngineTimeBudget(double viewBudgetMs) const;
  void ObserveWindow(vtkRenderWindow* window);
  void StopObserving();
  static void OnWindowEvent(vtkObject*, unsigned long event, void* clientData, void*);

  // For the INR_VOLUME_DEBUG report of what changed.
  bool haveLastScene = false;
  inr::RenderScene lastScene;

  // Tiled rendering: where this render's image lies in the full picture (whole: fullWidth 0).
  inr::ImageWindow window;
  // Sub-domain rendering under MPI (InrMapperRanks.h): this rank's device, pixel share and
  // depth composite, and the refinement state reduced over all ranks after each render.
  InrMapperRanks ranks;
  // Reduces the refinement state over the ranks once per Render, on every exit path: every rank
  // must take part in the collective or the others wait forever.
  void ReduceOverRanks(vtkInrVolumeMapper* self, bool rendered);
  // Once-per-mapper warnings: translucent geometry in the renderer, camera features ignored.
  bool warnedTranslucent = false, warnedPeeling = false;
  int uploadedEpoch = -1;  // the session's resets + reprojections when the image was uploaded
  std::string warnedCamera;
  void WarnAboutScene(vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, int width, int height);

  bool UpdateModel(vtkUnsignedCharArray* bytes);
  InrEngineRequest Request(vtkInrVolumeMapper* self);
  bool UpdateEngine(vtkInrVolumeMapper* self);
  inr::RenderScene TranslateScene(vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol,
    vtkDataSet* input, const Viewport& tile);
  // This render's decision (Decide: InrRenderDecision with the mapper's state as its queries).
  InrRenderDecision decision;
  InrRenderDecision::Inputs DecisionInputs(
    vtkInrVolumeMapper* self, vtkRenderer* ren, double time, const Viewport& tile);
  InrRenderDecision Decide(vtkInrVolumeMapper* self, const InrRenderDecision::Inputs& in, double time);
  bool Refine(vtkInrVolumeMapper* self, const inr::RenderScene& scene,
    const InrRenderDecision::Inputs& in);
  void Composite(vtkInrVolumeMapper* self, vtkRenderer* ren, int width, int height);
};

vtkStandardNewMacro(vtkInrVolumeMapper);

vtkInrVolumeMapper::vtkInrVolumeMapper()
  : Internal(new Internals)
{
  InrEngines& engines = this->Internal->engines;
  engines.error = [this](const std::string& message) { vtkErrorMacro(<< message); };
  engines.warning = [this](const std::string& message) { vtkWarningMacro(<< message); };
  const bool* muted = &engines.muteProgress;
  engines.progress = [this, muted](const std::string& prefix)
  { return progressHandler(this, prefix, muted); };
  // Frames measured while the worker shared the CPU were slower: a scale barred by them may be
  // tried again.
  engines.worker.joined = [this]()
  {
    this->Internal->lod.ForgetCeiling();
    this->Internal->lodStandIn.ForgetCeiling();
  };
}

vtkInrVolumeMapper::~vtkInrVolumeMapper()
{
  this->Internal->worker.JoinBackgroundBuild();
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
  this->Internal->worker.JoinBackgroundBuild();
  for (InrEngineSlot* slot : { &this->Internal->engines.fine, &this->Internal->engines.coarse })
  {
    if (slot->session)
    {
      slot->session->resetAccumulation();
    }
    slot->refinement.restart();
  }
}

// The panel's figures (InrMapperReport.h). The refinement figures are refreshed from the engine
// whenever read: a reset, a property change or a finished job between renders shows at once.
const InrMapperReport& vtkInrVolumeMapper::Internals::Report(vtkInrVolumeMapper* self)
{
  InrMapperReport& r = this->report;
  r.ranks = this->ranks.Ranks().count;
  r.haveEngine = this->engines.fine.session != nullptr;
  r.frames = this->ShownFrames();
  // Without progressive refinement nothing renders again by itself: "stopped" from the start.
  // A reduced interactive image is never the final one: a still render must follow. A
  // refinement step running on the worker, or a first render put off: not converged yet.
  r.localConverged = this->firstRender != FirstRender::PutOff &&
    (!self->ProgressiveRefinement ||
      (!this->lod.LastInteractive() && !this->worker.FineRefining() &&
        this->engines.fine.refinement.converged()));
  r.estimate = this->worker.FineRefining() ? this->worker.KeptEstimate()
                                            : this->engines.fine.refinement.estimate();
  r.queryReductionInUse = this->engines.queryReductionInUse;
  r.engineBuilds = this->engines.engineBuilds;
  return r;
}

// The sessions' counters, once the worker's job on them is done: `joinFine` waits for a job on
// the fine session only (the fine session's figures; the coarse ones may be on the worker),
// else any job finishes first (both sessions' figures).
const InrMapperReport& vtkInrVolumeMapper::Internals::ReportEngineCounters(
  vtkInrVolumeMapper* self, bool joinFine)
{
  if (joinFine)
  {
    this->worker.JoinFineBuild();
  }
  else
  {
    this->worker.FinishBackgroundBuild();
  }
  InrMapperReport& r = this->report;
  const auto& fine = this->engines.fine.session;
  const auto& coarse = this->engines.coarse.session;
  r.slicesBuilt = fine ? fine->macrocellInfo().slicesBuilt : 0;
  r.engineOptions = fine ? InrDescribeSession(*fine) : "";
  if (!joinFine)
  {
    r.interactiveSlicesBuilt = coarse ? coarse->macrocellInfo().slicesBuilt : 0;
    r.interactiveEngineOptions = coarse ? InrDescribeSession(*coarse) : "";
    // On the CPU the coarse session's evaluator is the switch to a stand-in (InrStandInSwitch),
    // around the fine session's network.
    const InrStandInSwitch* standIn = this->engines.StandIn();
    const inr::FieldEvaluator* coarseNetwork =
      coarse ? (standIn ? &standIn->Network() : &coarse->evaluator()) : nullptr;
    r.sharesEvaluator = fine && coarse && &fine->evaluator() == coarseNetwork;
  }
  return this->Report(self);
}

int vtkInrVolumeMapper::GetAccumulatedFrames()
{
  return this->Internal->Report(this).Frames();
}

int vtkInrVolumeMapper::GetConverged()
{
  return this->Internal->Report(this).Converged() ? 1 : 0;
}

int vtkInrVolumeMapper::GetLocalConverged()
{
  return this->Internal->Report(this).localConverged ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderInteractive()
{
  return this->Internal->report.interactive ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastImageWidth()
{
  return this->Internal->report.imageWidth;
}

int vtkInrVolumeMapper::GetLastImageHeight()
{
  return this->Internal->report.imageHeight;
}

double vtkInrVolumeMapper::GetLastRenderMilliseconds()
{
  return this->Internal->report.renderMs;
}

double vtkInrVolumeMapper::GetConvergenceEstimate()
{
  return this->Internal->Report(this).Estimate();
}

std::string vtkInrVolumeMapper::FormatConvergenceEstimate(double db)
{
  return InrFormatConvergenceEstimate(db);
}

const char* vtkInrVolumeMapper::GetConvergenceEstimateText()
{
  InrMapperReport& r = this->Internal->report;
  r.estimateText = InrFormatConvergenceEstimate(this->Internal->Report(this).Estimate());
  return r.estimateText.c_str();
}

const char* vtkInrVolumeMapper::GetRefinementState()
{
  InrMapperReport& r = this->Internal->report;
  r.refinementState = InrDescribeRefinement(this->Internal->Report(this),
    InrRefinementLimits{ this->ProgressiveRefinement != 0, this->ConvergenceTarget, this->MaximumFrames });
  return r.refinementState.c_str();
}

const char* vtkInrVolumeMapper::GetBackendInUse()
{
  return this->Internal->report.backendInUse.c_str();
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
  return this->Internal->report.ranksInUse.c_str();
}

double vtkInrVolumeMapper::GetLastUpdateMilliseconds()
{
  return this->Internal->report.step.total.updateMs;
}

int vtkInrVolumeMapper::GetSlicesBuilt()
{
  return this->Internal->ReportEngineCounters(this, true).slicesBuilt;
}

int vtkInrVolumeMapper::GetInteractiveSlicesBuilt()
{
  return this->Internal->ReportEngineCounters(this, false).interactiveSlicesBuilt;
}

const char* vtkInrVolumeMapper::GetEngineOptionsInUse()
{
  return this->Internal->ReportEngineCounters(this, true).engineOptions.c_str();
}

const char* vtkInrVolumeMapper::GetInteractiveEngineOptionsInUse()
{
  return this->Internal->ReportEngineCounters(this, false).interactiveEngineOptions.c_str();
}

int vtkInrVolumeMapper::GetInteractiveSharesEvaluator()
{
  return this->Internal->ReportEngineCounters(this, false).sharesEvaluator ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderStandIn()
{
  return this->Internal->report.shownStandIn ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderCoarse()
{
  return this->Internal->report.shownCoarse ? 1 : 0;
}

double vtkInrVolumeMapper::InteractiveFreshFrameScale(double scale, int fresh)
{
  return InrLevelOfDetail::FreshFrameScale(scale, fresh);
}

int vtkInrVolumeMapper::InteractiveFreshFrameCount(double scale, int fresh)
{
  return InrLevelOfDetail::FreshFrameCount(scale, fresh);
}

int vtkInrVolumeMapper::GetEngineBuilds()
{
  return this->Internal->Report(this).engineBuilds;
}

double vtkInrVolumeMapper::GetLastQueries()
{
  return double(this->Internal->report.step.total.totalQueries());
}

double vtkInrVolumeMapper::GetLastRays()
{
  return double(this->Internal->report.step.total.rays);
}

double vtkInrVolumeMapper::GetLastBudgetSkipped()
{
  return double(this->Internal->report.step.total.budgetSkipped);
}

double vtkInrVolumeMapper::GetLastPruned()
{
  return double(this->Internal->report.step.total.pruned);
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
INR_STORED_OPTION(RayBudget, int, options.queryReduction.budget, static_cast<inr::BudgetScheme>(v),
  static_cast<int>(this->Internal->options.queryReduction.budget))
INR_STORED_OPTION(BudgetFraction, double, options.queryReduction.budgetFraction, v,
  this->Internal->options.queryReduction.budgetFraction)
INR_STORED_OPTION(BudgetMaxSkip, int, options.queryReduction.budgetMaxSkip, v,
  this->Internal->options.queryReduction.budgetMaxSkip)
INR_STORED_OPTION(BudgetAlpha, double, options.queryReduction.budgetAlpha, v,
  this->Internal->options.queryReduction.budgetAlpha)
INR_STORED_OPTION(Reproject, int, options.queryReduction.reproject, v != 0,
  this->Internal->options.queryReduction.reproject ? 1 : 0)
INR_STORED_OPTION(PruneEpsilon, double, options.queryReduction.pruneEpsilon, v,
  this->Internal->options.queryReduction.pruneEpsilon)
INR_STORED_OPTION(PruneFalloff, double, options.queryReduction.pruneFalloff, v,
  this->Internal->options.queryReduction.pruneFalloff)

const char* vtkInrVolumeMapper::GetQueryReductionInUse()
{
  return this->Internal->Report(this).queryReductionInUse.c_str();
}

INR_STORED_OPTION(SkipBlock, int, options.macrocellsAsked.skipBlockCells, v,
  this->Internal->options.macrocellsAsked.skipBlockCells)
INR_STORED_OPTION(BoundsPadding, double, options.macrocellsAsked.boundsPadding, v,
  this->Internal->options.macrocellsAsked.boundsPadding)
INR_STORED_OPTION(GhostPasses, int, options.trackingAsked.ghostPassesOnUpdate, v,
  this->Internal->options.trackingAsked.ghostPassesOnUpdate)
INR_STORED_OPTION(RefineMacrocells, int, options.trackingAsked.refineMacrocells, v != 0,
  this->Internal->options.trackingAsked.refineMacrocells ? 1 : 0)
INR_STORED_OPTION(Estimator, int, options.trackingAsked.estimator, static_cast<inr::PrimaryEstimator>(v),
  static_cast<int>(this->Internal->options.trackingAsked.estimator))
INR_STORED_OPTION(MajorantScale, double, options.trackingAsked.majorantScale, v,
  this->Internal->options.trackingAsked.majorantScale)
INR_STORED_OPTION(ResidualScale, double, options.trackingAsked.residualScale, v,
  this->Internal->options.trackingAsked.residualScale)
INR_STORED_OPTION(PointsPerIteration, int, options.trackingAsked.pointsPerIteration, v,
  this->Internal->options.trackingAsked.pointsPerIteration)
#undef INR_STORED_OPTION

const char* vtkInrVolumeMapper::GetMacrocellsInUse()
{
  return this->Internal->report.macrocellsInUse.c_str();
}

void vtkInrVolumeMapper::ReleaseGraphicsResources(vtkWindow* win)
{
  this->Internal->interop.Release();  // before its texture goes
  this->Internal->compositor.ReleaseGraphicsResources(win);
  this->Internal->uploadedWindow = nullptr;
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
  if (I.DefersFirstRender(this))
  {
    return;  // Render puts it off
  }
  if (I.worker.BuildDone())
  {
    I.worker.FinishBackgroundBuild();  // finished on the worker: join it
    if (lodReport() && I.worker.LastCoarseAheadMs() > 0.0)
    {
      std::fprintf(stderr, "INR Volume LOD: interactive macrocell slices built ahead on a worker "
                           "thread, %.1f ms\n", I.worker.LastCoarseAheadMs());
    }
  }
  if (vtkAlgorithm* producer = this->GetInputAlgorithm())
  {
    producer->Update();
  }
  vtkDataSet* input = this->GetInput();
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  auto* bytes = vtkUnsignedCharArray::SafeDownCast(fd ? fd->GetAbstractArray("InrModel") : nullptr);
  if (!bytes || bytes->GetNumberOfValues() == 0 || !I.UpdateModel(bytes) || !I.UpdateEngine(this))
  {
    return;  // Render reports what is wrong
  }
  if (I.worker.FineBuilding())
  {
    // Still building on the worker: show how far (the render draws the coarse session).
    this->SetProgressText("INR Volume: building macrocells");
    this->UpdateProgress(I.worker.BuildProgress());
    this->SetProgressText(nullptr);
    return;
  }
  const inr::InrModel& model = I.engines.Model();
  const double time =
    InrSceneTranslator::Time(input, 0.5 * (model.domain.timeBegin + model.domain.timeEnd));
  const InrLevelOfDetail::Settings lod = I.LodSettings(this);
  const InrLevelOfDetail::Decision d = I.lod.Classify(lod,
    ren->GetRenderWindow() ? ren->GetRenderWindow()->GetDesiredUpdateRate() : 0.0, time);
  const bool coarse = I.RendersCoarse(this, d);
  try
  {
    if (coarse)
    {
      I.engines.coarse.session->buildSlicesFor(time);
    }
    else if (I.worker.FineRefining())
    {
      // The worker holds the fine session for a refinement step: this render draws its image, or
      // a reduced coarse frame when the time moved (Render); the fine slices of the new time
      // build once the step is done.
      if (I.worker.FineTimeDiffers(time) &&
        I.engines.UpdateCoarse(this->InteractiveMacrocellResolution))
      {
        I.engines.coarse.session->buildSlicesFor(time);
      }
    }
    else if (!I.worker.DeferFineBuild(
               time, I.BuildsInBackground(this), this->InteractiveMacrocellResolution))
    {
      I.engines.fine.session->buildSlicesFor(time);
    }
  }
  catch (const std::exception&)
  {
    // The render's setScene meets the same failure and reports it.
  }
  if (I.worker.FineBusy() || I.worker.FineBuildPending())
  {
    return;
  }
  // The coarse slices of later time-change frames, once a still image of the fine grid is shown
  // (the first image is not delayed by them): on the worker where the fine slices may build
  // there (the GUI: the event loop is not held for the whole build; a render that needs the
  // coarse session stops it within a slice, and a later still render builds the rest), else here.
  if (!d.interactive && !I.lod.LastInteractive() &&
    I.engines.fine.session->accumulatedFrames() > 0 && InrLevelOfDetail::BuildsCoarseAhead(lod))
  {
    if (I.BuildsInBackground(this))
    {
      if (I.worker.StartCoarseAhead(this->InteractiveMacrocellResolution))
      {
        this->SetProgressText("INR Volume (interactive macrocells): building macrocells");
        this->UpdateProgress(I.worker.BuildProgress());
        this->SetProgressText(nullptr);
      }
    }
    else
    {
      I.BuildCoarseAhead(this);
    }
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
  // The depth limit before anything can return: under MPI its composite is collective, and a
  // rank that draws nothing must still bring its geometry to the others' rays.
  I.depthValid = I.ranks.CompositeDepth(ren, vol, I.depth);
  I.ranks.LookUpLocalRank();
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
  if (I.DefersFirstRender(this))
  {
    // The render inside Apply (ParaView's own work there, pipeline update, representation and
    // panel, already holds the event loop for a long while): the engine, the coarse macrocells
    // and the first frame come with the refinement behaviour's render, a turn of the event loop
    // later (the converged state says "not yet"). Figures: RESULTS.md, "Apply: the plugin's part
    // of the event-loop stall".
    I.firstRender = Internals::FirstRender::PutOff;
    // Observed from this window render on: its end clears the view-update mark, so Apply's
    // pipeline update is no part of the next render's budget.
    I.ObserveWindow(ren->GetRenderWindow());
    return;
  }
  I.firstRender = Internals::FirstRender::Done;
  if (!I.UpdateModel(bytes) || !I.UpdateEngine(this))
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
  I.lastEngineBudgetMs = -1.0;
  const auto refineStart = Clock::now();
  const double refineCpuStart = processCpuMs();
  // What this render does (InrRenderDecision.h): reduced or still, which session, on the worker.
  const InrRenderDecision::Inputs in = I.DecisionInputs(this, ren, scene.time, tile);
  I.decision = I.Decide(this, in, scene.time);
  const InrRenderDecision& dec = I.decision;
  const InrLevelOfDetail::Decision& d = dec.lod;
  const bool interactive = dec.frame.interactive, useCoarse = dec.useCoarse;
  const bool background = dec.background, drawStandIn = dec.drawStandIn;
  const int width = dec.frame.width, height = dec.frame.height;
  if (interactive)
  {
    scene.depthLimit = resampleDepthLimit(scene.depthLimit, tile.width, tile.height, width, height);
  }
  I.lod.SawTime(scene.time);  // the one model that classifies renders (lodStandIn only plans)
  if (dec.joinFine)
  {
    I.worker.JoinFineBuild();  // this frame needs the fine session: wait for the worker
  }
  I.engines.UseStandIn(drawStandIn);
  const bool refined = I.Refine(this, scene, in);
  I.engines.UseStandIn(false);
  I.report.shownStandIn = drawStandIn && refined;
  if (!refined)
  {
    return;
  }
  if (!useCoarse && !background && I.worker.HasFineScene())
  {
    I.engines.KeepStandIn(I.worker.FineSceneTime());  // a frame of the fine session was rendered here
  }
  reduction.rendered = true;
  const double refineMs = msSince(refineStart);
  I.framesEnd = Clock::now();
  const double refineCpuMs = processCpuMs() - refineCpuStart;
  const auto compositeStart = Clock::now();
  I.Composite(this, ren, width, height);
  if (interactive)
  {
    // The image must be drawn before the time is read (the GL pipeline is asynchronous).
    glFinish();
  }
  const double compositeMs = msSince(compositeStart);
  I.report.renderMs = msSince(renderStart);
  I.lod.Drew(interactive);
  I.report.interactive = interactive;
  I.lodStandIn.Drew(interactive);
  I.renderedInWindow = true;
  I.report.imageWidth = width;
  I.report.imageHeight = height;
  if (background)
  {
    // The step's frames were rendered on the worker: its own time is the engine's part; this
    // render's time outside its refinement part (which holds the wait for the step) is the
    // render's fixed cost.
    const double engineMs = I.report.step.total.totalMs;
    I.lod.MeasureFrame(std::max(0.0, I.report.renderMs - refineMs) + engineMs,
      engineMs, I.report.step.total.updateMs, I.report.step.framesRendered, width, height, false);
  }
  else
  {
    (drawStandIn ? I.lodStandIn : I.lod)
      .MeasureFrame(I.report.renderMs, refineMs, I.report.step.total.updateMs,
        I.report.step.framesRendered, width, height, interactive);
  }
  if (lodReport())
  {
    std::string worker;
    if (background)
    {
      char step[160];
      std::snprintf(step, sizeof(step), ", refining on the worker (%s; step joined: %d frames, %.1f ms)",
        I.worker.KeepsImage() ? "image kept" : "image drawn", I.report.step.framesRendered, I.report.step.total.totalMs);
      worker = step;
    }
    std::fprintf(stderr,
      "INR Volume LOD: %s frame %dx%d of %dx%d (scale %.3f), %.1f ms (budget %.0f ms; macrocell "
      "update %.1f ms; scene %.1f ms, engine %.1f ms of %.1f (process CPU %.1f ms), composite "
      "%.1f ms), frames %d%s%s\n",
      interactive ? "interactive" : "still", width, height, tile.width, tile.height,
      double(width) / tile.width, I.report.renderMs, d.budgetMs, I.report.step.total.updateMs,
      std::chrono::duration<double, std::milli>(refineStart - renderStart).count(), refineMs,
      I.lastEngineBudgetMs, refineCpuMs, compositeMs, I.ShownFrames(),
      useCoarse ? (drawStandIn ? ", coarse macrocells, stand-in" : ", coarse macrocells") : "",
      worker.c_str());
  }
  // A still render that time-change frames may follow: build the coarse slices they will need
  // now (after the frame is measured: it is no part of the frame's cost).
  // (A view that prepares its renders builds them in PrepareRender instead, outside the GL render.)
  if (!I.quietRenders && !interactive && I.window.fullWidth == 0 &&
    InrLevelOfDetail::BuildsCoarseAhead(in.lodSettings))
  {
    I.BuildCoarseAhead(this);
  }
  // The reduced coarse frame is drawn: a fine build put off for it starts on the worker now.
  I.worker.StartPendingFineBuild();
  I.worker.LaunchRefine();
}

void vtkInrVolumeMapper::MarkViewUpdate()
{
  if (!this->Internal->viewUpdatePending)  // the earliest mark since the last render
  {
    this->Internal->viewUpdateStart = Clock::now();
    this->Internal->viewUpdatePending = true;
  }
}

// What the frames of this render may take: the view's budget less the time this render has
// already spent (since the view's update began, or the window's render) and the measured time
// after the frames (compositing the image, the rest of the window's render). Never below 0,
// which adds one frame.
double vtkInrVolumeMapper::Internals::EngineTimeBudget(double viewBudgetMs) const
{
  if (viewBudgetMs <= 0.0)
  {
    return 0.0;
  }
  // A mark long before the window's render is not this render's own update (a script's
  // UpdatePipeline, then a pause): only the window's render counts then.
  constexpr std::chrono::milliseconds kStaleMark(1000);
  const bool marked = this->viewUpdatePending && this->viewUpdateStart < this->windowStart &&
    this->windowStart - this->viewUpdateStart < kStaleMark;
  const Clock::time_point began = marked ? this->viewUpdateStart : this->windowStart;
  const double spent = std::chrono::duration<double, std::milli>(Clock::now() - began).count();
  return std::max(0.0, viewBudgetMs - spent - this->afterMs);
}

// Starts building the fine slices for `time` on a worker thread where that keeps the GUI
// responsive (background builds on, InrLevelOfDetail::BuildsFineInBackground, a coarse session to
// draw meanwhile); false where the caller builds them itself.
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

int vtkInrVolumeMapper::GetBackgroundWorkRunning()
{
  const InrEngines& e = this->Internal->engines;
  return (e.worker.FineRefining() || e.worker.CoarseBusy()) && !e.worker.BuildDone() ? 1 : 0;
}

bool vtkInrVolumeMapper::Internals::BuildsInBackground(vtkInrVolumeMapper* self) const
{
  return backgroundBuilds && this->engines.fine.session &&
    InrLevelOfDetail::BuildsFineInBackground(
      this->LodSettings(self), this->engines.fine.session->backend() == inr::RenderBackend::Cpu);
}

bool vtkInrVolumeMapper::Internals::DefersFirstRender(vtkInrVolumeMapper* self) const
{
  // Only where something renders again by itself: the GUI's refinement behaviour (it turns
  // background builds on) renders while the state is not converged, and only with progressive
  // refinement on. Never for a capture or a tile of a larger picture (they must draw now), and
  // once per mapper.
  return this->firstRender == FirstRender::NotReached && backgroundBuilds && self->ProgressiveRefinement &&
    !self->Capturing && this->ranks.Ranks().count <= 1;
}

// What the render decision reads (InrRenderDecision::Inputs): the level-of-detail policy's
// classification (not for a tile of a larger picture), the worker's state, the properties.
InrRenderDecision::Inputs vtkInrVolumeMapper::Internals::DecisionInputs(
  vtkInrVolumeMapper* self, vtkRenderer* ren, double time, const Viewport& tile)
{
  InrRenderDecision::Inputs in;
  in.lodSettings = this->LodSettings(self);
  in.tile = this->window.fullWidth != 0;
  if (!in.tile)
  {
    in.lod = this->lod.Classify(in.lodSettings, ren->GetRenderWindow()->GetDesiredUpdateRate(), time);
  }
  in.width = tile.width;
  in.height = tile.height;
  in.fineOnWorker = this->worker.FineBuilding() || this->worker.FineBuildPending() ||
    this->worker.FineTimeDiffers(time);
  in.fineBusy = this->worker.FineBusy();
  in.fineRefining = this->worker.FineRefining();
  in.backgroundAllowed = this->BuildsInBackground(self);
  in.standInOption = self->InteractiveStandIn != 0;
  in.reproject = this->options.queryReduction.reproject;
  in.progressive = self->ProgressiveRefinement != 0;
  in.framesPerRender = self->FramesPerRender;
  in.maximumFrames = self->MaximumFrames;
  in.convergenceTarget = self->ConvergenceTarget;
  in.timeBudgetMs = self->RefinementTimeBudget;
  return in;
}

// The decision with the mapper's state as its queries: the coarse session (created on first use),
// the stand-in kept for `time`, and the cost model that plans the image (the stand-in's own for a
// drag drawn on it).
InrRenderDecision vtkInrVolumeMapper::Internals::Decide(
  vtkInrVolumeMapper* self, const InrRenderDecision::Inputs& in, double time)
{
  InrRenderDecision::Queries ask;
  ask.coarseSession = [this, self]()
  { return this->engines.UpdateCoarse(self->InteractiveMacrocellResolution); };
  ask.standInReady = [this, time]() { return this->engines.StandInReady(time); };
  ask.plan = [this, &in](const InrLevelOfDetail::Decision& d, bool standIn)
  { return (standIn ? this->lodStandIn : this->lod).Plan(in.lodSettings, d, in.width, in.height); };
  return InrRenderDecision::Decide(in, ask);
}

InrLevelOfDetail::Settings vtkInrVolumeMapper::Internals::LodSettings(vtkInrVolumeMapper* self) const
{
  InrLevelOfDetail::Settings s;
  s.mode = self->InteractiveLevelOfDetail;
  s.frameTimeMs = self->InteractiveFrameTime;
  s.updateRate = self->InteractiveUpdateRate;
  s.freshFrames = self->InteractiveFreshFrames;
  s.framesPerRender = self->FramesPerRender;
  s.progressiveRefinement = self->ProgressiveRefinement != 0;
  s.capturing = self->Capturing;
  s.coarseAhead = self->InteractiveMacrocellsAhead != 0;
  s.ranks = this->ranks.Ranks().count;
  return s;
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
  else if (event == vtkCommand::EndEvent)
  {
    // Whatever this window render drew, the next render's work starts after it.
    self->viewUpdatePending = false;
  }
  if (event == vtkCommand::EndEvent && self->renderedInWindow)
  {
    self->lod.WindowRendered(msSince(self->windowStart), self->report.renderMs, self->aheadMs);
    self->lodStandIn.WindowRendered(msSince(self->windowStart), self->report.renderMs, self->aheadMs);
    const double after = msSince(self->framesEnd);
    self->afterMs = self->afterMs > 0.0 ? 0.5 * (self->afterMs + after) : after;
    self->renderedInWindow = false;
  }
}

// The model: loaded again only when its bytes changed (array, modification time, then the
// engines' content hash).
bool vtkInrVolumeMapper::Internals::UpdateModel(vtkUnsignedCharArray* bytes)
{
  if (bytes != this->bytesPtr || bytes->GetMTime() != this->bytesMTime)
  {
    this->bytesPtr = bytes;
    this->bytesMTime = bytes->GetMTime();
    this->engines.SetModel(bytes->GetPointer(0), static_cast<std::size_t>(bytes->GetNumberOfValues()));
  }
  return this->engines.HasModel();
}

// What the user asked of the engine (the properties, checked by InrEngineOptions::Check), with
// the device of this rank: what both sessions are built from (InrSessionOptions).
InrEngineRequest vtkInrVolumeMapper::Internals::Request(vtkInrVolumeMapper* self)
{
  this->options.Check(this->engines.error);
  InrEngineRequest r;
  r.backend = self->Backend == BACKEND_CUDA ? inr::RenderBackend::Cuda
    : self->Backend == BACKEND_CPU          ? inr::RenderBackend::Cpu
                                            : inr::RenderBackend::Auto;
  r.traversal = self->Traversal == TRAVERSAL_DDA ? inr::TraversalKind::Dda
    : self->Traversal == TRAVERSAL_OPTIX         ? inr::TraversalKind::Optix
                                                 : inr::TraversalKind::Auto;
  r.resolution = self->MacrocellResolution;
  r.temporalSlices = self->TemporalSlices;
  r.modelUsesTime = this->engines.Model().domain.usesTime();
  r.skipBlockCells = this->options.macrocellsValid.skipBlockCells;
  r.boundsPadding = this->options.macrocellsValid.boundsPadding;
  r.tracking = this->options.trackingValid;
  // One GPU per rank: the rank's index on its node picks the device (InrMapperRanks).
  const int device = this->ranks.CudaDevice();
  if (device >= 0)
  {
    r.cudaDevice = device;
  }
  return r;
}

// The engine sessions for the properties (InrEngines::UpdateFine: rebuilt when a build option
// changed, with progress through the mapper's ProgressEvent), and what runs, for the panel.
bool vtkInrVolumeMapper::Internals::UpdateEngine(vtkInrVolumeMapper* self)
{
  const InrEngineRequest want = this->Request(self);
  if (!this->engines.UpdateFine(want))
  {
    return false;
  }
  const InrEngineSlot& f = this->engines.fine;
  if (this->engines.Rebuilt())
  {
    this->worker.SessionRebuilt();
  }
  const std::string& rankNote = this->ranks.Note(this->engines.Rebuilt(),
    f.session->backend() == inr::RenderBackend::Cuda, f.built.cudaDevice);
  if (!this->worker.FineBusy())
  {
    this->report.backendInUse = f.session->description() +
      (this->imageTransfer.empty() ? "" : "; " + this->imageTransfer) + rankNote;
    this->report.macrocellsInUse = InrDescribeMacrocells(*f.session);
  }
  return true;
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
  // Depth limit: world distance to the opaque geometry rendered before the volume (of every rank:
  // CompositeDepth, called for this tile at the start of the render).
  if (this->depthValid)
  {
    scene.depthLimit = InrSceneTranslator::DepthToRayDistances(this->depth, width, height, cam);
  }
  double valueRange[2];
  InrSceneTranslator::ValueRange(input->GetFieldData(), valueRange);
  scene.transferFunction = this->translator.UpdateTransferFunction(
    vol->GetProperty(), self->UseDefaultTransferFunction != 0, valueRange);
  const inr::InrModel& model = this->engines.Model();
  scene.time =
    InrSceneTranslator::Time(input, 0.5 * (model.domain.timeBegin + model.domain.timeEnd));
  scene.background = { 0.f, 0.f, 0.f };
  scene.shadows = self->Shadows != 0;
  const double* l = self->LightDirection;
  scene.toLight = (l[0] == 0.0 && l[1] == 0.0 && l[2] == 0.0)
    ? inr::defaultLightDirection(scene.camera)
    : std::array<double, 3>{ l[0], l[1], l[2] };
  scene.ambient = static_cast<float>(self->Ambient);
  scene.shadowEstimator =
    self->ShadowEstimator == 1 ? inr::ShadowEstimator::Ratio : inr::ShadowEstimator::Delta;
  // The automatic light with shading alone is the view's lights (its light kit, headlight,
  // additional lights), taken as VTK's volume mapper takes them; shadows and a set
  // LightDirection light along that one direction.
  const bool automaticLight = l[0] == 0.0 && l[1] == 0.0 && l[2] == 0.0;
  const int left = InrSceneTranslator::TranslateShading(
    vol->GetProperty(), automaticLight && !scene.shadows ? ren : nullptr, scene);
  if (left > 0 && !this->warnedLightsLeftOut)
  {
    this->warnedLightsLeftOut = true;
    this->engines.warning("INR Volume: Shade lights the volume with the view's first " +
      std::to_string(inr::kMaxShadingLights) + " usable lights; " + std::to_string(left) +
      " are left out (beyond that number, or with no direction, a negative or an over-large "
      "intensity). Turn lights off or mend them in the view's Light Inspector.");
  }
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

// Hands the scene to the engine (it decides what to redo: SceneChange), then accumulates frames
// as the refinement options allow (RefinementDriver). False when the engine failed.
bool vtkInrVolumeMapper::Internals::Refine(vtkInrVolumeMapper* self,
  const inr::RenderScene& scene, const InrRenderDecision::Inputs& in)
{
  const int width = this->decision.frame.width, height = this->decision.frame.height;
  const bool useCoarse = this->decision.useCoarse, background = this->decision.background;
  // The session drawing this render: the fine one, or the coarse one for a time-change
  // interactive frame.
  InrEngineSlot& slot = useCoarse ? this->engines.coarse : this->engines.fine;
  this->report.shownCoarse = useCoarse;
  this->worker.BeginRender();
  inr::RenderSettings settings;
  settings.width = width;
  settings.height = height;
  settings.seed = static_cast<std::uint32_t>(self->Seed);
  settings.window = this->window;
  this->ranks.Share(settings);
  if (background && !this->worker.JoinRefineStep(scene, settings, this->report.step))
  {
    return true;  // the worker is busy: this render draws the image it has
  }
  if (!background)
  {
    this->worker.TakeRefineStep();  // a step joined for this render: its frames are in the image
  }
  inr::RenderSession& engine = *slot.session;
  inr::RefinementDriver& refinement = slot.refinement;
  if (!useCoarse)
  {
    this->worker.HandedFineScene(scene);
  }
  try
  {
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
    this->engines.PushQueryReduction(slot, this->options.queryReduction);
    engine.setScene(scene);

    // A step on the worker does not hold the view: it gets the whole budget; a frame here what
    // is left of it now.
    const inr::RefinementOptions options = this->decision.Refinement(in,
      this->decision.budget == InrRenderDecision::Budget::Remaining
        ? this->EngineTimeBudget(self->RefinementTimeBudget)
        : 0.0);
    if (this->decision.budget != InrRenderDecision::Budget::None)
    {
      this->lastEngineBudgetMs = options.timeBudgetMs;
    }
    refinement.setOptions(options);
    if (background)
    {
      // The frames go to the worker once this render has drawn (Render: LaunchRefine); this
      // render shows the steps joined so far (report.step, from JoinRefineStep).
      this->worker.PlanRefineStep(engine, refinement);
      return true;
    }
    this->report.step = inr::RefinementDriver::Step{};
    this->report.step = refinement.advance(engine);
    if (debug && this->report.step.framesRendered > 0)
    {
      std::fprintf(stderr,
        "INR Volume: now %d frames, %.0f queries, update %.1f ms, converged %d; %s: %.0f rays, "
        "%.0f pixels skipped, %.0f pruned\n",
        engine.accumulatedFrames(), double(this->report.step.total.totalQueries()),
        this->report.step.total.updateMs, int(refinement.converged()),
        this->engines.queryReductionInUse.c_str(), double(this->report.step.total.rays),
        double(this->report.step.total.budgetSkipped), double(this->report.step.total.pruned));
    }
    return true;
  }
  catch (const std::exception& e)
  {
    vtkErrorWithObjectMacro(self, << "INR Volume: rendering failed: " << e.what());
    return false;
  }
}

// What this rank did, reduced over the ranks (InrMapperRanks::Reduce).
void vtkInrVolumeMapper::Internals::ReduceOverRanks(vtkInrVolumeMapper* self, bool rendered)
{
  InrMapperRanks::Local local;
  local.rendered = rendered;
  if (rendered)
  {
    local.queries = this->report.step.total.totalQueries();
    local.shownFrames = this->ShownFrames();
    local.frames = this->Shown() ? this->Shown()->accumulatedFrames() : std::numeric_limits<int>::max();
    local.converged = self->GetLocalConverged() != 0;
    local.estimate = this->engines.fine.refinement.estimate();
    local.backend = this->report.backendInUse;
  }
  this->ranks.Reduce(local, this->report);
}

// Draws the accumulated image over what is in the framebuffer; the texture is loaded again only
// when the image changed.
void vtkInrVolumeMapper::Internals::Composite(
  vtkInrVolumeMapper* self, vtkRenderer* ren, int width, int height)
{
  auto* window = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow());
  if (!window)
  {
    return;
  }
  // The worker holds the fine session (KeepsImage), or its first frame of a new image is still to
  // come: the image on screen stays (the previous one, or the coarse one) rather than a blank view.
  if (this->worker.KeepsImage() ||
    (this->worker.StartsRefine() && this->engines.fine.session->accumulatedFrames() == 0))
  {
    std::string error;
    if (this->uploadedWindow == window && !this->compositor.Blend(window, &error))
    {
      vtkErrorWithObjectMacro(self, << error);
    }
    return;
  }
  inr::RenderSession& shown = *this->Shown();
  const int frames = shown.accumulatedFrames();
  if (frames == 0)
  {
    return;
  }
  // A reprojection (camera or volume moved) changes the image without rendering a frame when the
  // kept history already reaches the frame limit: upload on any new accumulation epoch too.
  const int epoch = shown.counters().accumulationResets + shown.counters().reprojections;
  if (this->compositor.NeedsUpload(window, width, height, frames,
        this->report.step.framesRendered > 0 || epoch != this->uploadedEpoch ||
          this->report.shownCoarse != this->uploadedCoarse))
  {
    // A reduced (interactive) image is stretched over the viewport: filter it linearly.
    int viewport[2] = { width, height };
    ren->GetTiledSize(&viewport[0], &viewport[1]);
    const bool upscaled = viewport[0] != width || viewport[1] != height;
    if (!this->compositor.Fits(window, width, height))
    {
      // GL cannot give a texture new storage while CUDA holds it registered.
      this->interop.Release();
    }
    bool onDevice = false;
    if (shown.backend() == inr::RenderBackend::Cuda && !this->interopFailed)
    {
      std::string why;
      this->compositor.Upload(window, width, height, frames, nullptr, upscaled);
      onDevice = this->interop.Copy(shown, this->compositor.TextureHandle(), width, height, &why);
      if (!onDevice)
      {
        this->interopFailed = true;
        this->imageTransfer = "image through host memory: " + why;
      }
      else
      {
        this->imageTransfer = "image to OpenGL on the GPU (CUDA-OpenGL interop)";
      }
    }
    if (!onDevice)
    {
      const inr::ImageRGBA image = shown.premultipliedImage();
      // The image is copied: the worker may take the session for the next step while this
      // render uploads and draws it.
      this->worker.LaunchRefine();
      this->compositor.Upload(window, width, height, frames, image.data.data(), upscaled);
    }
    this->uploadedEpoch = epoch;
    this->uploadedCoarse = this->report.shownCoarse;
    this->uploadedWindow = window;
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
  os << indent << "InteractiveStandIn: " << this->InteractiveStandIn << "\n";
  os << indent << "MacrocellResolution: " << this->MacrocellResolution << "\n";
  os << indent << "TemporalSlices: " << this->TemporalSlices << "\n";
  os << indent << "Shadows: " << this->Shadows << "\n";
  os << indent << "MaximumFrames: " << this->MaximumFrames << "\n";
  os << indent << "ConvergenceTarget: " << this->ConvergenceTarget << "\n";
  os << indent << "FramesPerRender: " << this->FramesPerRender << "\n";
  os << indent << "RefinementTimeBudget: " << this->RefinementTimeBudget << " ms\n";
  os << indent << "ProgressiveRefinement: " << this->ProgressiveRefinement << "\n";
  os << indent << "Macrocells in use: " << this->Internal->report.macrocellsInUse << "\n";
  os << indent << "Seed: " << this->Seed << "\n";
  os << indent << "InteractiveLevelOfDetail: " << this->InteractiveLevelOfDetail << "\n";
  os << indent << "InteractiveFrameTime: " << this->InteractiveFrameTime << " ms\n";
  os << indent << "InteractiveUpdateRate: " << this->InteractiveUpdateRate << "\n";
  os << indent << "InteractiveMacrocellResolution: " << this->InteractiveMacrocellResolution
     << "\n";
  os << indent << "InteractiveMacrocellsAhead: " << this->InteractiveMacrocellsAhead << "\n";
  os << indent << "InteractiveFreshFrames: " << this->InteractiveFreshFrames << "\n";
  os << indent << "QueryReduction: " << InrDescribeQueryReduction(this->Internal->options.queryReduction)
     << " (in use: " << this->Internal->engines.queryReductionInUse << ")\n";
}
