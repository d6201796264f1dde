// Unit tests of InrSceneTranslator (VTK -> engine scene translation), no render window needed:
//  - depth unprojection, perspective and parallel: a point placed on a pixel's ray at a known
//    distance is projected with VTK's composite projection matrix (which must put it at that
//    pixel's centre), its window depth is unprojected, and the distance must come back; the
//    engine's own ray for the pixel must reach the point at that distance;
//  - the horizontal view angle conversion, checked against VTK's projection;
//  - transfer-function sampling (colour ends, opacity nodes with midpoint/sharpness, unit
//    distance, empty functions, the default TF) and its cache;
//  - value range and time from field data / DATA_TIME_STEP;
//  - the window centre against VTK's projection, the volume's matrix, tile windows, and the
//    camera features named as ignored.
#include "InrSceneTranslator.h"

#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkDataObject.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkLight.h"
#include "vtkLightCollection.h"
#include "vtkLightKit.h"
#include "vtkMatrix4x4.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkRenderer.h"
#include "vtkSmartPointer.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"

#include "Render/CameraView.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace
{
using V3 = std::array<double, 3>;

V3 sub(const V3& a, const V3& b)
{
  return { a[0] - b[0], a[1] - b[1], a[2] - b[2] };
}
V3 axpy(const V3& a, double s, const V3& b)
{
  return { a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2] };
}
V3 cross(const V3& a, const V3& b)
{
  return { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0] };
}
double dot(const V3& a, const V3& b)
{
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
V3 normalized(const V3& a)
{
  const double l = std::sqrt(dot(a, a));
  return { a[0] / l, a[1] / l, a[2] / l };
}

// The camera's frame, computed here from position, focal point and view up (not from VTK's
// matrices): forward, right, up.
struct Frame
{
  V3 eye, forward, right, up;
};
Frame frameOf(vtkCamera* cam)
{
  Frame f;
  V3 focal, viewUp;
  cam->GetPosition(f.eye.data());
  cam->GetFocalPoint(focal.data());
  cam->GetViewUp(viewUp.data());
  f.forward = normalized(sub(focal, f.eye));
  f.right = normalized(cross(f.forward, viewUp));
  f.up = cross(f.right, f.forward);
  return f;
}

// VTK's projection of a world point: normalized device coordinates (x, y, z in [-1, 1]).
V3 projectWithVtk(vtkCamera* cam, double aspect, const V3& p)
{
  vtkMatrix4x4* m = cam->GetCompositeProjectionTransformMatrix(aspect, -1, 1);
  const double in[4] = { p[0], p[1], p[2], 1.0 };
  double out[4];
  m->MultiplyPoint(in, out);
  return { out[0] / out[3], out[1] / out[3], out[2] / out[3] };
}

struct Probe
{
  int i, j;         // pixel, GL rows (j = 0 at the bottom)
  double distance;  // along the pixel's ray
};

// Places a point on each probe pixel's centre ray at the probe's distance, projects it with VTK,
// writes its window depth into an otherwise empty depth buffer, unprojects the buffer and checks
// the distances (and that the engine's ray for the pixel reaches the point).
void checkUnprojection(vtkCamera* cam, int width, int height, const std::vector<Probe>& probes)
{
  const double aspect = double(width) / double(height);
  const Frame f = frameOf(cam);
  const bool parallel = cam->GetParallelProjection() != 0;
  const double halfHeight =
    parallel ? cam->GetParallelScale() : std::tan(0.5 * cam->GetViewAngle() * M_PI / 180.0);
  std::vector<float> depth(std::size_t(width) * height, 1.0f);
  std::vector<V3> points;
  for (const Probe& p : probes)
  {
    const double nx = 2.0 * (p.i + 0.5) / width - 1.0, ny = 2.0 * (p.j + 0.5) / height - 1.0;
    const double sx = nx * halfHeight * aspect, sy = ny * halfHeight;
    V3 point;
    if (parallel)
    {
      point = axpy(axpy(axpy(f.eye, sx, f.right), sy, f.up), p.distance, f.forward);
    }
    else
    {
      const V3 dir = normalized(axpy(axpy(f.forward, sx, f.right), sy, f.up));
      point = axpy(f.eye, p.distance, dir);
    }
    points.push_back(point);
    const V3 ndc = projectWithVtk(cam, aspect, point);
    ASSERT_NEAR(ndc[0], nx, 1e-9) << "VTK puts the point at pixel " << p.i << "," << p.j;
    ASSERT_NEAR(ndc[1], ny, 1e-9) << "VTK puts the point at pixel " << p.i << "," << p.j;
    ASSERT_GT(ndc[2], -1.0);
    ASSERT_LT(ndc[2], 1.0);
    depth[std::size_t(p.j) * width + p.i] = float(0.5 * (ndc[2] + 1.0));
  }

  const std::vector<float> distance =
    InrSceneTranslator::DepthToRayDistances(depth, width, height, cam);
  ASSERT_EQ(distance.size(), depth.size());
  const inr::CameraView view =
    InrSceneTranslator::TranslateCamera(cam, width, height).view(width, height);
  for (std::size_t k = 0; k < probes.size(); ++k)
  {
    const Probe& p = probes[k];
    const int row = height - 1 - p.j;  // engine rows: 0 at the top
    const float d = distance[std::size_t(row) * width + p.i];
    // The depth buffer holds floats: allow their resolution (perspective depth is coarse far
    // from the near plane).
    EXPECT_NEAR(d, p.distance, 2e-4 * p.distance) << "pixel " << p.i << "," << p.j;
    inr::Vec3f origin, dir;
    inr::cameraRay(view, p.i, row, 0.5f, 0.5f, origin, dir);
    const V3 reached = { origin.x + d * dir.x, origin.y + d * dir.y, origin.z + d * dir.z };
    const V3 miss = sub(reached, points[k]);
    EXPECT_LT(std::sqrt(dot(miss, miss)), 1e-3 * p.distance)
      << "the engine's ray reaches the point at pixel " << p.i << "," << p.j;
  }
  std::size_t limited = 0;
  for (float d : distance)
  {
    limited += d < std::numeric_limits<float>::max() ? 1 : 0;
  }
  EXPECT_EQ(limited, probes.size()) << "pixels with depth 1 have no limit";
}

vtkNew<vtkCamera> makeCamera(bool parallel)
{
  vtkNew<vtkCamera> cam;
  cam->SetPosition(3.0, -2.0, 4.5);
  cam->SetFocalPoint(0.5, 0.25, -0.5);
  cam->SetViewUp(0.1, 1.0, 0.2);
  cam->OrthogonalizeViewUp();
  cam->SetViewAngle(35.0);
  cam->SetParallelProjection(parallel ? 1 : 0);
  cam->SetParallelScale(1.7);
  cam->SetClippingRange(0.5, 20.0);
  return cam;
}
}

