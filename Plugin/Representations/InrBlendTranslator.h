/**
 * @class InrBlendTranslator
 * @brief VTK's blend mode, isosurface values, slice plane and cropping box -> the engine's
 * inr::BlendScene, read where VTK's own volume mappers read them (plain C++, not wrapped):
 *  - the blend mode: vtkVolumeMapper::GetBlendMode (ParaView's Volume representation forwards
 *    its BlendMode property there): COMPOSITE, ISOSURFACE and SLICE are drawn; the maximum,
 *    minimum, average and additive blends are not (drawn as Composite, with a note saying so);
 *  - the isovalues: vtkVolumeProperty::GetIsoSurfaceValues (ParaView's IsosurfaceValues);
 *  - the slice plane: vtkVolumeProperty::GetSliceFunction, a vtkPlane (ParaView's SliceFunction,
 *    a vtkPVPlane whose Offset moves it along its normal), origin and normal in world
 *    coordinates as VTK's GPU ray-cast mapper takes them;
 *  - the cropping box: vtkVolumeMapper::GetCropping and GetCroppingRegionPlanes, in the data's
 *    coordinates (ParaView's representation computes the planes from UseCropping,
 *    CroppingOrigin, CroppingScale and the data bounds); only the sub-volume region
 *    (VTK_CROP_SUBVOLUME, ParaView's box) is drawn: other region flags are noted.
 * What cannot be drawn as asked is described in `notes` (one sentence each, naming the
 * property), so that the mapper says it once instead of drawing something else silently.
 */
#ifndef InrBlendTranslator_h
#define InrBlendTranslator_h

#include "Render/SurfaceRenderer.h"

#include <string>
#include <vector>

class vtkVolumeMapper;
class vtkVolumeProperty;

class InrBlendTranslator
{
public:
  struct Result
  {
    inr::BlendScene blend;
    /// Isosurface with no value, or Slice without a plane (or with a zero normal): nothing to
    /// draw (not an error: the state a user passes through while setting the mode up). `empty`
    /// says why, for the panel.
    bool nothingToDraw = false;
    std::string empty;
    /// What is not drawn as asked (each a sentence naming the property).
    std::vector<std::string> notes;
  };

  /// The blend scene of `mapper` and `property` (either may be null: composite, no crop).
  static Result Translate(vtkVolumeMapper* mapper, vtkVolumeProperty* property);
};

#endif
