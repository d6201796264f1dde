#pragma once
// Shadows: after the primary traverse–evaluate loop, every ray with a real collision becomes a
// shadow ray from the collision point towards the (directional) light, through the same
// traversal code (kRayShadow) until it is blocked (delta tracking) or leaves the box. The
// visibility it leaves behind is applied in finalisation. The ray's random stream continues, so
// shadow draws never repeat primary draws.
#include "Render/RayState.h"

namespace inr {

INR_HD void spawnShadowRay(const FrameConstants& fc, const MajorantGridView& grid,
                           const RayStateView& rs, int i) {
  const std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayHit)) {
    rs.flags[i] = flags & std::uint8_t(~kRayActive);
    return;
  }
  const Vec3f p = rs.origin[i] + rs.direction[i] * rs.t[i];
  const Vec3f d = fc.toLight;
  float tEnter, tExit;
  rs.visibility[i] = 1.f;
  // p is inside the box (up to rounding): tEnter is 0 and tExit where the light ray leaves.
  if (!intersectBox(fc.box, p, d, tEnter, tExit) || !(tExit > 0.f)) {
    rs.flags[i] = kRayHit;
    return;
  }
  Int3 cell;
  Vec3f tNext;
  ddaStart(grid, p, d, 0.f, cell, tNext);
  rs.origin[i] = p;
  rs.direction[i] = d;
  rs.t[i] = 0.f;
  rs.tEnd[i] = tExit;
  rs.cell[i] = cell;
  rs.tNext[i] = tNext;
  rs.sample[i] = NAN;
  rs.flags[i] = std::uint8_t(kRayHit | kRayShadow | kRayActive);
}

}  // namespace inr