TEST(InrSceneTranslator, DepthUnprojectionPerspective)
{
  vtkNew<vtkCamera> cam = makeCamera(false);
  checkUnprojection(cam, 40, 30, { { 20, 15, 5.8 }, { 3, 5, 2.0 }, { 39, 0, 9.5 }, { 0, 29, 1.0 } });
}

TEST(InrSceneTranslator, DepthUnprojectionParallel)
{
  vtkNew<vtkCamera> cam = makeCamera(true);
  checkUnprojection(cam, 40, 30, { { 20, 15, 5.8 }, { 3, 5, 2.0 }, { 39, 0, 9.5 }, { 0, 29, 1.0 } });
}

TEST(InrSceneTranslator, DepthUnprojectionPure)
{
  // Identity "inverse projection", eye at the origin, looking down -z: the unprojected point of
  // pixel centre (nx, ny, 2d - 1) itself.
  const double identity[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
  const double eye[3] = { 0, 0, 0 }, forward[3] = { 0, 0, -1 };
  const std::vector<float> nothing(6, 1.0f);
  EXPECT_TRUE(InrSceneTranslator::DepthToRayDistances(nothing.data(), 3, 2, identity, eye, forward, false)
                .empty())
    << "no depth below 1: no limit at all";
  std::vector<float> depth(6, 1.0f);
  depth[0] = 0.25f;  // GL pixel (0, 0), bottom left: ndc (-2/3, -1/2, -1/2)
  const std::vector<float> perspective =
    InrSceneTranslator::DepthToRayDistances(depth.data(), 3, 2, identity, eye, forward, false);
  ASSERT_EQ(perspective.size(), 6u);
  EXPECT_NEAR(perspective[3], std::sqrt(4.0 / 9.0 + 0.25 + 0.25), 1e-6) << "bottom row is engine row 1";
  EXPECT_EQ(perspective[0], std::numeric_limits<float>::max());
  const std::vector<float> parallel =
    InrSceneTranslator::DepthToRayDistances(depth.data(), 3, 2, identity, eye, forward, true);
  EXPECT_NEAR(parallel[3], 0.5, 1e-6) << "parallel: distance along the direction";
}

TEST(InrSceneTranslator, HorizontalViewAngle)
{
  EXPECT_NEAR(InrSceneTranslator::VerticalViewAngle(90.0, 2.0), 2.0 * std::atan(0.5) * 180.0 / M_PI, 1e-12);
  EXPECT_NEAR(InrSceneTranslator::VerticalViewAngle(40.0, 1.0), 40.0, 1e-12);

  const int width = 64, height = 40;
  const double aspect = double(width) / height;
  vtkNew<vtkCamera> cam = makeCamera(false);
  cam->SetViewAngle(50.0);
  cam->UseHorizontalViewAngleOff();
  EXPECT_DOUBLE_EQ(InrSceneTranslator::TranslateCamera(cam, width, height).viewAngle, 50.0);
  cam->UseHorizontalViewAngleOn();
  const inr::Camera camera = InrSceneTranslator::TranslateCamera(cam, width, height);
  const double halfWidth = std::tan(0.5 * camera.viewAngle * M_PI / 180.0) * aspect;
  EXPECT_NEAR(halfWidth, std::tan(25.0 * M_PI / 180.0), 1e-12);
  // VTK's own projection in horizontal mode puts the edge of a 50-degree horizontal view at the
  // image's left/right border, and the converted vertical angle at its top.
  const Frame f = frameOf(cam);
  const V3 rightEdge = axpy(axpy(f.eye, 3.0, f.forward), 3.0 * halfWidth, f.right);
  EXPECT_NEAR(projectWithVtk(cam, aspect, rightEdge)[0], 1.0, 1e-9);
  const V3 topEdge = axpy(axpy(f.eye, 3.0, f.forward), 3.0 * halfWidth / aspect, f.up);
  EXPECT_NEAR(projectWithVtk(cam, aspect, topEdge)[1], 1.0, 1e-9);

  double position[3];
  cam->GetPosition(position);
  EXPECT_EQ(camera.position[0], position[0]);
  EXPECT_FALSE(camera.parallelProjection);
  cam->ParallelProjectionOn();
  const inr::Camera parallel = InrSceneTranslator::TranslateCamera(cam, width, height);
  EXPECT_TRUE(parallel.parallelProjection);
  EXPECT_DOUBLE_EQ(parallel.parallelScale, 1.7);
}

// The window centre (vtkWindowToImageFilter shifts it per tile): the engine's ray through a
// pixel reaches the point VTK's projection puts at that pixel's centre.
TEST(InrSceneTranslator, WindowCenterMatchesVtkProjection)
{
  for (const bool parallel : { false, true })
  {
    vtkNew<vtkCamera> cam;
    cam->SetPosition(2.0, 1.5, 4.0);
    cam->SetFocalPoint(0.2, -0.1, 0.3);
    cam->SetViewUp(0.1, 1.0, 0.0);
    cam->OrthogonalizeViewUp();
    cam->SetViewAngle(22.0);
    cam->SetParallelProjection(parallel);
    cam->SetParallelScale(1.3);
    cam->SetWindowCenter(0.7, -1.4);
    const int width = 40, height = 30;
    const inr::Camera camera = InrSceneTranslator::TranslateCamera(cam, width, height);
    EXPECT_EQ(camera.windowCenter[0], 0.7);
    EXPECT_EQ(camera.windowCenter[1], -1.4);
    const inr::CameraView view = camera.view(width, height);
    for (const auto& px : { std::array<int, 2>{ 0, 0 }, { 39, 29 }, { 12, 20 } })
    {
      inr::Vec3f o, d;
      inr::cameraRay(view, px[0], px[1], 0.5f, 0.5f, o, d);
      const V3 point{ o.x + 3.0 * d.x, o.y + 3.0 * d.y, o.z + 3.0 * d.z };
      const V3 ndc = projectWithVtk(cam, double(width) / height, point);
      EXPECT_NEAR(ndc[0], 2.0 * (px[0] + 0.5) / width - 1.0, 1e-5) << parallel;
      EXPECT_NEAR(ndc[1], 1.0 - 2.0 * (px[1] + 0.5) / height, 1e-5) << parallel;
    }
  }
}

// ParaView's IceT compositing renders with an explicit projection matrix: for a tile display,
// the tile's part of the full frustum (an NDC scale and shift of the camera's projection). The
// engine's rays through the tile's pixel centres must reach the points VTK projects there.
TEST(InrSceneTranslator, ExplicitTileProjectionMatchesVtk)
{
  for (const bool parallel : { false, true })
  {
    vtkNew<vtkCamera> cam;
    cam->SetPosition(2.0, 1.5, 4.0);
    cam->SetFocalPoint(0.2, -0.1, 0.3);
    cam->SetViewUp(0.1, 1.0, 0.0);
    cam->OrthogonalizeViewUp();
    cam->SetParallelProjection(parallel);
    cam->SetParallelScale(1.3);
    const int fullWidth = 80, fullHeight = 60, width = 40, height = 30;
    vtkNew<vtkMatrix4x4> full, tileTransform, explicitProjection;
    full->DeepCopy(cam->GetProjectionTransformMatrix(double(fullWidth) / fullHeight, -1, 1));
    // The tile covering the right half and bottom half of the display: x_tile = 2 x - 1,
    // y_tile = 2 y + 1 in normalized device coordinates.
    tileTransform->SetElement(0, 0, 2.0);
    tileTransform->SetElement(0, 3, -1.0);
    tileTransform->SetElement(1, 1, 2.0);
    tileTransform->SetElement(1, 3, 1.0);
    vtkMatrix4x4::Multiply4x4(tileTransform, full, explicitProjection);
    cam->SetExplicitProjectionTransformMatrix(explicitProjection);
    cam->UseExplicitProjectionTransformMatrixOn();
    EXPECT_EQ(InrSceneTranslator::UnsupportedCameraFeatures(cam, nullptr, width, height), "");
    const inr::Camera camera = InrSceneTranslator::TranslateCamera(cam, width, height);
    EXPECT_EQ(camera.parallelProjection, parallel);
    const inr::CameraView view = camera.view(width, height);
    for (const auto& px : { std::array<int, 2>{ 0, 0 }, { 39, 29 }, { 25, 7 } })
    {
      inr::Vec3f o, d;
      inr::cameraRay(view, px[0], px[1], 0.5f, 0.5f, o, d);
      const V3 point{ o.x + 3.0 * d.x, o.y + 3.0 * d.y, o.z + 3.0 * d.z };
      const V3 ndc = projectWithVtk(cam, double(width) / height, point);
      EXPECT_NEAR(ndc[0], 2.0 * (px[0] + 0.5) / width - 1.0, 1e-5) << parallel;
      EXPECT_NEAR(ndc[1], 1.0 - 2.0 * (px[1] + 0.5) / height, 1e-5) << parallel;
    }
    // A sheared projection (e.g. stereo) is not an orthonormal camera: named, not followed.
    explicitProjection->SetElement(0, 1, 0.2);
    cam->SetExplicitProjectionTransformMatrix(explicitProjection);
    EXPECT_NE(InrSceneTranslator::UnsupportedCameraFeatures(cam, nullptr, width, height)
                .find("explicit projection"),
      std::string::npos);
  }
}

TEST(InrSceneTranslator, ModelToWorldIsTheVolumeMatrix)
{
  vtkNew<vtkVolume> volume;
  const auto identity = InrSceneTranslator::ModelToWorld(volume);
  EXPECT_EQ(identity, (std::array<double, 16>{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 }));
  EXPECT_EQ(InrSceneTranslator::ModelToWorld(nullptr), identity);
  volume->SetPosition(1, 2, 3);
  volume->SetScale(2, 3, 4);
  volume->RotateZ(90);
  vtkNew<vtkMatrix4x4> user;
  user->SetElement(0, 1, 0.5);
  volume->SetUserMatrix(user);
  const auto m = InrSceneTranslator::ModelToWorld(volume);
  vtkMatrix4x4* vtk = volume->GetMatrix();
  for (int r = 0; r < 4; ++r)
  {
    for (int c = 0; c < 4; ++c)
    {
      EXPECT_EQ(m[4 * r + c], vtk->GetElement(r, c));  // row-major
    }
  }
  inr::Camera camera;
  camera.modelToWorld = m;
  // Model point (1, 0, 0) goes where VTK sends it.
  const inr::CameraView view = camera.view(4, 4);
  const inr::Vec3f p = inr::modelToWorld(view, inr::Vec3f{ 1, 0, 0 });
  double in[4] = { 1, 0, 0, 1 }, out[4];
  vtk->MultiplyPoint(in, out);
  EXPECT_NEAR(p.x, out[0], 1e-5);
  EXPECT_NEAR(p.y, out[1], 1e-5);
  EXPECT_NEAR(p.z, out[2], 1e-5);
}

// vtkWindowToImageFilter's tiles (tile scale 2 of a 100 x 80 window: GetSize is 200 x 160) and a
// renderer covering part of the window.
TEST(InrSceneTranslator, TileWindow)
{
  const double whole[4] = { 0, 0, 1, 1 };
  const int size[2] = { 200, 160 };
  const double topRight[4] = { 0.5, 0.5, 1.0, 1.0 }, bottomLeft[4] = { 0, 0, 0.5, 0.5 };
  inr::ImageWindow w = InrSceneTranslator::TileWindow(whole, topRight, size, 100, 80);
  EXPECT_EQ(w, (inr::ImageWindow{ 200, 160, 100, 0 }));  // rows from the top
  w = InrSceneTranslator::TileWindow(whole, bottomLeft, size, 100, 80);
  EXPECT_EQ(w, (inr::ImageWindow{ 200, 160, 0, 80 }));
  // Untiled: the whole picture.
  const int untiled[2] = { 100, 80 };
  EXPECT_EQ(InrSceneTranslator::TileWindow(whole, whole, untiled, 100, 80).fullWidth, 0);
  // A renderer on the right half of the window, tile = the window's top-right quarter: the
  // renderer's picture is 100 x 160; the part in this tile is its top half.
  const double rightHalf[4] = { 0.5, 0, 1, 1 };
  w = InrSceneTranslator::TileWindow(rightHalf, topRight, size, 100, 80);
  EXPECT_EQ(w, (inr::ImageWindow{ 100, 160, 0, 0 }));
  // Numbers that do not fit: the whole picture.
  EXPECT_EQ(InrSceneTranslator::TileWindow(whole, topRight, size, 300, 80).fullWidth, 0);
}

TEST(InrSceneTranslator, UnsupportedCameraFeatures)
{
  vtkNew<vtkCamera> cam;
  EXPECT_EQ(InrSceneTranslator::UnsupportedCameraFeatures(cam, nullptr, 8, 8), "");
  cam->SetUseOffAxisProjection(1);
  vtkNew<vtkMatrix4x4> model;
  model->SetElement(0, 3, 2.0);
  cam->SetModelTransformMatrix(model);
  const std::string list = InrSceneTranslator::UnsupportedCameraFeatures(cam, nullptr, 8, 8);
  EXPECT_NE(list.find("off-axis projection"), std::string::npos) << list;
  EXPECT_NE(list.find("camera model transform"), std::string::npos) << list;
}

TEST(InrSceneTranslator, TransferFunctionSampling)
{
  vtkNew<vtkColorTransferFunction> ctf;
  ctf->SetColorSpaceToRGB();
  ctf->AddRGBPoint(-1.0, 1.0, 0.0, 0.0);
  ctf->AddRGBPoint(3.0, 0.0, 0.2, 1.0);
  vtkNew<vtkPiecewiseFunction> otf;
  otf->AddPoint(0.0, 0.1, 0.3, 0.7);
  otf->AddPoint(2.0, 0.9, 0.5, 0.0);
  vtkNew<vtkVolumeProperty> prop;
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  prop->SetScalarOpacityUnitDistance(0.25);
  const double range[2] = { 0.0, 1.0 };

  const inr::TransferFunction tf = InrSceneTranslator::SampleTransferFunction(prop, range);
  ASSERT_EQ(tf.color.size(), std::size_t(InrSceneTranslator::ColorSamples));
  const auto& first = tf.color.front();
  const auto& last = tf.color.back();
  EXPECT_DOUBLE_EQ(first.x, -1.0);
  EXPECT_NEAR(first.r, 1.0, 1e-12);
  EXPECT_NEAR(first.g, 0.0, 1e-12);
  EXPECT_NEAR(first.b, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(last.x, 3.0);
  EXPECT_NEAR(last.r, 0.0, 1e-12);
  EXPECT_NEAR(last.g, 0.2, 1e-12);
  EXPECT_NEAR(last.b, 1.0, 1e-12);
  const auto& mid = tf.color[85];  // RGB space: linear in between
  const double t = (mid.x + 1.0) / 4.0;
  EXPECT_NEAR(mid.x, -1.0 + 4.0 * 85 / 255.0, 1e-12);
  EXPECT_NEAR(mid.r, 1.0 - t, 1e-6);
  EXPECT_NEAR(mid.b, t, 1e-6);

  ASSERT_EQ(tf.opacity.size(), 2u);
  EXPECT_DOUBLE_EQ(tf.opacity[0].x, 0.0);
  EXPECT_DOUBLE_EQ(tf.opacity[0].alpha, 0.1);
  EXPECT_DOUBLE_EQ(tf.opacity[0].midpoint, 0.3);
  EXPECT_DOUBLE_EQ(tf.opacity[0].sharpness, 0.7);
  EXPECT_DOUBLE_EQ(tf.opacity[1].x, 2.0);
  EXPECT_DOUBLE_EQ(tf.opacity[1].alpha, 0.9);
  EXPECT_DOUBLE_EQ(tf.opacity[1].midpoint, 0.5);
  EXPECT_DOUBLE_EQ(tf.opacity[1].sharpness, 0.0);
  EXPECT_DOUBLE_EQ(tf.unitDistance, 0.25);
}

TEST(InrSceneTranslator, TransferFunctionEmptyAndDefault)
{
  vtkNew<vtkVolumeProperty> prop;
  vtkNew<vtkColorTransferFunction> ctf;
  vtkNew<vtkPiecewiseFunction> otf;
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  prop->SetScalarOpacityUnitDistance(0.5);
  const double range[2] = { -2.0, 6.0 };
  // No nodes: colours over the value range, zero opacity over it.
  const inr::TransferFunction empty = InrSceneTranslator::SampleTransferFunction(prop, range);
  ASSERT_EQ(empty.color.size(), std::size_t(InrSceneTranslator::ColorSamples));
  EXPECT_DOUBLE_EQ(empty.color.front().x, -2.0);
  EXPECT_DOUBLE_EQ(empty.color.back().x, 6.0);
  ASSERT_EQ(empty.opacity.size(), 2u);
  EXPECT_DOUBLE_EQ(empty.opacity[0].x, -2.0);
  EXPECT_DOUBLE_EQ(empty.opacity[1].x, 6.0);
  EXPECT_DOUBLE_EQ(empty.opacity[0].alpha + empty.opacity[1].alpha, 0.0);

  // The default TF: the engine's preset over the value range, the property's unit distance.
  InrSceneTranslator translator;
  const inr::TransferFunction& def = translator.UpdateTransferFunction(prop, true, range);
  inr::TransferFunction preset = inr::TransferFunction::preset(-2.0, 6.0);
  ASSERT_EQ(def.color.size(), preset.color.size());
  ASSERT_EQ(def.opacity.size(), preset.opacity.size());
  EXPECT_DOUBLE_EQ(def.color.front().x, preset.color.front().x);
  EXPECT_DOUBLE_EQ(def.color.back().x, preset.color.back().x);
  EXPECT_DOUBLE_EQ(def.opacity.back().alpha, preset.opacity.back().alpha);
  EXPECT_DOUBLE_EQ(def.unitDistance, 0.5);
  EXPECT_DOUBLE_EQ(translator.UpdateTransferFunction(nullptr, false, range).unitDistance, 1.0)
    << "no property: the default TF with unit distance 1";
}

TEST(InrSceneTranslator, TransferFunctionCache)
{
  vtkNew<vtkColorTransferFunction> ctf;
  ctf->AddRGBPoint(0.0, 0.0, 0.0, 0.0);
  ctf->AddRGBPoint(1.0, 1.0, 1.0, 1.0);
  vtkNew<vtkPiecewiseFunction> otf;
  otf->AddPoint(0.0, 0.0);
  otf->AddPoint(1.0, 1.0);
  vtkNew<vtkVolumeProperty> prop;
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  const double range[2] = { 0.0, 1.0 };
  InrSceneTranslator translator;
  translator.UpdateTransferFunction(prop, false, range);
  translator.UpdateTransferFunction(prop, false, range);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 1) << "unchanged inputs: no conversion";
  otf->AddPoint(0.5, 0.2);
  EXPECT_EQ(translator.UpdateTransferFunction(prop, false, range).opacity.size(), 3u);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 2) << "opacity edit";
  ctf->AddRGBPoint(0.5, 1.0, 0.0, 0.0);
  translator.UpdateTransferFunction(prop, false, range);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 3) << "colour edit";
  prop->SetScalarOpacityUnitDistance(2.0);
  EXPECT_DOUBLE_EQ(translator.UpdateTransferFunction(prop, false, range).unitDistance, 2.0);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 4) << "unit distance edit";
  translator.UpdateTransferFunction(prop, true, range);
  translator.UpdateTransferFunction(prop, true, range);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 5) << "switch to the default TF";
  const double other[2] = { 0.0, 2.0 };
  EXPECT_DOUBLE_EQ(translator.UpdateTransferFunction(prop, true, other).color.back().x, 2.0);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 6) << "default TF follows the value range";
  translator.UpdateTransferFunction(prop, false, other);
  EXPECT_EQ(translator.GetTransferFunctionConversions(), 7) << "back to the property's TF";
}

