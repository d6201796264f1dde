// The engine side of vtkInrVolumeMapper's render: the model and the engine sessions for its
// properties, the VTK scene translated, the warnings about what the engine leaves out, the frames
// accumulated (Refine), the refinement time budget from the window's render, and the state
// reduced over the ranks.
#include "vtkInrVolumeMapperInternals.h"

#include "Common/DeviceMemory.h"

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
  if (!this->gpuOutOfMemory.empty() && self->Backend == this->gpuOutOfMemoryBackend)
  {
    r.backend = inr::RenderBackend::Cpu;  // out of GPU memory (Refine): the CPU until Backend changes
  }
  else
  {
    this->gpuOutOfMemory.clear();
  }
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
      (this->imageTransfer.empty() ? "" : "; " + this->imageTransfer) + rankNote +
      (this->gpuOutOfMemory.empty() ? "" : " (the GPU ran out of memory: " + this->gpuOutOfMemory + ")");
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
  const std::string& problem2D = this->translator.GetTransfer2DProblem();
  if (problem2D != this->warned2D)
  {
    this->warned2D = problem2D;
    if (!problem2D.empty())
    {
      this->engines.warning("INR Volume: Use Transfer2D is on but its 2D transfer function is left out (" +
        problem2D + "): the volume is rendered with the colour map and opacity.");
    }
  }
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
  this->cropEmpty = !this->CropSettings(self, settings);
  if (this->cropEmpty)
  {
    return false;  // the crop box holds none of the model: nothing drawn
  }
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
    inr::RefinementOptions options = this->decision.Refinement(in,
      this->decision.budget == InrRenderDecision::Budget::Remaining
        ? this->EngineTimeBudget(self->RefinementTimeBudget)
        : 0.0);
    this->ranks.ShareRefinement(options);
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
  catch (const inr::DeviceOutOfMemory& e)
  {
    // The session kept its previous image and settings; the next render rebuilds it on the CPU.
    if (engine.backend() == inr::RenderBackend::Cuda)
    {
      this->gpuOutOfMemory = e.what();
      this->gpuOutOfMemoryBackend = self->Backend;
      vtkErrorWithObjectMacro(self, << "INR Volume: " << e.what()
                                    << ". Rendering on the CPU from now on; set Backend again to "
                                       "retry the GPU.");
    }
    else
    {
      vtkErrorWithObjectMacro(self, << "INR Volume: rendering failed: " << e.what());
    }
    return false;
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

// What the render drew, for the panel (InrMapperReport) and the level-of-detail cost model; the
// INR_VOLUME_LOD_LOG line.
void vtkInrVolumeMapper::Internals::RecordRender(const Viewport& tile, const RenderTimes& t)
{
  const InrRenderDecision& dec = this->decision;
  const bool interactive = dec.frame.interactive, useCoarse = dec.useCoarse;
  const bool background = dec.background, drawStandIn = dec.drawStandIn;
  const int width = dec.frame.width, height = dec.frame.height;
  const double refineMs = t.refineMs;
  this->lod.Drew(interactive);
  this->report.interactive = interactive;
  this->lodStandIn.Drew(interactive);
  this->renderedInWindow = true;
  this->report.imageWidth = width;
  this->report.imageHeight = height;
  if (background)
  {
    // The step's frames were rendered on the worker: its own time is the engine's part; this
    // render's time outside its refinement part (which holds the wait for the step) is the
    // render's fixed cost.
    const double engineMs = this->report.step.total.totalMs;
    this->lod.MeasureFrame(std::max(0.0, this->report.renderMs - refineMs) + engineMs,
      engineMs, this->report.step.total.updateMs, this->report.step.framesRendered, width, height, false);
  }
  else
  {
    (drawStandIn ? this->lodStandIn : this->lod)
      .MeasureFrame(this->report.renderMs, refineMs, this->report.step.total.updateMs,
        this->report.step.framesRendered, width, height, interactive);
  }
  if (lodReport())
  {
    std::string workerNote;
    if (background)
    {
      char step[160];
      std::snprintf(step, sizeof(step), ", refining on the worker (%s; step joined: %d frames, %.1f ms)",
        this->worker.KeepsImage() ? "image kept" : "image drawn", this->report.step.framesRendered, this->report.step.total.totalMs);
      workerNote = step;
    }
    std::fprintf(stderr,
      "INR Volume LOD: %s frame %dx%d of %dx%d (scale %.3f), %.1f ms (budget %.0f ms; macrocell "
      "update %.1f ms; scene %.1f ms, engine %.1f ms of %.1f (process CPU %.1f ms), composite "
      "%.1f ms), frames %d%s%s\n",
      interactive ? "interactive" : "still", width, height, tile.width, tile.height,
      double(width) / tile.width, this->report.renderMs, dec.lod.budgetMs, this->report.step.total.updateMs,
      std::chrono::duration<double, std::milli>(t.refineStart - t.renderStart).count(), refineMs,
      this->lastEngineBudgetMs, t.refineCpuMs, t.compositeMs, this->ShownFrames(),
      useCoarse ? (drawStandIn ? ", coarse macrocells, stand-in" : ", coarse macrocells") : "",
      workerNote.c_str());
  }
}

bool vtkInrVolumeMapper::Internals::InsideDepthPeeling(vtkInrVolumeMapper* self, vtkVolume* vol)
{
  if (!insideDepthPeeling(vol))
  {
    return false;
  }
  // Its peels expect the GPU ray-cast mapper's shaders; blending a finished image into them
  // (several times a frame) corrupts the picture. ParaView's representation avoids this path.
  if (!this->warnedPeeling)
  {
    vtkWarningWithObjectMacro(self,
      "INR Volume: not drawn while the renderer depth-peels volumes with "
      "translucent geometry (UseDepthPeelingForVolumes, which only the GPU "
      "ray-cast mapper supports): turn UseDepthPeelingForVolumes off to see it.");
    this->warnedPeeling = true;
  }
  return true;
}

// A tile of a larger picture (screenshot larger than the view, tile display): the camera is
// already the tile's (window centre); the window keys the random streams by the full picture.
void vtkInrVolumeMapper::Internals::PlaceTile(vtkRenderer* ren, const Viewport& tile)
{
  vtkRenderWindow* win = ren->GetRenderWindow();
  double tileViewport[4] = { 0, 0, 1, 1 };
  win->GetTileViewport(tileViewport);
  this->window = InrSceneTranslator::TileWindow(
    ren->GetViewport(), tileViewport, win->GetSize(), tile.width, tile.height);
}
