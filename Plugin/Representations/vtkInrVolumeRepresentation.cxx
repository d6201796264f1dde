#include "vtkInrVolumeRepresentation.h"

#include "vtkCommand.h"
#include "vtkDataObject.h"
#include "vtkDataArray.h"
#include "vtkFieldData.h"
#include "InrParallelRendering.h"
#include "vtkInformation.h"
#include "vtkInrVolumeMapper.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPVLODVolume.h"
#include "vtkPVRenderView.h"
#include "vtkPVView.h"
#include "vtkSmartPointer.h"
#include "vtkVolumeMapper.h"
#include "vtkVolumeProperty.h"

#include <algorithm>
#include <string>

vtkStandardNewMacro(vtkInrVolumeRepresentation);

namespace
{
// vtkPVView::GetInCaptureScreenshot (true between PrepareForScreenshot and CleanupAfterScreenshot:
// SaveScreenshot, SaveAnimation) is protected; a pointer to it formed in a derived class's scope
// reads it on any view. The class is never instantiated.
class CaptureProbe : public vtkPVView
{
public:
  static bool InCapture(vtkPVView* view)
  {
    return view && (view->*(&CaptureProbe::GetInCaptureScreenshot))();
  }
};
}

// ParaView's progress bar shows "<text>: <percent>" in the status bar's narrow box (~200 px): the
// mapper's text ("INR Volume (interactive macrocells): building macrocells: 16 of 16 time slices,
// 8x8x8 cells") wrapped there and was cut off. The representation (what ParaView observes) says
// what is built in a few words; the mapper's full text stays on the mapper.
const char* vtkInrVolumeRepresentation::ShortProgressText(const char* text)
{
  if (!text)
  {
    return nullptr;
  }
  const std::string t = text;
  if (t.find("building macrocells") == std::string::npos)
  {
    return text;
  }
  return t.find("interactive macrocells") != std::string::npos ? "INR coarse macrocells"
                                                                 : "INR macrocells";
}

vtkInrVolumeRepresentation::vtkInrVolumeRepresentation()
{
  this->VolumeMapper = vtkSmartPointer<vtkInrVolumeMapper>::New();
  this->VolumeMapper->AddObserver(
    vtkCommand::ProgressEvent, this, &vtkInrVolumeRepresentation::ForwardMapperProgress);
}

void vtkInrVolumeRepresentation::ForwardMapperProgress(vtkObject* mapper, unsigned long, void* progress)
{
  auto* algorithm = vtkAlgorithm::SafeDownCast(mapper);
  this->SetProgressText(ShortProgressText(algorithm ? algorithm->GetProgressText() : nullptr));
  this->UpdateProgress(*static_cast<double*>(progress));
  this->SetProgressText(nullptr);  // only for this event: the executive's own events carry none
}

vtkInrVolumeRepresentation::~vtkInrVolumeRepresentation()
{
  this->StopWatchingUpstream();
}

void vtkInrVolumeRepresentation::WatchUpstream()
{
  std::vector<vtkAlgorithm*> chain;
  std::vector<vtkAlgorithm*> pending;
  if (this->GetNumberOfInputConnections(0) > 0)
  {
    pending.push_back(this->GetInputAlgorithm(0, 0));
  }
  constexpr std::size_t kMaxAlgorithms = 64;  // bounded whatever the pipeline
  while (!pending.empty() && chain.size() < kMaxAlgorithms)
  {
    vtkAlgorithm* a = pending.back();
    pending.pop_back();
    if (!a || std::find(chain.begin(), chain.end(), a) != chain.end())
    {
      continue;
    }
    chain.push_back(a);
    for (int port = 0; port < a->GetNumberOfInputPorts(); ++port)
    {
      for (int c = 0; c < a->GetNumberOfInputConnections(port); ++c)
      {
        pending.push_back(a->GetInputAlgorithm(port, c));
      }
    }
  }
  bool same = chain.size() == this->WatchedUpstream.size();
  for (std::size_t k = 0; same && k < chain.size(); ++k)
  {
    same = this->WatchedUpstream[k] == chain[k];
  }
  if (same)
  {
    return;
  }
  this->StopWatchingUpstream();
  for (vtkAlgorithm* a : chain)
  {
    this->WatchedUpstream.emplace_back(a);
    this->WatchTags.push_back(
      a->AddObserver(vtkCommand::StartEvent, this, &vtkInrVolumeRepresentation::OnUpstreamStart));
  }
}