TEST(InrSceneTranslator, GradientOpacityFromTheVolumeProperty)
{
  const double range[2] = { 0.0, 1.0 };
  vtkNew<vtkVolumeProperty> prop;
  InrSceneTranslator translator;
  // VTK's default: gradient opacity enabled but unset (a constant 1 on request): none.
  EXPECT_TRUE(translator.UpdateTransferFunction(prop, true, range).gradientOpacity.empty());
  vtkNew<vtkPiecewiseFunction> gof;
  gof->AddPoint(0.0, 1.0);
  gof->AddPoint(5.0, 1.0);
  prop->SetGradientOpacity(gof);
  EXPECT_TRUE(InrSceneTranslator::GradientOpacity(prop).empty()) << "1 everywhere: no cost for nothing";
  gof->AddPoint(2.0, 0.25);
  const auto nodes = InrSceneTranslator::GradientOpacity(prop);
  ASSERT_EQ(nodes.size(), 3u);
  EXPECT_DOUBLE_EQ(nodes[1].x, 2.0);
  EXPECT_DOUBLE_EQ(nodes[1].alpha, 0.25);
  // Both transfer functions carry it: the default colour map and the property's own.
  EXPECT_EQ(translator.UpdateTransferFunction(prop, true, range).gradientOpacity.size(), 3u);
  EXPECT_EQ(translator.UpdateTransferFunction(prop, false, range).gradientOpacity.size(), 3u);
  prop->DisableGradientOpacityOn();
  EXPECT_TRUE(translator.UpdateTransferFunction(prop, false, range).gradientOpacity.empty()) << "disabled";
}

