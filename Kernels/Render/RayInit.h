#pragma once
// Stage I — ray initialisation: one jittered camera ray per pixel, clipped to the model's box
// and to the per-pixel depth limit (opaque geometry drawn before the volume). Rays that miss,
// or whose segment is empty, start inactive and cost nothing in later stages.
#include <cmath>

#include "Render/CounterRng.h"
#include "Render/RayState.h"

namespace inr {

// The stratified sub-pixel jitter (FrameConstants::pixelJitter 2) of frame `frame` of the pixel
// with stream key `key`: frame j of each half (frameHalf; j = frame / 2) takes term j of the R2
// sequence (Roberts 2018: the additive recurrence with the plastic number's inverse powers, evenly
// spread in 2D for any number of terms), rotated by a random start per pixel and half
// (Cranley-Patterson). Each frame's position is uniform in the pixel, so each frame's estimate
// stays unbiased; a half's frames fill the pixel evenly, so the antialiasing's share of the error
// falls about as 1 / frames instead of 1 / sqrt(frames); the two halves' positions are
// independent of each other. In 32-bit fixed point, exact for every frame number.
INR_HD void stratifiedJitter(std::uint32_t key, std::uint32_t frame, std::uint32_t seed, float& u0, float& u1) {
  const std::uint32_t half = frameHalf(frame), j = frame >> 1;
  const std::uint32_t start0 = counterHash(key, half, seed ^ 0x5851f42du, 0u);
  const std::uint32_t start1 = counterHash(key, half, seed ^ 0x5851f42du, 1u);
  const std::uint32_t x = start0 + j * 3242174889u;  // 2^32 / 1.32471795724 (the plastic number)
  const std::uint32_t y = start1 + j * 2447445414u;  // 2^32 / 1.32471795724^2
  u0 = float(x >> 8) * (1.0f / 16777216.0f);
  u1 = float(y >> 8) * (1.0f / 16777216.0f);
}

// Draw indices 0 and 1 of every pixel's stream are the sub-pixel jitter (drawn even when jitter
// is off or stratified, so the tracking draws do not shift with that option). Pixel i's position
// in the pixel this frame, in [0, 1)^2 ((0.5, 0.5) without jitter); `rng` left after the two draws.
INR_HD void primaryJitter(const FrameConstants& fc, int i, RngStream& rng, float& u0, float& u1) {
  rng = RngStream{pixelStreamKey(fc, i), fc.frame, fc.seed, 0u};
  u0 = rng.next();
  u1 = rng.next();
  if (fc.pixelJitter == 2) stratifiedJitter(rng.pixel, fc.frame, fc.seed, u0, u1);
  if (!fc.pixelJitter) u0 = u1 = 0.5f;
}

INR_HD void initPrimaryRay(const FrameConstants& fc, const MajorantGridView& grid,
                           const RayStateView& rs, int i) {
  RngStream rng;
  float u0, u1;
  primaryJitter(fc, i, rng, u0, u1);
  const int px = i % fc.camera.width, py = i / fc.camera.width;
  Vec3f o, d;
  cameraRayWorld(fc.camera, px, py, u0, u1, o, d);
  // Model space from here on; the depth limit is a world distance along the world ray.
  const float modelPerWorld = worldRayToModel(fc.camera, o, d);

  rs.origin[i] = o;
  rs.direction[i] = d;
  rs.flags[i] = 0;
  rs.sample[i] = NAN;
  rs.collisionProduct[i] = 0.f;
  rs.radiance[i] = Vec4f{0.f, 0.f, 0.f, 0.f};
  rs.visibility[i] = 1.f;
  rs.rngCounter[i] = rng.counter;
  rs.pruned[i] = 0;
  rs.pointCount[i] = 0;
  rs.hitT[i] = 0.f;
  rs.combNext[i] = NAN;
  rs.residualNext[i] = NAN;
  rs.lastExtinction[i] = NAN;  // march's control: not known yet
  rs.controlKnown[i] = 0;
  rs.hitWeight[i] = 1.f;
  rs.combPhase[i] = NAN;
  rs.lastCombValue[i] = NAN;  // preintegrated: no comb point yet
  rs.combInCell[i] = 0;
  rs.marchLevel[i] = 0;  // debiased: no comb interval yet (combPhase NaN)
  rs.marchStep[i] = 0;
  rs.leftKnown[i] = 0;
  rs.leftScale[i] = 1.f;
  rs.t[i] = 0.f;
  rs.tEnd[i] = 0.f;

  if (fc.shareCount > 1) {
    // Image-space split: another share's pixel stays empty, like one behind geometry at depth 0.
    int x, y;
    picturePixel(fc, i, x, y);
    if ((x + y) % fc.shareCount != fc.shareIndex) return;
  }

  float tEnter, tExit;
  // The primary box is the whole box, or this rank's brick (sub-domain rendering).
  if (!intersectBox(fc.primaryBox, o, d, tEnter, tExit)) return;
  if (fc.depthLimit) tExit = minf(tExit, fc.depthLimit[i] * modelPerWorld);
  if (!(tEnter < tExit)) return;  // behind opaque geometry (or NaN depth): nothing to do

  Int3 cell;
  Vec3f tNext;
  ddaStart(grid, o, d, tEnter, cell, tNext);
  rs.t[i] = tEnter;
  rs.tEnd[i] = tExit;
  rs.cell[i] = cell;
  rs.tNext[i] = tNext;
  rs.flags[i] = kRayActive | kRayEntered;
}

// Ray budgeting (paper §4.2.1), decided per pixel before its ray is cast: does pixel (px, py)
// = i get a ray this frame? A pixel with nothing accumulated always does (there is nothing to
// reuse; this also makes the first frame after a reset complete). Otherwise, by scheme:
//   histogram      a pixel rendered last frame whose residual r_i is below the threshold tau
//                  starts a skip countdown of floor((1 - r_i / tau) S_max + 0.5) frames (Eq. 6),
//                  counting this one; a pixel in a countdown skips until it runs out, then
//                  renders: every pixel renders at least once per S_max + 1 frames.
//   stbn           u(x, n) < rho, u the blue-noise mask tiled over the screen (Eq. 7).
//   weighted-stbn  u(x, n) < rho_eff = clamp(rho + alpha (r_i - rho), floor, 1) (Eq. 8): the
//                  floor (budgetRhoFloor: the paper's 2/256, at least 1/D for a D-slice mask)
//                  keeps every pixel rendering at least once per D frames.
// Only the histogram scheme writes pixel state (the countdown).
INR_HD bool budgetPixel(const BudgetConstants& b, const AccumulationView& acc, int i, int px, int py) {
  if (b.scheme == 0 || acc.sampleCount[i] == 0u) return true;
  if (b.scheme == 1) {
    const std::int32_t left = acc.skip[i];
    if (left > 0) {
      acc.skip[i] = left - 1;
      return false;
    }
    if (left == 0) return true;  // countdown over
    const float r = acc.residual[i];
    if (!(r < b.tau) || b.maxSkip <= 0) return true;
    const int frames = int(floorf((1.f - r / b.tau) * float(b.maxSkip) + 0.5f));
    if (frames <= 0) return true;
    acc.skip[i] = frames - 1;
    return false;
  }
  const float u = blueNoiseValue(b.mask, px, py, b.noiseFrame);
  if (b.scheme == 2) return u < b.rho;
  const float rhoEff = clampf(b.rho + b.alpha * (acc.residual[i] - b.rho), b.rhoFloor, 1.f);
  return u < rhoEff;
}

// Stage I for a displayed frame: the budgeting decision, then the camera ray. A skipped pixel's
// ray is inactive (kRayBudgetSkipped): it costs nothing in later stages and finalisation keeps
// its accumulation as it is.
INR_HD void initBudgetedRay(const FrameConstants& fc, const MajorantGridView& grid, const RayStateView& rs,
                            const AccumulationView& acc, int i) {
  int px, py;
  picturePixel(fc, i, px, py);  // the blue-noise mask is tiled over the full picture
  if (!budgetPixel(fc.budget, acc, i, px, py)) {
    rs.flags[i] = kRayBudgetSkipped;
    rs.pruned[i] = 0;  // summed over all rays at the end of the frame
    return;
  }
  initPrimaryRay(fc, grid, rs, i);
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
