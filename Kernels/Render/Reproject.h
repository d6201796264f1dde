#pragma once
// Reprojection of the accumulation after a camera move (paper §4.2.1, "Residual reprojection"):
// instead of restarting from nothing, each pixel of the old view that saw the volume moves its
// accumulated colour, residual, variance and mean hit point to where that hit point lands in
// the new view. Forward splatting with a depth test, in two passes that any backend runs over
// the pixels (INR_HD, CPU loops or GPU threads):
//   1. scatter (per old pixel j that saw the volume's box): project its representative point
//      (reprojectionPoint: the mean hit, or mid-box for a pixel that never hit) into the new camera and offer
//      j to the 2 x 2 new pixels around the projected position, keeping per new pixel the
//      minimum of a 64-bit key = (depth bucket, distance to the pixel centre, j). The minimum
//      does not depend on the order the offers arrive in (atomicMin on the GPU), so both
//      backends pick the same source. Depth buckets are 1% apart: within a bucket the closer
//      pixel centre wins (sharper), across buckets the nearer surface wins (occlusion).
//   2. gather (per new pixel i): resample the old accumulation (the history) bilinearly where
//      the winner's hit point lies in the old view, capping the frame count at `maxHistory` so
//      new samples soon outweigh what reprojection blurred (the pixel keeps the sources' blended
//      per-frame variance, written back into its halves' means); the residual is the largest of
//      the sources'. New pixels nobody offered to (disoccluded, or outside the box before)
//      restart with residual 1: every budgeting scheme renders them first.
// The approximation is the paper's: it degrades under large rotations, and mean hit points of
// translucent pixels are only representative depths.
#include <cstdint>

#include "Render/CameraView.h"
#include "Render/Finalize.h"

