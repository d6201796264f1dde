#include "InrEngineSlots.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <vector>

#ifdef __linux__
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "Render/MacrocellLayout.h"
#include "Render/WavefrontRenderer.h"
#include "Common/Stopwatch.h"

bool InrEngineRequest::SameBuild(const InrEngineRequest& o) const
{
  return std::tie(this->backend, this->traversal, this->resolution, this->temporalSlices,
           this->modelUsesTime, this->skipBlockCells, this->boundsPadding, this->cudaDevice,
           this->cpuThreads) ==
    std::tie(o.backend, o.traversal, o.resolution, o.temporalSlices, o.modelUsesTime,
      o.skipBlockCells, o.boundsPadding, o.cudaDevice, o.cpuThreads);
}

inr::RenderSessionOptions InrSessionOptions(const InrEngineRequest& r, const InrSessionLevel& level)
{
  inr::RenderSessionOptions o;
  o.backend = r.backend;
  o.allowFallback = true;  // CUDA asked where it cannot run: the CPU, and the mapper says so
  o.cudaDevice = r.cudaDevice;
  o.cpuThreads = r.cpuThreads;
  o.traversal.kind = r.traversal;
  const int n = level.resolution > 0 ? level.resolution : r.resolution;
  o.macrocells.dims = inr::Int3{ n, n, n };
  o.macrocells.temporalSlices = r.modelUsesTime ? r.temporalSlices : 1;
  // A skip block larger than the grid would be one block: the largest power of two that fits.
  int skip = std::min(r.skipBlockCells, n);
  while (skip & (skip - 1))
  {
    skip &= skip - 1;
  }
  o.macrocells.skipBlockCells = skip;
  o.macrocells.boundsPadding = r.boundsPadding;
  o.tracking = r.tracking;
  if (level.evaluator)
  {
    // The evaluator decides the backend and device: the one the fine session actually runs.
    o.evaluator = level.evaluator;
    o.backend = level.evaluator.backend;
    o.cudaDevice = level.evaluator.cudaDevice;
  }
  return o;
}

std::string InrDescribeMacrocells(const inr::RenderSession& session)
{
  const inr::MacrocellInfo m = session.macrocellInfo();
  const inr::TrackingOptions& t = session.trackingOptions();
  std::ostringstream s;
  s << "dims=" << m.dims.x << "x" << m.dims.y << "x" << m.dims.z << " slices=" << m.temporalSlices
    << " skip_block=" << m.skipBlockCells << " bounds_padding=" << m.boundsPadding
    << " ghost_passes=" << t.ghostPassesOnUpdate << " refine=" << int(t.refineMacrocells)
    << " estimator=" << inr::primaryEstimatorName(t.estimator) << " majorant_scale=" << t.majorantScale
    << " residual_scale=" << t.residualScale << " points_per_iteration=" << t.pointsPerIteration;
  return s.str();
}

std::string InrDescribeQueryReduction(const inr::QueryReductionSettings& q)
{
  std::ostringstream s;
  s << "budget=" << inr::budgetSchemeName(q.budget) << " rho=" << q.budgetFraction
    << " K=" << q.budgetMaxSkip << " alpha=" << q.budgetAlpha << " reproject=" << int(q.reproject)
    << " epsilon=" << q.pruneEpsilon << " delta=" << q.pruneFalloff;
  return s.str();
}

std::string InrDescribeSession(const inr::RenderSession& session)
{
  const inr::RenderSessionOptions& o = session.options();
  std::ostringstream s;
  s << "backend=" << inr::renderBackendName(session.backend())
    << " traversal=" << inr::traversalKindName(o.traversal.kind) << " cuda_device=" << o.cudaDevice
    << " cpu_threads=" << o.cpuThreads << " " << InrDescribeMacrocells(session) << " "
    << InrDescribeQueryReduction(session.queryReduction());
  return s.str();
}