// A 2D transfer function as vtkPVTransferFunction2D builds one: RGBA float pixels, origin the
// range's low corner, spacing the range over the dimensions.
vtkSmartPointer<vtkImageData> transferFunction2DImage(int w, int h, const double range[4])
{
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(w, h, 1);
  image->SetOrigin(range[0], range[2], 0.0);
  image->SetSpacing((range[1] - range[0]) / w, (range[3] - range[2]) / h, 1.0);
  image->AllocateScalars(VTK_FLOAT, 4);
  for (int j = 0; j < h; ++j)
  {
    for (int i = 0; i < w; ++i)
    {
      float* p = static_cast<float*>(image->GetScalarPointer(i, j, 0));
      p[0] = float(i) / w;
      p[1] = float(j) / h;
      p[2] = 0.5f;
      p[3] = 0.1f * float(i + j);
    }
  }
  return image;
}

TEST(InrSceneTranslator, Transfer2DFromTheVolumeProperty)
{
  const double valueRange[2] = { 0.0, 1.0 };
  const double range[4] = { -1.0, 3.0, 0.0, 8.0 };
  vtkNew<vtkVolumeProperty> prop;
  InrSceneTranslator translator;
  auto image = transferFunction2DImage(4, 3, range);
  prop->SetTransferFunction2D(image);
  // In the 1D mode (ParaView's Use Transfer2D off) the image is not used.
  EXPECT_FALSE(translator.UpdateTransferFunction(prop, false, valueRange).usesTransfer2D());
  prop->SetTransferFunctionModeTo2D();
  const inr::TransferFunction& tf = translator.UpdateTransferFunction(prop, false, valueRange);
  ASSERT_TRUE(tf.usesTransfer2D());
  EXPECT_TRUE(translator.GetTransfer2DProblem().empty());
  EXPECT_EQ(tf.transfer2D.width, 4);
  EXPECT_EQ(tf.transfer2D.height, 3);
  EXPECT_DOUBLE_EQ(tf.transfer2D.scalarLo, -1.0);
  EXPECT_DOUBLE_EQ(tf.transfer2D.scalarHi, 3.0);
  EXPECT_DOUBLE_EQ(tf.transfer2D.gradientLo, 0.0);
  EXPECT_DOUBLE_EQ(tf.transfer2D.gradientHi, 8.0);
  EXPECT_FLOAT_EQ(tf.transfer2D.rgba[4 * (2 * 4 + 3) + 3], 0.5f);  // pixel (3, 2)
  EXPECT_FLOAT_EQ(tf.transfer2D.rgba[4 * (1 * 4 + 2) + 0], 0.5f);  // pixel (2, 1): red i / w
  EXPECT_TRUE(tf.gradientOpacity.empty()) << "the 2D mode has no gradient opacity, as in VTK";
  // An edit of the image reaches the next render.
  static_cast<float*>(image->GetScalarPointer(0, 0, 0))[3] = 0.75f;
  image->Modified();
  EXPECT_FLOAT_EQ(translator.UpdateTransferFunction(prop, false, valueRange).transfer2D.rgba[3], 0.75f);
  // The default colour map leaves it out; so does an unusable image, saying why.
  EXPECT_FALSE(translator.UpdateTransferFunction(prop, true, valueRange).usesTransfer2D());
  const double flat[4] = { 2.0, 2.0, 0.0, 1.0 };
  prop->SetTransferFunction2D(transferFunction2DImage(4, 3, flat));
  EXPECT_FALSE(translator.UpdateTransferFunction(prop, false, valueRange).usesTransfer2D());
  EXPECT_NE(translator.GetTransfer2DProblem().find("range"), std::string::npos) << translator.GetTransfer2DProblem();
  vtkNew<vtkImageData> rgb;
  rgb->SetDimensions(2, 2, 1);
  rgb->AllocateScalars(VTK_FLOAT, 3);
  prop->SetTransferFunction2D(rgb);
  EXPECT_FALSE(translator.UpdateTransferFunction(prop, false, valueRange).usesTransfer2D());
  EXPECT_NE(translator.GetTransfer2DProblem().find("RGBA"), std::string::npos) << translator.GetTransfer2DProblem();
  // Back in the 1D mode: none, and no problem to report.
  prop->SetTransferFunctionModeTo1D();
  EXPECT_FALSE(translator.UpdateTransferFunction(prop, false, valueRange).usesTransfer2D());
  EXPECT_TRUE(translator.GetTransfer2DProblem().empty());
}