namespace inr {

constexpr std::uint64_t kNoReprojection = ~std::uint64_t(0);

// World depth along the view direction of model point p (hit points are model coordinates).
INR_HD float viewDepth(const CameraView& cam, const Vec3f& p) {
  return dot(modelToWorld(cam, p) - cam.position, cam.forward);
}

// Continuous image position (pixel centres at +0.5) and world depth along the view direction of
// model point p in `cam`; false when p is behind the camera or not finite.
INR_HD bool projectToImage(const CameraView& cam, const Vec3f& p, float& fx, float& fy, float& depth) {
  const Vec3f v = modelToWorld(cam, p) - cam.position;
  depth = dot(v, cam.forward);
  float sx = dot(v, cam.right), sy = dot(v, cam.up);
  if (!cam.parallel) {
    if (!(depth > 0.f)) return false;
    sx /= depth;
    sy /= depth;
  }
  // Inverse of cameraRayWorld: sx = (cx + 2 fx / W - 1) h a, sy = (cy + 1 - 2 fy / H) h.
  fx = (sx / (cam.halfHeight * cam.aspect) - cam.centerX + 1.f) * 0.5f * float(cam.width);
  fy = (1.f + cam.centerY - sy / cam.halfHeight) * 0.5f * float(cam.height);
  return fx == fx && fy == fy && depth == depth && fabsf(fx) < 1e9f && fabsf(fy) < 1e9f;
}

// The splat key of old pixel j offered to the new pixel centred at (cx, cy).
INR_HD std::uint64_t reprojectionKey(float depth, float fx, float fy, float cx, float cy, int j) {
  // Depth bucket: log(depth) in steps of 1% (parallel views may have depth <= 0: shift them).
  const float d = depth > 1e-20f ? depth : 1e-20f;
  const int bucket = clampi(int(floorf(logf(d) * 100.5f)) + 0x8000, 0, 0xffff);
  const float dx = fx - cx, dy = fy - cy;
  const int dist = clampi(int((dx * dx + dy * dy) * 127.f), 0, 0xff);  // <= 2 for a 2x2 splat
  return (std::uint64_t(bucket) << 40) | (std::uint64_t(dist) << 32) | std::uint64_t(std::uint32_t(j));
}

// Representative (model-space) point of old pixel j: the mean of its real collisions, or, for a pixel
// whose rays crossed the volume without a collision in any frame, the middle of its centre ray's
// segment in the box (its history, "empty here", is as valid as a hit's; resetting such pixels
// left the faint parts of a volume speckled with single samples after every move). False when
// the pixel has nothing accumulated or never reached the box.
INR_HD bool reprojectionPoint(const CameraView& oldView, const Box3f& box, const AccumulationView& history, int j,
                              Vec3f& p, bool& hit) {
  if (history.sampleCount[j] == 0u) return false;
  hit = history.accum[j].w > 0.f;
  if (hit) {
    p = history.hitPoint[j];
    return true;
  }
  Vec3f o, d;
  cameraRay(oldView, j % oldView.width, j / oldView.width, 0.5f, 0.5f, o, d);
  float tEnter, tExit;
  if (!intersectBox(box, o, d, tEnter, tExit) || !(tExit > 0.f)) return false;
  p = o + d * (0.5f * (maxf(tEnter, 0.f) + tExit));
  return true;
}

// Pass 1 for old pixel j: calls offer(newPixel, key) for each new pixel it may fill. Empty
// pixels offer themselves behind every hit (the last depth bucket): a surface that moves over
// them wins.
template <typename Offer>
INR_HD void reprojectionOffers(const CameraView& oldView, const CameraView& newView, const Box3f& box,
                               const AccumulationView& history, int j, Offer&& offer) {
  Vec3f p;
  bool hit;
  if (!reprojectionPoint(oldView, box, history, j, p, hit)) return;
  float fx, fy, depth;
  if (!projectToImage(newView, p, fx, fy, depth)) return;
  const int x0 = int(floorf(fx - 0.5f)), y0 = int(floorf(fy - 0.5f));
  for (int y = y0; y <= y0 + 1; ++y) {
    if (y < 0 || y >= newView.height) continue;
    for (int x = x0; x <= x0 + 1; ++x) {
      if (x < 0 || x >= newView.width) continue;
      std::uint64_t key = reprojectionKey(depth, fx, fy, float(x) + 0.5f, float(y) + 0.5f, j);
      if (!hit) key |= std::uint64_t(0xffff) << 40;
      offer(y * newView.width + x, key);
    }
  }
}

// What old pixel o adds, with weight w, to a new pixel's blended per-frame variance, its second
// half's direction from the mean and that half's share of the frames (reprojectionGather).
INR_HD void addHalves(const AccumulationView& history, int o, const Vec3f& background, float w, float& variance,
                      Vec3f& halfOffset, float& halfShare) {
  const std::uint32_t n = history.sampleCount[o];
  if (n == 0u) return;
  const Vec4f h = history.halfMean[o];
  const float meanVariance = pixelConvergence(history, o, background).meanVariance;
  if (meanVariance < INFINITY) variance += w * meanVariance * float(n);  // else unknown yet: as none
  if (h.w > 0.f) {
    const Vec3f m = overBackground(history.accum[o], background);
    halfOffset = Vec3f{halfOffset.x + w * (h.x - m.x), halfOffset.y + w * (h.y - m.y), halfOffset.z + w * (h.z - m.z)};
  }
  halfShare += w * h.w / float(n);
}

// The second half's mean for a reprojected pixel of `kept` frames whose blended colour is `accum`
// and whose frames have the per-frame variance `variance`: the kept frames split between the
// halves by `share`, and the second half's mean lies off the mean, in the blended direction
// `offset` (grey where that is zero), as far as makes the pixel's estimate (pixelConvergence)
// variance / kept. With M the mean and B the second half's, A - B = n (M - B) / n_A, so that
// estimate is |M - B|^2 / 3 * n_B / n_A.
INR_HD Vec4f reprojectedHalfMean(const Vec4f& accum, std::uint32_t kept, float variance, const Vec3f& offset,
                                 float share, const Vec3f& background) {
  const Vec3f m = overBackground(accum, background);
  const float n = float(kept), nB = minf(floorf(n * share + 0.5f), n), nA = n - nB;
  if (!(nA >= 1.f && nB >= 1.f)) return Vec4f{m.x, m.y, m.z, nB};
  const float wanted = 3.f * (variance / n) * nA / nB;  // |M - B|^2
  const float length2 = offset.x * offset.x + offset.y * offset.y + offset.z * offset.z;
  const Vec3f d = length2 > 0.f ? offset : Vec3f{1.f, 1.f, 1.f};
  const float scale = sqrtf(wanted / (length2 > 0.f ? length2 : 3.f));
  return Vec4f{m.x + d.x * scale, m.y + d.y * scale, m.z + d.z * scale, nB};
}

// Pass 2 for new pixel i with the minimum key it was offered: the winner's hit point is the
// pixel's representative (model-space) point; its motion between the views gives where pixel i was in
// the old image, and the old accumulation is resampled there bilinearly (nearest-pixel copies would misplace every pixel
// by up to half a pixel, which edges show). Old neighbours whose hit point lies at a clearly
// different depth (another surface: occlusion) are left out; old background neighbours are
// kept (empty is a valid value of the image).
INR_HD void reprojectionGather(const CameraView& oldView, const CameraView& newView, const Box3f& box,
                               const AccumulationView& history, const AccumulationView& acc, int i, std::uint64_t key,
                               std::uint32_t maxHistory, const Vec3f& background) {
  if (key == kNoReprojection) {
    resetPixel(acc, i);
    return;
  }
  const int j = int(std::uint32_t(key & 0xffffffffu));
  Vec3f p;
  bool hit;
  if (!reprojectionPoint(oldView, box, history, j, p, hit)) {  // cannot happen: j offered itself
    resetPixel(acc, i);
    return;
  }
  float ox, oy, depth, nx, ny, newDepth;
  float x0f = 0.f, y0f = 0.f;
  int x0 = j % oldView.width, y0 = j / oldView.width;
  const int newWidth = oldView.width;
  bool bilinear = projectToImage(oldView, p, ox, oy, depth) && projectToImage(newView, p, nx, ny, newDepth);
  if (bilinear) {
    // The winner's motion vector, applied at this pixel's centre: where the pixel was in the old
    // image. (Not the hit point's own old position: a mean hit point need not lie at its pixel's
    // centre, e.g. at edges, and resampling there would blur.)
    ox = float(i % newWidth) + 0.5f - (nx - ox);
    oy = float(i / newWidth) + 0.5f - (ny - oy);
    x0 = int(floorf(ox - 0.5f));
    y0 = int(floorf(oy - 0.5f));
    x0f = ox - 0.5f - float(x0);
    y0f = oy - 0.5f - float(y0);
  }
  Vec4f sum{0.f, 0.f, 0.f, 0.f};
  // Besides the colour, the sources' per-frame variance (their displayed mean's variance times
  // their frame count, Finalize.h) is blended, as is the direction of their second half's mean
  // from their mean and that half's share of the frames. Blending the halves' means themselves
  // would average the neighbours' independent errors away and make the estimate optimistic.
  Vec3f halfOffset{0.f, 0.f, 0.f};
  float weight = 0.f, variance = 0.f, halfShare = 0.f, residual = 0.f;
  std::uint32_t fewest = 0xffffffffu;
  for (int k = 0; k < (bilinear ? 4 : 1); ++k) {
    const int x = bilinear ? x0 + (k & 1) : x0, y = bilinear ? y0 + (k >> 1) : y0;
    if (x < 0 || y < 0 || x >= oldView.width || y >= oldView.height) continue;
    const int o = y * oldView.width + x;
    const std::uint32_t n = history.sampleCount[o];
    if (n == 0u) continue;
    const float w = bilinear ? ((k & 1) ? x0f : 1.f - x0f) * ((k >> 1) ? y0f : 1.f - y0f) : 1.f;
    if (!(w > 0.f)) continue;
    if (bilinear && history.accum[o].w > 0.f) {
      const float d = viewDepth(oldView, history.hitPoint[o]);
      if (fabsf(d - depth) > 0.1f * fabsf(depth)) continue;  // another surface
    }
    const Vec4f c = history.accum[o];
    sum = Vec4f{sum.x + w * c.x, sum.y + w * c.y, sum.z + w * c.z, sum.w + w * c.w};
    weight += w;
    addHalves(history, o, background, w, variance, halfOffset, halfShare);
    residual = maxf(residual, history.residual[o]);
    fewest = n < fewest ? n : fewest;
  }
  if (!(weight > 0.f)) {  // nothing consistent around it: the winner alone
    sum = history.accum[j];
    weight = 1.f;
    const std::uint32_t n = history.sampleCount[j];
    variance = halfShare = 0.f;
    halfOffset = Vec3f{0.f, 0.f, 0.f};
    addHalves(history, j, background, 1.f, variance, halfOffset, halfShare);
    residual = history.residual[j];
    fewest = n;
  }
  const float inv = 1.f / weight;
  const std::uint32_t cap = maxHistory > 0u ? maxHistory : 1u;
  const std::uint32_t kept = fewest < cap ? fewest : cap;
  acc.accum[i] = Vec4f{sum.x * inv, sum.y * inv, sum.z * inv, sum.w * inv};
  acc.sampleCount[i] = kept;
  acc.residual[i] = residual;
  acc.halfMean[i] = reprojectedHalfMean(acc.accum[i], kept, variance * inv, halfOffset,
                                        halfShare * inv, background);
  acc.skip[i] = -1;
  acc.hitPoint[i] = hit ? p : history.hitPoint[j];
}

}  // namespace inr
