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

// The isosurface or slice of this render: the fine session's surface renderer (made again when
// the engine was rebuilt or its macrocell grid changed), handed the scene only when it changed (a
// new scene restarts its image, which is exact in its first frame), a camera drag drawn at a
// reduced resolution where a full frame would not fit the interactive frame time.
bool vtkInrVolumeMapper::Internals::RenderSurface(
  vtkInrVolumeMapper* self, vtkRenderer* ren, vtkVolume* vol, vtkDataSet* input, const Viewport& tile)
{
  const auto renderStart = Clock::now();
  SurfaceBlend& s = this->surface;
  const bool wasActive = s.active;
  s.active = true;
  s.interactive = false;
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
    // A camera drag: the resolution whose frame fits the interactive frame time, from the last
    // full frame's time per pixel (the work scales with the pixels: one ray each).
    const double budget = std::min(self->InteractiveFrameTime, rate > 0.0 ? 1000.0 / rate : 1e9);
    const double full = s.msPerPixel * double(width) * double(height);
    const double scale = std::max(0.125, std::min(1.0, std::sqrt(budget / std::max(full, 1e-9))));
    if (scale < 1.0)
    {
      width = std::max(1, int(std::lround(width * scale)));
      height = std::max(1, int(std::lround(height * scale)));
      scene.depthLimit = resampleDepthLimit(scene.depthLimit, tile.width, tile.height, width, height);
      s.interactive = true;
    }
  }
  int framesRendered = 0;
  try
  {
    if (!s.renderer || s.engineBuild != this->engines.engineBuilds ||
      s.resolution != self->MacrocellResolution || s.temporalSlices != slices)
    {
      inr::SurfaceOptions options;
      options.macrocells.dims = inr::Int3{ self->MacrocellResolution, self->MacrocellResolution,
        self->MacrocellResolution };
      options.macrocells.temporalSlices = slices;
      s.renderer = inr::SessionSurfaceRenderer::create(
        session, inr::modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, options);
      s.engineBuild = this->engines.engineBuilds;
      s.resolution = self->MacrocellResolution;
      s.temporalSlices = slices;
      s.haveSettings = s.haveScene = false;
    }
    inr::RenderSettings settings;
    settings.width = width;
    settings.height = height;
    settings.seed = static_cast<std::uint32_t>(self->Seed);
    settings.window = s.interactive ? inr::ImageWindow{} : this->window;
    if (!s.haveSettings || settings.width != s.settings.width || settings.height != s.settings.height ||
      settings.seed != s.settings.seed || !(settings.window == s.settings.window))
    {
      s.renderer->setSettings(settings);
      s.settings = settings;
      s.haveSettings = true;
      s.haveScene = false;  // the depth limit is the new size's
    }
    s.drew = !this->blend.nothingToDraw;
    if (s.drew)
    {
      const bool changed = !s.haveScene || inr::diffScenes(&s.scene, scene).any() ||
        !sameBlend(s.blend, this->blend.blend);
      if (changed)
      {
        s.renderer->setScene(scene, this->blend.blend);
        s.scene = scene;
        s.blend = this->blend.blend;
        s.haveScene = true;
        s.queries = 0.0;
      }
      // Exact in the first frame; later ones (FramesPerRender, jittered) anti-alias it.
      const int want = std::min(self->MaximumFrames,
        s.interactive || !self->ProgressiveRefinement ? 1 : std::max(1, self->FramesPerRender));
      while (s.renderer->accumulatedFrames() < want)
      {
        const inr::FrameStats st = s.renderer->renderFrame();
        s.queries += double(st.queries + st.shadingQueries);
        ++framesRendered;
        if (!s.interactive)
        {
          s.msPerPixel = st.totalMs / std::max(1.0, double(width) * double(height));
        }
      }
    }
  }
  catch (const std::exception& e)
  {
    s.drew = false;
    vtkErrorWithObjectMacro(self, << "INR Volume: Blend Mode " << modeName << ": " << e.what());
    return false;
  }
  s.frames = s.drew ? s.renderer->accumulatedFrames() : 0;
  s.state = !s.drew ? this->blend.empty
    : s.interactive ? std::string("interacting: reduced ") + std::to_string(width) + "x" +
        std::to_string(height) + " " + modeName
                    : std::string(modeName) + ": exact in one frame (" + std::to_string(s.frames) +
        (s.frames == 1 ? " frame" : " frames, anti-aliased") + ")";
  this->report.imageWidth = width;
  this->report.imageHeight = height;
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
  if (framesRendered > 0 || !wasActive ||
    this->compositor.NeedsUpload(window, width, height, s.frames, false))
  {
    const inr::ImageRGBA image = s.renderer->premultipliedImage();
    int viewport[2] = { width, height };
    ren->GetTiledSize(&viewport[0], &viewport[1]);
    const bool upscaled = viewport[0] != width || viewport[1] != height;
    if (!this->compositor.Fits(window, width, height))
    {
      this->interop.Release();  // GL cannot give a texture new storage while CUDA holds it
    }
    this->compositor.Upload(window, width, height, s.frames, image.data.data(), upscaled);
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
    const std::vector<float> distance = s.renderer->surfaceDepth();
    if (distance.size() == std::size_t(width) * std::size_t(height))
    {
      const std::vector<float> depth = InrFramebufferCompositor::RayDistancesToDepth(
        distance.data(), image.data.data(), width, height, kOpaqueSurfaceAlpha,
        projection->GetData(), eye, fwd, cam->GetParallelProjection() != 0);
      this->compositor.UploadDepth(window, width, height, depth.data());
    }
  }
  std::string error;
  if (!this->compositor.Blend(window, &error, /*writeDepth=*/true))
  {
    vtkErrorWithObjectMacro(self, << error);
  }
  this->report.renderMs = msSince(renderStart);
  return true;
}