bool InrSameQueryReduction(const inr::QueryReductionSettings& a, const inr::QueryReductionSettings& b)
{
  auto key = [](const inr::QueryReductionSettings& q)
  {
    return std::make_tuple(q.budget, q.budgetFraction, q.budgetMaxSkip, q.budgetAlpha, q.reproject,
      q.pruneEpsilon, q.pruneFalloff);
  };
  return key(a) == key(b);
}

void InrEngineSlot::SetSettings(const inr::RenderSettings& s)
{
  const inr::RenderSettings& held = this->settings;
  if (!this->haveSettings || s.width != held.width || s.height != held.height ||
    s.seed != held.seed || s.window != held.window || s.pixelShare != held.pixelShare)
  {
    this->session->setSettings(s);
    this->settings = s;
    this->haveSettings = true;
  }
}

void InrSyncTrackingOptions(inr::RenderSession& session, const inr::TrackingOptions& want)
{
  const inr::TrackingOptions& held = session.trackingOptions();
  if (held.ghostPassesOnUpdate != want.ghostPassesOnUpdate ||
    held.refineMacrocells != want.refineMacrocells || held.estimator != want.estimator ||
    held.majorantScale != want.majorantScale || held.residualScale != want.residualScale ||
    held.pointsPerIteration != want.pointsPerIteration)
  {
    session.setTrackingOptions(want);
  }
}

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

// For the refusal messages of InrEngineOptions::Check.
std::ostream& operator<<(std::ostream& os, inr::PrimaryEstimator e)
{
  return os << inr::primaryEstimatorName(e) << " (" << static_cast<int>(e) << ")";
}

using inr::msSince;

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

// Each asked value is checked as `inr render` checks it (the engine's validation and message:
// skipBlockShift, TrackingOptions::validate, the layout's padding rule); a refused one is reported
// once, naming the property, and the last valid value (at first the engine's default) stays.
void InrEngineOptions::Check(const std::function<void(const std::string&)>& error)
{
  auto accept = [&error](const char* property, auto asked, auto& valid, auto& refused, auto check)
  {
    if (asked == valid)
    {
      return;
    }
    try
    {
      check(asked);
      valid = asked;
      refused = asked;  // a value refused before is reported again when asked again later
    }
    catch (const std::invalid_argument& e)
    {
      if (refused != asked)
      {
        refused = asked;
        std::ostringstream s;
        s << "INR Volume: " << property << " = " << asked << " refused: " << e.what()
          << "; keeping " << valid;
        if (error)
        {
          error(s.str());
        }
      }
    }
  };
  accept("Skip Block (InrSkipBlock)", this->macrocellsAsked.skipBlockCells,
    this->macrocellsValid.skipBlockCells, this->macrocellsRefused.skipBlockCells,
    [](int cells) { inr::skipBlockShift(cells); });
  accept("Bounds Padding (InrBoundsPadding)", this->macrocellsAsked.boundsPadding,
    this->macrocellsValid.boundsPadding, this->macrocellsRefused.boundsPadding,
    [](double padding)
    {
      if (!(padding >= 0.0))
      {
        throw std::invalid_argument("bounds padding must be >= 0");
      }
    });
  accept("Ghost Passes (InrGhostPasses)", this->trackingAsked.ghostPassesOnUpdate,
    this->trackingValid.ghostPassesOnUpdate, this->trackingRefused.ghostPassesOnUpdate,
    [this](int passes)
    {
      inr::TrackingOptions t = this->trackingValid;
      t.ghostPassesOnUpdate = passes;
      t.validate();
    });
  // The estimator's options, each checked by TrackingOptions::validate on the valid set.
  auto trackingField = [&](const char* property, auto member)
  {
    accept(property, this->trackingAsked.*member, this->trackingValid.*member,
      this->trackingRefused.*member,
      [this, member](auto asked)
      {
        inr::TrackingOptions t = this->trackingValid;
        t.*member = asked;
        t.validate();
      });
  };
  trackingField("Estimator (InrEstimator)", &inr::TrackingOptions::estimator);
  trackingField("Majorant Scale (InrMajorantScale)", &inr::TrackingOptions::majorantScale);
  trackingField("Residual Scale (InrResidualScale)", &inr::TrackingOptions::residualScale);
  trackingField("Points Per Iteration (InrPointsPerIteration)", &inr::TrackingOptions::pointsPerIteration);
  this->trackingValid.refineMacrocells = this->trackingAsked.refineMacrocells;
}

