#pragma once
// The isosurface and slice blend modes' per-ray logic (ParaView's Volume Blend Mode Isosurface and
// Slice), written once as INR_HD code for every backend; a backend only batches the queries
// (Render/SurfaceRenderer.cpp on the CPU). Both are exact in one frame: no random numbers but the
// optional sub-pixel jitter of later frames (anti-aliasing by accumulation).
//
// Slice: each pixel's ray meets the plane (origin, normal) once; inside the clip box (the model's
// box, cropped) and before the opaque geometry, the network is evaluated there (one query per
// pixel) and coloured by the transfer function as VTK's GPU ray caster colours its SLICE_BLEND:
// colour(v) premultiplied by the scalar opacity table's alpha(v) (or opaque, SliceOptions), lit
// with the network's gradient when shading is on.
//
// Isosurface: the ray walks the macrocell grid (Traverse.h's DdaWalker over a mask whose
// "majorant" is 1 where a cell's value range [min, max] holds some isovalue and 0 elsewhere, so
// the walker's empty-block skipping applies) and samples only candidate cells, at equal steps of
// at most `step` with both ends of every candidate run included, so no part of a candidate cell
// goes unsampled. A crossing of isovalue c between two neighbouring samples (their sides of c,
// v >= c, differ; of several isovalues crossed, the one nearest the first sample, which a
// monotone field crosses first) is bracketed and refined by R-section (the bracket cut into
// R + 1 equal parts per iteration, R = refinePoints, or fewer parts when fewer reach the
// tolerance; the first part whose ends differ in side is kept) until it is at most `tolerance`
// long; the hit is then the secant point inside
// the bracket, so it lies within `tolerance` (along the ray) of a crossing. The hit's colour and
// opacity are the transfer function's colour map and scalar opacity at c (VTK's isosurface
// blend); with shading on it is lit (Shading.h) from the network's gradient at the hit, one
// gradient query. Several surfaces along a ray composite front to back; after a hit the rest of
// the march interval (the bracket's far end to the march sample that closed it) is checked for
// another isovalue's crossing, and the march goes on from that sample, its next samples evaluated
// with the bracket's last refinement round (so a hit costs its refinement rounds and no march
// iteration of its own); it stops when the remaining transmittance is at most
// opaqueTransmittance, at the clip box's exit or at the opaque geometry's depth.
//
// What can be missed: a crossing pair (in and out of a surface) between two samples, i.e. a
// feature thinner than the step; and a cell whose lattice-sampled value range (MacrocellGrid)
// misses an isovalue its interior reaches (the renderer pads the ranges for that).
#include <cmath>
#include <cstdint>

#include "Common/HostDevice.h"
#include "Render/CameraView.h"
#include "Render/CounterRng.h"
#include "Render/MajorantGrid.h"
#include "Render/RayState.h"
#include "Render/RenderMath.h"
#include "Render/Shading.h"
#include "Render/TransferFunctionTable.h"
#include "Render/Traverse.h"

