/**
 * @class vtkInrVolumeRepresentation
 * @brief ParaView's "INR Volume" representation: the image-volume representation with its mapper
 * replaced by vtkInrVolumeMapper, which renders the INR carried in the input's field data.
 *
 * Everything else (colour map / opacity editor, ScalarOpacityUnitDistance, visibility, data
 * delivery to the rendering processes, remote rendering) is vtkImageVolumeRepresentation's. While
 * the representation is not coloured by an array, the mapper uses its default transfer function
 * over the model's value range, so the model shows up at once.
 *
 * Progress: ParaView's progress handler observes the objects its proxies create (this
 * representation), not the mapper inside it, so the representation re-issues the mapper's
 * ProgressEvents (macrocell builds, done in the render request before the GL render: see
 * vtkInrVolumeMapper::PrepareRender) as its own, with a short text ("INR macrocells", "INR coarse
 * macrocells") that fits ParaView's progress bar.
 */
#ifndef vtkInrVolumeRepresentation_h
#define vtkInrVolumeRepresentation_h

#include "InrVolumeRepresentationsModule.h"
#include "vtkImageVolumeRepresentation.h"
#include "vtkRenderer.h"    // for vtkWeakPointer<vtkRenderer>
#include "vtkWeakPointer.h" // for PeelingRenderer

#include <vector> // for WatchedUpstream

class vtkInrVolumeMapper;

