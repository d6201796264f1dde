// The mapper's background worker, without VTK: one thread that does the long work of the GUI's
// renders away from the view's thread, one job at a time, on the sessions of InrEngines, and the
// bookkeeping of the renders that hand it that work.
//
// The jobs:
//  - the fine slices of a new time (StartFineBuild), while renders draw reduced frames of the
//    coarse session: the event loop never waits seconds for a macrocell build;
//  - every coarse slice not built yet (StartCoarseAhead), slice by slice, so that a render that
//    needs the coarse session stops it within one slice;
//  - one refinement step of the fine session (StartFineRefine), so that a still render of the GUI
//    draws the image of the steps finished so far instead of waiting for a whole frame (a render
//    with another scene stops the step within a tracking iteration: JoinBackgroundBuild);
//  - the candidate macrocells of the isosurface blend mode at a new time (StartSurfaceBuild,
//    through the fine session's network), while renders draw the image they have.
// The session a job works on belongs to the worker until the job is joined: nothing else touches
// it meanwhile (what the panel reads of the fine session is kept: KeptFrames, KeptEstimate).
//
// The renders' side (vtkInrVolumeMapper): a new time's fine build is put off until the render
// has drawn its reduced coarse frame (DeferFineBuild, StartPendingFineBuild: that frame does not
// share the CPU with it); a still render joins a finished refinement step, hands the scene over,
// draws the image so far and starts the next step once the image is read (JoinRefineStep,
// PlanRefineStep, LaunchRefine); a render that finds the step running waits a little for it, then
// draws the image it has (KeepsImage).
#ifndef InrBackgroundWorker_h
#define InrBackgroundWorker_h

#include <atomic>
#include <functional>
#include <limits>
#include <thread>

#include "Backends/Refinement.h"
#include "Backends/RenderSession.h"
#include "Render/SceneInputs.h"

class InrEngines;

class InrBackgroundWorker
{
public:
  explicit InrBackgroundWorker(InrEngines& engines)
    : engines(engines)
  {
  }
  ~InrBackgroundWorker();
  InrBackgroundWorker(const InrBackgroundWorker&) = delete;
  InrBackgroundWorker& operator=(const InrBackgroundWorker&) = delete;

  /// Called after a job other than a refinement step was joined (frames measured meanwhile were
  /// slower: the level-of-detail cost model forgets what it barred).
  std::function<void()> joined;

  ///@{
  /// The jobs. StartFineBuild waits a few ms first, as most calls find the slices built; true
  /// when the build went to the worker. StartCoarseAhead: true while it runs (or was already
  /// running). StartFineRefine: advances the fine session's refinement driver under the options
  /// set on it, after the caller's setScene. TakeRefineStep: what the last joined step rendered
  /// (once; empty after).
  bool StartFineBuild(double time);
  bool StartCoarseAhead(int resolution);
  bool StartFineRefine();
  bool StartSurfaceBuild(std::function<void()> work);
  inr::RefinementDriver::Step TakeRefineStep();
  ///@}

  ///@{
  /// JoinFineBuild waits for a job on the fine session; JoinBackgroundBuild stops a build ahead
  /// (after its current slice) or a refinement step (within a tracking iteration: its frame in
  /// progress is dropped) and waits for whichever job runs; FinishBackgroundBuild lets either
  /// finish.
  void JoinFineBuild();
  void JoinBackgroundBuild();
  void FinishBackgroundBuild();
  /// Asks a build ahead to stop after its current slice, without waiting for it.
  void AskToStop() { this->stopBuild = true; }
  ///@}

  ///@{
  /// The running job (not joined yet): on the fine session (a slice build or a refinement step),
  /// building the coarse slices ahead; whether it is done, and its progress in [0, 1].
  bool FineBusy() const
  {
    return this->job == Job::FineSlices || this->job == Job::FineRefine || this->job == Job::SurfaceBuild;
  }
  bool SurfaceBuilding() const { return this->job == Job::SurfaceBuild; }
  bool FineBuilding() const { return this->job == Job::FineSlices; }
  bool FineRefining() const { return this->job == Job::FineRefine; }
  bool CoarseBusy() const { return this->job == Job::CoarseAhead; }
  bool BuildDone() const { return this->buildDone; }
  double BuildProgress() const { return this->buildProgress; }
  /// Milliseconds the last joined build ahead ran on the worker (0 before).
  double LastCoarseAheadMs() const { return this->coarseAheadMs; }
  ///@}