TEST(InrSceneTranslator, FieldDataTimeAndRange)
{
  vtkNew<vtkImageData> image;
  const double fallback = 1.5;
  double range[2];
  InrSceneTranslator::ValueRange(image->GetFieldData(), range);
  EXPECT_DOUBLE_EQ(range[0], 0.0);
  EXPECT_DOUBLE_EQ(range[1], 1.0);
  InrSceneTranslator::ValueRange(nullptr, range);
  EXPECT_DOUBLE_EQ(range[1], 1.0);
  vtkNew<vtkDoubleArray> vr;
  vr->SetName("InrValueRange");
  vr->InsertNextValue(-0.14);
  vr->InsertNextValue(1.17);
  image->GetFieldData()->AddArray(vr);
  InrSceneTranslator::ValueRange(image->GetFieldData(), range);
  EXPECT_DOUBLE_EQ(range[0], -0.14);
  EXPECT_DOUBLE_EQ(range[1], 1.17);

  EXPECT_DOUBLE_EQ(InrSceneTranslator::Time(image, fallback), fallback) << "no time at all";
  EXPECT_DOUBLE_EQ(InrSceneTranslator::Time(nullptr, fallback), fallback);
  image->GetInformation()->Set(vtkDataObject::DATA_TIME_STEP(), 7.5);
  EXPECT_DOUBLE_EQ(InrSceneTranslator::Time(image, fallback), 7.5) << "DATA_TIME_STEP";
  vtkNew<vtkDoubleArray> time;
  time->SetName("InrTime");
  image->GetFieldData()->AddArray(time);
  EXPECT_DOUBLE_EQ(InrSceneTranslator::Time(image, fallback), fallback)
    << "an empty InrTime: the fallback, not DATA_TIME_STEP";
  time->InsertNextValue(2.5);
  EXPECT_DOUBLE_EQ(InrSceneTranslator::Time(image, fallback), 2.5) << "InrTime wins";
}

