// Surface modes in the GUI's still renders (issue 48): with the GUI's background work on
// (vtkInrVolumeMapper::SetBackgroundMacrocellBuilds, which the refinement behaviour turns on) and
// an Interactive Frame Time far below a full isosurface frame, the renders after an isovalue
// change draw
//  - first the candidate macrocells' build on the worker (the first isosurface), the view kept;
//  - then a reduced frame of the new scene, upscaled: close to the exact picture, but not it
//    (the control that the reduced frame is really reduced);
//  - then the full frame in parts over several renders, the reduced frame shown meanwhile;
//  - and at last the exact frame, which must equal the picture a script's render draws in one
//    go (background work off) pixel for pixel, with the state converged.
// Also: every render stays within a few times the budget (CPU time, not asserted: printed).
// Usage: TestInrSurfaceParts MODEL.inr [OUT_DIR: the reduced and the final window as PNG files]
#include "InrPluginTestChecks.h"
#include "InrPluginTestScene.h"
#include "vtkColorTransferFunction.h"
#include "vtkContourValues.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeReader.h"
#include "vtkNew.h"
#include "vtkPNGWriter.h"
#include "vtkPiecewiseFunction.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkUnsignedCharArray.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"
#include "vtkWindowToImageFilter.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

namespace
{
using inr_plugin_test::check;
using inr_plugin_test::failures;

constexpr int kSize = 160;

struct View
{
  vtkNew<vtkInrVolumeReader> reader;
  vtkNew<vtkInrVolumeMapper> mapper;
  vtkNew<vtkVolume> volume;
  vtkNew<vtkColorTransferFunction> ctf;
  vtkNew<vtkPiecewiseFunction> otf;
  vtkNew<vtkRenderer> ren;
  vtkNew<vtkRenderWindow> win;

  explicit View(const char* model)
  {
    this->reader->SetFileName(model);
    this->reader->SetPreviewResolution(2);
    this->mapper->SetInputConnection(this->reader->GetOutputPort());
    this->mapper->SetBackend(vtkInrVolumeMapper::BACKEND_CPU);
    this->mapper->SetMacrocellResolution(16);
    this->mapper->SetFramesPerRender(1);
    this->mapper->SetSeed(7);
    this->volume->SetMapper(this->mapper);
    SetTestRamps(this->ctf, this->otf);
    this->volume->GetProperty()->SetColor(this->ctf);
    this->volume->GetProperty()->SetScalarOpacity(this->otf);
    this->mapper->SetBlendModeToIsoSurface();
    this->volume->GetProperty()->GetIsoSurfaceValues()->SetValue(0, 0.8);
    this->ren->SetBackground(0.32, 0.34, 0.43);
    this->ren->AddVolume(this->volume);
    this->win->SetMultiSamples(0);
    this->win->SetSize(kSize, kSize);
    this->win->AddRenderer(this->ren);
    this->reader->UpdateTimeStep(2.5);
    this->ren->ResetCamera();
  }

  void Save(const std::string& path)
  {
    vtkNew<vtkWindowToImageFilter> grab;
    grab->SetInput(this->win);
    grab->ReadFrontBufferOff();
    vtkNew<vtkPNGWriter> png;
    png->SetInputConnection(grab->GetOutputPort());
    png->SetFileName(path.c_str());
    png->Write();
  }

  std::vector<unsigned char> Pixels()
  {
    vtkNew<vtkUnsignedCharArray> rgb;
    this->win->GetPixelData(0, 0, kSize - 1, kSize - 1, 1, rgb);
    return std::vector<unsigned char>(rgb->GetPointer(0), rgb->GetPointer(0) + 3 * kSize * kSize);
  }
};

// PSNR (8-bit) of `a` against `b` over the pixels where either differs from the background
// (b's corner pixel): the surface's pixels, not the background's.
double psnrOverSurface(const std::vector<unsigned char>& a, const std::vector<unsigned char>& b,
  int* covered = nullptr)
{
  double se = 0.0;
  long n = 0;
  for (std::size_t p = 0; p + 2 < b.size(); p += 3)
  {
    bool surface = false;
    for (int c = 0; c < 3; ++c)
    {
      surface = surface || a[p + c] != b[c] || b[p + c] != b[c];
    }
    if (!surface)
    {
      continue;
    }
    for (int c = 0; c < 3; ++c)
    {
      const double d = double(a[p + c]) - double(b[p + c]);
      se += d * d;
    }
    n += 3;
  }
  if (covered)
  {
    *covered = int(n / 3);
  }
  return se > 0.0 ? 10.0 * std::log10(255.0 * 255.0 * double(n) / se) : INFINITY;
}

bool contains(const char* text, const char* part)
{
  return text && std::string(text).find(part) != std::string::npos;
}
}

