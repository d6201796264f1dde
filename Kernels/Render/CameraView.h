#pragma once
// The camera as the per-ray code sees it: an orthonormal world frame, the image-plane extents
// (with VTK's window centre, which tiled rendering shifts per tile) and the affine map from world
// to the volume's model space (the volume actor's transform, inverted), produced on the host from
// a VTK-style Camera (SceneInputs.h). Device-facing: plain data only.
//
// Rays live in model space: the engine's box, macrocells, queries and hit points are model
// coordinates, and ray parameters are model distances (a unit model-space direction). That is how
// VTK's GPU ray-cast mapper measures the scalar opacity unit distance (it steps along a unit
// data-space direction), so a scaled volume keeps its optical depth, as it does in ParaView. An
// actor transform with shear or non-uniform scale is not an orthonormal camera in model space,
// which is why the camera keeps its world frame and maps each ray instead.
#include "Render/RenderMath.h"

namespace inr {

// x' = linear * x + offset, rows of the 3x3 linear part.
struct Affine3f {
  Vec3f row0, row1, row2, offset;
};

INR_HD Vec3f applyLinear(const Affine3f& m, Vec3f v) {
  return Vec3f{dot(m.row0, v), dot(m.row1, v), dot(m.row2, v)};
}
INR_HD Vec3f applyPoint(const Affine3f& m, Vec3f p) { return applyLinear(m, p) + m.offset; }

struct CameraView {
  Vec3f position;  // eye (perspective) / centre of the view plane through the eye (parallel); world
  Vec3f forward, right, up;  // orthonormal world frame; forward points at the focal point
  float halfHeight;  // perspective: tan(view angle / 2); parallel: parallel scale (world units)
  float aspect;      // width / height
  float centerX, centerY;  // vtkCamera's window centre: the image's centre on the view plane, in
                           // half-extents (0, 0 = centred)
  int width, height;
  int parallel;  // 0 perspective, 1 parallel projection
  int transformed;  // 0: model space is world space (the maps below are identities)
  Affine3f modelFromWorld, worldFromModel;
};

// World-space primary ray through image position (px + jx, py + jy); (jx, jy) in [0,1)² is the
// sub-pixel offset (0.5, 0.5 = pixel centre). Row 0 is the top of the image, as in ImageRGBA. The
// direction is unit length: ray parameters are world distances from `origin`.
INR_HD void cameraRayWorld(const CameraView& cam, int px, int py, float jx, float jy, Vec3f& origin, Vec3f& dir) {
  const float sx = (cam.centerX + 2.f * (float(px) + jx) / float(cam.width) - 1.f) * cam.halfHeight * cam.aspect;
  const float sy = (cam.centerY + 1.f - 2.f * (float(py) + jy) / float(cam.height)) * cam.halfHeight;
  if (cam.parallel) {
    origin = cam.position + cam.right * sx + cam.up * sy;
    dir = cam.forward;
  } else {
    origin = cam.position;
    dir = normalize(cam.forward + cam.right * sx + cam.up * sy);
  }
}

// A world ray (unit direction) as a model-space ray (unit direction). Returns the model distance
// per world distance along it (1 without a transform), which converts world ray parameters such
// as the depth limit.
INR_HD float worldRayToModel(const CameraView& cam, Vec3f& origin, Vec3f& dir) {
  if (!cam.transformed) return 1.f;
  origin = applyPoint(cam.modelFromWorld, origin);
  const Vec3f d = applyLinear(cam.modelFromWorld, dir);
  const float scale = length(d);
  dir = scale > 0.f ? d * (1.f / scale) : d;
  return scale;
}

// The primary ray in model space (what every stage traverses); ray parameters are model distances.
INR_HD void cameraRay(const CameraView& cam, int px, int py, float jx, float jy, Vec3f& origin, Vec3f& dir) {
  cameraRayWorld(cam, px, py, jx, jy, origin, dir);
  worldRayToModel(cam, origin, dir);
}

// World position of model point p.
INR_HD Vec3f modelToWorld(const CameraView& cam, Vec3f p) {
  return cam.transformed ? applyPoint(cam.worldFromModel, p) : p;
}

}  // namespace inr