// ParaView's Shade, Ambient, Diffuse, Specular and SpecularPower (vtkVolumeProperty) drive the
// engine's shading; with Shade on the property's Ambient is the scene's one ambient.
TEST(InrSceneTranslator, ShadingFromTheVolumeProperty)
{
  vtkNew<vtkVolumeProperty> prop;
  inr::RenderScene scene;
  scene.ambient = 0.35f;  // the shadows' ambient (the mapper's Ambient)
  vtkNew<vtkRenderer> headlightOnly;  // one white headlight of intensity 1: VTK's default lighting
  vtkNew<vtkLight> headlight;
  headlight->SetLightTypeToHeadlight();
  headlightOnly->AddLight(headlight);
  InrSceneTranslator::TranslateShading(prop, headlightOnly, scene);
  EXPECT_FALSE(scene.shading.enabled);  // Shade off: nothing changes
  EXPECT_EQ(scene.ambient, 0.35f);
  InrSceneTranslator::TranslateShading(nullptr, headlightOnly, scene);
  EXPECT_FALSE(scene.shading.enabled);

  prop->ShadeOn();
  prop->SetAmbient(0.1);
  prop->SetDiffuse(0.6);
  prop->SetSpecular(0.3);
  prop->SetSpecularPower(40.0);
  InrSceneTranslator::TranslateShading(prop, headlightOnly, scene);
  EXPECT_TRUE(scene.shading.enabled);
  EXPECT_TRUE(scene.shading.headlight);
  EXPECT_FALSE(scene.shading.lightList);
  EXPECT_FLOAT_EQ(scene.ambient, 0.1f);
  EXPECT_FLOAT_EQ(scene.shading.diffuse, 0.6f);
  EXPECT_FLOAT_EQ(scene.shading.specular, 0.3f);
  EXPECT_FLOAT_EQ(scene.shading.specularPower, 40.f);
  EXPECT_NO_THROW(scene.shading.validate());
  InrSceneTranslator::TranslateShading(prop, nullptr, scene);  // the one light of scene.toLight
  EXPECT_FALSE(scene.shading.headlight);
  EXPECT_FALSE(scene.shading.lightList);

  // Turning Shade off again leaves shading off (the scene is rebuilt per render).
  prop->ShadeOff();
  InrSceneTranslator::TranslateShading(prop, headlightOnly, scene);
  EXPECT_FALSE(scene.shading.enabled);
}