  ///@{
  /// A new time's fine build, put off until the render has drawn. DeferFineBuild: false where the
  /// caller builds the slices itself (`inBackground` false, the worker busy, or no coarse session
  /// of `coarseResolution` cells to draw meanwhile); else marks the build pending, or, when this
  /// time was put off once already, starts it. StartPendingFineBuild, once the render has drawn.
  bool DeferFineBuild(double time, bool inBackground, int coarseResolution);
  bool FineBuildPending() const { return this->fineBuildPending; }
  void StartPendingFineBuild();
  /// The fine session was rebuilt: its first build is put off again, it holds no scene.
  void SessionRebuilt()
  {
    this->haveDeferredFineBuild = false;
    this->haveFineScene = false;
  }
  ///@}

  ///@{
  /// The scene last handed to the fine session, and whether the worker's refinement step is for
  /// another time than `time` (a render at `time` then draws a reduced coarse frame).
  void HandedFineScene(const inr::RenderScene& scene)
  {
    this->fineScene = scene;
    this->haveFineScene = true;
  }
  bool HasFineScene() const { return this->haveFineScene; }
  double FineSceneTime() const { return this->fineScene.time; }
  bool FineTimeDiffers(double time) const
  {
    return this->FineRefining() && this->haveFineScene && time != this->fineScene.time;
  }
  ///@}

  ///@{
  /// A still render of the GUI refining the fine session on the worker.
  ///  - BeginRender: nothing planned yet for this render.
  ///  - JoinRefineStep: waits a little for a running job (a refinement step, or the coarse slices
  ///    built ahead) and joins it when it is done, `step` what it rendered; false (KeepsImage)
  ///    when it is still running and the render changes nothing the fine session renders (scene
  ///    or `settings`): the render draws the image it has. A changed scene stops a build ahead
  ///    (within a slice) or waits for the refinement step.
  ///  - PlanRefineStep: after the scene and options were handed to `engine`, whether a step
  ///    starts once this render has drawn (a new accumulation epoch, or not converged).
  ///  - LaunchRefine: starts it (once the image was read), keeping what the panel reads.
  void BeginRender()
  {
    this->keepImage = false;
    this->startRefine = false;
  }
  bool JoinRefineStep(const inr::RenderScene& scene, const inr::RenderSettings& settings,
    inr::RefinementDriver::Step& step);
  void PlanRefineStep(const inr::RenderSession& engine, const inr::RefinementDriver& refinement);
  bool KeepsImage() const { return this->keepImage; }
  bool StartsRefine() const { return this->startRefine; }
  void LaunchRefine();
  /// The fine session's frames and estimate when its step was started (read while it runs).
  int KeptFrames() const { return this->keptFrames; }
  double KeptEstimate() const { return this->keptEstimate; }
  ///@}

private:
  enum class Job
  {
    None,
    FineSlices,
    CoarseAhead,
    FineRefine,
    SurfaceBuild
  };
  void Launch(Job what, inr::RenderSession* session, std::function<void()> work);
  void Join();

  InrEngines& engines;
  std::thread builder;
  Job job = Job::None;
  std::atomic<bool> buildDone{ false };
  std::atomic<bool> stopBuild{ false };  // asks a build ahead or a refinement step to stop
  std::atomic<double> buildProgress{ 0.0 };
  std::atomic<double> coarseAheadRunMs{ 0.0 };
  double coarseAheadMs = 0.0;
  inr::RefinementDriver::Step refineRun, refineStep;  // on the worker; joined, not taken yet

  bool fineBuildPending = false;
  bool haveDeferredFineBuild = false;
  double fineBuildTime = 0.0;  // the time of the last deferred build
  bool startRefine = false;    // this render starts a refinement step once it has drawn
  bool keepImage = false;      // this render draws the texture as it is
  bool haveFineScene = false;
  inr::RenderScene fineScene;
  int refinedEpoch = -1;  // the fine session's resets + reprojections when its step was started
  int keptFrames = 0;
  double keptEstimate = -std::numeric_limits<double>::infinity();
};

#endif
