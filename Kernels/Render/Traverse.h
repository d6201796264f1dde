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
  const Vec4f c = valid ? sampleColourOpacity(medium.tf, rs.sample[i], rs.opacityScale, i) : Vec4f{0.f, 0.f, 0.f, 0.f};
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

// Delta tracking inside a segment of constant majorant m > 0 (a macrocell, or whatever a
// traversal hands out), in two steps any traversal (the DDA below, a ray-tracing-core traversal)
// calls: draw the free flight from t; if the candidate collision lands before the segment's end,
// save the traversal's own state and emit the candidate as the ray's pending query.
INR_HD float candidateDistance(RngStream& rng, float m, float t) { return t + freeFlightDistance(m, rng.next()); }

INR_HD void emitCandidate(const FrameConstants& fc, const RayStateView& rs, int i, std::uint8_t& flags,
                          RngStream& rng, float m, float tCandidate) {
  rs.t[i] = tCandidate;
  const bool ratio = (flags & kRayShadow) && fc.shadowEstimator == ShadowEstimator::Ratio;
  rs.collisionProduct[i] = ratio ? m : rng.next() * m;
  rs.sample[i] = NAN;
  flags |= kRayPending;
}

// What delta tracking inside one segment of constant majorant found.
enum class SegmentOutcome { Passed, Candidate, Capped };

// Delta tracking inside one segment [t, segmentEnd) of constant majorant m: the per-segment step
// every traversal runs, the DDA (trackSegments below) and the OptiX intersection program
// (Render/Cuda/OptixPrograms.cu) alike. Empty segments (m <= 0, NaN) draw nothing; the
// per-frame draw budget is checked before the draw (bounded work); a free flight that ends
// before segmentEnd is a candidate collision at tCandidate. No collision in the segment:
// exponential flights are memoryless, so the next segment restarts from its own entry.
INR_HD SegmentOutcome trackInSegment(const FrameConstants& fc, RngStream& rng, float m, float t, float segmentEnd,
                                     float& tCandidate) {
  if (!(m > 0.f)) return SegmentOutcome::Passed;
  if (rng.counter >= fc.maxRngDraws) return SegmentOutcome::Capped;  // (no draw: images unchanged below)
  tCandidate = candidateDistance(rng, m, t);
  return tCandidate < segmentEnd ? SegmentOutcome::Candidate : SegmentOutcome::Passed;
}

// The DDA as a walker over the majorant grid: hands out one segment (cell) after another, front
// to back, jumping over empty blocks (empty-space skipping). Its resumable state is the ray's
// cell and crossings (RayStateView::cell, tNext).
struct DdaWalker {
  // A copy, not a reference: on the GPU the view is a kernel parameter, and a stored reference
  // to it would force the parameter block into local memory.
  MajorantGridView grid;
  Vec3f origin, direction;
  Int3 cell;
  Vec3f tNext;

  INR_HD DdaWalker(const MajorantGridView& g, const RayStateView& rs, int i)
      : grid(g), origin(rs.origin[i]), direction(rs.direction[i]), cell(rs.cell[i]), tNext(rs.tNext[i]) {}
  INR_HD void store(const RayStateView& rs, int i) const {
    rs.cell[i] = cell;
    rs.tNext[i] = tNext;
  }
  // Linear index of the current segment's macrocell (what per-cell data such as pruning's
  // bounds and expected scalars is indexed by).
  INR_HD int cellIndex() const { return linearCellIndex(grid.dims, cell); }
  // The current segment from t: its majorant and end (clipped to tEnd). Over empty blocks it
  // first moves to the next non-empty one (updating t where the cell walk would enter it).
  // Returns false when the ray leaves its segment first.
  INR_HD bool segment(float tEnd, float& t, float& majorant, float& segmentEnd) {
    for (;;) {
      majorant = majorantAt(grid, cell);
      if (majorant > 0.f || !inEmptyBlock(grid, cell)) break;
      // The whole block is empty, so walking it cell by cell would draw nothing; jump to the
      // next non-empty block, where that walk would enter it (same cell, crossings and t).
      if (!ddaSkipEmptyBlocks(grid, origin, direction, tEnd, cell, tNext, t)) return false;
    }
    segmentEnd = minf(ddaCellExit(tNext), tEnd);
    return true;
  }
  // Steps past the segment ending at segmentEnd; false when that was the last one.
  INR_HD bool advance(float segmentEnd, float tEnd) {
    return !(segmentEnd >= tEnd) && ddaStep(grid, origin, direction, cell, tNext);
  }
};