int main(int argc, char* argv[])
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s MODEL.inr\n", argv[0]);
    return 2;
  }
  // A script's render: the whole frame at once.
  vtkInrVolumeMapper::SetBackgroundMacrocellBuilds(false);
  View script(argv[1]);
  script.win->Render();
  const std::vector<unsigned char> exact = script.Pixels();
  std::printf("script render: state '%s'\n", script.mapper->GetRefinementState());
  check(contains(script.mapper->GetRefinementState(), "exact in one frame"),
    "a script's render draws the exact frame at once");

  // The GUI's renders: background work on, a budget far below one full frame.
  vtkInrVolumeMapper::SetBackgroundMacrocellBuilds(true);
  View gui(argv[1]);
  gui.mapper->SetInteractiveFrameTime(1.0);
  int building = 0, reducedShown = 0, parts = 0, renders = 0;
  double longestMs = 0.0;
  std::vector<unsigned char> reduced;
  for (; renders < 2000; ++renders)
  {
    gui.win->Render();
    longestMs = std::max(longestMs, gui.mapper->GetLastRenderMilliseconds());
    const char* state = gui.mapper->GetRefinementState();
    if (renders < 3 || renders % 20 == 0)
    {
      std::printf("render %d: %.1f ms, state '%s'\n", renders, gui.mapper->GetLastRenderMilliseconds(), state);
    }
    if (contains(state, "building the candidate macrocells"))
    {
      ++building;
      while (gui.mapper->GetBackgroundWorkRunning())
      {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
    }
    else if (contains(state, "frame shown"))
    {
      ++parts;
      if (reduced.empty())
      {
        ++reducedShown;
        reduced = gui.Pixels();
        if (argc > 2)
        {
          gui.Save(std::string(argv[2]) + "/surface_parts_reduced.png");
        }
      }
    }
    if (gui.mapper->GetConverged())
    {
      break;
    }
  }
  const std::vector<unsigned char> final = gui.Pixels();
  if (argc > 2)
  {
    gui.Save(std::string(argv[2]) + "/surface_parts_final.png");
  }
  std::printf("GUI renders: %d (macrocell build %d, with the reduced frame shown %d), longest %.1f ms; "
              "final state '%s'\n",
    renders + 1, building, parts, longestMs, gui.mapper->GetRefinementState());
  check(building >= 1, "the first isosurface's candidate macrocells are built on the worker");
  check(reducedShown == 1 && parts >= 3, "a reduced frame, then the full frame in several parts");
  check(gui.mapper->GetConverged() == 1 &&
      contains(gui.mapper->GetRefinementState(), "exact in one frame"),
    "the renders end with the exact frame, converged");
  int covered = 0;
  const double finalPsnr = psnrOverSurface(final, exact, &covered);
  std::printf("final vs the script's render: %.2f dB over %d surface pixels\n", finalPsnr, covered);
  check(covered > kSize * kSize / 50, "the isosurface covers part of the view");
  check(std::isinf(finalPsnr), "the final frame is the script's render, pixel for pixel");
  if (!reduced.empty())
  {
    const double reducedPsnr = psnrOverSurface(reduced, exact);
    std::printf("the reduced frame vs the exact one: %.2f dB\n", reducedPsnr);
    check(reducedPsnr > 20.0, "the reduced frame shows the same surface (PSNR > 20 dB)");
    check(reducedPsnr < 40.0, "the reduced frame is not the exact one (PSNR < 40 dB): really reduced");
  }
  vtkInrVolumeMapper::SetBackgroundMacrocellBuilds(false);
  std::printf("%d failure(s)\n", failures);
  return failures == 0 ? 0 : 1;
}
