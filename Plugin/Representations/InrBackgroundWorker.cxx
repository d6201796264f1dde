#include "InrBackgroundWorker.h"

#include "InrEngineSlots.h"

#include <chrono>
#include <string>
#include <vector>

#ifdef __linux__
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "Common/Stopwatch.h"
#include "Render/MacrocellLayout.h"
#include "Render/SceneChange.h"

namespace
{
using inr::msSince;

// A still render of the GUI waits this long for the worker's refinement step before it draws
// the image it has (the GUI's own refinement loop renders once the step is done:
// GetBackgroundWorkRunning; other renders, e.g. a property change, find it running).
constexpr double kRefineWaitMs = 30.0;

// The worker's jobs (slice builds, refinement steps) should not delay what the view's thread
// draws meanwhile (reduced frames, the image): the worker is a batch thread for the scheduler,
// which then never preempts a woken interactive thread for it, and so are the evaluator threads
// it starts (Linux threads inherit their creator's policy). Its share of the CPU is unchanged (a
// lower nice value starved it on a machine busy with other work).
void MarkThisThreadBatch()
{
#ifdef __linux__
  sched_param none{};
  none.sched_priority = 0;
  ::sched_setscheduler(static_cast<pid_t>(::syscall(SYS_gettid)), SCHED_BATCH, &none);
#endif
}
}

InrBackgroundWorker::~InrBackgroundWorker()
{
  this->JoinBackgroundBuild();
}

void InrBackgroundWorker::Launch(Job what, inr::RenderSession* session, std::function<void()> work)
{
  this->buildProgress = 0.0;
  this->buildDone = false;
  this->stopBuild = false;
  // Progress from the worker goes to an atomic, read by the view's thread (PrepareRender): VTK's
  // progress events may only be fired from there.
  session->setProgressHandler([this](double fraction, const std::string&)
    { this->buildProgress = fraction; });
  if (what != Job::FineSlices)
  {
    session->setProgressHandler({});  // the build ahead reports per slice itself
  }
  this->job = what;
  this->builder = std::thread(
    [this, work]()
    {
      MarkThisThreadBatch();
      try
      {
        work();
      }
      catch (const std::exception&)
      {
        // The render's setScene meets the same failure and reports it.
      }
      this->buildDone = true;
    });
}

