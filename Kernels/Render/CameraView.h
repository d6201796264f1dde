#pragma once
// The camera as the per-ray code sees it: an orthonormal frame and the image-plane extents,
// produced on the host from a VTK-style Camera (SceneInputs.h). Device-facing: plain data only.
#include "Render/RenderMath.h"

namespace inr {

struct CameraView {
  Vec3f position;  // eye (perspective) / centre of the view plane through the eye (parallel)
  Vec3f forward, right, up;  // orthonormal; forward points at the focal point
  float halfHeight;  // perspective: tan(view angle / 2); parallel: parallel scale (world units)
  float aspect;      // width / height
  int width, height;
  int parallel;  // 0 perspective, 1 parallel projection
};

// Primary ray through image position (px + jx, py + jy); (jx, jy) in [0,1)² is the sub-pixel
// offset (0.5, 0.5 = pixel centre). Row 0 is the top of the image, as in ImageRGBA. The
// direction is unit length, so ray parameters are world distances from `origin`.
INR_HD void cameraRay(const CameraView& cam, int px, int py, float jx, float jy, Vec3f& origin,
                      Vec3f& dir) {
  const float sx = (2.f * (float(px) + jx) / float(cam.width) - 1.f) * cam.halfHeight * cam.aspect;
  const float sy = (1.f - 2.f * (float(py) + jy) / float(cam.height)) * cam.halfHeight;
  if (cam.parallel) {
    origin = cam.position + cam.right * sx + cam.up * sy;
    dir = cam.forward;
  } else {
    origin = cam.position;
    dir = normalize(cam.forward + cam.right * sx + cam.up * sy);
  }
}

}  // namespace inr
