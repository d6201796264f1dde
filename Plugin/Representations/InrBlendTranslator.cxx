#include "InrBlendTranslator.h"

#include "vtkContourValues.h"
#include "vtkPVPlane.h"
#include "vtkPlane.h"
#include "vtkVolumeMapper.h"
#include "vtkVolumeProperty.h"

#include <algorithm>
#include <cmath>

namespace
{
const char* unsupportedBlendName(int mode)
{
  switch (mode)
  {
    case vtkVolumeMapper::MAXIMUM_INTENSITY_BLEND:
      return "Maximum Intensity";
    case vtkVolumeMapper::MINIMUM_INTENSITY_BLEND:
      return "Minimum Intensity";
    case vtkVolumeMapper::AVERAGE_INTENSITY_BLEND:
      return "Average Intensity";
    case vtkVolumeMapper::ADDITIVE_BLEND:
      return "Additive";
    default:
      return nullptr;
  }
}
}

InrBlendTranslator::Result InrBlendTranslator::Translate(
  vtkVolumeMapper* mapper, vtkVolumeProperty* property)
{
  Result r;
  const int mode = mapper ? mapper->GetBlendMode() : vtkVolumeMapper::COMPOSITE_BLEND;
  if (mode == vtkVolumeMapper::ISOSURFACE_BLEND)
  {
    r.blend.mode = inr::BlendMode::Isosurface;
    vtkContourValues* values = property ? property->GetIsoSurfaceValues() : nullptr;
    const int n = values ? values->GetNumberOfContours() : 0;
    const int kept = std::min(n, inr::BlendScene::kMaxIsovalues);
    for (int i = 0; i < kept; ++i)
    {
      const double v = values->GetValue(i);
      if (std::isfinite(v))
      {
        r.blend.isovalues.push_back(v);
      }
    }
    if (n > kept)
    {
      r.notes.push_back("Isosurface Values: " + std::to_string(n) + " values given, the first " +
        std::to_string(kept) + " are drawn (the engine draws at most " + std::to_string(kept) + ")");
    }
    if (int(r.blend.isovalues.size()) < kept)
    {
      r.notes.push_back("Isosurface Values: values that are not finite numbers are not drawn");
    }
    if (r.blend.isovalues.empty())
    {
      r.nothingToDraw = true;
      r.empty = "isosurface: no Isosurface Values, nothing to draw";
    }
  }
  else if (mode == vtkVolumeMapper::SLICE_BLEND)
  {
    r.blend.mode = inr::BlendMode::Slice;
    vtkImplicitFunction* fn = property ? property->GetSliceFunction() : nullptr;
    auto* plane = vtkPlane::SafeDownCast(fn);
    if (!plane)
    {
      r.nothingToDraw = true;
      r.empty = "slice: no Slice plane, nothing to draw";
      if (fn)
      {
        r.notes.push_back(std::string("Slice: the slice function is a ") + fn->GetClassName() +
          "; only a plane (vtkPlane) can be drawn, so nothing is drawn");
      }
    }
    else
    {
      double origin[3], normal[3];
      plane->GetOrigin(origin);
      plane->GetNormal(normal);
      // ParaView's plane (vtkPVPlane) lies Offset along its unit normal from its origin.
      if (auto* pvPlane = vtkPVPlane::SafeDownCast(plane))
      {
        const double len = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
        const double offset = pvPlane->GetOffset();
        if (offset != 0.0 && len > 0.0)
        {
          for (int a = 0; a < 3; ++a)
          {
            origin[a] += offset * normal[a] / len;
          }
        }
      }
      r.blend.sliceOrigin = { origin[0], origin[1], origin[2] };
      r.blend.sliceNormal = { normal[0], normal[1], normal[2] };
      // A zero normal is a state the panel passes through while a user types one (0 0 1 from
      // 1 0 0 goes by 0 0 0): no plane yet, nothing to draw, as for a missing value.
      const bool finite = std::isfinite(origin[0]) && std::isfinite(origin[1]) &&
        std::isfinite(origin[2]) && std::isfinite(normal[0]) && std::isfinite(normal[1]) &&
        std::isfinite(normal[2]);
      if (!finite || (normal[0] == 0.0 && normal[1] == 0.0 && normal[2] == 0.0))
      {
        r.nothingToDraw = true;
        r.empty = finite ? "slice: the Slice plane's normal is zero, nothing to draw"
                         : "slice: the Slice plane is not finite, nothing to draw";
      }
    }
  }
  else if (const char* name = unsupportedBlendName(mode))
  {
    r.notes.push_back(std::string("Blend Mode ") + name +
      " is not drawn by INR Volume (it draws Composite, Isosurface and Slice): drawn as Composite");
  }
  if (mapper && mapper->GetCropping())
  {
    const double* p = mapper->GetCroppingRegionPlanes();
    r.blend.crop = true;
    r.blend.cropBox = inr::Box3f{ { float(std::min(p[0], p[1])), float(std::min(p[2], p[3])),
                                    float(std::min(p[4], p[5])) },
      { float(std::max(p[0], p[1])), float(std::max(p[2], p[3])), float(std::max(p[4], p[5])) } };
    if (mapper->GetCroppingRegionFlags() != VTK_CROP_SUBVOLUME)
    {
      r.notes.push_back("Cropping: only the box between the cropping planes (VTK_CROP_SUBVOLUME, "
                        "ParaView's cropping box) is drawn; other cropping region flags are "
                        "drawn as that box");
    }
  }
  return r;
}
