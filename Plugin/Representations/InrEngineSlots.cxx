#include "InrEngineSlots.h"

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <vector>

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
    << " residual_scale=" << t.residualScale << " points_per_iteration=" << t.pointsPerIteration
    << " jitter_control_frames=" << t.jitterControlFrames;
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
  // The crop box (Cropping of the composite) clips the primary rays as a brick's does.
  const auto sameBox = [](const inr::Box3f& a, const inr::Box3f& b)
  {
    return a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x &&
      a.hi.y == b.hi.y && a.hi.z == b.hi.z;
  };
  if (!this->haveSettings || s.width != held.width || s.height != held.height ||
    s.seed != held.seed || s.window != held.window || s.pixelShare != held.pixelShare ||
    s.clipToBrick != held.clipToBrick || (s.clipToBrick && !sameBox(s.brick, held.brick)))
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
    held.pointsPerIteration != want.pointsPerIteration || held.stratifiedJitter != want.stratifiedJitter ||
    held.jitterControlFrames != want.jitterControlFrames)
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
  {
    // 0: the estimator's own density (after the estimator above, so that it follows a change).
    const double asked = this->trackingAsked.majorantScale == 0.0
      ? inr::TrackingOptions::recommendedFor(this->trackingValid.estimator).majorantScale
      : this->trackingAsked.majorantScale;
    accept("Majorant Scale (InrMajorantScale)", asked, this->trackingValid.majorantScale,
      this->trackingRefused.majorantScale,
      [this](double scale)
      {
        inr::TrackingOptions t = this->trackingValid;
        t.majorantScale = scale;
        t.validate();
      });
  }
  trackingField("Residual Scale (InrResidualScale)", &inr::TrackingOptions::residualScale);
  trackingField("Points Per Iteration (InrPointsPerIteration)", &inr::TrackingOptions::pointsPerIteration);
  trackingField("Jitter Control Frames (InrJitterControlFrames)", &inr::TrackingOptions::jitterControlFrames);
  this->trackingValid.stratifiedJitter = this->trackingAsked.stratifiedJitter;  // (either value is valid)
  this->trackingValid.refineMacrocells = this->trackingAsked.refineMacrocells;
}

InrEngines::~InrEngines()
{
  this->worker.JoinBackgroundBuild();
}

bool InrEngines::SetModel(const unsigned char* bytes, std::size_t n)
{
  const std::uint64_t h = hashBytes(bytes, n);
  if (h == this->hash && this->modelOk)
  {
    return true;
  }
  this->worker.JoinBackgroundBuild();
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
  if (this->worker.FineBusy())
  {
    if (f.asked.SameBuild(want) || !this->worker.BuildDone())
    {
      // The worker owns the session until its job is joined; a rebuild waits for that (the
      // view keeps drawing what it has meanwhile) rather than the render waiting for the job.
      return true;
    }
    this->worker.JoinFineBuild();
  }
  if (!f.session || !f.asked.SameBuild(want))
  {
    this->worker.JoinBackgroundBuild();  // a build ahead of the coarse session that goes with it
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
  if (this->worker.FineBusy() || !this->fine.session || (this->standInField && this->standInTime == time))
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
  if (this->worker.CoarseBusy())
  {
    this->worker.JoinBackgroundBuild();  // the caller draws with it: the rest of the build ahead later
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