// Delta tracking from t to tEnd over the segments of `walker`: returns true when a candidate
// was emitted (the walker's state is stored for resuming), false when the ray left its segment.
// A walker that is not a segment walker (the OptiX GAS walker) supplies its own non-template
// overload, which traverseRayWith picks up by argument-dependent lookup.
template <typename Walker>
INR_HD bool trackSegments(const FrameConstants& fc, const RayStateView& rs, int i, std::uint8_t& flags,
                          RngStream& rng, Walker& walker, float t, float tEnd) {
  for (;;) {
    float m, segmentEnd;
    if (!walker.segment(tEnd, t, m, segmentEnd)) return false;
    float tCandidate;
    const SegmentOutcome outcome = trackInSegment(fc, rng, m, t, segmentEnd, tCandidate);
    if (outcome == SegmentOutcome::Capped) {  // bounded work per frame
      flags |= kRayCapped;
      return false;
    }
    if (outcome == SegmentOutcome::Candidate) {
      walker.store(rs, i);  // before the next draw: fewer live registers on the GPU
      emitCandidate(fc, rs, i, flags, rng, m, tCandidate);
      return true;
    }
    if (!walker.advance(segmentEnd, tEnd)) return false;
    t = segmentEnd;
  }
}

// Homogeneity pruning (Render/Pruning.h) of the candidate just emitted in linear cell `cell`:
// when the decision says prune, the candidate is answered with the cell's expected scalar
// (rs.sample, as if the evaluation had returned it; the ray stays pending for resolveCandidate)
// and counted, and true is returned; false sends it to the evaluator. A non-finite estimate is
// never substituted.
INR_HD bool answerPruned(const PruneView& prune, int cell, const RayStateView& rs, int i, RngStream& rng) {
  if (!prunes(prune, cell, rng)) return false;
  const float s = prune.expected[cell];
  if (!isFiniteValue(s)) return false;
  rs.sample[i] = s;
  rs.pruned[i] += 1u;
  return true;
}

// An empty asm that "redefines" the ray index, so nvcc cannot hoist the addresses derived from
// it (rs.origin + i, ...) out of traverseRayWith's pruning loop: hoisted, they would stay live
// through the DDA's inner loop and push ddaTraverseKernel past its register bound (ptxas -v,
// sm_90: 28 / 104 bytes of spill stores / loads hoisted, 10 / 20 with the barrier, 10 / 16
// before pruning existed). Emits no instruction. Left out where INR_NO_REGISTER_BARRIERS is
// defined: the OptiX programs (Render/Cuda/OptixPrograms.cu), whose OptiX-IR OptiX compiles
// itself and whose register allocation this trick was never measured for.
INR_HD void opaqueRayIndex(int& i) {
#if defined(__CUDA_ARCH__) && !defined(INR_NO_REGISTER_BARRIERS)
  asm volatile("" : "+r"(i));
#else
  (void)i;
#endif
}

// One traversal pass for ray i (paper §4.1.3) with any walker constructible from (grid, rays,
// ray) that exposes cellIndex(): resolve the pending candidate, then track to the next candidate
// or the end of the ray's segment. A pruned candidate is resolved here at once and tracking goes
// on from it (null collision) or the ray finishes (real collision, blocked shadow ray); only
// candidates that need the network leave the ray pending. The walker is rebuilt from the ray
// state after each pruned candidate rather than kept live across resolveCandidate: pruning stays
// a loop back-edge. kPruning = false compiles the pass without the loop (one candidate at most):
// with the loop present but never taken, nvcc still allocated for it, and the GPU traversal
// took twice as long (Benchmarks/RESULTS.md has the figures).
template <typename Walker, bool kPruning = true>
INR_HD void traverseRayWith(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs, int i) {
  std::uint8_t flags = rs.flags[i];
  if (!(flags & kRayActive)) return;
  RngStream rng{pixelStreamKey(fc, i), fc.frame, fc.seed, rs.rngCounter[i]};

  bool finished = false;
  bool resolve = (flags & kRayPending) != 0;
  for (;;) {
    if (kPruning) opaqueRayIndex(i);
    if (resolve && (finished = resolveCandidate(fc, medium, rs, i, flags, rng))) break;
    Walker walker(medium.grid, rs, i);
    if (!trackSegments(fc, rs, i, flags, rng, walker, rs.t[i], rs.tEnd[i])) {
      finished = true;
      break;
    }
    if (!kPruning) break;  // the candidate is pending for the evaluator
    resolve = answerPruned(medium.prune, walker.cellIndex(), rs, i, rng);
    if (!resolve) break;  // a query for the evaluator is pending
  }
  if (finished) flags &= std::uint8_t(~kRayActive);  // primary ray escaped / shadow ray reached light
  rs.flags[i] = flags;
  rs.rngCounter[i] = rng.counter;
}

// The DDA traversal over the majorant grid; pruning only when the medium has expected scalars.
template <bool kPruning>
INR_HD void traverseDdaRay(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs, int i) {
  traverseRayWith<DdaWalker, kPruning>(fc, medium, rs, i);
}
INR_HD void traverseRay(const FrameConstants& fc, const TrackingMedium& medium, const RayStateView& rs, int i) {
  if (medium.prune.expected)
    traverseDdaRay<true>(fc, medium, rs, i);
  else
    traverseDdaRay<false>(fc, medium, rs, i);
}

}  // namespace inr
