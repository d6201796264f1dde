#include "vtkInrVolumeMapper.h"

#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkDataArray.h"
#include "vtkDataSet.h"
#include "vtkFieldData.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkMatrix4x4.h"
#include "vtkObjectFactory.h"
#include "vtkOpenGLQuadHelper.h"
#include "vtkOpenGLRenderUtilities.h"
#include "vtkOpenGLRenderWindow.h"
#include "vtkOpenGLShaderCache.h"
#include "vtkOpenGLState.h"
#include "vtkPiecewiseFunction.h"
#include "vtkRenderer.h"
#include "vtkShaderProgram.h"
#include "vtkSmartPointer.h"
#include "vtkTextureObject.h"
#include "vtkUnsignedCharArray.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"
#include "vtk_glew.h"

#include "Model/InrModel.h"
#include "Backends/RenderSession.h"
#include "Render/SceneInputs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
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

const char* const kFragmentImpl =
  "  gl_FragData[0] = texture2D(inrImage, vec2(texCoord.x, 1.0 - texCoord.y));\n";
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
  std::unique_ptr<inr::RenderSession> renderer;
  int builtResolution = 0, builtSlices = 0, builtBackend = -1;
  int engineBuilds = 0;
  std::string backendInUse = "none (no model rendered yet)";
  bool warnedCuda = false;

  bool haveSettings = false;
  inr::RenderSettings settings;

  // Transfer-function cache (conversion from VTK only when its inputs changed).
  vtkMTimeType ctfTime = 0, otfTime = 0, propTime = 0;
  int tfDefault = -1;
  double tfRange[2] = { 0, 0 };
  inr::TransferFunction tf;

  // Convergence.
  double estimate = std::numeric_limits<double>::infinity();
  bool converged = false;
  double lastUpdateMs = 0.0;
  double lastQueries = 0.0;

  // Drawing.
  std::unique_ptr<vtkOpenGLQuadHelper> quad;
  vtkSmartPointer<vtkTextureObject> texture;
  int texW = 0, texH = 0;
  int uploadedFrames = -1;
  bool textureValid = false;
  std::vector<float> depth;
  inr::RenderScene lastScene;  // for the INR_VOLUME_DEBUG report of what changed
};

vtkStandardNewMacro(vtkInrVolumeMapper);

vtkInrVolumeMapper::vtkInrVolumeMapper()
  : Internal(new Internals)
{
}

vtkInrVolumeMapper::~vtkInrVolumeMapper()
{
  delete this->Internal;
}

int vtkInrVolumeMapper::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkImageData");
  return 1;
}

void vtkInrVolumeMapper::ResetAccumulation()
{
  if (this->Internal->renderer)
  {
    this->Internal->renderer->resetAccumulation();
  }
  this->Internal->converged = false;
  this->Internal->estimate = std::numeric_limits<double>::infinity();
}

int vtkInrVolumeMapper::GetAccumulatedFrames()
{
  return this->Internal->renderer ? this->Internal->renderer->accumulatedFrames() : 0;
}

int vtkInrVolumeMapper::GetConverged()
{
  return this->Internal->converged ? 1 : 0;
}

double vtkInrVolumeMapper::GetConvergenceEstimate()
{
  return this->Internal->estimate;
}

const char* vtkInrVolumeMapper::GetBackendInUse()
{
  return this->Internal->backendInUse.c_str();
}

double vtkInrVolumeMapper::GetLastUpdateMilliseconds()
{
  return this->Internal->lastUpdateMs;
}

int vtkInrVolumeMapper::GetSlicesBuilt()
{
  return this->Internal->renderer ? this->Internal->renderer->macrocellInfo().slicesBuilt : 0;
}

int vtkInrVolumeMapper::GetEngineBuilds()
{
  return this->Internal->engineBuilds;
}

double vtkInrVolumeMapper::GetLastQueries()
{
  return this->Internal->lastQueries;
}

void vtkInrVolumeMapper::ReleaseGraphicsResources(vtkWindow* win)
{
  Internals& I = *this->Internal;
  if (I.quad)
  {
    I.quad->ReleaseGraphicsResources(win);
    I.quad.reset();
  }
  if (I.texture)
  {
    I.texture->ReleaseGraphicsResources(win);
    I.texture = nullptr;
  }
  I.textureValid = false;
  this->Superclass::ReleaseGraphicsResources(win);
}

