#include "InrEngineSlots.h"

#include <algorithm>
#include <sstream>
#include <tuple>

#include "Render/MacrocellLayout.h"
#include "Render/WavefrontRenderer.h"

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
