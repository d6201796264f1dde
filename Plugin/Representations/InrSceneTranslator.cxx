#include "InrSceneTranslator.h"

#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkDataArray.h"
#include "vtkDataObject.h"
#include "vtkDataSet.h"
#include "vtkFieldData.h"
#include "vtkImageData.h"
#include "vtkPointData.h"
#include "vtkInformation.h"
#include "vtkLight.h"
#include "vtkLightCollection.h"
#include "vtkMatrix4x4.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkProp3D.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkVolumeProperty.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace
{
// A vtkPiecewiseFunction's nodes (x, value, midpoint, sharpness) as the engine's points.
std::vector<inr::TransferFunction::OpacityPoint> PiecewiseNodes(vtkPiecewiseFunction* fn)
{
  std::vector<inr::TransferFunction::OpacityPoint> nodes;
  for (int k = 0; k < fn->GetSize(); ++k)
  {
    double node[4];
    fn->GetNodeValue(k, node);
    nodes.push_back({ node[0], node[1], node[2], node[3] });
  }
  return nodes;
}
}

double InrSceneTranslator::VerticalViewAngle(double horizontalDegrees, double aspect)
{
  return 2.0 * std::atan(std::tan(0.5 * horizontalDegrees * M_PI / 180.0) / aspect) * 180.0 / M_PI;
}

inr::Camera InrSceneTranslator::TranslateCamera(vtkCamera* cam, int width, int height)
{
  inr::Camera camera;
  cam->GetPosition(camera.position.data());
  cam->GetFocalPoint(camera.focalPoint.data());
  cam->GetViewUp(camera.viewUp.data());
  camera.viewAngle = cam->GetViewAngle();
  if (cam->GetUseHorizontalViewAngle())
  {
    camera.viewAngle = VerticalViewAngle(camera.viewAngle, double(width) / double(height));
  }
  camera.parallelProjection = cam->GetParallelProjection() != 0;
  camera.parallelScale = cam->GetParallelScale();
  cam->GetWindowCenter(camera.windowCenter.data());
  if (cam->GetUseExplicitProjectionTransformMatrix() && cam->GetExplicitProjectionTransformMatrix())
  {
    ProjectionToCamera(
      &cam->GetExplicitProjectionTransformMatrix()->Element[0][0], width, height, camera);
  }
  return camera;
}

bool InrSceneTranslator::ProjectionToCamera(
  const double p[16], int width, int height, inr::Camera& camera)
{
  // Frustum: x_clip = p0 x + p2 z, w = -z; at one unit ahead (z = -1) the image's x in [-1, 1]
  // covers view-plane x = (x_ndc + p2) / p0, i.e. half-extent 1 / p0 around the window centre
  // p2 (likewise y with p5, p6). Box (Ortho): x_ndc = p0 x + p3, centre -p3.
  const bool perspective = p[12] == 0.0 && p[13] == 0.0 && p[14] == -1.0 && p[15] == 0.0;
  const bool box = p[12] == 0.0 && p[13] == 0.0 && p[14] == 0.0 && p[15] == 1.0;
  if (!(perspective || box) || p[1] != 0.0 || p[4] != 0.0 || !(p[0] > 0.0) || !(p[5] > 0.0) ||
    width <= 0 || height <= 0)
  {
    return false;
  }
  if ((perspective && (p[3] != 0.0 || p[7] != 0.0)) || (box && (p[2] != 0.0 || p[6] != 0.0)))
  {
    return false;
  }
  const double halfHeight = 1.0 / p[5], halfWidth = 1.0 / p[0];
  const double aspect = double(width) / double(height);
  if (!(std::abs(halfWidth - halfHeight * aspect) <= 1e-6 * halfWidth))
  {
    return false;  // non-square pixels: not an orthonormal camera over this image
  }
  camera.parallelProjection = box;
  if (box)
  {
    camera.parallelScale = halfHeight;
    camera.windowCenter = { -p[3], -p[7] };
  }
  else
  {
    camera.viewAngle = 2.0 * std::atan(halfHeight) * 180.0 / M_PI;
    camera.windowCenter = { p[2], p[6] };
  }
  return true;
}