InrEngines::~InrEngines()
{
  this->JoinBackgroundBuild();
}

bool InrEngines::SetModel(const unsigned char* bytes, std::size_t n)
{
  const std::uint64_t h = hashBytes(bytes, n);
  if (h == this->hash && this->modelOk)
  {
    return true;
  }
  this->JoinBackgroundBuild();
  this->hash = h;
  this->modelOk = false;
  this->coarse.session.reset();  // before the fine one: it runs the fine one's evaluator
  this->standIn.reset();
  this->standInField.reset();
  this->fine.session.reset();
  this->coarseFailed = false;
  try
  {
    this->model = inr::InrModel::loadBytes(bytes, n, "INR model (field data)");
    this->modelOk = true;
  }
  catch (const std::exception& e)
  {
    if (this->reportedBadHash != h)
    {
      if (this->error)
      {
        this->error(e.what());
      }
      this->reportedBadHash = h;
    }
  }
  return this->modelOk;
}

bool InrEngines::UpdateFine(const InrEngineRequest& want)
{
  this->rebuilt = false;
  InrEngineSlot& f = this->fine;
  if (this->FineBusy())
  {
    if (f.asked.SameBuild(want) || !this->buildDone)
    {
      // The worker owns the session until its job is joined; a rebuild waits for that (the
      // view keeps drawing what it has meanwhile) rather than the render waiting for the job.
      return true;
    }
    this->JoinFineBuild();
  }
  if (!f.session || !f.asked.SameBuild(want))
  {
    this->JoinBackgroundBuild();  // a build ahead of the coarse session that goes with it
    try
    {
      // The coarse session runs the fine session's evaluator: it goes with it.
      this->coarse.session.reset();
      this->standIn.reset();
      this->standInField.reset();
      this->coarseFailed = false;
      f.session.reset();
      InrEngineRequest built = want;
      try
      {
        f.session = inr::RenderSession::create(this->model, InrSessionOptions(built, InrSessionLevel::Fine()));
      }
      catch (const std::exception& e)
      {
        if (built.traversal != inr::TraversalKind::Optix)
        {
          throw;
        }
        // OptiX asked for where it cannot run (no OptiX in this build, or the driver's): say why
        // and let auto choose, rather than leaving the view empty.
        if (this->warning)
        {
          this->warning(std::string("INR Volume: the OptiX traversal is not available here (") +
            e.what() + "); using Traversal Auto.");
        }
        built.traversal = inr::TraversalKind::Auto;
        f.session = inr::RenderSession::create(this->model, InrSessionOptions(built, InrSessionLevel::Fine()));
      }
      if (this->progress)
      {
        f.session->setProgressHandler(this->progress("INR Volume: "));
      }
      // The engine's once-per-cause warnings (work caps hit) go where the mapper's go.
      auto warn = this->warning;
      f.session->setWarningHandler([warn](const std::string& message)
        {
          if (warn)
          {
            warn("INR Volume: " + message);
          }
        });
      if (want.backend == inr::RenderBackend::Cuda &&
        f.session->backend() != inr::RenderBackend::Cuda && !this->warnedCuda && this->warning)
      {
        this->warning("INR Volume: the CUDA backend was requested but is not usable here; "
                      "rendering on the CPU (" + f.session->description() + ").");
        this->warnedCuda = true;
      }
      f.asked = want;
      f.built = built;
      f.Started();
      ++this->engineBuilds;
      this->rebuilt = true;
    }
    catch (const std::exception& e)
    {
      if (this->error)
      {
        this->error(std::string("INR Volume: cannot set up the renderer: ") + e.what());
      }
      f.session.reset();
      return false;
    }
  }
  InrSyncTrackingOptions(*f.session, want.tracking);  // valid: checked by the caller
  f.built.tracking = want.tracking;
  return true;
}

