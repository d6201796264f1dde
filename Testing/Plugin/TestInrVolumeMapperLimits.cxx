// vtkInrVolumeMapper (CPU backend) where a plain volume render is not enough. Usage:
//   TestInrVolumeMapperLimits CASE MODEL.inr -T OUTDIR
// CASE:
//   transform    the volume's transform (position, orientation, uniform scale, non-uniform scale,
//                user matrix) applied to the rays: a transformed volume renders as the
//                untransformed one seen by the inverse-transformed camera (PSNR over covered
//                pixels >= 40 dB, same seed), and differs from the untransformed volume seen by
//                the same camera (the transform is not ignored)
//   tiled        vtkWindowToImageFilter with SetScale(2) (tiles of a picture twice the window)
//                against a direct render at twice the size, with an opaque sphere in the scene
//   translucent  translucent geometry in the renderer: one warning, however many renders; with
//                the renderer depth-peeling volumes: one more warning, nothing drawn
// Images are written to OUTDIR for inspection.
#include "InrPluginTestChecks.h"
#include "InrPluginTestScene.h"
#include "vtkActor.h"
#include "vtkCallbackCommand.h"
#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkCommand.h"
#include "vtkImageData.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeReader.h"
#include "vtkMatrix4x4.h"
#include "vtkNew.h"
#include "vtkPNGWriter.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPointData.h"
#include "vtkPolyDataMapper.h"
#include "vtkProperty.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkSmartPointer.h"
#include "vtkSphereSource.h"
#include "vtkUnsignedCharArray.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"
#include "vtkWindowToImageFilter.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace
{
const double kMinPsnr = 40.0;
const double kBackground[3] = { 0.32, 0.34, 0.43 };

using inr_plugin_test::check;
using inr_plugin_test::failures;

void setTransferFunction(vtkVolumeProperty* prop)
{
  vtkNew<vtkColorTransferFunction> ctf;
  ctf->AddRGBPoint(-0.14, 0.23, 0.30, 0.75);
  ctf->AddRGBPoint(0.515, 0.87, 0.87, 0.87);
  ctf->AddRGBPoint(1.17, 0.71, 0.02, 0.15);
  vtkNew<vtkPiecewiseFunction> otf;
  otf->AddPoint(0.55, 0.0);
  otf->AddPoint(0.85, 0.5);
  otf->AddPoint(1.17, 1.0);
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  prop->SetScalarOpacityUnitDistance(0.1);
}

// The window's RGB (back buffer), also written to OUTDIR/name.png.
vtkSmartPointer<vtkImageData> grab(vtkRenderWindow* win, int scale, const std::string& path)
{
  vtkNew<vtkWindowToImageFilter> filter;
  filter->SetInput(win);
  filter->SetScale(scale);
  filter->SetInputBufferTypeToRGB();
  filter->ReadFrontBufferOff();
  filter->Update();
  vtkNew<vtkPNGWriter> writer;
  writer->SetInputConnection(filter->GetOutputPort());
  writer->SetFileName(path.c_str());
  writer->Write();
  vtkSmartPointer<vtkImageData> image = vtkSmartPointer<vtkImageData>::New();
  image->DeepCopy(filter->GetOutput());
  return image;
}

struct Comparison
{
  double psnr = 0;      // over the covered pixels (either image differs from the background)
  int covered = 0, identical = 0, pixels = 0;
};

Comparison compare(vtkImageData* a, vtkImageData* b)
{
  Comparison r;
  int da[3], db[3];
  a->GetDimensions(da);
  b->GetDimensions(db);
  if (da[0] != db[0] || da[1] != db[1])
  {
    std::printf("image sizes differ: %dx%d vs %dx%d\n", da[0], da[1], db[0], db[1]);
    return r;
  }
  auto* pa = vtkUnsignedCharArray::SafeDownCast(a->GetPointData()->GetScalars());
  auto* pb = vtkUnsignedCharArray::SafeDownCast(b->GetPointData()->GetScalars());
  const int ca = pa->GetNumberOfComponents(), cb = pb->GetNumberOfComponents();
  int bg[3];
  for (int c = 0; c < 3; ++c)
  {
    bg[c] = int(std::lround(kBackground[c] * 255.0));
  }
  double se = 0.0;
  r.pixels = int(pa->GetNumberOfTuples());
  for (vtkIdType i = 0; i < pa->GetNumberOfTuples(); ++i)
  {
    bool covered = false, same = true;
    double pixelSe = 0.0;
    for (int c = 0; c < 3; ++c)
    {
      const int va = pa->GetValue(i * ca + c), vb = pb->GetValue(i * cb + c);
      covered = covered || std::abs(va - bg[c]) > 1 || std::abs(vb - bg[c]) > 1;
      same = same && va == vb;
      pixelSe += double(va - vb) * (va - vb);
    }
    r.identical += same ? 1 : 0;
    if (covered)
    {
      ++r.covered;
      se += pixelSe;
    }
  }
  const double mse = r.covered > 0 ? se / (3.0 * r.covered) : 0.0;
  r.psnr = mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 999.0;
  return r;
}

struct Scene
{
  vtkNew<vtkInrVolumeReader> reader;
  vtkNew<vtkInrVolumeMapper> mapper;
  vtkNew<vtkVolume> volume;
  vtkNew<vtkRenderer> ren;
  vtkNew<vtkRenderWindow> win;

  Scene(const std::string& model, int width, int height, int frames)
  {
    reader->SetFileName(model.c_str());
    reader->SetPreviewResolution(2);
    reader->UpdateTimeStep(2.5);
    mapper->SetInputConnection(reader->GetOutputPort());
    mapper->SetBackend(vtkInrVolumeMapper::BACKEND_CPU);
    mapper->SetSeed(11);
    mapper->SetMacrocellResolution(16);
    mapper->SetTemporalSlices(16);
    mapper->SetConvergenceTarget(0.0);
    mapper->SetMaximumFrames(frames);
    mapper->SetFramesPerRender(frames);
    volume->SetMapper(mapper);
    setTransferFunction(volume->GetProperty());
    ren->SetBackground(kBackground[0], kBackground[1], kBackground[2]);
    ren->AddVolume(volume);
    win->SetMultiSamples(0);
    win->SetSize(width, height);
    win->AddRenderer(ren);
  }
};

// Camera `c` seen from model space: the inverse of the volume's matrix applied to its points and
// directions; a parallel scale divided by the matrix's scale across the view (`scale`).
void inverseTransformCamera(vtkCamera* c, vtkMatrix4x4* modelToWorld, double scale)
{
  vtkNew<vtkMatrix4x4> inv;
  vtkMatrix4x4::Invert(modelToWorld, inv);
  double p[4], f[4], u[4];
  c->GetPosition(p);
  c->GetFocalPoint(f);
  c->GetViewUp(u);
  p[3] = f[3] = 1.0;
  u[3] = 0.0;
  inv->MultiplyPoint(p, p);
  inv->MultiplyPoint(f, f);
  inv->MultiplyPoint(u, u);
  c->SetPosition(p);
  c->SetFocalPoint(f);
  c->SetViewUp(u);
  c->OrthogonalizeViewUp();
  c->SetParallelScale(c->GetParallelScale() / scale);
}

int transformCase(const std::string& model, const std::string& outDir)
{
  struct Transform
  {
    const char* name;
    bool parallel;
    double scaleAcrossView;
    void (*apply)(vtkVolume*);
  };
  // The model's box is [0, 2] x [-1, 1] x [0, 1] (clouds.inr); the camera looks along the
  // transformed model's z axis for the non-uniform cases, where stretching along the view keeps
  // a parallel view's rays (the inverse camera is then orthonormal too).
  const Transform transforms[] = {
    { "translation", false, 1.0, [](vtkVolume* v) { v->SetPosition(0.6, -0.4, 0.3); } },
    { "rotation", false, 1.0,
      [](vtkVolume* v)
      {
        v->SetOrigin(1.0, 0.0, 0.5);
        v->SetOrientation(20, 35, -15);
      } },
    { "uniform_scale", false, 1.6,
      [](vtkVolume* v)
      {
        v->SetOrigin(1.0, 0.0, 0.5);
        v->SetScale(1.6);
        v->SetPosition(0.2, 0.1, 0.0);
      } },
    { "nonuniform_scale", true, 1.3,
      [](vtkVolume* v)
      {
        v->SetScale(1.3, 1.3, 2.5);
        v->RotateY(-30);
        v->SetPosition(0.0, 0.5, 0.0);
      } },
    { "user_matrix", true, 1.2,
      [](vtkVolume* v)
      {
        // Through the user matrix: a 30 degree turn about z with a scale of 1.2 across the view,
        // and a shear of z by x and y (along the view); then a position.
        const double c = 1.2 * std::cos(M_PI / 6), s = 1.2 * std::sin(M_PI / 6);
        vtkNew<vtkMatrix4x4> m;
        m->SetElement(0, 0, c);
        m->SetElement(0, 1, -s);
        m->SetElement(1, 0, s);
        m->SetElement(1, 1, c);
        m->SetElement(2, 0, 0.4);
        m->SetElement(2, 1, -0.3);
        v->SetUserMatrix(m);
        v->SetPosition(-0.3, 0.2, 0.1);
      } },
  };
  for (const Transform& t : transforms)
  {
    const int frames = 16, size = 128;
    // The transformed volume, camera framing it along the transformed model's z axis (parallel
    // cases) or obliquely (perspective cases).
    Scene a(model, size, size, frames);
    t.apply(a.volume);
    vtkMatrix4x4* m = a.volume->GetMatrix();
    vtkCamera* cam = a.ren->GetActiveCamera();
    a.ren->ResetCamera();
    if (t.parallel)
    {
      double centre[4] = { 1.0, 0.0, 0.5, 1.0 }, axis[4] = { 0.0, 0.0, 1.0, 0.0 },
             up[4] = { 0.0, 1.0, 0.0, 0.0 };
      m->MultiplyPoint(centre, centre);
      m->MultiplyPoint(axis, axis);
      m->MultiplyPoint(up, up);
      const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
      cam->SetParallelProjection(1);
      cam->SetFocalPoint(centre);
      cam->SetPosition(centre[0] + 8 * axis[0] / len, centre[1] + 8 * axis[1] / len,
        centre[2] + 8 * axis[2] / len);
      cam->SetViewUp(up);
      cam->OrthogonalizeViewUp();
      cam->SetParallelScale(1.4 * t.scaleAcrossView);
    }
    else
    {
      cam->Azimuth(25);
      cam->Elevation(30);
      cam->OrthogonalizeViewUp();
    }
    a.ren->ResetCameraClippingRange();
    a.win->Render();
    auto transformed = grab(a.win, 1, outDir + "/transform_" + t.name + ".png");

    // The untransformed volume seen by the inverse-transformed camera.
    Scene b(model, size, size, frames);
    b.ren->GetActiveCamera()->DeepCopy(cam);
    inverseTransformCamera(b.ren->GetActiveCamera(), m, t.scaleAcrossView);
    b.ren->ResetCameraClippingRange();
    b.win->Render();
    auto inverse = grab(b.win, 1, outDir + "/transform_" + t.name + "_inverse_camera.png");

    // The untransformed volume seen by the same camera: what ignoring the transform would show.
    Scene c(model, size, size, frames);
    c.ren->GetActiveCamera()->DeepCopy(cam);
    c.ren->ResetCameraClippingRange();
    c.win->Render();
    auto ignored = grab(c.win, 1, outDir + "/transform_" + t.name + "_ignored.png");

    // Moving that volume once its frames are at the limit: the reprojected picture is shown (it
    // used to keep the old picture: no new frame, so nothing was uploaded).
    t.apply(c.volume);
    c.win->Render();
    auto moved = grab(c.win, 1, outDir + "/transform_" + t.name + "_moved_after_limit.png");
    const Comparison stale = compare(moved, ignored);
    std::printf("%s: after moving the volume at the frame limit: %.2f dB vs before\n", t.name, stale.psnr);
    check(stale.psnr < 30.0, std::string(t.name) + ": moving the volume updates the picture");

    const Comparison same = compare(transformed, inverse);
    const Comparison differ = compare(transformed, ignored);
    std::printf("%s: vs inverse-transformed camera PSNR %.2f dB over %d covered pixels (%d of %d "
                "identical); vs transform ignored %.2f dB\n",
      t.name, same.psnr, same.covered, same.identical, same.pixels, differ.psnr);
    check(same.covered > size * size / 10, std::string(t.name) + ": the volume is in view");
    check(same.psnr >= kMinPsnr, std::string(t.name) + ": equals the inverse-transformed camera");
    check(differ.psnr < 30.0, std::string(t.name) + ": differs from the untransformed volume");
  }
  return 0;
}

int tiledCase(const std::string& model, const std::string& outDir)
{
  const int frames = 12, width = 96, height = 72;
  auto frame = [](vtkRenderer* ren)
  {
    ren->ResetCamera();
    ren->GetActiveCamera()->Azimuth(25);
    ren->GetActiveCamera()->Elevation(30);
    ren->GetActiveCamera()->OrthogonalizeViewUp();
    ren->ResetCameraClippingRange();
  };
  for (const bool parallel : { false, true })
  {
    const std::string tag = parallel ? "parallel" : "perspective";
    Scene direct(model, 2 * width, 2 * height, frames);
    AddOpaqueSphere(direct.ren);
    frame(direct.ren);
    direct.ren->GetActiveCamera()->SetParallelProjection(parallel);
    direct.win->Render();
    auto whole = grab(direct.win, 1, outDir + "/tiled_" + tag + "_direct.png");

    Scene tiled(model, width, height, frames);
    AddOpaqueSphere(tiled.ren);
    frame(tiled.ren);
    tiled.ren->GetActiveCamera()->SetParallelProjection(parallel);
    tiled.win->Render();  // the view itself, as before a screenshot
    auto tiles = grab(tiled.win, 2, outDir + "/tiled_" + tag + "_scale2.png");
    const Comparison r = compare(tiles, whole);
    std::printf("%s: 2x2 tiles of a %dx%d window vs a direct %dx%d render: PSNR %.2f dB over %d "
                "covered pixels, %d of %d pixels identical; %d frames in the last tile\n",
      tag.c_str(), width, height, 2 * width, 2 * height, r.psnr, r.covered, r.identical, r.pixels,
      tiled.mapper->GetAccumulatedFrames());
    check(r.covered > r.pixels / 10, tag + ": the volume is in view");
    check(r.psnr >= kMinPsnr, tag + ": tiles equal the direct render at the full size");
    check(tiled.mapper->GetAccumulatedFrames() == frames, tag + ": a tile refines to MaximumFrames in its one render");
  }
  return 0;
}

int translucentCase(const std::string& model)
{
  Scene s(model, 96, 96, 2);
  int warnings = 0, translucentWarnings = 0;
  vtkNew<vtkCallbackCommand> observer;
  struct Counts
  {
    int* all;
    int* translucent;
  } counts{ &warnings, &translucentWarnings };
  observer->SetClientData(&counts);
  observer->SetCallback(
    [](vtkObject*, unsigned long, void* clientData, void* callData)
    {
      auto* c = static_cast<Counts*>(clientData);
      const std::string message = callData ? static_cast<const char*>(callData) : "";
      std::printf("warning: %s\n", message.c_str());
      ++*c->all;
      *c->translucent += message.find("translucent geometry") != std::string::npos ? 1 : 0;
    });
  s.mapper->AddObserver(vtkCommand::WarningEvent, observer);

  vtkNew<vtkSphereSource> sphere;
  sphere->SetCenter(1.0, 0.0, 0.8);
  sphere->SetRadius(0.4);
  vtkNew<vtkPolyDataMapper> sm;
  sm->SetInputConnection(sphere->GetOutputPort());
  vtkNew<vtkActor> actor;
  actor->SetMapper(sm);
  s.ren->AddActor(actor);
  s.ren->ResetCamera();
  s.win->Render();
  check(translucentWarnings == 0, "opaque geometry: no translucency warning");
  actor->GetProperty()->SetOpacity(0.5);
  for (int i = 0; i < 3; ++i)
  {
    s.ren->GetActiveCamera()->Azimuth(10);
    s.win->Render();
  }
  std::printf("translucency warnings after 3 renders with a translucent sphere: %d (warnings: %d)\n",
    translucentWarnings, warnings);
  check(translucentWarnings == 1, "translucent geometry: warned exactly once");

  // VTK's dual depth peeling for volumes renders volumes inside its peels (GPU ray-cast mapper
  // only): the mapper draws nothing there rather than a corrupted picture, and says so once.
  s.ren->SetUseDepthPeeling(1);
  s.ren->SetUseDepthPeelingForVolumes(1);
  const int before = warnings;
  for (int i = 0; i < 2; ++i)
  {
    s.ren->GetActiveCamera()->Azimuth(10);
    s.win->Render();
  }
  std::printf("warnings while depth-peeling volumes: %d\n", warnings - before);
  check(warnings - before == 1, "depth peeling for volumes: one warning, the volume left out");
  return 0;
}
}

int main(int argc, char* argv[])
{
  if (argc < 5)
  {
    std::fprintf(stderr, "usage: %s CASE MODEL.inr -T OUTDIR\n", argv[0]);
    return 2;
  }
  const std::string testCase = argv[1], model = argv[2];
  std::string outDir = ".";
  for (int i = 3; i + 1 < argc; ++i)
  {
    if (std::string(argv[i]) == "-T")
    {
      outDir = argv[i + 1];
    }
  }
  if (testCase == "transform")
  {
    transformCase(model, outDir);
  }
  else if (testCase == "tiled")
  {
    tiledCase(model, outDir);
  }
  else if (testCase == "translucent")
  {
    translucentCase(model);
  }
  else
  {
    std::fprintf(stderr, "unknown case %s\n", testCase.c_str());
    return 2;
  }
  std::printf("%s: %d failure(s)\n", testCase.c_str(), failures);
  return failures == 0 ? 0 : 1;
}
