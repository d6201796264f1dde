// vtkInrVolumeMapper's information getters (the panel's figures, read from InrMapperReport) and
// the options it stores as asked; PrintSelf.
#include "vtkInrVolumeMapperInternals.h"

// The panel's figures (InrMapperReport.h). The refinement figures are refreshed from the engine
// whenever read: a reset, a property change or a finished job between renders shows at once.
const InrMapperReport& vtkInrVolumeMapper::Internals::Report(vtkInrVolumeMapper* self)
{
  InrMapperReport& r = this->report;
  r.ranks = this->ranks.Ranks().count;
  r.haveEngine = this->engines.fine.session != nullptr;
  r.frames = this->ShownFrames();
  // Without progressive refinement nothing renders again by itself: "stopped" from the start.
  // A reduced interactive image is never the final one: a still render must follow. A
  // refinement step running on the worker, or a first render put off: not converged yet.
  r.localConverged = this->firstRender != FirstRender::PutOff &&
    (!self->ProgressiveRefinement ||
      (!this->lod.LastInteractive() && !this->worker.FineRefining() &&
        this->engines.fine.refinement.converged()));
  r.estimate = this->worker.FineRefining() ? this->worker.KeptEstimate()
                                            : this->engines.fine.refinement.estimate();
  if (this->surface.active)
  {
    // Isosurface and slice: exact in their first frame, nothing left to refine once their frames
    // are all drawn (a reduced drag frame is followed by a still one; a still frame drawn in
    // parts by the renders after it).
    r.frames = this->surface.frames;
    r.localConverged = !this->surface.interactive && this->surface.complete;
    r.estimate = std::numeric_limits<double>::infinity();
  }
  else if (this->cropEmpty)
  {
    r.localConverged = true;  // nothing to draw inside the crop box
  }
  r.queryReductionInUse = this->engines.queryReductionInUse;
  r.engineBuilds = this->engines.engineBuilds;
  return r;
}

// The sessions' counters, once the worker's job on them is done: `joinFine` waits for a job on
// the fine session only (the fine session's figures; the coarse ones may be on the worker),
// else any job finishes first (both sessions' figures).
const InrMapperReport& vtkInrVolumeMapper::Internals::ReportEngineCounters(
  vtkInrVolumeMapper* self, bool joinFine)
{
  if (joinFine)
  {
    this->worker.JoinFineBuild();
  }
  else
  {
    this->worker.FinishBackgroundBuild();
  }
  InrMapperReport& r = this->report;
  const auto& fine = this->engines.fine.session;
  const auto& coarse = this->engines.coarse.session;
  r.slicesBuilt = fine ? fine->macrocellInfo().slicesBuilt : 0;
  r.engineOptions = fine ? InrDescribeSession(*fine) : "";
  if (!joinFine)
  {
    r.interactiveSlicesBuilt = coarse ? coarse->macrocellInfo().slicesBuilt : 0;
    r.interactiveEngineOptions = coarse ? InrDescribeSession(*coarse) : "";
    // On the CPU the coarse session's evaluator is the switch to a stand-in (InrStandInSwitch),
    // around the fine session's network.
    const InrStandInSwitch* standIn = this->engines.StandIn();
    const inr::FieldEvaluator* coarseNetwork =
      coarse ? (standIn ? &standIn->Network() : &coarse->evaluator()) : nullptr;
    r.sharesEvaluator = fine && coarse && &fine->evaluator() == coarseNetwork;
  }
  return this->Report(self);
}

int vtkInrVolumeMapper::GetAccumulatedFrames()
{
  return this->Internal->Report(this).Frames();
}

int vtkInrVolumeMapper::GetConverged()
{
  return this->Internal->Report(this).Converged() ? 1 : 0;
}

