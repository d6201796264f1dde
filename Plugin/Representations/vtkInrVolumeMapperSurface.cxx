// vtkInrVolumeMapper's blend modes (InrBlendTranslator.h): the isosurface and slice of the
// network drawn by the fine session's surface renderer (inr::SessionSurfaceRenderer: exact in one
// frame, on the session's backend), the composite's cropping box, and the notes said once about
// what is not drawn as asked.
#include "vtkInrVolumeMapperInternals.h"

#include "Render/ModelBox.h"

namespace
{
// A pixel the surfaces make at least this opaque writes their depth (254.5 / 255: opaque in an
// 8-bit framebuffer); anti-aliased edges and translucent surfaces do not, as VTK's translucent
// geometry does not.
constexpr float kOpaqueSurfaceAlpha = 254.5f / 255.0f;
// A reduced frame (a drag's, or the first of a still frame drawn in parts) keeps at least this
// share of each side: below it the picture says little, and its cost is mostly fixed.
constexpr double kSmallestSurfaceScale = 0.125;

bool sameBox(const inr::Box3f& a, const inr::Box3f& b)
{
  return a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x &&
    a.hi.y == b.hi.y && a.hi.z == b.hi.z;
}

bool sameBlend(const inr::BlendScene& a, const inr::BlendScene& b)
{
  return a.mode == b.mode && a.isovalues == b.isovalues && a.sliceOrigin == b.sliceOrigin &&
    a.sliceNormal == b.sliceNormal && a.sliceOpaque == b.sliceOpaque && a.crop == b.crop &&
    (!a.crop || sameBox(a.cropBox, b.cropBox));
}

inr::Box3f intersect(const inr::Box3f& a, const inr::Box3f& b)
{
  return inr::Box3f{ { std::max(a.lo.x, b.lo.x), std::max(a.lo.y, b.lo.y), std::max(a.lo.z, b.lo.z) },
    { std::min(a.hi.x, b.hi.x), std::min(a.hi.y, b.hi.y), std::min(a.hi.z, b.hi.z) } };
}
}

void vtkInrVolumeMapper::Internals::NoteBlend(vtkInrVolumeMapper* self, const std::string& note)
{
  if (std::find(this->blendNotesSaid.begin(), this->blendNotesSaid.end(), note) !=
    this->blendNotesSaid.end())
  {
    return;
  }
  this->blendNotesSaid.push_back(note);
  vtkWarningWithObjectMacro(self, << "INR Volume: " << note << ".");
}

bool vtkInrVolumeMapper::Internals::DrawsSurface(vtkInrVolumeMapper* self)
{
  if (this->blend.blend.mode == inr::BlendMode::Composite)
  {
    return false;
  }
  if (this->ranks.Ranks().count > 1)
  {
    // Each rank draws a share of the pixels of the composite; the surface renderer draws whole
    // pictures, which IceT's ordered compositing would add up.
    this->NoteBlend(self, std::string("Blend Mode ") +
        (this->blend.blend.mode == inr::BlendMode::Isosurface ? "Isosurface" : "Slice") +
        " is not drawn under MPI with several ranks (each rank renders a share of the pixels of "
        "the composite only): drawn as Composite");
    return false;
  }
  return true;
}

bool vtkInrVolumeMapper::Internals::CropSettings(vtkInrVolumeMapper* self, inr::RenderSettings& settings)
{
  if (!this->blend.blend.crop)
  {
    return true;
  }
  if (settings.pixelShare.count > 1 || settings.sampleShare.count > 1)
  {
    this->NoteBlend(self, "Cropping is not drawn under MPI with several ranks (the crop box and "
                          "the ranks' pixel shares are two ways to split the rays the engine does "
                          "not combine): the whole volume is drawn");
    return true;
  }
  const inr::Box3f clip = intersect(this->blend.blend.cropBox, inr::modelWorldBox(this->engines.Model()));
  if (!(clip.lo.x < clip.hi.x && clip.lo.y < clip.hi.y && clip.lo.z < clip.hi.z))
  {
    return false;  // the crop box holds none of the model: nothing to draw
  }
  settings.clipToBrick = true;
  settings.brick = clip;
  return true;
}