void InrEngines::KeepStandIn(double time)
{
  if (this->FineBusy() || !this->fine.session || (this->standInField && this->standInTime == time))
  {
    return;
  }
  if (auto field = this->fine.session->workingMeanField(time))
  {
    this->standInField = std::move(field);
    this->standInTime = time;
  }
}

bool InrEngines::UpdateCoarse(int n)
{
  InrEngineSlot& c = this->coarse;
  if (this->CoarseBusy())
  {
    this->JoinBackgroundBuild();  // the caller draws with it: the rest of the build ahead later
  }
  if (n <= 0 || !this->fine.session || n >= this->fine.built.resolution)
  {
    return false;
  }
  InrEngineRequest want = this->fine.built;  // the fine session's request, as it was built
  want.resolution = n;
  if (!c.session || !c.asked.SameBuild(want))
  {
    if (this->coarseFailed && c.asked.SameBuild(want))
    {
      return false;
    }
    c.session.reset();
    c.asked = want;
    c.built = want;
    try
    {
      // No progress handler for its lazy builds (inside interactive frames, short); the build
      // ahead reports progress (BuildCoarseAhead).
      InrSessionLevel level = InrSessionLevel::Coarse(n, *this->fine.session);
      this->standIn.reset();
      if (level.evaluator.backend == inr::RenderBackend::Cpu)
      {
        // On the CPU a camera drag may draw a stand-in of the network (StandInReady).
        this->standIn = std::make_shared<InrStandInSwitch>(level.evaluator.evaluator);
        level.evaluator.evaluator = this->standIn;
      }
      c.session =
        inr::RenderSession::create(this->model, InrSessionOptions(this->fine.built, level));
      auto warn = this->warning;
      c.session->setWarningHandler([warn](const std::string& message)
        {
          if (warn)
          {
            warn("INR Volume (interactive macrocells): " + message);
          }
        });
      c.Started();
      this->coarseFailed = false;
    }
    catch (const std::exception& e)
    {
      if (this->error)
      {
        this->error("INR Volume: Interactive Macrocell Resolution "
                    "(InrInteractiveMacrocellResolution) = " + std::to_string(n) +
          ": cannot set up the coarse renderer: " + e.what() +
          "; time changes render with the fine macrocells");
      }
      c.session.reset();
      this->coarseFailed = true;
      return false;
    }
  }
  InrSyncTrackingOptions(*c.session, this->fine.built.tracking);
  return true;
}

double InrEngines::BuildCoarseAhead(int n, bool report)
{
  if (!this->UpdateCoarse(n))
  {
    return 0.0;
  }
  inr::RenderSession& engine = *this->coarse.session;
  const inr::MacrocellInfo before = engine.macrocellInfo();
  if (before.slicesBuilt >= before.temporalSlices)
  {
    return 0.0;
  }
  const auto start = inr::Clock::now();
  if (this->progress)
  {
    engine.setProgressHandler(this->progress("INR Volume (interactive macrocells): "));
  }
  try
  {
    engine.buildAllSlices();
  }
  catch (const std::exception& e)
  {
    if (this->error)
    {
      this->error(std::string("INR Volume: building the interactive macrocells ahead failed: ") +
        e.what() + "; time changes build them when needed");
    }
  }
  engine.setProgressHandler({});
  const double ms = msSince(start);
  if (report)
  {
    std::fprintf(stderr, "INR Volume LOD: built %d interactive macrocell slices ahead (%dx%dx%d "
                         "cells), %.1f ms\n",
      engine.macrocellInfo().slicesBuilt - before.slicesBuilt, before.dims.x, before.dims.y,
      before.dims.z, ms);
  }
  return ms;
}

