#include "vtkInrVolumeMapperInternals.h"

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
  const int blendMode = this->GetBlendMode();
  if ((blendMode == ISOSURFACE_BLEND || blendMode == SLICE_BLEND) && I.ranks.Ranks().count <= 1)
  {
    return;  // the surface renderer (Render) needs none of the composite's macrocell slices
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
  Internals::InsideRender inside(I);
  // Under MPI every rank reaches this point in every render (IceT composites all of them):
  // whatever happens below, the refinement state is reduced over the ranks once on the way out.
  Internals::RankReduction reduction{ I, this };
  I.ranks.SetSplit(this->RankSplit == RANK_SPLIT_PIXELS ? InrMapperRanks::Split::Pixels
                                                         : InrMapperRanks::Split::Samples);
  I.ranks.BeginRender();
  // The depth limit before anything can return: under MPI its composite is collective, and a
  // rank that draws nothing must still bring its geometry to the others' rays.
  I.depthValid = I.ranks.CompositeDepth(ren, vol, I.depth);
  I.ranks.LookUpLocalRank();
  if (I.InsideDepthPeeling(this, vol))
  {
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
  I.PlaceTile(ren, tile);
  I.WarnAboutScene(this, ren, vol, tile.width, tile.height);
  // The blend mode, isovalues, slice plane and crop box, read as VTK's own mappers read them;
  // what is not drawn as asked is said once.
  I.blend = InrBlendTranslator::Translate(this, vol->GetProperty());
  for (const std::string& note : I.blend.notes)
  {
    I.NoteBlend(this, note);
  }
  if (I.DrawsSurface(this))
  {
    I.ObserveWindow(ren->GetRenderWindow());
    reduction.rendered = I.RenderSurface(this, ren, vol, input, tile);
    return;
  }
  if (I.worker.SurfaceBuilding())
  {
    I.worker.JoinBackgroundBuild();  // the isosurface's macrocell build holds the fine session
  }
  if (I.surface.active)
  {
    I.surface.active = false;
    I.uploadedEpoch = -1;  // the texture holds the surface image: load the composite again
  }
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
  I.RecordRender(tile, Internals::RenderTimes{ renderStart, refineStart, refineMs, refineCpuMs, compositeMs });
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
  return (e.worker.FineRefining() || e.worker.CoarseBusy() || e.worker.SurfaceBuilding()) &&
      !e.worker.BuildDone()
    ? 1
    : 0;
}

bool vtkInrVolumeMapper::Internals::BuildsInBackground(vtkInrVolumeMapper* self) const
{
  return backgroundBuilds && this->engines.fine.session &&
    InrLevelOfDetail::BuildsFineInBackground(
      this->LodSettings(self), this->engines.fine.session->backend() == inr::RenderBackend::Cpu);
}

bool vtkInrVolumeMapper::Internals::RendersAgainByItself(vtkInrVolumeMapper* self) const
{
  return backgroundBuilds && self->ProgressiveRefinement && !self->Capturing &&
    this->ranks.Ranks().count <= 1;
}

bool vtkInrVolumeMapper::Internals::DefersFirstRender(vtkInrVolumeMapper* self) const
{
  // Only where something renders again by itself, and once per mapper.
  return this->firstRender == FirstRender::NotReached && this->RendersAgainByItself(self);
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
  // A reduced (interactive) image is stretched over the viewport: filter it linearly.
  int viewport[2] = { width, height };
  ren->GetTiledSize(&viewport[0], &viewport[1]);
  const bool upscaled = viewport[0] != width || viewport[1] != height;
  if (this->ranks.SplitsSamples())
  {
    this->UploadSampleShares(window, width, height, upscaled);
    if (this->uploadedWindow == window)
    {
      this->BlendTexture(self, window);
    }
    return;
  }
  // The worker holds the fine session (KeepsImage), or its first frame of a new image is still to
  // come: the image on screen stays (the previous one, or the coarse one) rather than a blank view.
  if (this->worker.KeepsImage() ||
    (this->worker.StartsRefine() && this->engines.fine.session->accumulatedFrames() == 0))
  {
    if (this->uploadedWindow == window)
    {
      this->BlendTexture(self, window);
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
  this->BlendTexture(self, window);
}

void vtkInrVolumeMapper::Internals::BlendTexture(
  vtkInrVolumeMapper* self, vtkOpenGLRenderWindow* window, bool writeDepth)
{
  std::string error;
  if (!this->compositor.Blend(window, &error, writeDepth))
  {
    vtkErrorWithObjectMacro(self, << error);
  }
}

void vtkInrVolumeMapper::Internals::UploadSampleShares(
  vtkOpenGLRenderWindow* window, int width, int height, bool upscaled)
{
  // Every render on every rank: another rank's new frames change this rank's pixels too.
  std::vector<float> image;
  int frames = 0;
  inr::RenderSession* shown = this->worker.KeepsImage() ? nullptr : this->Shown();
  if (shown && shown->accumulatedFrames() > 0)
  {
    frames = shown->accumulatedFrames();
    image = shown->premultipliedImage().data;
  }
  const int total = this->ranks.CombineImage(width, height, frames, image);
  if (total == 0)
  {
    return;  // no rank has frames: the texture keeps what it shows
  }
  if (!this->compositor.Fits(window, width, height))
  {
    this->interop.Release();  // (GL cannot give a texture new storage while CUDA holds it)
  }
  this->compositor.Upload(window, width, height, total, image.data(), upscaled);
  this->imageTransfer = "image through host memory: the ranks' sample shares averaged";
  this->uploadedEpoch = -1;
  this->uploadedCoarse = this->report.shownCoarse;
  this->uploadedWindow = window;
}