void vtkInrVolumeMapper::Render(vtkRenderer* ren, vtkVolume* vol)
{
  Internals& I = *this->Internal;
  if (!ren || !vol || ren->GetSelector())
  {
    return;  // no picking support: hardware-selection passes skip the volume
  }
  if (vtkAlgorithm* producer = this->GetInputAlgorithm())
  {
    producer->Update();
  }
  vtkDataSet* input = this->GetInput();
  if (!input)
  {
    return;
  }
  vtkFieldData* fd = input->GetFieldData();
  auto* bytes = vtkUnsignedCharArray::SafeDownCast(fd ? fd->GetAbstractArray("InrModel") : nullptr);
  if (!bytes || bytes->GetNumberOfValues() == 0)
  {
    return;  // e.g. an empty piece in a parallel run: nothing to draw here
  }

  // --- the model (reload only when its bytes changed)
  if (bytes != I.bytesPtr || bytes->GetMTime() != I.bytesMTime)
  {
    I.bytesPtr = bytes;
    I.bytesMTime = bytes->GetMTime();
    const std::uint64_t h =
      hashBytes(bytes->GetPointer(0), static_cast<std::size_t>(bytes->GetNumberOfValues()));
    if (h != I.hash || !I.modelOk)
    {
      I.hash = h;
      I.modelOk = false;
      I.renderer.reset();
      try
      {
        I.model = inr::InrModel::loadBytes(bytes->GetPointer(0),
          static_cast<std::size_t>(bytes->GetNumberOfValues()), "INR model (field data)");
        I.modelOk = true;
      }
      catch (const std::exception& e)
      {
        if (I.reportedBadHash != h)
        {
          vtkErrorMacro(<< e.what());
          I.reportedBadHash = h;
        }
      }
    }
  }
  if (!I.modelOk)
  {
    return;
  }

  // --- backend and engine objects (rebuilt when the model, macrocells or backend change)
  const int backend = this->Backend;
  if (!I.renderer || I.builtResolution != this->MacrocellResolution ||
    I.builtSlices != this->TemporalSlices || I.builtBackend != backend)
  {
    try
    {
      I.renderer.reset();
      inr::RenderSessionOptions so;
      so.backend = backend == BACKEND_CUDA ? inr::RenderBackend::Cuda
        : backend == BACKEND_CPU          ? inr::RenderBackend::Cpu
                                          : inr::RenderBackend::Auto;
      so.allowFallback = true;
      const int n = this->MacrocellResolution;
      so.macrocells.dims = inr::Int3{ n, n, n };
      so.macrocells.temporalSlices = I.model.domain.usesTime() ? this->TemporalSlices : 1;
      I.renderer = inr::RenderSession::create(I.model, so);
      if (backend == BACKEND_CUDA && I.renderer->backend() != inr::RenderBackend::Cuda && !I.warnedCuda)
      {
        vtkWarningMacro("INR Volume: the CUDA backend was requested but is not usable here; "
                        "rendering on the CPU (" << I.renderer->description() << ").");
        I.warnedCuda = true;
      }
      I.builtResolution = this->MacrocellResolution;
      I.builtSlices = this->TemporalSlices;
      I.builtBackend = backend;
      I.haveSettings = false;
      ++I.engineBuilds;
    }
    catch (const std::exception& e)
    {
      vtkErrorMacro(<< "INR Volume: cannot set up the renderer: " << e.what());
      I.renderer.reset();
      return;
    }
  }
  const std::string backendText = I.renderer->description();
  I.backendInUse = backendText;

  // --- image size, camera
  int width = 0, height = 0, x0 = 0, y0 = 0;
  ren->GetTiledSizeAndOrigin(&width, &height, &x0, &y0);
  if (width <= 0 || height <= 0)
  {
    return;
  }
  vtkCamera* cam = ren->GetActiveCamera();
  inr::Camera camera;
  cam->GetPosition(camera.position.data());
  cam->GetFocalPoint(camera.focalPoint.data());
  cam->GetViewUp(camera.viewUp.data());
  camera.viewAngle = cam->GetViewAngle();
  if (cam->GetUseHorizontalViewAngle())
  {
    const double aspect = double(width) / double(height);
    camera.viewAngle = 2.0 *
      std::atan(std::tan(0.5 * camera.viewAngle * M_PI / 180.0) / aspect) * 180.0 / M_PI;
  }
  camera.parallelProjection = cam->GetParallelProjection() != 0;
  camera.parallelScale = cam->GetParallelScale();

  // --- depth limit from the depth buffer (opaque geometry rendered before the volume)
  std::vector<float> depthLimit;
  {
    I.depth.resize(std::size_t(width) * height);
    if (auto* glWin = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow()))
    {
      glWin->GetState()->vtkglPixelStorei(GL_PACK_ALIGNMENT, 1);
    }
    glReadPixels(x0, y0, width, height, GL_DEPTH_COMPONENT, GL_FLOAT, I.depth.data());
    bool any = false;
    for (float d : I.depth)
    {
      if (d < 1.0f)
      {
        any = true;
        break;
      }
    }
    if (any)
    {
      const double aspect = double(width) / double(height);
      vtkNew<vtkMatrix4x4> inv;
      inv->DeepCopy(cam->GetCompositeProjectionTransformMatrix(aspect, -1, 1));
      inv->Invert();
      const double* m = inv->GetData();  // row-major, column vectors
      double eye[3], fwd[3];
      cam->GetPosition(eye);
      cam->GetDirectionOfProjection(fwd);
      const bool parallel = camera.parallelProjection;
      depthLimit.assign(std::size_t(width) * height, std::numeric_limits<float>::max());
      for (int j = 0; j < height; ++j)  // j: GL row (0 = bottom)
      {
        const double ny = 2.0 * (j + 0.5) / height - 1.0;
        const int row = height - 1 - j;  // engine row (0 = top)
        for (int i = 0; i < width; ++i)
        {
          const float d = I.depth[std::size_t(j) * width + i];
          if (!(d < 1.0f))
          {
            continue;
          }
          const double nx = 2.0 * (i + 0.5) / width - 1.0;
          const double nz = 2.0 * d - 1.0;
          double p[4];
          for (int r = 0; r < 4; ++r)
          {
            p[r] = m[4 * r] * nx + m[4 * r + 1] * ny + m[4 * r + 2] * nz + m[4 * r + 3];
          }
          const double w = p[3] != 0.0 ? 1.0 / p[3] : 0.0;
          const double dx = p[0] * w - eye[0], dy = p[1] * w - eye[1], dz = p[2] * w - eye[2];
          const double dist = parallel ? (dx * fwd[0] + dy * fwd[1] + dz * fwd[2])
                                       : std::sqrt(dx * dx + dy * dy + dz * dz);
          depthLimit[std::size_t(row) * width + i] = float(std::max(0.0, dist));
        }
      }
    }
  }

  // --- transfer function
  double valueRange[2] = { 0.0, 1.0 };
  if (auto* vr = vtkDataArray::SafeDownCast(fd->GetAbstractArray("InrValueRange")))
  {
    if (vr->GetNumberOfTuples() >= 2)
    {
      valueRange[0] = vr->GetComponent(0, 0);
      valueRange[1] = vr->GetComponent(1, 0);
    }
  }
  vtkVolumeProperty* prop = vol->GetProperty();
  if (this->UseDefaultTransferFunction || !prop)
  {
    const double unit = prop ? prop->GetScalarOpacityUnitDistance(0) : 1.0;
    if (I.tfDefault != 1 || I.tfRange[0] != valueRange[0] || I.tfRange[1] != valueRange[1] ||
      I.tf.unitDistance != unit)
    {
      I.tf = inr::TransferFunction::preset(valueRange[0], valueRange[1]);
      I.tf.unitDistance = unit;
      I.tfDefault = 1;
      I.tfRange[0] = valueRange[0];
      I.tfRange[1] = valueRange[1];
    }
  }
  else
  {
    vtkColorTransferFunction* ctf = prop->GetRGBTransferFunction(0);
    vtkPiecewiseFunction* otf = prop->GetScalarOpacity(0);
    if (I.tfDefault != 0 || ctf->GetMTime() != I.ctfTime || otf->GetMTime() != I.otfTime ||
      prop->GetMTime() != I.propTime)
    {
      inr::TransferFunction tf;
      double cr[2];
      ctf->GetRange(cr);
      if (ctf->GetSize() == 0)
      {
        cr[0] = valueRange[0];
        cr[1] = valueRange[1];
      }
      // Sample the colour function so its colour space (Diverging, Lab, HSV...) and log scale
      // are reproduced exactly by the engine's RGB interpolation.
      const int samples = cr[1] > cr[0] ? 256 : 1;
      for (int k = 0; k < samples; ++k)
      {
        const double x = samples > 1 ? cr[0] + (cr[1] - cr[0]) * k / (samples - 1) : cr[0];
        double rgb[3];
        ctf->GetColor(x, rgb);
        tf.color.push_back({ x, rgb[0], rgb[1], rgb[2] });
      }
      for (int k = 0; k < otf->GetSize(); ++k)
      {
        double node[4];
        otf->GetNodeValue(k, node);
        tf.opacity.push_back({ node[0], node[1], node[2], node[3] });
      }
      if (tf.opacity.empty())
      {
        tf.opacity.push_back({ cr[0], 0.0 });
        tf.opacity.push_back({ cr[1] > cr[0] ? cr[1] : cr[0] + 1.0, 0.0 });
      }
      tf.unitDistance = prop->GetScalarOpacityUnitDistance(0);
      I.tf = tf;
      I.tfDefault = 0;
      I.ctfTime = ctf->GetMTime();
      I.otfTime = otf->GetMTime();
      I.propTime = prop->GetMTime();
    }
  }

  // --- time
  double time = 0.5 * (I.model.domain.timeBegin + I.model.domain.timeEnd);
  if (auto* ta = vtkDataArray::SafeDownCast(fd->GetAbstractArray("InrTime")))
  {
    if (ta->GetNumberOfTuples() >= 1)
    {
      time = ta->GetComponent(0, 0);
    }
  }
  else if (input->GetInformation()->Has(vtkDataObject::DATA_TIME_STEP()))
  {
    time = input->GetInformation()->Get(vtkDataObject::DATA_TIME_STEP());
  }

  // --- hand everything to the engine; it decides what to rebuild
  const int framesBefore = I.renderer->accumulatedFrames();
  bool renderedAny = false;
  try
  {
    inr::RenderSettings settings;
    settings.width = width;
    settings.height = height;
    settings.seed = static_cast<std::uint32_t>(this->Seed);
    if (!I.haveSettings || settings.width != I.settings.width ||
      settings.height != I.settings.height || settings.seed != I.settings.seed)
    {
      I.renderer->setSettings(settings);
      I.settings = settings;
      I.haveSettings = true;
    }
    inr::RenderScene scene;
    scene.camera = camera;
    scene.transferFunction = I.tf;
    scene.background = { 0.f, 0.f, 0.f };
    scene.time = time;
    scene.depthLimit = std::move(depthLimit);
    scene.shadows = this->Shadows != 0;
    if (this->LightDirection[0] == 0.0 && this->LightDirection[1] == 0.0 &&
      this->LightDirection[2] == 0.0)
    {
      scene.toLight = inr::defaultLightDirection(camera);
    }
    else
    {
      scene.toLight = { this->LightDirection[0], this->LightDirection[1], this->LightDirection[2] };
    }
    scene.ambient = static_cast<float>(this->Ambient);
    scene.shadowEstimator =
      this->ShadowEstimator == 1 ? inr::ShadowEstimator::Ratio : inr::ShadowEstimator::Delta;
    if (std::getenv("INR_VOLUME_DEBUG"))
    {
      const inr::RenderScene& o = I.lastScene;
      std::string what;
      if (o.camera.position != scene.camera.position || o.camera.focalPoint != scene.camera.focalPoint ||
        o.camera.viewUp != scene.camera.viewUp || o.camera.viewAngle != scene.camera.viewAngle ||
        o.camera.parallelScale != scene.camera.parallelScale)
        what += " camera";
      if (o.time != scene.time)
        what += " time";
      if (o.depthLimit != scene.depthLimit)
        what += " depth";
      if (o.toLight != scene.toLight || o.shadows != scene.shadows)
        what += " light";
      if (o.transferFunction.color.size() != scene.transferFunction.color.size() ||
        o.transferFunction.opacity.size() != scene.transferFunction.opacity.size() ||
        o.transferFunction.unitDistance != scene.transferFunction.unitDistance ||
        (!o.transferFunction.opacity.empty() &&
          (o.transferFunction.opacity.back().x != scene.transferFunction.opacity.back().x ||
            o.transferFunction.opacity.front().x != scene.transferFunction.opacity.front().x)))
        what += " tf";
      std::fprintf(stderr, "INR Volume: render %dx%d, frames %d, changed:%s\n", width, height,
        I.renderer->accumulatedFrames(), what.empty() ? " nothing" : what.c_str());
      I.lastScene = scene;
    }
    I.renderer->setScene(scene);

    int frames = I.renderer->accumulatedFrames();
    if (frames == 0 || frames < framesBefore)
    {
      I.estimate = std::numeric_limits<double>::infinity();
    }
    // Re-evaluated every render: the limits may have changed since the last one.
    I.converged = frames >= this->MaximumFrames ||
      (this->ConvergenceTarget > 0.0 && frames >= 4 && I.estimate < this->ConvergenceTarget);
    const int goal = std::min(this->MaximumFrames, std::max(frames + 1, this->FramesPerRender));
    I.lastUpdateMs = 0.0;
    I.lastQueries = 0.0;
    while (!I.converged && frames < goal)
    {
      const inr::FrameStats st = I.renderer->renderFrame();
      renderedAny = true;
      I.lastUpdateMs += st.updateMs;
      I.lastQueries += double(st.totalQueries());
      frames = I.renderer->accumulatedFrames();
      const auto& res = I.renderer->residual();
      double sum = 0.0;
      for (float r : res)
      {
        sum += r;
      }
      I.estimate = res.empty() ? 0.0 : sum / double(res.size()) / std::sqrt(double(frames));
      I.converged = frames >= this->MaximumFrames ||
        (this->ConvergenceTarget > 0.0 && frames >= 4 && I.estimate < this->ConvergenceTarget);
    }
    if (frames >= this->MaximumFrames)
    {
      I.converged = true;
    }
    if (std::getenv("INR_VOLUME_DEBUG") && renderedAny)
    {
      std::fprintf(stderr, "INR Volume: now %d frames, %.0f queries, update %.1f ms, converged %d\n",
        frames, I.lastQueries, I.lastUpdateMs, int(I.converged));
    }
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro(<< "INR Volume: rendering failed: " << e.what());
    return;
  }

  // --- draw the accumulated image over what is in the framebuffer
  vtkOpenGLRenderWindow* renWin = vtkOpenGLRenderWindow::SafeDownCast(ren->GetRenderWindow());
  if (!renWin || I.renderer->accumulatedFrames() == 0)
  {
    return;
  }
  if (!I.texture)
  {
    I.texture = vtkSmartPointer<vtkTextureObject>::New();
    I.textureValid = false;
  }
  I.texture->SetContext(renWin);
  const int frames = I.renderer->accumulatedFrames();
  if (!I.textureValid || I.texW != width || I.texH != height || I.uploadedFrames != frames ||
    renderedAny)
  {
    const inr::ImageRGBA img = I.renderer->premultipliedImage();
    if (I.textureValid && I.texW == width && I.texH == height)
    {
      I.texture->Bind();
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_FLOAT, img.data.data());
    }
    else
    {
      I.texture->Create2DFromRaw(width, height, 4, VTK_FLOAT,
        const_cast<void*>(static_cast<const void*>(img.data.data())));
      I.texture->SetMinificationFilter(vtkTextureObject::Nearest);
      I.texture->SetMagnificationFilter(vtkTextureObject::Nearest);
      I.texW = width;
      I.texH = height;
      I.textureValid = true;
    }
    I.uploadedFrames = frames;
  }

  vtkOpenGLState* ostate = renWin->GetState();
  vtkOpenGLState::ScopedglEnableDisable blendSaver(ostate, GL_BLEND);
  vtkOpenGLState::ScopedglEnableDisable depthSaver(ostate, GL_DEPTH_TEST);
  vtkOpenGLState::ScopedglBlendFuncSeparate blendFuncSaver(ostate);
  vtkOpenGLState::ScopedglDepthMask depthMaskSaver(ostate);
  ostate->vtkglEnable(GL_BLEND);
  ostate->vtkglDisable(GL_DEPTH_TEST);
  ostate->vtkglDepthMask(GL_FALSE);
  ostate->vtkglBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);

  if (!I.quad)
  {
    std::string fs = vtkOpenGLRenderUtilities::GetFullScreenQuadFragmentShaderTemplate();
    vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Decl", "uniform sampler2D inrImage;\n");
    vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Impl", kFragmentImpl);
    I.quad = std::make_unique<vtkOpenGLQuadHelper>(renWin,
      vtkOpenGLRenderUtilities::GetFullScreenQuadVertexShader().c_str(), fs.c_str(), "");
  }
  else
  {
    renWin->GetShaderCache()->ReadyShaderProgram(I.quad->Program);
  }
  if (!I.quad->Program || !I.quad->Program->GetCompiled())
  {
    vtkErrorMacro("INR Volume: could not build the compositing shader.");
    return;
  }
  I.texture->Activate();
  I.quad->Program->SetUniformi("inrImage", I.texture->GetTextureUnit());
  I.quad->Render();
  I.texture->Deactivate();
}

void vtkInrVolumeMapper::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Backend: " << this->Backend << " (" << this->GetBackendInUse() << ")\n";
  os << indent << "MacrocellResolution: " << this->MacrocellResolution << "\n";
  os << indent << "TemporalSlices: " << this->TemporalSlices << "\n";
  os << indent << "Shadows: " << this->Shadows << "\n";
  os << indent << "MaximumFrames: " << this->MaximumFrames << "\n";
  os << indent << "ConvergenceTarget: " << this->ConvergenceTarget << "\n";
  os << indent << "FramesPerRender: " << this->FramesPerRender << "\n";
  os << indent << "Seed: " << this->Seed << "\n";
}