void vtkInrVolumeRepresentation::StopWatchingUpstream()
{
  for (std::size_t k = 0; k < this->WatchedUpstream.size(); ++k)
  {
    if (vtkAlgorithm* a = this->WatchedUpstream[k])
    {
      a->RemoveObserver(this->WatchTags[k]);
    }
  }
  this->WatchedUpstream.clear();
  this->WatchTags.clear();
}

void vtkInrVolumeRepresentation::OnUpstreamStart(vtkObject*, unsigned long, void*)
{
  if (this->GetVisibility())
  {
    this->GetInrMapper()->MarkViewUpdate();
  }
}

vtkInrVolumeMapper* vtkInrVolumeRepresentation::GetInrMapper()
{
  return vtkInrVolumeMapper::SafeDownCast(this->VolumeMapper);
}

void vtkInrVolumeRepresentation::UpdateMapperParameters()
{
  this->Superclass::UpdateMapperParameters();
  const char* colorArray = nullptr;
  if (vtkInformation* info = this->GetInputArrayInformation(0))
  {
    if (info->Has(vtkDataObject::FIELD_NAME()))
    {
      colorArray = info->Get(vtkDataObject::FIELD_NAME());
    }
  }
  const bool colored = colorArray && colorArray[0];
  this->GetInrMapper()->SetUseDefaultTransferFunction(colored ? 0 : 1);
  if (!colored)
  {
    // vtkPVLODVolume renders a volume only when its mapper finds the selected scalars: point at
    // the active point scalars (the reader's "value"), which our mapper never reads anyway.
    this->VolumeMapper->SetScalarMode(VTK_SCALAR_MODE_DEFAULT);
  }
  // The superclass hides the volume when no array is selected; ours renders the network itself.
  this->Actor->SetVisibility(this->GetVisibility() ? 1 : 0);
}

#define INR_FORWARD(Name, Type)                                                                    \
  void vtkInrVolumeRepresentation::SetInr##Name(Type v)                                            \
  {                                                                                                \
    this->GetInrMapper()->Set##Name(v);                                                            \
    this->Modified();                                                                              \
  }
INR_FORWARD(Backend, int)
INR_FORWARD(Traversal, int)
INR_FORWARD(MacrocellResolution, int)
INR_FORWARD(TemporalSlices, int)
INR_FORWARD(Shadows, int)
INR_FORWARD(Ambient, double)
INR_FORWARD(ShadowEstimator, int)
INR_FORWARD(MaximumFrames, int)
INR_FORWARD(ConvergenceTarget, double)
INR_FORWARD(FramesPerRender, int)
INR_FORWARD(RefinementTimeBudget, double)
INR_FORWARD(Seed, int)
INR_FORWARD(RankSplit, int)
INR_FORWARD(SkipBlock, int)
INR_FORWARD(BoundsPadding, double)
INR_FORWARD(GhostPasses, int)
INR_FORWARD(RefineMacrocells, int)
INR_FORWARD(Estimator, int)
INR_FORWARD(MajorantScale, double)
INR_FORWARD(ResidualScale, double)
INR_FORWARD(PointsPerIteration, int)
INR_FORWARD(StratifiedJitter, int)
INR_FORWARD(JitterControlFrames, int)
INR_FORWARD(ProgressiveRefinement, int)
INR_FORWARD(RayBudget, int)
INR_FORWARD(BudgetFraction, double)
INR_FORWARD(BudgetMaxSkip, int)
INR_FORWARD(BudgetAlpha, double)
INR_FORWARD(Reproject, int)
INR_FORWARD(PruneEpsilon, double)
INR_FORWARD(PruneFalloff, double)
INR_FORWARD(InteractiveLevelOfDetail, int)
INR_FORWARD(InteractiveFrameTime, double)
INR_FORWARD(InteractiveMacrocellResolution, int)
INR_FORWARD(InteractiveMacrocellsAhead, int)
INR_FORWARD(InteractiveFreshFrames, int)
INR_FORWARD(InteractiveStandIn, int)
#undef INR_FORWARD