void InrEngines::Launch(Job what, inr::RenderSession* session, std::function<void()> work)
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

bool InrEngines::StartFineBuild(double time)
{
  if (this->FineBuilding() || !this->fine.session)
  {
    return false;
  }
  this->JoinBackgroundBuild();  // a refinement step finishes first: the build needs the session
  inr::RenderSession* session = this->fine.session.get();
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

bool InrEngines::StartCoarseAhead(int n)
{
  if (this->CoarseBusy())
  {
    return true;
  }
  if (this->FineBusy() || !this->UpdateCoarse(n))
  {
    return false;
  }
  inr::RenderSession* session = this->coarse.session.get();
  const inr::MacrocellInfo info = session->macrocellInfo();
  if (info.slicesBuilt >= info.temporalSlices)
  {
    return false;
  }
  // The slices' times, as the engine lays them out (MacrocellLayout::sliceTime): one slice per
  // call, so that a stop request is seen between slices.
  inr::MacrocellLayout layout;
  layout.temporalSlices = info.temporalSlices;
  layout.timeBegin = this->model.domain.timeBegin;
  layout.timeEnd = this->model.domain.timeEnd;
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

bool InrEngines::StartFineRefine()
{
  if (this->job != Job::None || !this->fine.session)
  {
    return false;
  }
  inr::RenderSession* session = this->fine.session.get();
  inr::RefinementDriver* refinement = &this->fine.refinement;
  this->refineRun = {};
  this->Launch(Job::FineRefine, session,
    [this, session, refinement]() { this->refineRun = refinement->advance(*session); });
  return true;
}

inr::RefinementDriver::Step InrEngines::TakeRefineStep()
{
  inr::RefinementDriver::Step step = this->refineStep;
  this->refineStep = {};
  return step;
}

void InrEngines::Join()
{
  if (this->job == Job::None)
  {
    return;
  }
  const Job was = this->job;
  this->builder.join();
  this->job = Job::None;
  const bool onFine = was == Job::FineSlices || was == Job::FineRefine;
  InrEngineSlot& slot = onFine ? this->fine : this->coarse;
  if (was == Job::FineRefine)
  {
    this->refineStep = this->refineRun;
  }
  if (slot.session)
  {
    // The fine session reports its lazy builds as VTK progress again; the coarse one reports
    // none (its lazy builds happen inside interactive frames).
    if (onFine && this->progress)
    {
      slot.session->setProgressHandler(this->progress("INR Volume: "));
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

void InrEngines::JoinFineBuild()
{
  if (this->FineBusy())
  {
    this->Join();
  }
}

void InrEngines::JoinBackgroundBuild()
{
  this->stopBuild = true;  // a build ahead stops after its current slice; a fine build finishes
  this->Join();
}

void InrEngines::FinishBackgroundBuild()
{
  this->Join();
}

// A rejected set is reported once and the engine keeps what it had; a pruning change restarts its
// accumulation, which the refinement driver notices (accumulated frames drop to 0).
void InrEngines::PushQueryReduction(InrEngineSlot& slot, const inr::QueryReductionSettings& asked)
{
  inr::RenderSession& engine = *slot.session;
  if (!slot.haveQueryReduction || !InrSameQueryReduction(asked, slot.queryReductionTried))
  {
    slot.haveQueryReduction = true;
    slot.queryReductionTried = asked;
    try
    {
      engine.setQueryReduction(asked);
      this->haveRefusedQueryReduction = false;
    }
    catch (const std::invalid_argument& e)
    {
      if ((!this->haveRefusedQueryReduction ||
            !InrSameQueryReduction(asked, this->refusedQueryReduction)) &&
        this->error)
      {
        this->error(std::string("INR Volume: ") + e.what() + "; keeping " +
          InrDescribeQueryReduction(engine.queryReduction()));
      }
      this->haveRefusedQueryReduction = true;
      this->refusedQueryReduction = asked;
    }
  }
  this->queryReductionInUse = InrDescribeQueryReduction(engine.queryReduction());
}