namespace inr {

// The most march samples a ray hands the evaluator per iteration (the backend stores them).
constexpr int kMaxSurfaceSamples = 32;
// The most refinement points per round (computed where they are used, never stored): at 999 a
// bracket one step long reaches the default tolerance (step / 1000) in one round.
constexpr int kMaxSurfaceRefinePoints = 1024;

// ---- Camera rays shared by both modes --------------------------------------------------------

// Pixel i's model-space ray for `frame`: the pixel centre in frame 0 (the one-frame image) and
// without jitter; a jittered position drawn from the pixel's counter-based stream in later
// frames. Returns the model distance per world distance along the ray (CameraView.h).
INR_HD float surfacePixelRay(const CameraView& cam, int i, std::uint32_t key, std::uint32_t frame, std::uint32_t seed,
                             int jitter, Vec3f& o, Vec3f& d) {
  float jx = 0.5f, jy = 0.5f;
  if (jitter && frame > 0u) {
    RngStream rng{key, frame, seed, 0u};
    jx = rng.next();
    jy = rng.next();
  }
  cameraRayWorld(cam, i % cam.width, i / cam.width, jx, jy, o, d);
  return worldRayToModel(cam, o, d);
}

// ---- Slice -----------------------------------------------------------------------------------

struct SliceConstants {
  CameraView camera;
  Box3f clipBox;               // the model's box, cropped (model space)
  Vec3f origin, normal;        // the plane in model space (normal of any non-zero length)
  TransferFunctionView tf;
  int opaque = 0;              // 1: alpha 1 where the plane is hit; 0: the TF's scalar opacity (VTK)
  float time = 0.f;
  int shade = 0;               // light with the gradient (Shading.h)
  ShadingConstants shading;
  float ambient = 0.2f;
  Vec3f toLight{0.f, 0.f, 1.f};  // unit, model space
  const float* depthLimit = nullptr;  // per pixel world distance to opaque geometry, or null
  std::uint32_t frame = 0, seed = 0;
  int jitter = 0;
  int windowX = 0, windowY = 0, fullWidth = 0;  // RenderSettings::window (keys the jitter)
};

INR_HD std::uint32_t surfacePixelKey(int i, int width, int windowX, int windowY, int fullWidth) {
  return fullWidth == 0 ? std::uint32_t(i)
                        : std::uint32_t(i / width + windowY) * std::uint32_t(fullWidth) + std::uint32_t(i % width + windowX);
}

// Where pixel i's ray meets the plane inside the clip box and in front of the opaque geometry:
// false when it does not (parallel ray, hit outside the box, behind the eye or the geometry).
INR_HD bool slicePixelPoint(const SliceConstants& sc, int i, Vec3f& p) {
  Vec3f o, d;
  const std::uint32_t key = surfacePixelKey(i, sc.camera.width, sc.windowX, sc.windowY, sc.fullWidth);
  const float modelPerWorld = surfacePixelRay(sc.camera, i, key, sc.frame, sc.seed, sc.jitter, o, d);
  const float denom = dot(sc.normal, d);
  if (!(fabsf(denom) > 1e-12f * length(sc.normal))) return false;
  const float t = dot(sc.origin - o, sc.normal) / denom;
  float tEnter, tExit;
  if (!intersectBox(sc.clipBox, o, d, tEnter, tExit)) return false;
  if (!(t >= tEnter && t <= tExit)) return false;
  if (sc.depthLimit && !(t < sc.depthLimit[i] * modelPerWorld)) return false;
  p = o + d * t;
  return true;
}

// The premultiplied colour of the slice at p with network value v and gradient g (read only with
// shading); a non-finite value is empty (as in the other modes).
INR_HD Vec4f sliceColour(const SliceConstants& sc, Vec3f p, float v, Vec3f g) {
  if (!isFiniteValue(v)) return Vec4f{0.f, 0.f, 0.f, 0.f};
  const Vec4f c = lookupTransferFunction(sc.tf, v);
  Vec3f colour{c.x, c.y, c.z};
  if (sc.shade) colour = litColour(colour, sc.ambient, sampleLightAt(sc.camera, sc.shading, sc.toLight, p, g), 1.f);
  const float a = sc.opaque ? 1.f : clampf(c.w, 0.f, 1.f);
  return Vec4f{colour.x * a, colour.y * a, colour.z * a, a};
}

// ---- Isosurface ------------------------------------------------------------------------------

struct SurfaceConstants {
  CameraView camera;
  Box3f clipBox;            // the model's box, cropped (model space)
  MajorantGridView cells;   // candidate mask: "majorant" > 0 where a cell may hold an isovalue
  TransferFunctionView tf;
  const float* isovalues = nullptr;
  int isoCount = 0;
  float step = 0.f;         // longest distance between march samples (model units)
  float tolerance = 0.f;    // a hit's bracket is at most this long (model units)
  int samplesPerIteration = 8;  // K: march samples per ray per batch
  int maxMarchSamples = kMaxSurfaceSamples;  // march samples per ray per batch at most (surfaceMarchSamples)
  int refinePoints = 8;     // R: a bracket's points per refinement round at most (surfaceRefineCount)
  int maxRefinements = 24;  // R-section rounds per hit at most (float resolution can stall one)
  float opaqueTransmittance = 1e-3f;  // stop once the remaining transmittance is at most this
  float time = 0.f;
  int shade = 0;
  ShadingConstants shading;
  float ambient = 0.2f;
  Vec3f toLight{0.f, 0.f, 1.f};
  const float* depthLimit = nullptr;
  std::uint32_t frame = 0, seed = 0;
  int jitter = 0;
  int windowX = 0, windowY = 0, fullWidth = 0;
};

enum SurfacePhase : int {
  kSurfaceDone = 0,    // finished (left the clip box, opaque, or missed)
  kSurfaceMarch = 1,   // sampling candidate cells
  kSurfaceRefine = 2,  // narrowing a bracket [ta, tb]
};

// One ray's state between batches (the backend keeps an array of these).
struct SurfaceRay {
  Vec3f o, d;                 // model space, unit direction
  float tEnd = 0.f;           // clip box exit or the opaque geometry's depth
  float modelPerWorld = 1.f;
  Int3 cell;                  // DdaWalker state
  Vec3f tNext;
  float walkT = 0.f;          // where the walk stands: the end of the current segment
  float s0 = 0.f, s1 = 0.f;   // current candidate segment
  int segN = 0;               // its intervals (0: none yet, -1: the walk has ended)
  int segJ = 0;               // next sample index in it (0..segN)
  int adjacent = 0;           // a segment starting at walkT continues from the last sample
  float tPrev = 0.f, vPrev = 0.f;
  int prevValid = 0;
  float ta = 0.f, tb = 0.f, fa = 0.f, fb = 0.f;  // bracket (values at its ends)
  // The march sample that closed the bracket's march interval, and its value: the march goes on
  // from there after the hit (the walk stands there while the bracket is refined).
  float tOuter = 0.f, fOuter = 0.f;
  int iso = -1;               // the isovalue being refined
  int refinements = 0;
  float hitT = 0.f;
  // A hit composited without its colour yet: it waits for its gradient (shading), which the
  // backend evaluates at hitT in the same iteration (surfaceShadeHit adds w x lit colour).
  int pendingShade = 0, pendingIso = -1;
  float pendingW = 0.f;
  int phase = kSurfaceDone;
  float r = 0.f, g = 0.f, b = 0.f, T = 1.f;  // front-to-back composite (premultiplied)
  float firstHitWorld = INFINITY;           // world distance to the first hit that took colour
};

// The walker's view of a SurfaceRay (DdaWalker reads and stores through a RayStateView).
INR_HD RayStateView surfaceWalkerView(SurfaceRay& r) {
  RayStateView v;
  v.count = 1;
  v.origin = &r.o;
  v.direction = &r.d;
  v.cell = &r.cell;
  v.tNext = &r.tNext;
  return v;
}

// Puts the walk at ray parameter t: the next candidate segment is looked up from the cell
// holding t (adjacent: t is the last sample, not sampled again unless a gap follows).
INR_HD void surfaceWalkAt(const SurfaceConstants& sc, SurfaceRay& r, float t, bool adjacent) {
  ddaStart(sc.cells, r.o, r.d, t, r.cell, r.tNext);
  r.walkT = t;
  r.segN = 0;
  r.segJ = 0;
  r.adjacent = adjacent ? 1 : 0;
}

// Pixel i's ray: clipped to the clip box and the opaque geometry; done at once when nothing is left.
INR_HD void surfaceInitRay(const SurfaceConstants& sc, int i, SurfaceRay& r) {
  r = SurfaceRay{};
  const std::uint32_t key = surfacePixelKey(i, sc.camera.width, sc.windowX, sc.windowY, sc.fullWidth);
  r.modelPerWorld = surfacePixelRay(sc.camera, i, key, sc.frame, sc.seed, sc.jitter, r.o, r.d);
  r.phase = kSurfaceDone;
  float tEnter, tExit;
  if (sc.isoCount <= 0 || !intersectBox(sc.clipBox, r.o, r.d, tEnter, tExit)) return;
  if (sc.depthLimit) tExit = minf(tExit, sc.depthLimit[i] * r.modelPerWorld);
  if (!(tEnter < tExit)) return;
  r.tEnd = tExit;
  surfaceWalkAt(sc, r, tEnter, false);
  r.phase = kSurfaceMarch;
}

// Moves to the next candidate segment after walkT; false when the walk has ended.
INR_HD bool surfaceNextSegment(const SurfaceConstants& sc, SurfaceRay& r) {
  if (r.segN < 0) return false;
  RayStateView view = surfaceWalkerView(r);
  DdaWalker walker(sc.cells, view, 0);
  float t = r.walkT;
  bool gap = false;
  if (r.segN > 0 && !walker.advance(r.walkT, r.tEnd)) {  // past the segment just sampled
    r.segN = -1;
    return false;
  }
  float segmentEnd = t;
  for (;;) {
    float m;
    const float before = t;
    if (!walker.segment(r.tEnd, t, m, segmentEnd)) {
      r.segN = -1;
      return false;
    }
    if (t != before) gap = true;  // jumped over empty blocks
    if (m > 0.f && segmentEnd > t) break;
    if (!(m > 0.f)) gap = true;   // a cell that cannot hold an isovalue: not sampled
    if (!walker.advance(segmentEnd, r.tEnd)) {
      r.segN = -1;
      return false;
    }
    t = segmentEnd;
  }
  walker.store(view, 0);
  const bool continues = r.adjacent && !gap;
  r.s0 = t;
  r.s1 = segmentEnd;
  r.walkT = segmentEnd;
  const int n = int(ceilf((segmentEnd - t) / sc.step));
  r.segN = n < 1 ? 1 : n;
  r.segJ = continues ? 1 : 0;  // the segment's start is the last sample when it continues
  r.adjacent = 1;              // (true for the next segment once this one is sampled to its end)
  return true;
}

// March: up to marchSamples sample parameters into ts; breaks[k] = 1 when sample k does not
// follow the previous sample without a gap (no crossing is looked for between them). Returns the
// count; 0 means the ray has nothing left to sample. The samples' positions do not depend on
// marchSamples (a ray's march is the same however it is cut into batches), only the batches do.
INR_HD int surfaceEmitMarch(const SurfaceConstants& sc, SurfaceRay& r, float* ts, std::uint8_t* breaks,
                            int marchSamples) {
  int n = 0;
  while (n < marchSamples) {
    if (r.segN == 0 || r.segJ > r.segN) {
      if (!surfaceNextSegment(sc, r)) break;
    }
    const int j = r.segJ++;
    ts[n] = j == r.segN ? r.s1 : r.s0 + (r.s1 - r.s0) * (float(j) / float(r.segN));
    breaks[n] = j == 0 ? 1 : 0;
    ++n;
  }
  return n;
}

// Refinement: the points of this round, cutting the bracket into equal parts: R of them (R + 1
// parts), or the fewest whose parts are at most `tolerance` long when those are fewer (the last
// round of a hit asks only what it needs).
INR_HD int surfaceRefineCount(const SurfaceConstants& sc, const SurfaceRay& r) {
  const float length = r.tb - r.ta;
  const int R = sc.refinePoints;
  if (!(length <= sc.tolerance * float(R + 1))) return R;
  const int parts = int(ceilf(length / sc.tolerance));
  return parts - 1 < 1 ? 1 : (parts - 1 > R ? R : parts - 1);
}

// Point j of the n points of a refinement round over the bracket [ta, tb].
INR_HD float surfaceRefineT(float ta, float tb, int j, int n) {
  return ta + (tb - ta) * (float(j + 1) / float(n + 1));
}

// Whether a round of `points` refinement points ends the bracket (its parts reach the tolerance,
// or it is the last round allowed).
INR_HD bool surfaceRefineIsLast(const SurfaceConstants& sc, const SurfaceRay& r, int points) {
  return r.refinements + 1 >= sc.maxRefinements || !((r.tb - r.ta) / float(points + 1) > sc.tolerance);
}

// How many of the samples a ray asked for this iteration are refinement points (the first ones;
// 0 while it marches). Computed once per ray for surfaceSampleT.
INR_HD int surfaceRefinePointsAsked(const SurfaceConstants& sc, const SurfaceRay& r) {
  return r.phase == kSurfaceRefine ? surfaceRefineCount(sc, r) : 0;
}

// Sample j of those a ray asked for this iteration, the first `refinePoints` of them refinement
// points (surfaceRefinePointsAsked; computed from the bracket, never stored), the rest march
// samples (ts[j - refinePoints], as surfaceEmit wrote them).
INR_HD float surfaceSampleT(const SurfaceRay& r, const float* ts, int j, int refinePoints) {
  return j < refinePoints ? surfaceRefineT(r.ta, r.tb, j, refinePoints) : ts[j - refinePoints];
}

// What a ray asks of the evaluator this iteration: marchSamples march samples (in
// [1, kMaxSurfaceSamples]; surfaceMarchSamples says how many; into ts and breaks, which hold
// marchSamples entries) or its refinement points (surfaceRefineCount; nothing written: see
// surfaceSampleT), followed in a bracket's last round by up to marchSamples march samples past
// tOuter, where the march goes on after the hit: so the march after a hit costs no iteration of
// its own (the samples are dropped if the round does not end the bracket after all, or a
// crossing lies between the hit and tOuter). 0 when it has finished (phase kSurfaceDone).
INR_HD int surfaceEmit(const SurfaceConstants& sc, SurfaceRay& r, float* ts, std::uint8_t* breaks, int marchSamples) {
  if (r.phase == kSurfaceRefine) {
    const int points = surfaceRefineCount(sc, r);
    return surfaceRefineIsLast(sc, r, points) ? points + surfaceEmitMarch(sc, r, ts, breaks, marchSamples) : points;
  }
  if (r.phase != kSurfaceMarch) return 0;
  const int n = surfaceEmitMarch(sc, r, ts, breaks, marchSamples);
  if (n == 0) r.phase = kSurfaceDone;
  return n;
}

// March samples per ray for an iteration with `active` of `slots` rays still marching: K while
// most rays march, growing as rays finish so that a batch keeps about slots x K points, up to
// maxMarchSamples. Why: a frame's last iterations carry a few long rays (grazing a surface,
// crossing many candidate cells); at K samples each they cost as many launches and host round
// trips as the first, full iterations. The image does not depend on it (surfaceEmitMarch).
INR_HD int surfaceMarchSamples(int K, int maxMarchSamples, long slots, long active) {
  const int cap = maxMarchSamples > K ? maxMarchSamples : K;
  if (active <= 0) return cap;
  const long grown = slots * long(K) / active;
  return grown >= cap ? cap : (grown > K ? int(grown) : K);
}

INR_HD bool surfaceSide(float v, float iso) { return v >= iso; }

// Of the isovalues whose side differs between values a and b, the one nearest a (the first a
// monotone field crosses going from a to b); -1 when none is crossed or a value is not finite.
INR_HD int surfaceCrossedIsovalue(const SurfaceConstants& sc, float a, float b) {
  if (!isFiniteValue(a) || !isFiniteValue(b)) return -1;
  int best = -1;
  float bestDistance = INFINITY;
  for (int k = 0; k < sc.isoCount; ++k) {
    const float c = sc.isovalues[k];
    if (surfaceSide(a, c) == surfaceSide(b, c)) continue;
    const float distance = fabsf(c - a);
    if (distance < bestDistance) {
      bestDistance = distance;
      best = k;
    }
  }
  return best;
}

INR_HD Vec3f surfacePoint(const SurfaceRay& r, float t) { return r.o + r.d * t; }

// The secant point of the bracket for its isovalue (the midpoint where the values are equal).
INR_HD float surfaceSecant(const SurfaceConstants& sc, const SurfaceRay& r) {
  const float c = sc.isovalues[r.iso];
  const float df = r.fb - r.fa;
  const float w = df != 0.f ? clampf((c - r.fa) / df, 0.f, 1.f) : 0.5f;
  return r.ta + (r.tb - r.ta) * w;
}

// A bracket from ta to tb for isovalue iso, refined from the next iteration on (a bracket already
// within the tolerance still takes one round of one point: that round carries the march samples
// past tOuter, so it costs no extra iteration).
INR_HD void surfaceStartBracket(SurfaceRay& r, float ta, float fa, float tb, float fb, int iso) {
  r.ta = ta;
  r.fa = fa;
  r.tb = tb;
  r.fb = fb;
  r.iso = iso;
  r.refinements = 0;
  r.phase = kSurfaceRefine;
}

// A bracket short enough: the hit is its secant point, composited with the TF's colour and opacity
// at its isovalue (VTK's isosurface blend). Lit hits wait for their gradient (pendingShade: the
// backend evaluates it and calls surfaceShadeHit in the same iteration); their opacity is known,
// so the march goes on at once: the ray finishes when opaque, else refines a crossing between the
// bracket's far end and tOuter if there is one, else marches on from tOuter.
INR_HD void surfaceBracketDone(const SurfaceConstants& sc, SurfaceRay& r) {
  r.hitT = surfaceSecant(sc, r);
  const Vec4f c = lookupTransferFunction(sc.tf, sc.isovalues[r.iso]);
  const float alpha = clampf(c.w, 0.f, 1.f);
  if (alpha > 0.f) {
    const float w = r.T * alpha;
    if (sc.shade) {
      r.pendingShade = 1;
      r.pendingIso = r.iso;
      r.pendingW = w;
    } else {
      r.r += w * c.x;
      r.g += w * c.y;
      r.b += w * c.z;
    }
    r.T *= 1.f - alpha;
    if (!(r.firstHitWorld < INFINITY)) r.firstHitWorld = r.hitT / r.modelPerWorld;
  }
  if (r.T <= sc.opaqueTransmittance) {
    r.phase = kSurfaceDone;
    return;
  }
  // [tb, tOuter]: both ends on the far side of this isovalue, maybe not of another one.
  const int next = r.tb < r.tOuter ? surfaceCrossedIsovalue(sc, r.fb, r.fOuter) : -1;
  if (next >= 0) {
    surfaceStartBracket(r, r.tb, r.fb, r.tOuter, r.fOuter, next);
    surfaceWalkAt(sc, r, r.tOuter, true);  // any march samples emitted past tOuter are dropped
    return;
  }
  r.tPrev = r.tOuter;
  r.vPrev = r.fOuter;
  r.prevValid = 1;
  r.phase = kSurfaceMarch;
}

// The colour of a hit that waited for its gradient g at hitT: lit, weighted as it was composited.
INR_HD void surfaceShadeHit(const SurfaceConstants& sc, SurfaceRay& r, Vec3f g) {
  if (!r.pendingShade) return;
  const Vec4f c = lookupTransferFunction(sc.tf, sc.isovalues[r.pendingIso]);
  const Vec3f colour = litColour(Vec3f{c.x, c.y, c.z}, sc.ambient,
                                 sampleLightAt(sc.camera, sc.shading, sc.toLight, surfacePoint(r, r.hitT), g), 1.f);
  r.r += r.pendingW * colour.x;
  r.g += r.pendingW * colour.y;
  r.b += r.pendingW * colour.z;
  r.pendingShade = 0;
}

// Marching: the n march samples' values; a crossing starts a bracket (the samples after it are
// dropped: the march resumes from it, where the walk is put back).
INR_HD void surfaceConsumeMarch(const SurfaceConstants& sc, SurfaceRay& r, const float* ts, const std::uint8_t* breaks,
                                const float* values, int n) {
  for (int k = 0; k < n; ++k) {
    const float v = values[k];
    if (!breaks[k] && r.prevValid) {
      const int iso = surfaceCrossedIsovalue(sc, r.vPrev, v);
      if (iso >= 0) {
        r.tOuter = ts[k];
        r.fOuter = v;
        surfaceStartBracket(r, r.tPrev, r.vPrev, ts[k], v, iso);
        surfaceWalkAt(sc, r, ts[k], true);
        return;
      }
    }
    r.tPrev = ts[k];
    r.vPrev = v;
    r.prevValid = isFiniteValue(v) ? 1 : 0;
  }
}

// Takes the values of the n samples surfaceEmit asked for (ts, breaks as it wrote them).
INR_HD void surfaceConsume(const SurfaceConstants& sc, SurfaceRay& r, const float* ts, const std::uint8_t* breaks,
                           const float* values, int n) {
  if (r.phase == kSurfaceRefine) {
    // The first part of the bracket whose ends lie on different sides of the isovalue.
    const int points = surfaceRefineCount(sc, r);
    const float c = sc.isovalues[r.iso];
    float ta = r.ta, fa = r.fa, tb = r.tb, fb = r.fb;
    for (int j = 0; j < points; ++j) {
      const float v = values[j];
      if (!isFiniteValue(v)) continue;  // no side: look on
      const float t = surfaceRefineT(r.ta, r.tb, j, points);
      if (surfaceSide(v, c) != surfaceSide(fa, c)) {
        tb = t;
        fb = v;
        break;
      }
      ta = t;
      fa = v;
    }
    r.ta = ta;
    r.fa = fa;
    r.tb = tb;
    r.fb = fb;
    r.refinements += 1;
    if (r.tb - r.ta > sc.tolerance && r.refinements < sc.maxRefinements) {
      if (n > points) surfaceWalkAt(sc, r, r.tOuter, true);  // not the last round after all
      return;
    }
    surfaceBracketDone(sc, r);
    if (r.phase == kSurfaceMarch) surfaceConsumeMarch(sc, r, ts, breaks, values + points, n - points);
    return;
  }
  if (r.phase == kSurfaceMarch) surfaceConsumeMarch(sc, r, ts, breaks, values, n);
}

// The ray's premultiplied RGBA (alpha = 1 - transmittance).
INR_HD Vec4f surfaceEstimate(const SurfaceRay& r) { return Vec4f{r.r, r.g, r.b, 1.f - r.T}; }

}  // namespace inr
