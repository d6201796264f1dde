// The mapper's private state and helpers, shared by its source files (vtkInrVolumeMapper.cxx:
// the adapter, PrepareRender, Render and drawing; vtkInrVolumeMapperEngine.cxx: the engine side
// of a render; vtkInrVolumeMapperInformation.cxx: the getters and stored options). Not installed.
#ifndef vtkInrVolumeMapperInternals_h
#define vtkInrVolumeMapperInternals_h

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

#include "InrBlendTranslator.h"
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
#include "Backends/SessionSurfaceRenderer.h"
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

// The renderer's tile in the window (the image the engine renders). Outside the unnamed
// namespace below: Internals' functions that take it are defined in several source files.
struct vtkInrVolumeMapperViewport
{
  int width = 0, height = 0, x0 = 0, y0 = 0;
};
using Viewport = vtkInrVolumeMapperViewport;

namespace vtkInrVolumeMapperDetail
{

// True while VTK's dual depth peeling renders the volume inside its peels (translucent geometry
// with UseDepthPeelingForVolumes): the pass registers itself in the props' keys.
inline bool insideDepthPeeling(vtkVolume* vol)
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

inline bool debugReport()
{
  return std::getenv("INR_VOLUME_DEBUG") != nullptr;
}

// CPU time of the whole process (all its threads), ms: logged beside the engine's wall time
// (INR_VOLUME_LOD_LOG) to see how much of a frame's time a loaded machine adds.
inline double processCpuMs()
{
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * double(t.tv_sec) + 1e-6 * double(t.tv_nsec);
}

inline bool lodReport()
{
  const char* v = std::getenv("INR_VOLUME_LOD_LOG");
  return v && v[0] && std::string(v) != "0";
}

using inr::Clock;
using inr::msSince;

// The depth limits (engine row order) of a width x height image, sampled at the centres of the
// pixels of a w x h image covering the same view.
inline std::vector<float> resampleDepthLimit(
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
inline inr::MacrocellProgress progressHandler(
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
using namespace vtkInrVolumeMapperDetail;

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
  std::string warned2D;  // the 2D transfer function's problem last said (said again when it changes)
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
  // Whether something renders this view again by itself while the state is not converged (the
  // GUI's refinement behaviour turns background builds on; progressive refinement; not a capture,
  // which must draw now; one rank), so a render may leave work to the next one.
  bool RendersAgainByItself(vtkInrVolumeMapper* self) const;
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

  // The blend modes (InrBlendTranslator.h), read from the mapper and the volume property at each
  // render: Composite through the sessions above (Cropping clips their primary rays: CropSettings),
  // Isosurface and Slice by the fine session's surface renderer (vtkInrVolumeMapperSurface.cxx).
  InrBlendTranslator::Result blend;
  std::vector<std::string> blendNotesSaid;  // each note about the blend mode is said once
  void NoteBlend(vtkInrVolumeMapper* self, const std::string& note);
  // The surface renderer over the fine session's evaluator, and what it was last handed.
  struct SurfaceBlend
  {
    std::unique_ptr<inr::SessionSurfaceRenderer> renderer;
    int engineBuild = -1;  // InrEngines::engineBuilds it was made for (a rebuild drops it)
    int resolution = 0, temporalSlices = 0;
    bool haveSettings = false, haveScene = false;
    inr::RenderSettings settings;
    inr::RenderScene scene;
    inr::BlendScene blend;
    bool active = false;       // the last render drew a surface mode (the panel's figures)
    bool interactive = false;  // ... at a reduced resolution (a camera drag)
    bool drew = false;         // ... and its image holds something (not "nothing to draw")
    // A still render of the GUI draws a full frame in parts: until its first frame is complete,
    // the texture shows `preview`, a reduced frame of the same scene (and its ray distances).
    bool previewing = false;
    inr::ImageRGBA preview;
    std::vector<float> previewDepth;
    int previewWidth = 0, previewHeight = 0;
    int want = 1;              // the frames this scene accumulates (FramesPerRender)
    double buildTime = 0.0;    // the time whose macrocells the worker builds (StartSurfaceBuild)
    bool complete = true;      // ... all rendered: nothing left to refine
    int frames = 0;
    double queries = 0.0;
    double msPerPixel = 0.0;   // of the last finished frame, update left out (sizes reduced frames)
    std::string state;         // the refinement-state line of surface modes
  };
  SurfaceBlend surface;
  // The worker may be building the surface renderer's macrocells: it stops before the renderer
  // (a member after the worker's) goes.
  ~Internals() { this->worker.JoinBackgroundBuild(); }
  // A render while the worker builds the isosurface's macrocells or finishes other work
  // (RenderSurface): the texture as it is, `what` in the state; false when it holds nothing of
  // this window's.
  bool DrawWhileBuilding(vtkInrVolumeMapper* self, vtkRenderer* ren, Clock::time_point renderStart,
    const std::string& what);
  // Draws this render's isosurface or slice (Render's surface path); false: nothing drawn.
  bool RenderSurface(vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, vtkDataSet* input,
    const Viewport& tile);
  // Whether this render draws the isosurface or slice path (a surface mode that can be drawn).
  bool DrawsSurface(vtkInrVolumeMapper* self);
  // The composite's Cropping: the sessions' primary rays clipped to the crop box (in the model's
  // box); false when the box holds none of the model (nothing to draw).
  bool CropSettings(vtkInrVolumeMapper* self, inr::RenderSettings& settings);
  bool cropEmpty = false;  // the last render's crop box held none of the model

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

  // Out of GPU memory (issue 52): a render's request that the GPU could not hold, for the
  // Backend setting it happened under; until that setting changes the engine runs on the CPU
  // (Request) and "Backend In Use" says why.
  std::string gpuOutOfMemory;
  int gpuOutOfMemoryBackend = -1;

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
  // Sample shares over several ranks: this rank's image averaged with every rank's (a collective
  // each render), its pixels of the average uploaded; the texture is then blended as Composite's.
  void UploadSampleShares(vtkOpenGLRenderWindow* window, int width, int height, bool upscaled);
  // Draws the loaded texture over the framebuffer (the composite blend; `writeDepth`: the loaded
  // depth where the image is opaque, as the surface modes do), an error if it cannot.
  void BlendTexture(vtkInrVolumeMapper* self, vtkOpenGLRenderWindow* window, bool writeDepth = false);
  // Render's scope: inside it, progress is muted where renders are prepared (SetInsideRender).
  struct InsideRender
  {
    Internals& I;
    explicit InsideRender(Internals& i)
      : I(i)
    {
      I.SetInsideRender(true);
    }
    ~InsideRender() { I.SetInsideRender(false); }
  };
  // Reduces the refinement state over the ranks on every way out of Render (also where this rank
  // draws nothing: a rank that skipped the collective would leave the others waiting in it).
  struct RankReduction
  {
    Internals& I;
    vtkInrVolumeMapper* self;
    bool rendered = false;
    ~RankReduction()
    {
      I.ranks.FinishRender();  // (the image combine that a render drawing nothing did not reach)
      I.ReduceOverRanks(self, rendered);
    }
  };
  // True (warned once) while VTK's dual depth peeling renders the volume inside its peels.
  bool InsideDepthPeeling(vtkInrVolumeMapper* self, vtkVolume* vol);
  // Where this render's image lies in the full picture (`window`; a tile of a larger one).
  void PlaceTile(vtkRenderer* ren, const Viewport& tile);
  // Records a drawn render (report, level-of-detail cost model, the INR_VOLUME_LOD_LOG line).
  struct RenderTimes
  {
    Clock::time_point renderStart, refineStart;
    double refineMs = 0.0, refineCpuMs = 0.0, compositeMs = 0.0;
  };
  void RecordRender(const Viewport& tile, const RenderTimes& times);
};

#endif