bool InrBackgroundWorker::StartFineBuild(double time)
{
  if (this->FineBuilding() || !this->engines.fine.session)
  {
    return false;
  }
  this->JoinBackgroundBuild();  // a refinement step finishes first: the build needs the session
  inr::RenderSession* session = this->engines.fine.session.get();
  this->Launch(Job::FineSlices, session, [session, time]() { session->buildSlicesFor(time); });
  const auto start = inr::Clock::now();
  while (!this->buildDone && msSince(start) < 20.0)
  {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (this->buildDone)
  {
    this->JoinFineBuild();
  }
  return true;
}

bool InrBackgroundWorker::StartCoarseAhead(int n)
{
  if (this->CoarseBusy())
  {
    return true;
  }
  if (this->FineBusy() || !this->engines.UpdateCoarse(n))
  {
    return false;
  }
  inr::RenderSession* session = this->engines.coarse.session.get();
  const inr::MacrocellInfo info = session->macrocellInfo();
  if (info.slicesBuilt >= info.temporalSlices)
  {
    return false;
  }
  // The slices' times, as the engine lays them out (MacrocellLayout::sliceTime): one slice per
  // call, so that a stop request is seen between slices.
  inr::MacrocellLayout layout;
  layout.temporalSlices = info.temporalSlices;
  layout.timeBegin = this->engines.Model().domain.timeBegin;
  layout.timeEnd = this->engines.Model().domain.timeEnd;
  std::vector<double> times;
  for (int k = 0; k < info.temporalSlices; ++k)
  {
    times.push_back(layout.sliceTime(k));
  }
  this->Launch(Job::CoarseAhead, session,
    [this, session, times]()
    {
      const auto start = inr::Clock::now();
      for (std::size_t k = 0; k < times.size() && !this->stopBuild; ++k)
      {
        session->buildSlicesFor(times[k]);
        this->buildProgress = double(k + 1) / double(times.size());
      }
      this->coarseAheadRunMs = msSince(start);
    });
  return true;
}

bool InrBackgroundWorker::StartFineRefine()
{
  if (this->job != Job::None || !this->engines.fine.session)
  {
    return false;
  }
  inr::RenderSession* session = this->engines.fine.session.get();
  inr::RefinementDriver* refinement = &this->engines.fine.refinement;
  this->refineRun = {};
  // A render whose scene differs stops the step within a tracking iteration (JoinBackgroundBuild,
  // AskToStop) instead of waiting for its frame: that frame would be thrown away.
  session->setStopRequest(&this->stopBuild);
  this->Launch(Job::FineRefine, session,
    [this, session, refinement]() { this->refineRun = refinement->advance(*session); });
  return true;
}

bool InrBackgroundWorker::StartSurfaceBuild(std::function<void()> work)
{
  if (this->job != Job::None || !this->engines.fine.session)
  {
    return false;
  }
  this->Launch(Job::SurfaceBuild, this->engines.fine.session.get(), std::move(work));
  return true;
}

inr::RefinementDriver::Step InrBackgroundWorker::TakeRefineStep()
{
  inr::RefinementDriver::Step step = this->refineStep;
  this->refineStep = {};
  return step;
}

void InrBackgroundWorker::Join()
{
  if (this->job == Job::None)
  {
    return;
  }
  const Job was = this->job;
  this->builder.join();
  this->job = Job::None;
  const bool onFine = was == Job::FineSlices || was == Job::FineRefine || was == Job::SurfaceBuild;
  InrEngineSlot& slot = onFine ? this->engines.fine : this->engines.coarse;
  if (was == Job::FineRefine)
  {
    this->refineStep = this->refineRun;
    if (slot.session)
    {
      slot.session->setStopRequest(nullptr);
    }
  }
  if (slot.session)
  {
    // The fine session reports its lazy builds as VTK progress again; the coarse one reports
    // none (its lazy builds happen inside interactive frames).
    if (onFine && this->engines.progress)
    {
      slot.session->setProgressHandler(this->engines.progress("INR Volume: "));
    }
    else
    {
      slot.session->setProgressHandler({});
    }
  }
  if (was == Job::CoarseAhead)
  {
    this->coarseAheadMs = this->coarseAheadRunMs;
  }
  if (this->joined && was != Job::FineRefine)
  {
    this->joined();
  }
}

void InrBackgroundWorker::JoinFineBuild()
{
  if (this->FineBusy())
  {
    this->Join();
  }
}

void InrBackgroundWorker::JoinBackgroundBuild()
{
  this->stopBuild = true;  // a build ahead stops after its current slice; a fine build finishes
  this->Join();
}

void InrBackgroundWorker::FinishBackgroundBuild()
{
  this->Join();
}

bool InrBackgroundWorker::DeferFineBuild(double time, bool inBackground, int coarseResolution)
{
  if (this->FineBusy() || !inBackground || !this->engines.UpdateCoarse(coarseResolution))
  {
    return false;
  }
  if (this->haveDeferredFineBuild && this->fineBuildTime == time)
  {
    // Deferred once for this time already: the build ran (or returns at once): go on as without
    // deferral, the render uses the fine session when it is done within a few ms.
    return this->StartFineBuild(time);
  }
  this->fineBuildPending = true;
  this->haveDeferredFineBuild = true;
  this->fineBuildTime = time;
  return true;
}

void InrBackgroundWorker::StartPendingFineBuild()
{
  if (!this->fineBuildPending)
  {
    return;
  }
  // The reduced coarse frame is drawn: the fine slices of this time build on the worker now
  // (StartFineBuild returns at once where they were built before).
  this->fineBuildPending = false;
  this->startRefine = false;
  if (this->engines.fine.session && !this->FineBusy())
  {
    this->StartFineBuild(this->fineBuildTime);
  }
}

bool InrBackgroundWorker::JoinRefineStep(const inr::RenderScene& scene,
  const inr::RenderSettings& settings, inr::RefinementDriver::Step& step)
{
  step = inr::RefinementDriver::Step{};
  if (this->FineRefining() || this->CoarseBusy())
  {
    const auto start = inr::Clock::now();
    while (!this->BuildDone() && msSince(start) < kRefineWaitMs)
    {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const InrEngineSlot& fine = this->engines.fine;
    const inr::RenderSettings& held = fine.settings;
    const bool changed = !this->haveFineScene || inr::diffScenes(&this->fineScene, scene).any() ||
      !fine.haveSettings || settings.width != held.width || settings.height != held.height ||
      settings.seed != held.seed || settings.window != held.window ||
      settings.pixelShare != held.pixelShare || settings.clipToBrick != held.clipToBrick ||
      (settings.clipToBrick &&
        (settings.brick.lo.x != held.brick.lo.x || settings.brick.lo.y != held.brick.lo.y ||
          settings.brick.lo.z != held.brick.lo.z || settings.brick.hi.x != held.brick.hi.x ||
          settings.brick.hi.y != held.brick.hi.y || settings.brick.hi.z != held.brick.hi.z));
    if (!this->BuildDone() && !changed)
    {
      this->keepImage = true;
      return false;
    }
    this->JoinBackgroundBuild();
  }
  step = this->TakeRefineStep();
  return true;
}

void InrBackgroundWorker::PlanRefineStep(
  const inr::RenderSession& engine, const inr::RefinementDriver& refinement)
{
  const int epoch = engine.counters().accumulationResets + engine.counters().reprojections;
  this->startRefine = epoch != this->refinedEpoch || !refinement.converged(engine.accumulatedFrames());
  this->refinedEpoch = epoch;
}

void InrBackgroundWorker::LaunchRefine()
{
  if (!this->startRefine)
  {
    return;
  }
  this->startRefine = false;
  if (this->haveFineScene)
  {
    this->engines.KeepStandIn(this->fineScene.time);  // while the fine session is not the worker's
  }
  this->keptFrames = this->engines.fine.session->accumulatedFrames();
  this->keptEstimate = this->engines.fine.refinement.estimate();
  this->StartFineRefine();
}
