#pragma once
// Persistent per-ray state (the paper's TraversalState) and the per-frame constants every stage
// reads. Struct-of-arrays: each stage touches only the fields it needs (the evaluation scatter
// writes `sample` only, finalisation reads `radiance`/`visibility`/`flags` only), and on the
// GPU consecutive lanes then read consecutive words. Host objects own the arrays; the stages see
// plain pointers through RayStateView, so the same INR_HD stage functions run on CPU and GPU.
//
// Ray i is the ray of pixel i (row-major, row 0 at the top); budgeting schemes that skip pixels
// simply leave a pixel's ray inactive.
#include <cstdint>

#include "Render/Budgeting.h"
#include "Render/CameraView.h"
#include "Render/MajorantGrid.h"
#include "Render/Pruning.h"
#include "Render/RenderMath.h"
#include "Render/Shading.h"
#include "Render/TransferFunctionTable.h"

namespace inr {

enum RayFlag : std::uint8_t {
  kRayActive = 1u << 0,     // still traversing (primary or shadow)
  kRayPending = 1u << 1,    // a candidate collision waits for its INR query
  kRayHit = 1u << 2,        // the primary ray had a real collision (radiance holds its colour)
  kRayShadow = 1u << 3,     // the ray is currently a shadow ray towards the light
  kRayBadSample = 1u << 4,  // the evaluator returned NaN/Inf for the pending query
  kRayCapped = 1u << 5,     // cut off by the per-frame work cap (FrameConstants::maxRngDraws)
  kRayBudgetSkipped = 1u << 6,  // ray budgeting left the pixel out this frame: no ray, accumulation kept
  kRayEntered = 1u << 7,        // the primary ray entered the volume (its segment was not empty)
};

// The primary (camera-ray) estimator of the emission-absorption integral.
enum class PrimaryEstimator : int {
  Delta = 0,  // the paper's delta tracking, collision estimator: one binary event per ray
  Ratio = 1,  // ratio-tracking emission weights at every tentative collision (RatioTracking.h)
  March = 2,  // unbiased ray marching: comb emission, residual ratio-tracked transmittance (UnbiasedMarch.h)
  // Unbiased ray marching with a pre-integrated control: the network linear between comb points,
  // the transfer function integrated exactly over that, residual points correct the rest
  // (PreintegratedMarch.h)
  Preintegrated = 3,
  // A ray march made unbiased by random refinement: each comb interval is marched at a random
  // number of halvings of the comb step and the levels are combined so that the expectation is
  // the limit of ever finer marches (DebiasedMarch.h)
  Debiased = 4,
};

enum class ShadowEstimator : int {
  Delta = 0,  // binary visibility: stop at the first real collision (fewest queries)
  Ratio = 1,  // transmittance product over all tentative collisions (less noise, more queries)
};

// The persistent per-ray fields, declared once: X(type, name) per field. Everything else is
// generated from this list — the view the stages read (RayStateView), the host and device
// storage (RayStateArrays in Render/RayStateArrays.h) and its resize — so adding a field is one
// line here (plus the stage code that uses it).
//   origin, direction  ray origin and unit direction: ray parameters are world distances
//   t                  current position (candidate collision while pending)
//   tEnd               end of the segment: box exit, depth limit or light exit
//   rngCounter         draw index of the ray's counter-based stream
//   sample             scalar returned by the evaluator for the pending query; NaN while pending
//   opacityScale       the gradient term at the pending query (gradientTermAt: the gradient
//                      opacity factor, or |grad f| for a 2D transfer function), written with
//                      `sample`; only written and read when the TF uses the gradient (usesGradient)
//   collisionProduct   delta tracking: xi * majorant, drawn when the candidate is emitted, so the
//                      acceptance test after evaluation is `collisionProduct < sigma(sample)` and
//                      neither xi nor the majorant has to be stored; ratio-tracked shadow rays
//                      store the majorant itself; ratio / march primary rays the sum of their
//                      emission weights' magnitudes
//   cell, tNext        DDA: current majorant cell, ray parameter of the next crossing per axis
//   radiance           frame result: premultiplied colour of the primary collision (rgb) and
//                      coverage (w = 1 on a real collision, 0 when the ray escaped)
//   visibility         visibility towards the light
//   pruned             candidates answered by homogeneity pruning this frame (Pruning.h), both legs
//   pointCount         ratio tracking (RatioTracking.h): the ray's points waiting for the evaluator
//   hitT               ratio tracking: ray parameter of the emission point picked for the shadow ray
//                      and the reprojection hit point (reservoir over the emission weights)
//   combNext, residualNext  march and preintegrated: the next comb and residual points of the
//                      current macrocell segment (NaN: draw them afresh at the next segment)
//   lastExtinction     march: the control extinction (at the last comb point)
//   combPhase          march, preintegrated: fraction of a comb interval to the next comb point, carried from
//                      one macrocell segment to the next (NaN: the ray has not started its comb)
//   controlKnown       march: the ray has drawn a comb point (its control is known)
//   lastCombValue      preintegrated: the network's value at the ray's last resolved comb point
//                      (NaN: none yet, or a non-finite value)
//   combInCell         preintegrated: that comb point lies in the macrocell the ray is in
//   marchLevel, marchStep  debiased: the current comb interval's level (halvings of the comb step)
//                      and the index of the ray's next point in it (1 .. 2^level; 2^level: the
//                      interval's closing comb point)
//   leftKnown, leftScale  debiased: the ray has resolved a comb point (its value in lastCombValue)
//                      and that point's gradient opacity factor
//   hitWeight          ratio / march with one picked emission point (shadows or shading): its
//                      weight's sign while tracking, then the signed weight the picked colour
//                      carries in the frame estimate; 1 for delta tracking (Shading.h applies it)
#define INR_RAY_STATE_FIELDS(X) \
  X(Vec3f, origin)              \
  X(Vec3f, direction)           \
  X(float, t)                   \
  X(float, tEnd)                \
  X(std::uint32_t, rngCounter)  \
  X(std::uint8_t, flags)        \
  X(float, sample)              \
  X(float, opacityScale)        \
  X(float, collisionProduct)    \
  X(Int3, cell)                 \
  X(Vec3f, tNext)               \
  X(Vec4f, radiance)            \
  X(float, visibility)          \
  X(std::uint32_t, pruned)       \
  X(std::uint8_t, pointCount)    \
  X(float, hitT)                 \
  X(float, combNext)             \
  X(float, residualNext)         \
  X(float, lastExtinction)       \
  X(float, combPhase)            \
  X(std::uint8_t, controlKnown)  \
  X(float, lastCombValue)        \
  X(std::uint8_t, combInCell)    \
  X(std::uint8_t, marchLevel)    \
  X(std::uint8_t, marchStep)     \
  X(std::uint8_t, leftKnown)     \
  X(float, leftScale)            \
  X(float, hitWeight)

// The per-pixel fields that outlive a frame (the accumulation: VisRTX's frame-owned state),
// declared the same way; resetPixel (Finalize.h) gives their values after a reset.
//   accum        running mean of premultiplied RGBA (alpha = coverage)
//   sampleCount  frames accumulated into the pixel
//   residual     r_i of the last frame that rendered the pixel
//   halfMean     running mean of the displayed colour (RGB, over the background) of the pixel's
//                frames in the accumulation's second half (frameHalf, CounterRng.h), and their
//                count (w); the first half's follow from accum and sampleCount. The two halves'
//                difference gives the error of the mean (Finalize.h, pixelConvergence)
//   skip         histogram budgeting's countdown (paper Eq. 6): frames still to skip; -1 = the
//                pixel was rendered last, decide at the next initialisation
//   hitPoint     mean world position of the pixel's real collisions (reprojection after camera
//                moves); meaningful while accum.w > 0
#define INR_PIXEL_STATE_FIELDS(X) \
  X(Vec4f, accum)                 \
  X(std::uint32_t, sampleCount)   \
  X(float, residual)              \
  X(Vec4f, halfMean)              \
  X(std::int32_t, skip)           \
  X(Vec3f, hitPoint)

#define INR_DECLARE_VIEW_FIELD(type, name) type* name = nullptr;
struct RayStateView {
  int count = 0;
  INR_RAY_STATE_FIELDS(INR_DECLARE_VIEW_FIELD)
};

struct AccumulationView {
  int count = 0;
  INR_PIXEL_STATE_FIELDS(INR_DECLARE_VIEW_FIELD)
};
#undef INR_DECLARE_VIEW_FIELD

// Everything the stages read that is constant for one frame.
struct FrameConstants {
  CameraView camera;
  Box3f box;                          // the model's box (model space: CameraView.h)
  Box3f primaryBox;                   // where primary rays are clipped: box, or this rank's brick
  const float* depthLimit = nullptr;  // per pixel world ray distance to opaque geometry, or null
  float time = 0.f;                   // world time of every query
  std::uint32_t frame = 0, seed = 0;  // RNG key (with the pixel index)
  int pixelJitter = 1;                // jitter the sub-pixel position (antialiasing): 0 off, 1 random,
                                      // 2 stratified over frames (RayInit.h)
  int jitterControl = 0;              // the jitter's control variate in the finalize stage (Finalize.h,
                                      // jitterControlled; TrackingOptions::jitterControlFrames)
  int shadows = 0;
  float ambient = 0.2f;               // unlit share of the colour (shadows and shading, Shading.h)
  Vec3f toLight{0.f, 0.f, 1.f};       // unit model-space vector towards the (directional) light
  Vec3f background{0.f, 0.f, 0.f};
  ShadowEstimator shadowEstimator = ShadowEstimator::Delta;
  ShadingConstants shading;           // gradient shading (Shading.h); ambient above is its ambient
  // Primary estimator and ratio tracking's knobs (TrackingOptions; RatioTracking.h).
  PrimaryEstimator estimator = PrimaryEstimator::Delta;
  float majorantScale = 1.f;       // ratio: points at this x the cell majorant; march: comb density
  float residualScale = 1.f;       // march: residual points at this x the cell majorant
  float combMinimumDensity = 0.f;  // preintegrated, debiased: comb points per unit length at least (model space)
  float combFloorDepth = 0.f;      // > 0: the floor applies only up to majorant / combFloorDepth (combDensity)
  float rouletteThreshold = 0.05f; // Russian roulette below this transmittance estimate
  // debiased (DebiasedMarch.h): a comb interval is refined at least k + 1 times with probability
  // levelRatio^(k+1) given k, at most maxLevel times
  float levelRatio = 0.3f;
  int maxLevel = 5;
  int pointsPerIteration = 1;      // tentative collisions a ray hands the evaluator per iteration
  // Bounded work: a ray whose random stream reaches this many draws in a frame stops tracking
  // (kRayCapped; it counts as escaped). Every candidate collision takes two draws, so this caps
  // the null collisions a pathological majorant (a tiny opacity unit distance) can cost.
  std::uint32_t maxRngDraws = 0xffffffffu;
  BudgetConstants budget;             // which pixels get a ray this frame (Budgeting.h)
  // The image's place in the full picture (RenderSettings::window): pixel (px, py) is
  // (px + windowX, py + windowY) of a fullWidth-wide picture, which keys its random stream and
  // its blue-noise value.
  int windowX = 0, windowY = 0, fullWidth = 0;
  // The same as arithmetic on the pixel index i (pixelStreamKey): key = i + keyBase +
  // row * keyRowStride, row = (i * rowMagic) >> 42 = i / width without a division (rowMagic =
  // floor(2^42 / width) + 1, exact while pixels * width < 2^42); all 0 for a whole picture.
  std::uint64_t rowMagic = 0;
  std::uint32_t keyBase = 0, keyRowStride = 0;
  // RenderSettings::pixelShare: this image traces the pixels with (x + y) mod shareCount =
  // shareIndex of the full picture (shareCount 1: all).
  int shareIndex = 0, shareCount = 1;
};

// Position of pixel i in the full picture, and its random-stream key (the full picture's pixel
// index), so a tile's pixels draw what the same pixels of the whole picture draw.
INR_HD void picturePixel(const FrameConstants& fc, int i, int& px, int& py) {
  px = i % fc.camera.width + fc.windowX;
  py = i / fc.camera.width + fc.windowY;
}
// Without a division: the traversal kernels call this, and one cost them registers (spills).
INR_HD std::uint32_t pixelStreamKey(const FrameConstants& fc, int i) {
  const std::uint32_t row = std::uint32_t((std::uint64_t(std::uint32_t(i)) * fc.rowMagic) >> 42);
  return std::uint32_t(i) + fc.keyBase + row * fc.keyRowStride;
}

// What traversal tracks against: the majorant grid and the transfer function. Ghost passes swap
// in their own pair over the same macrocell bounds.
struct TrackingMedium {
  MajorantGridView grid;
  TransferFunctionView tf;
  PruneView prune;  // homogeneity pruning (off in ghost passes)
};

}  // namespace inr