// Any other lights take VTK's light-list lighting, each light as the GPU ray-cast mapper reads
// it: switched-on lights only, colours times intensity, camera lights in camera coordinates.
TEST(InrSceneTranslator, ViewLightsBecomeTheEnginesLightList)
{
  vtkNew<vtkVolumeProperty> prop;
  prop->ShadeOn();
  inr::RenderScene scene;

  vtkNew<vtkRenderer> dimmed;  // a headlight of intensity 0.5 is no longer VTK's default lighting
  vtkNew<vtkLight> headlight;
  headlight->SetLightTypeToHeadlight();
  headlight->SetIntensity(0.5);
  dimmed->AddLight(headlight);
  EXPECT_EQ(InrSceneTranslator::TranslateShading(prop, dimmed, scene), 0);
  ASSERT_TRUE(scene.shading.lightList);
  ASSERT_EQ(scene.shading.lights.size(), 1u);
  EXPECT_TRUE(scene.shading.lights[0].cameraLight);
  EXPECT_EQ(scene.shading.lights[0].toLight, (std::array<double, 3>{ 0.0, 0.0, 1.0 }));
  EXPECT_EQ(scene.shading.lights[0].diffuse, (std::array<float, 3>{ 0.5f, 0.5f, 0.5f }));
  EXPECT_EQ(scene.shading.lights[0].ambient, (std::array<float, 3>{ 0.f, 0.f, 0.f }));

  // ParaView's light kit: key, fill and two back lights (camera lights, warm and cool colours)
  // and its headlight; one scene light beside them, coloured, and one switched off.
  vtkNew<vtkRenderer> kitView;
  vtkNew<vtkLightKit> kit;
  kit->AddLightsToRenderer(kitView);
  const int kitLights = kitView->GetLights()->GetNumberOfItems();
  vtkNew<vtkLight> scenic, off;
  scenic->SetLightTypeToSceneLight();
  scenic->SetPosition(1.0, 2.0, 3.0);
  scenic->SetFocalPoint(1.0, 2.0, 0.0);
  scenic->SetDiffuseColor(1.0, 0.5, 0.25);
  scenic->SetAmbientColor(0.2, 0.2, 0.2);
  scenic->SetIntensity(0.8);
  off->SwitchOff();
  kitView->AddLight(scenic);
  kitView->AddLight(off);
  EXPECT_EQ(InrSceneTranslator::TranslateShading(prop, kitView, scene), 0);
  ASSERT_TRUE(scene.shading.lightList);
  ASSERT_EQ(scene.shading.lights.size(), static_cast<std::size_t>(kitLights + 1));
  EXPECT_NO_THROW(inr::validateLighting(scene));
  int cameraLights = 0;
  for (int i = 0; i < kitLights; ++i)
  {
    cameraLights += scene.shading.lights[i].cameraLight;
  }
  EXPECT_EQ(cameraLights, kitLights);
  // The key light is the brightest: above and to the side of the viewer, towards it (z > 0),
  // with the kit's intensity (0.75 by default) in its warm colour; the kit's headlight sits at
  // the eye.
  const auto brightness = [](const inr::SceneLight& l)
  { return std::max({ l.diffuse[0], l.diffuse[1], l.diffuse[2] }); };
  const inr::SceneLight* key = &scene.shading.lights[0];
  int atTheEye = 0;
  for (int i = 0; i < kitLights; ++i)
  {
    const inr::SceneLight& l = scene.shading.lights[i];
    key = brightness(l) > brightness(*key) ? &l : key;
    atTheEye += l.toLight == std::array<double, 3>{ 0.0, 0.0, 1.0 };
  }
  EXPECT_EQ(atTheEye, 1);
  EXPECT_GT(key->toLight[1], 0.0);
  EXPECT_GT(key->toLight[2], 0.0);
  EXPECT_NEAR(brightness(*key), 0.75f, 0.1f);
  EXPECT_GT(key->diffuse[0], key->diffuse[2]);  // warm
  const inr::SceneLight& last = scene.shading.lights.back();
  EXPECT_FALSE(last.cameraLight);
  EXPECT_EQ(last.toLight, (std::array<double, 3>{ 0.0, 0.0, 3.0 }));
  // The CLI's --light-kit (inr::paraviewLightKit) is this kit: each of its lights has a twin here,
  // same direction and colours.
  const std::vector<inr::SceneLight> cliKit = inr::paraviewLightKit();
  ASSERT_EQ(cliKit.size(), static_cast<std::size_t>(kitLights));
  for (const inr::SceneLight& want : cliKit)
  {
    const auto unit = [](const std::array<double, 3>& v)
    {
      const double n = std::hypot(v[0], v[1], v[2]);
      return std::array<double, 3>{ v[0] / n, v[1] / n, v[2] / n };
    };
    int twins = 0;
    for (int i = 0; i < kitLights; ++i)
    {
      const inr::SceneLight& got = scene.shading.lights[i];
      const auto a = unit(got.toLight), b = unit(want.toLight);
      bool same = got.cameraLight == want.cameraLight;
      for (int c = 0; c < 3; ++c)
      {
        same = same && std::fabs(a[c] - b[c]) < 1e-5 && std::fabs(got.diffuse[c] - want.diffuse[c]) < 1e-3f &&
          std::fabs(got.specular[c] - want.specular[c]) < 1e-3f && got.ambient[c] == want.ambient[c];
      }
      twins += same;
    }
    EXPECT_EQ(twins, 1) << "kit light towards " << want.toLight[0] << " " << want.toLight[1] << " "
                        << want.toLight[2];
  }
  EXPECT_FLOAT_EQ(last.diffuse[1], 0.4f);
  EXPECT_FLOAT_EQ(last.ambient[0], 0.16f);

  // More lights than the engine takes: the first kMaxShadingLights, the rest counted.
  vtkNew<vtkRenderer> crowded;
  std::vector<vtkSmartPointer<vtkLight>> many;
  for (int i = 0; i < inr::kMaxShadingLights + 3; ++i)
  {
    many.push_back(vtkSmartPointer<vtkLight>::New());
    crowded->AddLight(many.back());
  }
  EXPECT_EQ(InrSceneTranslator::TranslateShading(prop, crowded, scene), 3);
  EXPECT_EQ(scene.shading.lights.size(), static_cast<std::size_t>(inr::kMaxShadingLights));
  EXPECT_NO_THROW(inr::validateLighting(scene));

  // A light the engine refuses (negative intensity) is left out and counted, not failed on.
  vtkNew<vtkRenderer> odd;
  vtkNew<vtkLight> good, negative;
  negative->SetIntensity(-1.0);
  odd->AddLight(good);
  odd->AddLight(negative);
  EXPECT_EQ(InrSceneTranslator::TranslateShading(prop, odd, scene), 1);
  EXPECT_EQ(scene.shading.lights.size(), 1u);

  // VTK's choice counts a switched-off light after the first switched-on one: a headlight of
  // intensity 1 followed by a switched-off scene light takes the light-list branch.
  vtkNew<vtkRenderer> headThenOff;
  vtkNew<vtkLight> head1, offScene;
  head1->SetLightTypeToHeadlight();
  offScene->SwitchOff();
  headThenOff->AddLight(head1);
  headThenOff->AddLight(offScene);
  InrSceneTranslator::TranslateShading(prop, headThenOff, scene);
  EXPECT_TRUE(scene.shading.lightList);
  EXPECT_EQ(scene.shading.lights.size(), 1u);

  // A coloured headlight of intensity 1 stays VTK's default lighting, with its colour.
  vtkNew<vtkRenderer> redHead;
  vtkNew<vtkLight> red;
  red->SetLightTypeToHeadlight();
  red->SetDiffuseColor(1.0, 0.0, 0.0);
  red->SetSpecularColor(0.0, 0.0, 1.0);
  redHead->AddLight(red);
  InrSceneTranslator::TranslateShading(prop, redHead, scene);
  EXPECT_TRUE(scene.shading.headlight);
  EXPECT_FALSE(scene.shading.lightList);
  EXPECT_EQ(scene.shading.oneLightDiffuse, (std::array<float, 3>{ 1.f, 0.f, 0.f }));
  EXPECT_EQ(scene.shading.oneLightSpecular, (std::array<float, 3>{ 0.f, 0.f, 1.f }));

  // Every light off: Shade with no light, as VTK's shader then has it (ambient term only).
  vtkNew<vtkRenderer> dark;
  vtkNew<vtkLight> unlit;
  unlit->SwitchOff();
  dark->AddLight(unlit);
  InrSceneTranslator::TranslateShading(prop, dark, scene);
  EXPECT_TRUE(scene.shading.lightList);
  EXPECT_TRUE(scene.shading.lights.empty());
}