namespace
{
// The size whose frame fits `budgetMs` at `msPerPixel` (one ray per pixel: the work scales with
// the pixels), at least an eighth of each side; `width` and `height` are left as they are when
// the whole frame fits. A cost not measured yet gives the smallest size, which measures it.
bool ReducedSize(double msPerPixel, double budgetMs, int& width, int& height)
{
  const double full = msPerPixel * double(width) * double(height);
  const double scale = msPerPixel <= 0.0
    ? kSmallestSurfaceScale
    : std::max(kSmallestSurfaceScale, std::min(1.0, std::sqrt(budgetMs / std::max(full, 1e-9))));
  if (scale >= 1.0)
  {
    return false;
  }
  width = std::max(1, int(std::lround(width * scale)));
  height = std::max(1, int(std::lround(height * scale)));
  return true;
}
}

// A render while the worker builds the isosurface's macrocells, or finishes the composite's
// work: the texture as it is (the last picture of this view) and the state saying `what`.
bool vtkInrVolumeMapper::Internals::DrawWhileBuilding(vtkInrVolumeMapper* self, vtkRenderer* ren,
  Clock::time_point renderStart, const std::string& what)
{
  SurfaceBlend& s = this->surface;
  s.drew = true;
  s.complete = false;
  s.previewing = false;
  s.frames = 0;
  s.state = std::string(inr::blendModeName(this->blend.blend.mode)) + ": " + what;
  this->report.interactive = false;
  this->report.renderMs = msSince(renderStart);
  auto* window = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow());
  if (!window || this->uploadedWindow != window)
  {
    return false;  // nothing of this view's drawn yet
  }
  // The surfaces' depth goes with a surface image (uploadedEpoch -1), none with a composite one.
  this->BlendTexture(self, window, /*writeDepth=*/this->uploadedEpoch == -1);
  return true;
}