class INRVOLUMEREPRESENTATIONS_EXPORT vtkInrVolumeRepresentation
  : public vtkImageVolumeRepresentation
{
public:
  static vtkInrVolumeRepresentation* New();
  vtkTypeMacro(vtkInrVolumeRepresentation, vtkImageVolumeRepresentation);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /// Forwarded to vtkInrVolumeMapper (see there).
  void SetInrBackend(int);
  void SetInrTraversal(int);
  void SetInrMacrocellResolution(int);
  void SetInrTemporalSlices(int);
  void SetInrShadows(int);
  void SetInrLightDirection(double, double, double);
  void SetInrAmbient(double);
  void SetInrShadowEstimator(int);
  void SetInrMaximumFrames(int);
  void SetInrConvergenceTarget(double);
  void SetInrFramesPerRender(int);
  void SetInrRefinementTimeBudget(double);
  void SetInrSeed(int);
  void SetInrRankSplit(int);
  void SetInrSkipBlock(int);
  void SetInrBoundsPadding(double);
  void SetInrGhostPasses(int);
  void SetInrRefineMacrocells(int);
  void SetInrEstimator(int);
  void SetInrMajorantScale(double);
  void SetInrResidualScale(double);
  void SetInrPointsPerIteration(int);
  void SetInrStratifiedJitter(int);
  void SetInrJitterControlFrames(int);
  void SetInrProgressiveRefinement(int);
  ///@}

  ///@{
  /// Gradient opacity: VTK's gradient opacity function of the volume property (the scalar opacity
  /// times a function of the gradient magnitude), which ParaView 5.11's Volume representation
  /// gives no property for. XML InrGradientOpacity: (|grad f|, factor) nodes, each added with
  /// AddInrGradientOpacityPoint after RemoveAllInrGradientOpacityPoints; no nodes turns it off.
  /// The mapper reads it from the volume property (InrSceneTranslator::GradientOpacity).
  void RemoveAllInrGradientOpacityPoints();
  void AddInrGradientOpacityPoint(double gradientMagnitude, double factor);
  ///@}

  ///@{
  /// Query reduction, forwarded to vtkInrVolumeMapper (XML: RayBudget, BudgetFraction,
  /// BudgetMaxSkip, BudgetAlpha, Reproject, PruneEpsilon, PruneFalloff).
  void SetInrRayBudget(int);
  void SetInrBudgetFraction(double);
  void SetInrBudgetMaxSkip(int);
  void SetInrBudgetAlpha(double);
  void SetInrReproject(int);
  void SetInrPruneEpsilon(double);
  void SetInrPruneFalloff(double);
  ///@}

  ///@{
  /// Refinement state after the last render (information properties; the GUI polls them).
  int GetInrAccumulatedFrames();
  int GetInrConverged();
  double GetInrConvergenceEstimate();
  /// For the panel: the estimate as "31.2 dB" or "\u2014" until known; one line of refinement
  /// state (vtkInrVolumeMapper::GetRefinementState).
  const char* GetInrConvergenceEstimateText();
  const char* GetInrRefinementState();
  const char* GetInrBackendInUse();
  const char* GetInrRanksInUse();
  const char* GetInrQueryReductionInUse();
  const char* GetInrMacrocellsInUse();
  ///@}

  ///@{
  /// Level of detail while interacting, forwarded to vtkInrVolumeMapper (XML:
  /// InrInteractiveLevelOfDetail, InrInteractiveFrameTime). GetInrLastRenderInteractive: 1 when
  /// the last render drew a reduced interactive frame (the GUI's refinement loop waits for the
  /// interaction to settle before refining).
  void SetInrInteractiveLevelOfDetail(int);
  void SetInrInteractiveFrameTime(double);
  /// InrInteractiveMacrocellResolution: the coarse majorant grid of time-change interactive frames.
  void SetInrInteractiveMacrocellResolution(int);
  /// InrInteractiveMacrocellsAhead: build that coarse grid's slices ahead, in a still render.
  void SetInrInteractiveMacrocellsAhead(int);
  /// InrInteractiveFreshFrames: frames of a time-change interactive image (at a lower resolution).
  void SetInrInteractiveFreshFrames(int);
  /// InrInteractiveStandIn: camera drags on the CPU draw a stand-in of the network.
  void SetInrInteractiveStandIn(int);
  int GetInrLastRenderInteractive();
  /// The last render's image size (reduced during interaction), its wall time and its macrocell /
  /// majorant update time (ms).
  int GetInrLastImageWidth();
  int GetInrLastImageHeight();
  double GetInrLastRenderMilliseconds();
  double GetInrLastUpdateMilliseconds();
  ///@}

  vtkInrVolumeMapper* GetInrMapper();

  /// Before each render while visible: VTK would render volumes inside dual depth peeling when
  /// the view has translucent geometry and "Depth Peeling for Volumes" is on, which only the GPU
  /// ray-cast mapper supports; the INR mapper is then composited after translucent geometry
  /// instead (the renderer's flag is set aside while the representation is visible, restored
  /// when it is hidden or removed).
  int ProcessViewRequest(vtkInformationRequestKey* request_type, vtkInformation* inInfo,
    vtkInformation* outInfo) override;
  void SetVisibility(bool visible) override;

protected:
  /// Under MPI with several ranks: reports this rank's box of a tiling of the model's box as its
  /// geometry bounds (ordered compositing), from the InrDomainBounds the reader adds to every piece.
  void ReportRankBrick(vtkInformation* inInfo);

  vtkInrVolumeRepresentation();
  ~vtkInrVolumeRepresentation() override;
  void UpdateMapperParameters() override;
  bool RemoveFromView(vtkView* view) override;
  void RestoreDepthPeelingForVolumes();
  void ForwardMapperProgress(vtkObject* mapper, unsigned long event, void* progress);
  /// The progress text ParaView's progress bar shows for the mapper's text (a few words).
  static const char* ShortProgressText(const char* text);

  /// Observes the start of every algorithm upstream of the input (the reader, ParaView's post
  /// filter): the first to execute after a render marks when the next render's work began
  /// (vtkInrVolumeMapper::MarkViewUpdate), whichever representation's update ran it.
  void WatchUpstream();
  void StopWatchingUpstream();
  void OnUpstreamStart(vtkObject*, unsigned long, void*);

private:
  std::vector<vtkWeakPointer<vtkAlgorithm>> WatchedUpstream;
  std::vector<unsigned long> WatchTags;
  // The renderer whose UseDepthPeelingForVolumes this representation turned off (null: none).
  vtkWeakPointer<vtkRenderer> PeelingRenderer;
  vtkInrVolumeRepresentation(const vtkInrVolumeRepresentation&) = delete;
  void operator=(const vtkInrVolumeRepresentation&) = delete;
};

#endif
