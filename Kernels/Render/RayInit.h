#pragma once
// Stage I — ray initialisation: one jittered camera ray per pixel, clipped to the model's box
// and to the per-pixel depth limit (opaque geometry drawn before the volume). Rays that miss,
// or whose segment is empty, start inactive and cost nothing in later stages.
#include <cmath>

#include "Render/CounterRng.h"
#include "Render/RayState.h"

namespace inr {

// Draw indices 0 and 1 of every pixel's stream are the sub-pixel jitter (drawn even when jitter
// is off, so the tracking draws do not shift with that option).
INR_HD void initPrimaryRay(const FrameConstants& fc, const MajorantGridView& grid,
                           const RayStateView& rs, int i) {
  RngStream rng{std::uint32_t(i), fc.frame, fc.seed, 0u};
  const float u0 = rng.next(), u1 = rng.next();
  const int px = i % fc.camera.width, py = i / fc.camera.width;
  Vec3f o, d;
  cameraRay(fc.camera, px, py, fc.pixelJitter ? u0 : 0.5f, fc.pixelJitter ? u1 : 0.5f, o, d);

  rs.origin[i] = o;
  rs.direction[i] = d;
  rs.flags[i] = 0;
  rs.sample[i] = NAN;
  rs.collisionProduct[i] = 0.f;
  rs.radiance[i] = Vec4f{0.f, 0.f, 0.f, 0.f};
  rs.visibility[i] = 1.f;
  rs.rngCounter[i] = rng.counter;
  rs.pruned[i] = 0;
  rs.t[i] = 0.f;
  rs.tEnd[i] = 0.f;

  float tEnter, tExit;
  if (!intersectBox(fc.box, o, d, tEnter, tExit)) return;
  if (fc.depthLimit) tExit = minf(tExit, fc.depthLimit[i]);
  if (!(tEnter < tExit)) return;  // behind opaque geometry (or NaN depth): nothing to do

  Int3 cell;
  Vec3f tNext;
  ddaStart(grid, o, d, tEnter, cell, tNext);
  rs.t[i] = tEnter;
  rs.tEnd[i] = tExit;
  rs.cell[i] = cell;
  rs.tNext[i] = tNext;
  rs.flags[i] = kRayActive;
}

// Ghost passes (SceneChange.h) trace every stride-th pixel in x and y; the other rays stay
// inactive.
INR_HD void initGhostRay(const FrameConstants& fc, const MajorantGridView& grid, const RayStateView& rs,
                         int i, int stride) {
  const int px = i % fc.camera.width, py = i / fc.camera.width;
  if (px % stride == 0 && py % stride == 0) {
    initPrimaryRay(fc, grid, rs, i);
  } else {
    rs.flags[i] = 0;
  }
}

}  // namespace inr
