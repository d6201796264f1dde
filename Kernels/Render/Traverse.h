#pragma once
// Stage II — traversal: resolve the ray's pending candidate (if the evaluation stage answered
// it), then continue delta tracking through the majorant grid with each cell's local majorant
// until the next candidate collision (emit it: at most one pending query per ray) or until the
// ray leaves its segment. Primary and shadow rays share this code; the kRayShadow flag selects
// what a real collision means.
#include <cmath>

#include "Render/CounterRng.h"
#include "Render/RayState.h"

namespace inr {

// Free-flight distance under majorant m (paper Eq. sample_majorant): exponential with rate m.
INR_HD float freeFlightDistance(float majorant, float xi) { return -log1pf(-xi) / majorant; }

// Russian roulette below this ratio-tracked transmittance keeps shadow rays from walking through
// thin media forever; survivors are reweighted, so the estimate stays unbiased.
constexpr float kRouletteThreshold = 0.1f;

// Applies the evaluated sample of a pending candidate. Returns true when the ray is finished.
INR_HD bool resolveCandidate(const FrameConstants& fc, const TrackingMedium& medium,
                             const RayStateView& rs, int i, std::uint8_t& flags, RngStream& rng) {
  flags &= std::uint8_t(~kRayPending);
  const bool valid = !(flags & kRayBadSample);
  flags &= std::uint8_t(~kRayBadSample);
  // An invalid network output is treated as empty space (a null collision).
  const Vec4f c = valid ? lookupTransferFunction(medium.tf, rs.sample[i]) : Vec4f{0.f, 0.f, 0.f, 0.f};
  const float sigma = opacityToExtinction(c.w, medium.tf.invUnitDistance);
  rs.sample[i] = NAN;
  if (flags & kRayShadow) {
    if (fc.shadowEstimator == ShadowEstimator::Ratio) {
      // collisionProduct holds the majorant here.
      float v = rs.visibility[i] * maxf(0.f, 1.f - sigma / rs.collisionProduct[i]);
      if (v < kRouletteThreshold) {
        const float survive = 0.5f;
        v = rng.next() < survive ? v / survive : 0.f;
      }
      rs.visibility[i] = v;
      return v <= 0.f;
    }
    if (rs.collisionProduct[i] < sigma) {  // real collision: the light is blocked
      rs.visibility[i] = 0.f;
      return true;
    }
    return false;
  }
  if (rs.collisionProduct[i] < sigma) {  // real collision: emission-absorption estimate
    rs.radiance[i] = Vec4f{c.x, c.y, c.z, 1.f};
    flags |= kRayHit;
    return true;
  }
  return false;  // null collision: keep tracking from the candidate position
}

// One traversal pass for ray i (paper §4.1.3 with DDA instead of OptiX, skipping empty blocks).
INR_HD void traverseRay(const FrameConstants& fc, const TrackingMedium& medium,
                        const RayStateView& rs, int i) {
  std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayActive)) return;
  RngStream rng{std::uint32_t(i), fc.frame, fc.seed, rs.rngCounter[i]};

  bool finished = false;
  if (flags & kRayPending) finished = resolveCandidate(fc, medium, rs, i, flags, rng);

  if (!finished) {
    const Vec3f o = rs.origin[i], d = rs.direction[i];
    const float tEnd = rs.tEnd[i];
    float t = rs.t[i];
    Int3 cell = rs.cell[i];
    Vec3f tNext = rs.tNext[i];
    for (;;) {
      const float m = majorantAt(medium.grid, cell);
      if (!(m > 0.f) && inEmptyBlock(medium.grid, cell)) {
        // Empty-space skipping: the whole block is empty, so walking it cell by cell would draw
        // nothing; jump to the next non-empty block, where that walk would enter it (same
        // cell, crossings and t).
        if (!ddaSkipEmptyBlocks(medium.grid, o, d, tEnd, cell, tNext, t)) {
          finished = true;
          break;
        }
        continue;
      }
      const float cellExit = minf(ddaCellExit(tNext), tEnd);
      if (m > 0.f) {
        const float tCandidate = t + freeFlightDistance(m, rng.next());
        if (tCandidate < cellExit) {
          // Candidate collision: persist the DDA state and hand the point to the evaluator.
          rs.t[i] = tCandidate;
          rs.cell[i] = cell;
          rs.tNext[i] = tNext;
          const bool ratio = (flags & kRayShadow) && fc.shadowEstimator == ShadowEstimator::Ratio;
          rs.collisionProduct[i] = ratio ? m : rng.next() * m;
          rs.sample[i] = NAN;
          flags |= kRayPending;
          break;
        }
      }
      // No collision in this cell: exponential flights are memoryless, so restarting the
      // sampling at the cell boundary with the next cell's majorant is exact.
      if (cellExit >= tEnd || !ddaStep(medium.grid, o, d, cell, tNext)) {
        finished = true;  // left the segment: primary ray escaped / shadow ray reached light
        break;
      }
      t = cellExit;
    }
  }
  if (finished) flags &= std::uint8_t(~kRayActive);
  rs.flags[i] = flags;
  rs.rngCounter[i] = rng.counter;
}

// World-space query of ray i's pending candidate.
INR_HD void pendingQueryPoint(const RayStateView& rs, int i, float& x, float& y, float& z) {
  const Vec3f p = rs.origin[i] + rs.direction[i] * rs.t[i];
  x = p.x;
  y = p.y;
  z = p.z;
}

}  // namespace inr