void vtkInrVolumeRepresentation::RemoveAllInrGradientOpacityPoints()
{
  // The representation's own function, set on its volume property once and kept there; off
  // until a node is added (VTK's gradient opacity is on by default, as a constant 1).
  if (!this->Property->HasGradientOpacity(0))
  {
    vtkNew<vtkPiecewiseFunction> fn;
    this->Property->SetGradientOpacity(0, fn);
  }
  this->Property->GetStoredGradientOpacity(0)->RemoveAllPoints();
  this->Property->SetDisableGradientOpacity(0, 1);
  this->Modified();
}

void vtkInrVolumeRepresentation::AddInrGradientOpacityPoint(double gradientMagnitude, double factor)
{
  if (!this->Property->HasGradientOpacity(0))
  {
    this->RemoveAllInrGradientOpacityPoints();
  }
  this->Property->GetStoredGradientOpacity(0)->AddPoint(gradientMagnitude, factor);
  this->Property->SetDisableGradientOpacity(0, 0);
  this->Modified();
}

void vtkInrVolumeRepresentation::SetInrLightDirection(double x, double y, double z)
{
  this->GetInrMapper()->SetLightDirection(x, y, z);
  this->Modified();
}

int vtkInrVolumeRepresentation::GetInrAccumulatedFrames()
{
  return this->GetInrMapper()->GetAccumulatedFrames();
}

int vtkInrVolumeRepresentation::GetInrConverged()
{
  return this->GetInrMapper()->GetConverged();
}

double vtkInrVolumeRepresentation::GetInrConvergenceEstimate()
{
  return this->GetInrMapper()->GetConvergenceEstimate();
}

const char* vtkInrVolumeRepresentation::GetInrConvergenceEstimateText()
{
  return this->GetInrMapper()->GetConvergenceEstimateText();
}

const char* vtkInrVolumeRepresentation::GetInrRefinementState()
{
  return this->GetInrMapper()->GetRefinementState();
}

const char* vtkInrVolumeRepresentation::GetInrBackendInUse()
{
  return this->GetInrMapper()->GetBackendInUse();
}

const char* vtkInrVolumeRepresentation::GetInrRanksInUse()
{
  return this->GetInrMapper()->GetRanksInUse();
}

int vtkInrVolumeRepresentation::GetInrLastRenderInteractive()
{
  return this->GetInrMapper()->GetLastRenderInteractive();
}

int vtkInrVolumeRepresentation::GetInrLastImageWidth()
{
  return this->GetInrMapper()->GetLastImageWidth();
}

int vtkInrVolumeRepresentation::GetInrLastImageHeight()
{
  return this->GetInrMapper()->GetLastImageHeight();
}

double vtkInrVolumeRepresentation::GetInrLastRenderMilliseconds()
{
  return this->GetInrMapper()->GetLastRenderMilliseconds();
}

double vtkInrVolumeRepresentation::GetInrLastUpdateMilliseconds()
{
  return this->GetInrMapper()->GetLastUpdateMilliseconds();
}

const char* vtkInrVolumeRepresentation::GetInrQueryReductionInUse()
{
  return this->GetInrMapper()->GetQueryReductionInUse();
}

const char* vtkInrVolumeRepresentation::GetInrMacrocellsInUse()
{
  return this->GetInrMapper()->GetMacrocellsInUse();
}

