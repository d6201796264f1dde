// The fine and the coarse (level-of-detail) engine sessions of vtkInrVolumeMapper (CPU backend,
// plain VTK window): the coarse session honours every user setting and runs the fine session's
// evaluator (issue 27, item 4).
//  - every engine option set away from its default (backend, GPU traversal, macrocell skip block
//    and padding, ghost passes, refinement, estimator, majorant / residual scale, points per
//    iteration, query reduction): after a time-change frame drawn by the coarse session, the two
//    sessions' options read back from the engine (GetEngineOptionsInUse,
//    GetInteractiveEngineOptionsInUse) differ in the macrocell dims only;
//  - both sessions run one evaluator (GetInteractiveSharesEvaluator);
//  - options changed later (an estimator change on the live sessions, a traversal change that
//    rebuilds them) reach the coarse session too, which again shares the new fine evaluator.
// Before the fix the coarse session's options were built by hand in a second place and took the
// traversal from nowhere (Auto whatever the user chose), and it built an evaluator of its own.
// Usage: TestInrEngineSessions MODEL.inr
#include "InrPluginTestChecks.h"
#include "InrPluginTestScene.h"
#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeReader.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"

#include <cstdio>
#include <regex>
#include <string>

namespace
{
using inr_plugin_test::check;
using inr_plugin_test::failures;

// A session's option line without its macrocell dims (the one field level of detail changes).
std::string withoutDims(const std::string& line)
{
  return std::regex_replace(line, std::regex("dims=[0-9x]+ "), "");
}

bool has(const std::string& line, const std::string& field)
{
  return line.find(field) != std::string::npos;
}
}

int main(int argc, char* argv[])
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s MODEL.inr\n", argv[0]);
    return 2;
  }
  vtkNew<vtkInrVolumeReader> reader;
  reader->SetFileName(argv[1]);
  reader->SetPreviewResolution(2);
  vtkNew<vtkColorTransferFunction> ctf;
  vtkNew<vtkPiecewiseFunction> otf;
  SetTestRamps(ctf, otf);

  vtkNew<vtkInrVolumeMapper> mapper;
  mapper->SetInputConnection(reader->GetOutputPort());
  mapper->SetSeed(5);
  mapper->SetConvergenceTarget(0.0);
  mapper->SetMaximumFrames(4);
  mapper->SetFramesPerRender(1);
  mapper->SetInteractiveFrameTime(1.0);  // reduced time-change frames on any machine
  mapper->SetMacrocellResolution(16);
  mapper->SetInteractiveMacrocellResolution(8);
  mapper->SetTemporalSlices(4);
  // Every engine option away from its default.
  mapper->SetBackend(vtkInrVolumeMapper::BACKEND_CPU);
  mapper->SetTraversal(vtkInrVolumeMapper::TRAVERSAL_DDA);
  mapper->SetSkipBlock(8);
  mapper->SetBoundsPadding(0.05);
  mapper->SetGhostPasses(2);
  mapper->SetRefineMacrocells(0);
  mapper->SetEstimator(0);  // delta
  mapper->SetMajorantScale(2.0);
  mapper->SetResidualScale(0.5);
  mapper->SetPointsPerIteration(2);
  mapper->SetJitterControlFrames(3);
  mapper->SetRayBudget(vtkInrVolumeMapper::BUDGET_STBN);
  mapper->SetBudgetFraction(0.5);
  mapper->SetBudgetMaxSkip(3);
  mapper->SetBudgetAlpha(0.25);
  mapper->SetPruneEpsilon(0.01);
  mapper->SetPruneFalloff(0.005);
  mapper->SetShadows(1);

  vtkNew<vtkVolume> volume;
  volume->SetMapper(mapper);
  volume->GetProperty()->SetColor(ctf);
  volume->GetProperty()->SetScalarOpacity(otf);
  volume->GetProperty()->SetScalarOpacityUnitDistance(0.1);
  vtkNew<vtkRenderer> ren;
  vtkNew<vtkRenderWindow> win;
  win->SetMultiSamples(0);
  win->SetSize(96, 72);
  win->AddRenderer(ren);
  ren->AddVolume(volume);
  reader->UpdateTimeStep(2.5);
  ren->ResetCamera();
  win->SetDesiredUpdateRate(0.0001);  // still renders

  auto timeChangeFrame = [&](double time)
  {
    win->Render();  // a still frame at the current time (fine session)
    reader->UpdateTimeStep(time);
    win->Render();  // a time change: a reduced frame of the coarse session
    return mapper->GetLastRenderCoarse() == 1;
  };
  auto compare = [&](const char* when)
  {
    const std::string fine = mapper->GetEngineOptionsInUse();
    const std::string coarse = mapper->GetInteractiveEngineOptionsInUse();
    std::printf("%s:\n  fine:   %s\n  coarse: %s\n", when, fine.c_str(), coarse.c_str());
    check(has(fine, "dims=16x16x16") && has(coarse, "dims=8x8x8"),
      std::string(when) + ": the sessions have 16^3 and 8^3 macrocells");
    check(!coarse.empty() && withoutDims(fine) == withoutDims(coarse),
      std::string(when) + ": the coarse session runs every option of the fine one");
    check(mapper->GetInteractiveSharesEvaluator() == 1,
      std::string(when) + ": both sessions run one evaluator");
  };

  check(timeChangeFrame(7.5), "a time change is drawn by the coarse session");
  const std::string fine = mapper->GetEngineOptionsInUse();
  for (const char* field : { "backend=cpu", "traversal=dda", "skip_block=8", "bounds_padding=0.05",
         "ghost_passes=2", "refine=0", "estimator=delta", "majorant_scale=2", "residual_scale=0.5",
         "points_per_iteration=2", "jitter_control_frames=3", "budget=stbn", "rho=0.5", "K=3", "alpha=0.25", "epsilon=0.01",
         "delta=0.005" })
  {
    check(has(fine, field), std::string("the fine session holds ") + field);
  }
  compare("every option set");

  // Changed on the live sessions (no rebuild): the coarse one follows.
  mapper->SetEstimator(1);  // ratio
  mapper->SetPointsPerIteration(3);
  mapper->SetJitterControlFrames(0);
  check(timeChangeFrame(5.0), "the next time change is drawn by the coarse session");
  check(has(mapper->GetInteractiveEngineOptionsInUse(), "estimator=ratio") &&
      has(mapper->GetInteractiveEngineOptionsInUse(), "points_per_iteration=3") &&
      has(mapper->GetInteractiveEngineOptionsInUse(), "jitter_control_frames=0"),
    "an estimator change reaches the coarse session");
  compare("estimator changed");

  // A traversal change rebuilds the sessions: the coarse one follows, on the new evaluator.
  const int builds = mapper->GetEngineBuilds();
  mapper->SetTraversal(vtkInrVolumeMapper::TRAVERSAL_AUTO);
  check(timeChangeFrame(2.5), "after a rebuild, a time change is drawn by the coarse session");
  check(mapper->GetEngineBuilds() == builds + 1, "the traversal change rebuilt the engine once");
  check(has(mapper->GetInteractiveEngineOptionsInUse(), "traversal=auto"),
    "the traversal change reaches the coarse session");
  compare("traversal changed");

  std::printf("RESULT: %s\n", failures ? "FAIL" : "PASS");
  return failures ? 1 : 0;
}