int vtkInrVolumeMapper::GetLocalConverged()
{
  return this->Internal->Report(this).localConverged ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderInteractive()
{
  return this->Internal->report.interactive ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastImageWidth()
{
  return this->Internal->report.imageWidth;
}

int vtkInrVolumeMapper::GetLastImageHeight()
{
  return this->Internal->report.imageHeight;
}

double vtkInrVolumeMapper::GetLastRenderMilliseconds()
{
  return this->Internal->report.renderMs;
}

double vtkInrVolumeMapper::GetConvergenceEstimate()
{
  return this->Internal->Report(this).Estimate();
}

std::string vtkInrVolumeMapper::FormatConvergenceEstimate(double db)
{
  return InrFormatConvergenceEstimate(db);
}

const char* vtkInrVolumeMapper::GetConvergenceEstimateText()
{
  InrMapperReport& r = this->Internal->report;
  r.estimateText = InrFormatConvergenceEstimate(this->Internal->Report(this).Estimate());
  return r.estimateText.c_str();
}

const char* vtkInrVolumeMapper::GetRefinementState()
{
  InrMapperReport& r = this->Internal->report;
  if (this->Internal->surface.active)
  {
    r.refinementState = this->Internal->surface.state;
    return r.refinementState.c_str();
  }
  r.refinementState = InrDescribeRefinement(this->Internal->Report(this),
    InrRefinementLimits{ this->ProgressiveRefinement != 0, this->ConvergenceTarget, this->MaximumFrames });
  return r.refinementState.c_str();
}

const char* vtkInrVolumeMapper::GetBackendInUse()
{
  return this->Internal->report.backendInUse.c_str();
}

double* vtkInrVolumeMapper::GetBounds()
{
  vtkDataSet* input = this->GetInput();
  vtkFieldData* fd = input ? input->GetFieldData() : nullptr;
  vtkDataArray* domain = fd ? fd->GetArray("InrDomainBounds") : nullptr;
  if (domain && domain->GetNumberOfValues() == 6)
  {
    for (int k = 0; k < 6; ++k)
    {
      this->Bounds[k] = domain->GetTuple1(k);
    }
    return this->Bounds;
  }
  return this->Superclass::GetBounds();
}

const char* vtkInrVolumeMapper::GetRanksInUse()
{
  return this->Internal->report.ranksInUse.c_str();
}

double vtkInrVolumeMapper::GetLastUpdateMilliseconds()
{
  return this->Internal->report.step.total.updateMs;
}

int vtkInrVolumeMapper::GetSlicesBuilt()
{
  return this->Internal->ReportEngineCounters(this, true).slicesBuilt;
}

int vtkInrVolumeMapper::GetInteractiveSlicesBuilt()
{
  return this->Internal->ReportEngineCounters(this, false).interactiveSlicesBuilt;
}

const char* vtkInrVolumeMapper::GetEngineOptionsInUse()
{
  return this->Internal->ReportEngineCounters(this, true).engineOptions.c_str();
}

const char* vtkInrVolumeMapper::GetInteractiveEngineOptionsInUse()
{
  return this->Internal->ReportEngineCounters(this, false).interactiveEngineOptions.c_str();
}

int vtkInrVolumeMapper::GetInteractiveSharesEvaluator()
{
  return this->Internal->ReportEngineCounters(this, false).sharesEvaluator ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderStandIn()
{
  return this->Internal->report.shownStandIn ? 1 : 0;
}

int vtkInrVolumeMapper::GetLastRenderCoarse()
{
  return this->Internal->report.shownCoarse ? 1 : 0;
}

double vtkInrVolumeMapper::InteractiveFreshFrameScale(double scale, int fresh)
{
  return InrLevelOfDetail::FreshFrameScale(scale, fresh);
}

int vtkInrVolumeMapper::InteractiveFreshFrameCount(double scale, int fresh)
{
  return InrLevelOfDetail::FreshFrameCount(scale, fresh);
}

int vtkInrVolumeMapper::GetEngineBuilds()
{
  return this->Internal->Report(this).engineBuilds;
}

double vtkInrVolumeMapper::GetLastQueries()
{
  return double(this->Internal->report.step.total.totalQueries());
}

double vtkInrVolumeMapper::GetLastRays()
{
  return double(this->Internal->report.step.total.rays);
}

double vtkInrVolumeMapper::GetLastBudgetSkipped()
{
  return double(this->Internal->report.step.total.budgetSkipped);
}

double vtkInrVolumeMapper::GetLastPruned()
{
  return double(this->Internal->report.step.total.pruned);
}

// Options kept in Internals as asked: query reduction (validated when pushed into the engine, so
// the error names the engine's parameter and range) and macrocell / tracking options (checked
// when the engine is updated, naming the property). Modified() makes ParaView render again.
#define INR_STORED_OPTION(Name, Type, member, toField, fromField)                                  \
  void vtkInrVolumeMapper::Set##Name(Type v)                                                      \
  {                                                                                                \
    if (this->Get##Name() != v)                                                                    \
    {                                                                                              \
      this->Internal->member = toField;                                                            \
      this->Modified();                                                                            \
    }                                                                                              \
  }                                                                                                \
  Type vtkInrVolumeMapper::Get##Name()                                                             \
  {                                                                                                \
    return fromField;                                                                              \
  }
INR_STORED_OPTION(RayBudget, int, options.queryReduction.budget, static_cast<inr::BudgetScheme>(v),
  static_cast<int>(this->Internal->options.queryReduction.budget))
INR_STORED_OPTION(BudgetFraction, double, options.queryReduction.budgetFraction, v,
  this->Internal->options.queryReduction.budgetFraction)
INR_STORED_OPTION(BudgetMaxSkip, int, options.queryReduction.budgetMaxSkip, v,
  this->Internal->options.queryReduction.budgetMaxSkip)
INR_STORED_OPTION(BudgetAlpha, double, options.queryReduction.budgetAlpha, v,
  this->Internal->options.queryReduction.budgetAlpha)
INR_STORED_OPTION(Reproject, int, options.queryReduction.reproject, v != 0,
  this->Internal->options.queryReduction.reproject ? 1 : 0)
INR_STORED_OPTION(PruneEpsilon, double, options.queryReduction.pruneEpsilon, v,
  this->Internal->options.queryReduction.pruneEpsilon)
INR_STORED_OPTION(PruneFalloff, double, options.queryReduction.pruneFalloff, v,
  this->Internal->options.queryReduction.pruneFalloff)

const char* vtkInrVolumeMapper::GetQueryReductionInUse()
{
  return this->Internal->Report(this).queryReductionInUse.c_str();
}

INR_STORED_OPTION(SkipBlock, int, options.macrocellsAsked.skipBlockCells, v,
  this->Internal->options.macrocellsAsked.skipBlockCells)
INR_STORED_OPTION(BoundsPadding, double, options.macrocellsAsked.boundsPadding, v,
  this->Internal->options.macrocellsAsked.boundsPadding)
INR_STORED_OPTION(GhostPasses, int, options.trackingAsked.ghostPassesOnUpdate, v,
  this->Internal->options.trackingAsked.ghostPassesOnUpdate)
INR_STORED_OPTION(RefineMacrocells, int, options.trackingAsked.refineMacrocells, v != 0,
  this->Internal->options.trackingAsked.refineMacrocells ? 1 : 0)
INR_STORED_OPTION(Estimator, int, options.trackingAsked.estimator, static_cast<inr::PrimaryEstimator>(v),
  static_cast<int>(this->Internal->options.trackingAsked.estimator))
INR_STORED_OPTION(MajorantScale, double, options.trackingAsked.majorantScale, v,
  this->Internal->options.trackingAsked.majorantScale)
INR_STORED_OPTION(ResidualScale, double, options.trackingAsked.residualScale, v,
  this->Internal->options.trackingAsked.residualScale)
INR_STORED_OPTION(PointsPerIteration, int, options.trackingAsked.pointsPerIteration, v,
  this->Internal->options.trackingAsked.pointsPerIteration)
INR_STORED_OPTION(StratifiedJitter, int, options.trackingAsked.stratifiedJitter, v != 0,
  this->Internal->options.trackingAsked.stratifiedJitter ? 1 : 0)
INR_STORED_OPTION(JitterControlFrames, int, options.trackingAsked.jitterControlFrames, v,
  this->Internal->options.trackingAsked.jitterControlFrames)
#undef INR_STORED_OPTION

const char* vtkInrVolumeMapper::GetMacrocellsInUse()
{
  return this->Internal->report.macrocellsInUse.c_str();
}

void vtkInrVolumeMapper::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Backend: " << this->Backend << " (" << this->GetBackendInUse() << ")\n";
  os << indent << "Traversal: " << this->Traversal << "\n";
  os << indent << "InteractiveStandIn: " << this->InteractiveStandIn << "\n";
  os << indent << "MacrocellResolution: " << this->MacrocellResolution << "\n";
  os << indent << "TemporalSlices: " << this->TemporalSlices << "\n";
  os << indent << "Shadows: " << this->Shadows << "\n";
  os << indent << "MaximumFrames: " << this->MaximumFrames << "\n";
  os << indent << "ConvergenceTarget: " << this->ConvergenceTarget << "\n";
  os << indent << "FramesPerRender: " << this->FramesPerRender << "\n";
  os << indent << "RefinementTimeBudget: " << this->RefinementTimeBudget << " ms\n";
  os << indent << "ProgressiveRefinement: " << this->ProgressiveRefinement << "\n";
  os << indent << "Macrocells in use: " << this->Internal->report.macrocellsInUse << "\n";
  os << indent << "Seed: " << this->Seed << "\n";
  os << indent << "InteractiveLevelOfDetail: " << this->InteractiveLevelOfDetail << "\n";
  os << indent << "InteractiveFrameTime: " << this->InteractiveFrameTime << " ms\n";
  os << indent << "InteractiveUpdateRate: " << this->InteractiveUpdateRate << "\n";
  os << indent << "InteractiveMacrocellResolution: " << this->InteractiveMacrocellResolution
     << "\n";
  os << indent << "InteractiveMacrocellsAhead: " << this->InteractiveMacrocellsAhead << "\n";
  os << indent << "InteractiveFreshFrames: " << this->InteractiveFreshFrames << "\n";
  os << indent << "QueryReduction: " << InrDescribeQueryReduction(this->Internal->options.queryReduction)
     << " (in use: " << this->Internal->engines.queryReductionInUse << ")\n";
}