std::array<double, 16> InrSceneTranslator::ModelToWorld(vtkProp3D* prop)
{
  std::array<double, 16> m{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
  if (vtkMatrix4x4* matrix = prop ? prop->GetMatrix() : nullptr)
  {
    std::copy(matrix->GetData(), matrix->GetData() + 16, m.begin());
  }
  return m;
}

std::string InrSceneTranslator::UnsupportedCameraFeatures(
  vtkCamera* cam, vtkRenderWindow* win, int width, int height)
{
  std::string list;
  auto add = [&list](const char* what) { list += (list.empty() ? "" : ", ") + std::string(what); };
  if (win && win->GetStereoRender())
  {
    add("stereo (the volume is drawn for the centre eye, without parallax)");
  }
  if (cam && cam->GetUseOffAxisProjection())
  {
    add("off-axis projection");
  }
  if (cam && cam->GetUseExplicitProjectionTransformMatrix() && cam->GetExplicitProjectionTransformMatrix())
  {
    inr::Camera probe;
    if (!ProjectionToCamera(&cam->GetExplicitProjectionTransformMatrix()->Element[0][0], width, height, probe))
    {
      add("an explicit projection matrix that is not a plain frustum or box");
    }
  }
  if (cam && cam->GetUserTransform())
  {
    add("a camera user transform");
  }
  if (cam && cam->GetModelTransformMatrix() && !cam->GetModelTransformMatrix()->IsIdentity())
  {
    add("a camera model transform matrix");
  }
  return list;
}

inr::ImageWindow InrSceneTranslator::TileWindow(const double vp[4], const double tvp[4],
  const int size[2], int tileWidth, int tileHeight)
{
  // VTK's pixel rounding (vtkViewport::GetTiledSizeAndOrigin): int(v + 0.5) of normalized
  // coordinates times the tiled window size.
  auto px = [](double v, int n) { return static_cast<int>(v * n + 0.5); };
  const int fullWidth = px(vp[2], size[0]) - px(vp[0], size[0]);
  const int fullHeight = px(vp[3], size[1]) - px(vp[1], size[1]);
  // The part's lower-left corner in the window: the tile's corner plus the part's offset in it.
  const int left = px(tvp[0], size[0]) +
    px(std::min(std::max(vp[0] - tvp[0], 0.0), 1.0), size[0]) - px(vp[0], size[0]);
  const int bottom = px(tvp[1], size[1]) +
    px(std::min(std::max(vp[1] - tvp[1], 0.0), 1.0), size[1]) - px(vp[1], size[1]);
  inr::ImageWindow w;
  if (tileWidth <= 0 || tileHeight <= 0 || tileWidth > fullWidth || tileHeight > fullHeight ||
    (tileWidth == fullWidth && tileHeight == fullHeight))
  {
    return w;  // the whole picture (or nothing sensible: keyed as a picture of its own)
  }
  w.fullWidth = fullWidth;
  w.fullHeight = fullHeight;
  w.x = std::min(std::max(left, 0), fullWidth - tileWidth);
  w.y = std::min(std::max(fullHeight - bottom - tileHeight, 0), fullHeight - tileHeight);
  return w;
}

std::vector<float> InrSceneTranslator::DepthToRayDistances(const float* depth, int width,
  int height, const double m[16], const double eye[3], const double fwd[3], bool parallel)
{
  const std::size_t n = std::size_t(width) * std::size_t(height);
  if (!depth || width <= 0 || height <= 0 || std::none_of(depth, depth + n, [](float d) { return d < 1.0f; }))
  {
    return {};
  }
  std::vector<float> distance(n, std::numeric_limits<float>::max());
  for (int j = 0; j < height; ++j)  // j: GL row (0 = bottom)
  {
    const double ny = 2.0 * (j + 0.5) / height - 1.0;
    const int row = height - 1 - j;  // engine row (0 = top)
    for (int i = 0; i < width; ++i)
    {
      const float d = depth[std::size_t(j) * width + i];
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
      distance[std::size_t(row) * width + i] = float(std::max(0.0, dist));
    }
  }
  return distance;
}

std::vector<float> InrSceneTranslator::DepthToRayDistances(
  const std::vector<float>& depth, int width, int height, vtkCamera* cam)
{
  if (depth.size() < std::size_t(width) * std::size_t(height))
  {
    return {};
  }
  vtkNew<vtkMatrix4x4> inverse;
  inverse->DeepCopy(cam->GetCompositeProjectionTransformMatrix(double(width) / double(height), -1, 1));
  inverse->Invert();
  double eye[3], fwd[3];
  cam->GetPosition(eye);
  cam->GetDirectionOfProjection(fwd);
  return DepthToRayDistances(
    depth.data(), width, height, inverse->GetData(), eye, fwd, cam->GetParallelProjection() != 0);
}

void InrSceneTranslator::ValueRange(vtkFieldData* fd, double range[2])
{
  range[0] = 0.0;
  range[1] = 1.0;
  if (auto* vr = vtkDataArray::SafeDownCast(fd ? fd->GetAbstractArray("InrValueRange") : nullptr))
  {
    if (vr->GetNumberOfTuples() >= 2)
    {
      range[0] = vr->GetComponent(0, 0);
      range[1] = vr->GetComponent(1, 0);
    }
  }
}

double InrSceneTranslator::Time(vtkDataSet* input, double fallback)
{
  if (!input)
  {
    return fallback;
  }
  vtkFieldData* fd = input->GetFieldData();
  if (auto* ta = vtkDataArray::SafeDownCast(fd ? fd->GetAbstractArray("InrTime") : nullptr))
  {
    return ta->GetNumberOfTuples() >= 1 ? ta->GetComponent(0, 0) : fallback;
  }
  vtkInformation* info = input->GetInformation();
  if (info && info->Has(vtkDataObject::DATA_TIME_STEP()))
  {
    return info->Get(vtkDataObject::DATA_TIME_STEP());
  }
  return fallback;
}

inr::TransferFunction InrSceneTranslator::SampleTransferFunction(
  vtkVolumeProperty* prop, const double valueRange[2])
{
  vtkColorTransferFunction* ctf = prop->GetRGBTransferFunction(0);
  vtkPiecewiseFunction* otf = prop->GetScalarOpacity(0);
  inr::TransferFunction tf;
  double cr[2];
  ctf->GetRange(cr);
  if (ctf->GetSize() == 0)
  {
    cr[0] = valueRange[0];
    cr[1] = valueRange[1];
  }
  // Sample the colour function so its colour space (Diverging, Lab, HSV...) and log scale are
  // reproduced exactly by the engine's RGB interpolation.
  const int samples = cr[1] > cr[0] ? ColorSamples : 1;
  for (int k = 0; k < samples; ++k)
  {
    const double x = samples > 1 ? cr[0] + (cr[1] - cr[0]) * k / (samples - 1) : cr[0];
    double rgb[3];
    ctf->GetColor(x, rgb);
    tf.color.push_back({ x, rgb[0], rgb[1], rgb[2] });
  }
  tf.opacity = PiecewiseNodes(otf);
  if (tf.opacity.empty())
  {
    tf.opacity.push_back({ cr[0], 0.0 });
    tf.opacity.push_back({ cr[1] > cr[0] ? cr[1] : cr[0] + 1.0, 0.0 });
  }
  tf.unitDistance = prop->GetScalarOpacityUnitDistance(0);
  return tf;
}

std::vector<inr::TransferFunction::OpacityPoint> InrSceneTranslator::GradientOpacity(vtkVolumeProperty* prop)
{
  // The property's own function where one was set and is not disabled (VTK's default, a constant
  // 1, is no function here: it would cost every sample a gradient for nothing, and so would any
  // function at 1 everywhere).
  // (HasGradientOpacity first: GetStoredGradientOpacity creates VTK's default function when none
  // is set, which modifies the property.)
  vtkPiecewiseFunction* gof = !prop || prop->GetTransferFunctionMode() != vtkVolumeProperty::TF_1D ||
      !prop->HasGradientOpacity(0) || prop->GetDisableGradientOpacity(0)
    ? nullptr
    : prop->GetStoredGradientOpacity(0);
  if (!gof)
  {
    return {};
  }
  std::vector<inr::TransferFunction::OpacityPoint> nodes = PiecewiseNodes(gof);
  const bool constantOne = std::all_of(
    nodes.begin(), nodes.end(), [](const inr::TransferFunction::OpacityPoint& p) { return p.alpha >= 1.0; });
  if (constantOne)
  {
    nodes.clear();
  }
  return nodes;
}

inr::TransferFunction::Transfer2D InrSceneTranslator::Transfer2D(vtkVolumeProperty* prop, std::string& problem)
{
  problem.clear();
  inr::TransferFunction::Transfer2D t;
  if (!prop || prop->GetTransferFunctionMode() != vtkVolumeProperty::TF_2D)
  {
    return t;
  }
  vtkImageData* image = prop->GetTransferFunction2D(0);
  vtkDataArray* scalars = image ? image->GetPointData()->GetScalars() : nullptr;
  int dims[3] = { 0, 0, 0 };
  if (image)
  {
    image->GetDimensions(dims);
  }
  if (!scalars || scalars->GetNumberOfComponents() != 4 || dims[0] < 1 || dims[1] < 1 || dims[2] != 1 ||
    scalars->GetNumberOfTuples() != vtkIdType(dims[0]) * dims[1])
  {
    problem = "its image has no RGBA scalars of one value per pixel in one slice";
    return t;
  }
  if (vtkIdType(dims[0]) * dims[1] > inr::TransferFunctionTable::kMaxTransfer2DPixels)
  {
    problem = "its image has more than " + std::to_string(inr::TransferFunctionTable::kMaxTransfer2DPixels) + " pixels";
    return t;
  }
  double origin[3], spacing[3];
  image->GetOrigin(origin);
  image->GetSpacing(spacing);
  t.scalarLo = origin[0];
  t.scalarHi = origin[0] + spacing[0] * dims[0];
  t.gradientLo = origin[1];
  t.gradientHi = origin[1] + spacing[1] * dims[1];
  if (!(std::isfinite(t.scalarLo) && std::isfinite(t.scalarHi) && t.scalarHi > t.scalarLo &&
        std::isfinite(t.gradientLo) && std::isfinite(t.gradientHi) && t.gradientHi > t.gradientLo))
  {
    problem = "its image spans no value or gradient range (origin and spacing: the 2D transfer "
              "function's Range must be wider than a point)";
    return t;
  }
  t.rgba.resize(std::size_t(4) * dims[0] * dims[1]);
  for (vtkIdType p = 0; p < vtkIdType(dims[0]) * dims[1]; ++p)
  {
    for (int c = 0; c < 4; ++c)
    {
      const double v = scalars->GetComponent(p, c);
      if (!std::isfinite(v))
      {
        problem = "its pixel " + std::to_string(p % dims[0]) + ", " + std::to_string(p / dims[0]) + " is not finite";
        return inr::TransferFunction::Transfer2D{};
      }
      t.rgba[std::size_t(4) * p + c] = static_cast<float>(v);
    }
  }
  t.width = dims[0];
  t.height = dims[1];
  return t;
}

inr::TransferFunction InrSceneTranslator::DefaultTransferFunction(
  const double valueRange[2], double unitDistance)
{
  inr::TransferFunction tf = inr::TransferFunction::preset(valueRange[0], valueRange[1]);
  tf.unitDistance = unitDistance;
  return tf;
}

const inr::TransferFunction& InrSceneTranslator::UpdateTransferFunction(
  vtkVolumeProperty* prop, bool useDefault, const double valueRange[2])
{
  const bool sameRange =
    this->CachedRange[0] == valueRange[0] && this->CachedRange[1] == valueRange[1];
  if (useDefault || !prop)
  {
    const double unit = prop ? prop->GetScalarOpacityUnitDistance(0) : 1.0;
    if (this->CachedDefault != 1 || !sameRange || this->CachedUnitDistance != unit)
    {
      this->TF = DefaultTransferFunction(valueRange, unit);
      this->CachedDefault = 1;
      this->CachedUnitDistance = unit;
      ++this->Conversions;
    }
  }
  else
  {
    // The value range only matters for a colour function without nodes; it is part of the key
    // so such a function follows the model's range.
    vtkColorTransferFunction* ctf = prop->GetRGBTransferFunction(0);
    vtkPiecewiseFunction* otf = prop->GetScalarOpacity(0);
    if (this->CachedDefault != 0 || !sameRange || ctf->GetMTime() != this->ColorTime ||
      otf->GetMTime() != this->OpacityTime || prop->GetMTime() != this->PropertyTime)
    {
      this->TF = SampleTransferFunction(prop, valueRange);
      this->CachedDefault = 0;
      this->ColorTime = ctf->GetMTime();
      this->OpacityTime = otf->GetMTime();
      this->PropertyTime = prop->GetMTime();
      ++this->Conversions;
    }
  }
  this->CachedRange[0] = valueRange[0];
  this->CachedRange[1] = valueRange[1];
  // With the default colour map too; read every time (a few nodes), so no key has to follow it.
  this->TF.gradientOpacity = GradientOpacity(prop);
  // The 2D transfer function, with the property's colours, unless the default colour map is asked
  // for; converted again when its image (or the property: the mode) changed.
  vtkImageData* image = prop ? prop->GetTransferFunction2D(0) : nullptr;
  if (useDefault || !prop)
  {
    this->Cached2D = {};
    this->Transfer2DProblem.clear();
    this->Image2D = nullptr;
  }
  else if (image != this->Image2D || (image && image->GetMTime() != this->Image2DTime) ||
    prop->GetMTime() != this->Property2DTime)
  {
    this->Cached2D = Transfer2D(prop, this->Transfer2DProblem);
    this->Image2D = image;
    this->Image2DTime = image ? image->GetMTime() : 0;
    this->Property2DTime = prop->GetMTime();
  }
  this->TF.transfer2D = this->Cached2D;
  return this->TF;
}

int InrSceneTranslator::TranslateShading(
  vtkVolumeProperty* property, vtkRenderer* viewLights, inr::RenderScene& scene)
{
  scene.shading = inr::ShadingOptions{};
  if (!property || !property->GetShade(0))
  {
    return 0;
  }
  // VTK clamps these to the ranges the engine accepts (Ambient, Diffuse, Specular in [0, 1],
  // SpecularPower in [0, 128]).
  scene.shading.enabled = true;
  scene.shading.diffuse = static_cast<float>(property->GetDiffuse(0));
  scene.shading.specular = static_cast<float>(property->GetSpecular(0));
  scene.shading.specularPower = static_cast<float>(property->GetSpecularPower(0));
  scene.ambient = static_cast<float>(property->GetAmbient(0));
  if (!viewLights)
  {
    return 0;
  }
  // vtkOpenGLGPUVolumeRayCastMapper's choice, its loop mirrored (switched-off lights after the
  // first switched-on one count too): its default lighting for one switched-on headlight of
  // intensity 1, its light-list lighting for anything else.
  std::vector<vtkLight*> on;
  bool defaultLighting = false;
  vtkLightCollection* lights = viewLights->GetLights();
  vtkCollectionSimpleIterator it;
  lights->InitTraversal(it);
  while (vtkLight* light = lights->GetNextLight(it))
  {
    if (light->GetSwitch())
    {
      defaultLighting = defaultLighting || on.empty();
      on.push_back(light);
    }
    if (defaultLighting &&
      (on.size() > 1 || light->GetIntensity() != 1.0 || !light->LightTypeIsHeadlight()))
    {
      defaultLighting = false;
    }
  }
  const auto times = [](const double* colour, double intensity) {
    return std::array<float, 3>{ static_cast<float>(colour[0] * intensity),
      static_cast<float>(colour[1] * intensity), static_cast<float>(colour[2] * intensity) };
  };
  // Lights the engine refuses (SceneLight::problem) are left out and counted, not failed on.
  if (defaultLighting)
  {
    scene.shading.headlight = true;
    const auto diffuse = times(on[0]->GetDiffuseColor(), 1.0);
    const auto specular = times(on[0]->GetSpecularColor(), 1.0);
    if (!inr::lightColourProblem(diffuse).empty() || !inr::lightColourProblem(specular).empty())
    {
      return 1;  // its colour refused: lit white
    }
    scene.shading.oneLightDiffuse = diffuse;
    scene.shading.oneLightSpecular = specular;
    return 0;
  }
  scene.shading.lightList = true;
  int left = 0;
  for (vtkLight* light : on)
  {
    if (scene.shading.lights.size() == static_cast<std::size_t>(inr::kMaxShadingLights))
    {
      ++left;
      continue;
    }
    inr::SceneLight l;
    const double intensity = light->GetIntensity();
    l.ambient = times(light->GetAmbientColor(), intensity);
    l.diffuse = times(light->GetDiffuseColor(), intensity);
    l.specular = times(light->GetSpecularColor(), intensity);
    // A headlight sits at the eye and a camera light is placed in camera coordinates (x right,
    // y up, z back towards the viewer): both stay fixed in those coordinates, so a camera move
    // changes only the camera. A scene light's transformed position and focal point are world
    // points.
    if (light->LightTypeIsHeadlight())
    {
      l.cameraLight = true;
      l.toLight = { 0.0, 0.0, 1.0 };
    }
    else
    {
      l.cameraLight = light->LightTypeIsCameraLight() != 0;
      const double* p = l.cameraLight ? light->GetPosition() : light->GetTransformedPosition();
      const double* f = l.cameraLight ? light->GetFocalPoint() : light->GetTransformedFocalPoint();
      l.toLight = { p[0] - f[0], p[1] - f[1], p[2] - f[2] };
    }
    if (!l.problem().empty())
    {
      ++left;  // no direction (position at the focal point), or a negative or huge intensity
      continue;
    }
    scene.shading.lights.push_back(l);
  }
  return left;
}
