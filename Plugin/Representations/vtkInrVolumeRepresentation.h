/**
 * @class vtkInrVolumeRepresentation
 * @brief ParaView's "INR Volume" representation: the image-volume representation with its mapper
 * replaced by vtkInrVolumeMapper, which renders the INR carried in the input's field data.
 *
 * Everything else (colour map / opacity editor, ScalarOpacityUnitDistance, visibility, data
 * delivery to the rendering processes, remote rendering) is vtkImageVolumeRepresentation's. While
 * the representation is not coloured by an array, the mapper uses its default transfer function
 * over the model's value range, so the model shows up at once.
 */
#ifndef vtkInrVolumeRepresentation_h
#define vtkInrVolumeRepresentation_h

#include "InrVolumeRepresentationsModule.h"
#include "vtkImageVolumeRepresentation.h"

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
  void SetInrMacrocellResolution(int);
  void SetInrTemporalSlices(int);
  void SetInrShadows(int);
  void SetInrLightDirection(double, double, double);
  void SetInrAmbient(double);
  void SetInrShadowEstimator(int);
  void SetInrMaximumFrames(int);
  void SetInrConvergenceTarget(double);
  void SetInrFramesPerRender(int);
  void SetInrSeed(int);
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
  const char* GetInrBackendInUse();
  const char* GetInrQueryReductionInUse();
  ///@}

  ///@{
  /// Level of detail while interacting, forwarded to vtkInrVolumeMapper (XML:
  /// InrInteractiveLevelOfDetail, InrInteractiveFrameTime). GetInrLastRenderInteractive: 1 when
  /// the last render drew a reduced interactive frame (the GUI's refinement loop waits for the
  /// interaction to settle before refining).
  void SetInrInteractiveLevelOfDetail(int);
  void SetInrInteractiveFrameTime(double);
  int GetInrLastRenderInteractive();
  /// The last render's image size (reduced during interaction), its wall time and its macrocell /
  /// majorant update time (ms).
  int GetInrLastImageWidth();
  int GetInrLastImageHeight();
  double GetInrLastRenderMilliseconds();
  double GetInrLastUpdateMilliseconds();
  ///@}

  vtkInrVolumeMapper* GetInrMapper();

protected:
  vtkInrVolumeRepresentation();
  ~vtkInrVolumeRepresentation() override;
  void UpdateMapperParameters() override;

private:
  vtkInrVolumeRepresentation(const vtkInrVolumeRepresentation&) = delete;
  void operator=(const vtkInrVolumeRepresentation&) = delete;
};

#endif