// The isosurface or slice of this render: the fine session's surface renderer (made again when
// the engine was rebuilt or its macrocell grid changed), handed the scene only when it changed (a
// new scene restarts its image, which is exact in its first frame). A camera drag is drawn at a
// reduced resolution where a full frame would not fit the interactive frame time. A still render
// of the GUI (something renders again while the state is not converged) spends at most about
// InteractiveFrameTime: where the full frame would take longer, it draws a reduced frame first
// and the full one in parts (SessionSurfaceRenderer::renderFramePart) over the following renders.
bool vtkInrVolumeMapper::Internals::RenderSurface(
  vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, vtkDataSet* input, const Viewport& tile)
{
  const auto renderStart = Clock::now();
  SurfaceBlend& s = this->surface;
  const bool wasActive = s.active;
  s.active = true;
  s.interactive = false;
  // In the GUI (something renders again while the state is not converged) a render must not wait
  // for long work: frames in parts, the isosurface's macrocells built on the worker. Scripts,
  // captures and tiles of a larger picture draw whole frames now.
  const bool inGui = this->RendersAgainByItself(self) && this->window.fullWidth == 0;
  if (inGui && this->worker.SurfaceBuilding() && !this->worker.BuildDone())
  {
    return this->DrawWhileBuilding(self, ren, renderStart,
      "building the candidate macrocells at time " + std::to_string(s.buildTime) + " (" +
        std::to_string(int(100.0 * this->worker.BuildProgress())) + "%)");
  }
  if (inGui && (this->worker.FineBusy() || this->worker.CoarseBusy()) && !this->worker.BuildDone())
  {
    // The composite's work on the worker (a refinement step, macrocell slices) ends first: a
    // build ahead at its current slice, the others by themselves, while renders draw what they have.
    this->worker.AskToStop();
    return this->DrawWhileBuilding(self, ren, renderStart, "waiting for the composite's work on the worker");
  }
  // The surface renderer evaluates the fine session's network: nothing else may meanwhile.
  this->worker.JoinBackgroundBuild();
  inr::RenderSession& session = *this->engines.fine.session;
  const inr::InrModel& model = this->engines.Model();
  const int slices = session.options().macrocells.temporalSlices;
  const char* modeName = inr::blendModeName(this->blend.blend.mode);
  inr::RenderScene scene = this->TranslateScene(self, ren, vol, input, tile);
  if (scene.shadows)
  {
    this->NoteBlend(self, "Shadows are not drawn with Blend Mode Isosurface or Slice (Shade "
                          "lights the surfaces with the view's lights)");
    scene.shadows = false;
  }
  int width = tile.width, height = tile.height;
  vtkRenderWindow* win = ren->GetRenderWindow();
  const double rate = win ? win->GetDesiredUpdateRate() : 0.0;
  if (self->InteractiveLevelOfDetail != LOD_OFF && !self->Capturing && this->window.fullWidth == 0 &&
    rate >= self->InteractiveUpdateRate && s.msPerPixel > 0.0)
  {
    // A camera drag: the resolution whose frame fits the interactive frame time.
    const double budget = std::min(self->InteractiveFrameTime, rate > 0.0 ? 1000.0 / rate : 1e9);
    if (ReducedSize(s.msPerPixel, budget, width, height))
    {
      scene.depthLimit = resampleDepthLimit(scene.depthLimit, tile.width, tile.height, width, height);
      s.interactive = true;
    }
  }
  const bool inParts = inGui && !s.interactive;
  const double budget = self->InteractiveFrameTime;
  int framesRendered = 0;
  bool previewDrawn = false;  // this render drew a reduced frame of a new scene
  std::string previewSize;
  try
  {
    if (!s.renderer || s.engineBuild != this->engines.engineBuilds ||
      s.resolution != self->MacrocellResolution || s.temporalSlices != slices)
    {
      inr::SurfaceOptions options;
      options.macrocells.dims = inr::Int3{ self->MacrocellResolution, self->MacrocellResolution,
        self->MacrocellResolution };
      options.macrocells.temporalSlices = slices;
      if (session.backend() == inr::RenderBackend::Cpu)
      {
        // A part of a GUI render's frame is one march iteration over a chunk's rays at least: a
        // quarter of the default chunk keeps that step well inside Interactive Frame Time on a
        // CPU (the GPU renderer draws whole frames).
        options.chunkPixels = inr::SurfaceOptions{}.chunkPixels / 4;
      }
      s.renderer = inr::SessionSurfaceRenderer::create(
        session, inr::modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, options);
      s.engineBuild = this->engines.engineBuilds;
      s.resolution = self->MacrocellResolution;
      s.temporalSlices = slices;
      s.haveSettings = s.haveScene = false;
    }
    // Whether the renderer holds `settings` / `frameScene` with this render's blend already.
    auto holdsSettings = [&](const inr::RenderSettings& settings)
    {
      return s.haveSettings && settings.width == s.settings.width &&
        settings.height == s.settings.height && settings.seed == s.settings.seed &&
        settings.window == s.settings.window;
    };
    auto holdsScene = [&](const inr::RenderScene& frameScene)
    {
      return s.haveScene && !inr::diffScenes(&s.scene, frameScene).any() &&
        sameBlend(s.blend, this->blend.blend);
    };
    // Hands the renderer `settings` and `frameScene` where they differ from what it holds (either
    // restarts its image); true when they did.
    auto handOver = [&](const inr::RenderSettings& settings, const inr::RenderScene& frameScene)
    {
      bool restarted = false;
      if (!holdsSettings(settings))
      {
        s.renderer->setSettings(settings);
        s.settings = settings;
        s.haveSettings = true;
        s.haveScene = false;  // the depth limit is the new size's
        restarted = true;
      }
      if (!holdsScene(frameScene))
      {
        s.renderer->setScene(frameScene, this->blend.blend);
        s.scene = frameScene;
        s.blend = this->blend.blend;
        s.haveScene = true;
        s.queries = 0.0;
        restarted = true;
      }
      return restarted;
    };
    // Counts a finished frame: its queries, and its time per pixel without the macrocell update
    // (what sizes reduced frames).
    auto finished = [&](const inr::FrameStats& st, int pixels)
    {
      s.queries += double(st.queries + st.shadingQueries);
      s.msPerPixel = std::max(0.0, st.totalMs - st.updateMs) / std::max(1.0, double(pixels));
    };
    inr::RenderSettings settings;
    settings.width = width;
    settings.height = height;
    settings.seed = static_cast<std::uint32_t>(self->Seed);
    settings.window = s.interactive ? inr::ImageWindow{} : this->window;
    s.drew = !this->blend.nothingToDraw;
    // Exact in the first frame; later ones (FramesPerRender, jittered) anti-alias it.
    s.want = std::min(self->MaximumFrames,
      s.interactive || !self->ProgressiveRefinement ? 1 : std::max(1, self->FramesPerRender));
    if (s.drew && !inParts)
    {
      s.previewing = false;
      handOver(settings, scene);
      while (s.renderer->accumulatedFrames() < s.want)
      {
        const inr::FrameStats st = s.renderer->renderFrame();
        finished(st, width * height);
        ++framesRendered;
      }
    }
    else if (s.drew && this->blend.blend.mode == inr::BlendMode::Isosurface &&
      !s.renderer->macrocellsBuiltFor(scene.time))
    {
      // A first isosurface, or a new time: its candidate macrocells are built on the worker
      // (lattice queries through the network, seconds on a CPU) while renders draw what they have.
      inr::SessionSurfaceRenderer* renderer = s.renderer.get();
      const double time = scene.time;
      if (this->worker.StartSurfaceBuild([renderer, time]() { renderer->buildMacrocellsFor(time); }))
      {
        s.buildTime = time;
        return this->DrawWhileBuilding(self, ren, renderStart,
          "building the candidate macrocells at time " + std::to_string(time));
      }
    }
    if (s.drew && inParts)
    {
      const bool sameTarget = holdsSettings(settings) && holdsScene(scene);
      int pw = width, ph = height;
      if (!sameTarget && ReducedSize(s.msPerPixel, budget, pw, ph))
      {
        // A new scene whose full frame would not fit the budget: a reduced frame of it now, the
        // full frame in parts from the next render on.
        inr::RenderSettings reduced = settings;
        reduced.width = pw;
        reduced.height = ph;
        inr::RenderScene reducedScene = scene;
        reducedScene.depthLimit = resampleDepthLimit(scene.depthLimit, tile.width, tile.height, pw, ph);
        handOver(reduced, reducedScene);
        const inr::FrameStats st = s.renderer->renderFrame();
        finished(st, pw * ph);
        s.preview = s.renderer->premultipliedImage();
        s.previewDepth = s.renderer->surfaceDepth();
        s.previewWidth = pw;
        s.previewHeight = ph;
        s.previewing = previewDrawn = true;
        handOver(settings, scene);
      }
      else if (!sameTarget)
      {
        // A new scene whose full frame fits the budget: drawn whole now.
        handOver(settings, scene);
        const inr::FrameStats st = s.renderer->renderFrame();
        finished(st, width * height);
        ++framesRendered;
        s.previewing = false;
      }
      // The frames in parts, one part at least, then while the budget lasts (none in a render
      // that drew a reduced frame). A frame after the first may be shown part-made: its pixels
      // hold means of one frame more or less, all exact.
      for (bool first = true; !previewDrawn && s.renderer->accumulatedFrames() < s.want &&
           (first || msSince(renderStart) < budget);
           first = false)
      {
        inr::FrameStats st;
        if (s.renderer->renderFramePart(std::max(0.0, budget - msSince(renderStart)), &st))
        {
          finished(st, width * height);
          ++framesRendered;
          s.previewing = false;
        }
      }
      if (s.previewing)
      {
        previewSize = std::to_string(s.previewWidth) + "x" + std::to_string(s.previewHeight);
      }
    }
  }
  catch (const std::exception& e)
  {
    s.drew = false;
    s.previewing = false;
    s.haveScene = false;  // the next render tries again
    vtkErrorWithObjectMacro(self, << "INR Volume: Blend Mode " << modeName << ": " << e.what());
    return false;
  }
  s.frames = s.drew ? s.renderer->accumulatedFrames() : 0;
  s.complete = s.drew && s.frames >= s.want;
  const std::string fullSize = std::to_string(width) + "x" + std::to_string(height);
  const int percent = int(100.0 * (s.drew ? s.renderer->frameProgress() : 0.0));
  s.state = !s.drew ? this->blend.empty
    : s.interactive ? std::string("interacting: reduced ") + fullSize + " " + modeName
    : s.previewing ? std::string(modeName) + ": a reduced " + previewSize + " frame shown, the " +
        fullSize + " frame " + std::to_string(percent) + "% drawn"
    : !s.complete ? std::string(modeName) + ": exact, anti-aliasing (" + std::to_string(s.frames) +
        " of " + std::to_string(s.want) + " frames)"
                  : std::string(modeName) + ": exact in one frame (" + std::to_string(s.frames) +
        (s.frames == 1 ? " frame" : " frames, anti-aliased") + ")";
  const int shownWidth = s.previewing ? s.previewWidth : width;
  const int shownHeight = s.previewing ? s.previewHeight : height;
  this->report.imageWidth = shownWidth;
  this->report.imageHeight = shownHeight;
  this->report.interactive = s.interactive;
  if (!s.drew)
  {
    this->report.renderMs = msSince(renderStart);
    return false;
  }
  auto* window = vtkOpenGLRenderWindow::SafeDownCast(win);
  if (!window)
  {
    return false;
  }
  if (framesRendered > 0 || previewDrawn || !wasActive ||
    this->compositor.NeedsUpload(window, shownWidth, shownHeight, s.frames, false))
  {
    // The reduced frame while the full one is in parts (the renderer's image is then part-made),
    // else the renderer's image.
    const inr::ImageRGBA image = s.previewing ? s.preview : s.renderer->premultipliedImage();
    const std::vector<float> distance = s.previewing ? s.previewDepth : s.renderer->surfaceDepth();
    int viewport[2] = { shownWidth, shownHeight };
    ren->GetTiledSize(&viewport[0], &viewport[1]);
    const bool upscaled = viewport[0] != shownWidth || viewport[1] != shownHeight;
    if (!this->compositor.Fits(window, shownWidth, shownHeight))
    {
      this->interop.Release();  // GL cannot give a texture new storage while CUDA holds it
    }
    this->compositor.Upload(window, shownWidth, shownHeight, s.frames, image.data.data(), upscaled);
    this->uploadedWindow = window;
    this->uploadedEpoch = -1;  // a composite image after this must be uploaded again
    // Where the surfaces are opaque their depth goes to the depth buffer, as opaque geometry's
    // does (what is drawn or read after the volume sees them: another volume, the view's depth
    // read-back), with the camera whose depth buffer TranslateScene read.
    vtkCamera* cam = ren->GetActiveCamera();
    vtkNew<vtkMatrix4x4> projection;
    projection->DeepCopy(cam->GetCompositeProjectionTransformMatrix(
      double(tile.width) / double(tile.height), -1, 1));
    double eye[3], fwd[3];
    cam->GetPosition(eye);
    cam->GetDirectionOfProjection(fwd);
    if (distance.size() == std::size_t(shownWidth) * std::size_t(shownHeight))
    {
      const std::vector<float> depth = InrFramebufferCompositor::RayDistancesToDepth(
        distance.data(), image.data.data(), shownWidth, shownHeight, kOpaqueSurfaceAlpha,
        projection->GetData(), eye, fwd, cam->GetParallelProjection() != 0);
      this->compositor.UploadDepth(window, shownWidth, shownHeight, depth.data());
    }
  }
  this->BlendTexture(self, window, /*writeDepth=*/true);
  this->report.renderMs = msSince(renderStart);
  return true;
}