int vtkInrVolumeRepresentation::ProcessViewRequest(
  vtkInformationRequestKey* request_type, vtkInformation* inInfo, vtkInformation* outInfo)
{
  if (request_type == vtkPVView::REQUEST_RENDER())
  {
    auto* view = vtkPVRenderView::SafeDownCast(inInfo->Get(vtkPVView::VIEW()));
    vtkRenderer* ren = view ? view->GetRenderer() : nullptr;
    this->GetInrMapper()->SetCapturing(CaptureProbe::InCapture(view));
    if (!this->GetVisibility())
    {
      this->RestoreDepthPeelingForVolumes();
    }
    else if (ren && ren->GetUseDepthPeelingForVolumes())
    {
      ren->SetUseDepthPeelingForVolumes(false);
      this->PeelingRenderer = ren;
    }
  }
  if (request_type == vtkPVView::REQUEST_UPDATE() && this->GetVisibility())
  {
    // Before the superclass updates the input (the reader may run here at a new time): that time
    // is part of the render the refinement budget is for. Another representation of the same
    // data may have run the reader already: the upstream observers caught that.
    this->GetInrMapper()->MarkViewUpdate();
    this->WatchUpstream();
  }
  if (!this->Superclass::ProcessViewRequest(request_type, inInfo, outInfo))
  {
    return 0;
  }
  if (request_type == vtkPVView::REQUEST_UPDATE())
  {
    this->ReportRankBrick(inInfo);
  }
  else if (request_type == vtkPVView::REQUEST_RENDER() && this->GetVisibility())
  {
    // Before the view's GL render (the superclass has just connected the mapper to the delivered
    // data): the engine and macrocell builds, with progress, while no GL render is under way.
    auto* view = vtkPVRenderView::SafeDownCast(inInfo->Get(vtkPVView::VIEW()));
    if (view && view->GetRenderer())
    {
      this->GetInrMapper()->PrepareRender(view->GetRenderer(), this->Actor);
    }
  }
  return 1;
}

// Sub-domain rendering under MPI: the superclass has asked for ordered compositing by bounds
// (IceT blends the ranks' premultiplied images in the visibility order of one box per rank, and
// the boxes must tile the domain). Each rank renders an interleaved share of the pixels through
// the whole model (vtkInrVolumeMapper), and disjoint pixels blend alike in any order, so any
// tiling serves: the k-d bricks of the model's box on the macrocell grid. The preview grid
// lives on rank 0 only, so the data bounds would say nothing.
void vtkInrVolumeRepresentation::ReportRankBrick(vtkInformation* inInfo)
{
  const InrParallelRendering::Ranks ranks = InrParallelRendering::GlobalRanks();
  if (ranks.count < 2 || !this->Cache)
  {
    return;
  }
  vtkFieldData* fd = this->Cache->GetFieldData();
  vtkDataArray* domain = fd ? fd->GetArray("InrDomainBounds") : nullptr;
  if (!domain || domain->GetNumberOfValues() != 6)
  {
    return;
  }
  double bounds[6];
  for (int k = 0; k < 6; ++k)
  {
    bounds[k] = domain->GetTuple1(k);
  }
  try
  {
    const inr::Brick brick = InrParallelRendering::RankBrick(
      bounds, this->GetInrMapper()->GetMacrocellResolution(), ranks.rank, ranks.count);
    const double brickBounds[6] = { brick.box.lo.x, brick.box.hi.x, brick.box.lo.y, brick.box.hi.y,
      brick.box.lo.z, brick.box.hi.z };
    vtkPVRenderView::SetGeometryBounds(inInfo, this, brickBounds);
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro(<< "INR Volume: cannot split the model over " << ranks.count
                  << " ranks: " << e.what());
  }
}

void vtkInrVolumeRepresentation::SetVisibility(bool visible)
{
  if (!visible)
  {
    this->RestoreDepthPeelingForVolumes();
  }
  this->Superclass::SetVisibility(visible);
}

bool vtkInrVolumeRepresentation::RemoveFromView(vtkView* view)
{
  this->RestoreDepthPeelingForVolumes();
  return this->Superclass::RemoveFromView(view);
}

void vtkInrVolumeRepresentation::RestoreDepthPeelingForVolumes()
{
  if (vtkRenderer* ren = this->PeelingRenderer)
  {
    ren->SetUseDepthPeelingForVolumes(true);
  }
  this->PeelingRenderer = nullptr;
}

void vtkInrVolumeRepresentation::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
}
