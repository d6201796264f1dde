#include "Render/SurfaceRenderer.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "Common/Stopwatch.h"
#include "Render/AccumulationImage.h"
#include "Render/CpuParallel.h"
#include "Render/RayMarch.h"
#include "Render/SurfaceMarch.h"

namespace inr {

BlendMode parseBlendMode(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
  if (n == "composite") return BlendMode::Composite;
  if (n == "isosurface") return BlendMode::Isosurface;
  if (n == "slice") return BlendMode::Slice;
  throw std::invalid_argument("unknown blend mode '" + name + "' (choose composite, isosurface or slice)");
}

const char* blendModeName(BlendMode mode) {
  switch (mode) {
    case BlendMode::Composite: return "composite";
    case BlendMode::Isosurface: return "isosurface";
    case BlendMode::Slice: return "slice";
  }
  return "?";
}

namespace {
bool finite3(const std::array<double, 3>& a) { return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]); }
bool finiteBox(const Box3f& b) {
  return isFiniteValue(b.lo.x) && isFiniteValue(b.lo.y) && isFiniteValue(b.lo.z) && isFiniteValue(b.hi.x) &&
         isFiniteValue(b.hi.y) && isFiniteValue(b.hi.z);
}
Box3f intersectBoxes(const Box3f& a, const Box3f& b) {
  return Box3f{{std::max(a.lo.x, b.lo.x), std::max(a.lo.y, b.lo.y), std::max(a.lo.z, b.lo.z)},
               {std::min(a.hi.x, b.hi.x), std::min(a.hi.y, b.hi.y), std::min(a.hi.z, b.hi.z)}};
}
}  // namespace

void BlendScene::validate() const {
  if (mode == BlendMode::Isosurface) {
    if (isovalues.empty()) throw std::invalid_argument("IsosurfaceValues: the isosurface blend mode needs at least one isovalue");
    if (int(isovalues.size()) > kMaxIsovalues)
      throw std::invalid_argument("IsosurfaceValues: at most " + std::to_string(kMaxIsovalues) + " isovalues, got " +
                                  std::to_string(isovalues.size()));
    for (double v : isovalues)
      if (!std::isfinite(v)) throw std::invalid_argument("IsosurfaceValues: every isovalue must be finite");
  }
  if (mode == BlendMode::Slice) {
    if (!finite3(sliceOrigin)) throw std::invalid_argument("Slice: the plane's origin must be finite");
    if (!finite3(sliceNormal) || !(std::hypot(sliceNormal[0], sliceNormal[1], sliceNormal[2]) > 0.0))
      throw std::invalid_argument("Slice: the plane's normal must be finite and non-zero");
  }
  if (crop) {
    if (!finiteBox(cropBox)) throw std::invalid_argument("Cropping: the crop box must be finite");
    if (!(cropBox.lo.x <= cropBox.hi.x && cropBox.lo.y <= cropBox.hi.y && cropBox.lo.z <= cropBox.hi.z))
      throw std::invalid_argument("Cropping: the crop box needs min <= max on every axis");
  }
}

Box3f paraviewCroppingBox(const Box3f& bounds, const std::array<double, 3>& origin, const std::array<double, 3>& scale) {
  Box3f out;
  for (int a = 0; a < 3; ++a) {
    const double p0 = origin[a] + double(component(bounds.lo, a)) * scale[a];
    const double p1 = origin[a] + double(component(bounds.hi, a)) * scale[a];
    setComponent(out.lo, a, float(std::min(p0, p1)));
    setComponent(out.hi, a, float(std::max(p0, p1)));
  }
  return out;
}

void SurfaceOptions::validate() const {
  if (!(stepFraction > 0.f && stepFraction <= 1.f)) throw std::invalid_argument("surface stepFraction must be in (0, 1]");
  if (!(toleranceFraction > 0.f && toleranceFraction <= 1.f))
    throw std::invalid_argument("surface toleranceFraction must be in (0, 1]");
  if (samplesPerIteration < 1 || samplesPerIteration > kMaxSurfaceSamples)
    throw std::invalid_argument("surface samplesPerIteration must be in [1, " + std::to_string(kMaxSurfaceSamples) + "]");
  if (maxMarchSamples != 0 && (maxMarchSamples < samplesPerIteration || maxMarchSamples > kMaxSurfaceSamples))
    throw std::invalid_argument("surface maxMarchSamples must be 0 (the backend's choice) or in [samplesPerIteration, " +
                                std::to_string(kMaxSurfaceSamples) + "], got " + std::to_string(maxMarchSamples));
  if (refinePoints < 0 || refinePoints > kMaxSurfaceRefinePoints)
    throw std::invalid_argument("surface refinePoints must be 0 (the backend's choice) or in [1, " +
                                std::to_string(kMaxSurfaceRefinePoints) + "], got " + std::to_string(refinePoints));
  if (maxRefinements < 1) throw std::invalid_argument("surface maxRefinements must be >= 1");
  if (!(opaqueTransmittance >= 0.f && opaqueTransmittance < 1.f))
    throw std::invalid_argument("surface opaqueTransmittance must be in [0, 1)");
  if (chunkPixels < 1) throw std::invalid_argument("surface chunkPixels must be >= 1");
}

SurfaceRenderer::SurfaceRenderer(const FieldEvaluator& evaluator, const Box3f& box, double timeBegin, double timeEnd,
                                 SurfaceOptions options)
    : evaluator_(evaluator), box_(box), timeBegin_(timeBegin), timeEnd_(timeEnd), options_(options) {
  options_.validate();
  options_.macrocells.lazySlices = true;  // built when an isosurface scene first needs a time
  const MacrocellLayout layout = MacrocellLayout::make(box, timeBegin, timeEnd, options_.macrocells);  // validates
  step_ = options_.stepFraction * std::min(layout.cellSize.x, std::min(layout.cellSize.y, layout.cellSize.z));
  tolerance_ = options_.toleranceFraction * step_;
  accum_.assign(std::size_t(settings_.width) * settings_.height, Vec4f{0, 0, 0, 0});
  depth_.assign(accum_.size(), INFINITY);
}

SurfaceRenderer::~SurfaceRenderer() = default;

void SurfaceRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  validateImageWindow(settings.window, settings.width, settings.height);
  if (settings.clipToBrick || settings.pixelShare.count > 1 || settings.sampleShare.count > 1)
    throw std::invalid_argument("the isosurface and slice blend modes render the whole picture: no bricks, pixel or sample shares");
  settings_ = settings;
  accum_.assign(std::size_t(settings_.width) * settings_.height, Vec4f{0, 0, 0, 0});
  depth_.assign(accum_.size(), INFINITY);
  if (haveScene_ && !scene_.depthLimit.empty() && scene_.depthLimit.size() != accum_.size()) scene_.depthLimit.clear();
  resetAccumulation();
}

void SurfaceRenderer::setScene(const RenderScene& scene, const BlendScene& blend) {
  if (blend.mode == BlendMode::Composite)
    throw std::invalid_argument("BlendMode: the surface renderer draws Isosurface and Slice; Composite is the volume renderer's");
  blend.validate();
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels)
    throw std::invalid_argument("depth limit must have one value per pixel");
  scene.camera.view(settings_.width, settings_.height);  // validates
  validateLighting(scene);
  if (scene.shadows)
    throw std::invalid_argument(std::string("shadows: the ") + blendModeName(blend.mode) +
                                " blend mode draws no shadows (turn them off)");
  if (scene.shading.enabled && !evaluator_.providesGradient())
    throw std::invalid_argument("shading: the evaluator " + evaluator_.name() + " computes no gradients");
  const bool timeChanged = !haveScene_ || scene.time != scene_.time;
  auto table = std::make_unique<TransferFunctionTable>(scene.transferFunction);
  // The isovalues the TF shows (opacity > 0 there): a transparent surface adds nothing to the
  // picture, so its cells need no sampling (a TF edit can change the mask, not the macrocells).
  std::vector<float> visible;
  for (double v : blend.isovalues)
    if (lookupTransferFunction(table->view(), float(v)).w > 0.f) visible.push_back(float(v));
  const bool isoChanged = !haveScene_ || visible != isovalues_;
  scene_ = scene;
  blend_ = blend;
  tfTable_ = std::move(table);
  isovalues_ = std::move(visible);
  if (timeChanged || isoChanged) candidatesValid_ = false;
  haveScene_ = true;
  if (blend_.mode == BlendMode::Isosurface && !candidatesValid_) {
    const auto t0 = Clock::now();
    updateCandidates();
    pendingUpdateMs_ += msSince(t0);
  }
  resetAccumulation();
}

bool SurfaceRenderer::macrocellsBuiltFor(double time) const {
  if (!grid_) return false;
  int k0 = 0, k1 = 0;
  float w = 0.f;
  grid_->interpolationWeights(time, k0, k1, w);
  return grid_->sliceBuilt(k0) && (w == 0.f || grid_->sliceBuilt(k1));
}

MacrocellGrid& SurfaceRenderer::candidateGrid() {
  if (!grid_) grid_ = std::make_unique<MacrocellGrid>(evaluator_, box_, timeBegin_, timeEnd_, options_.macrocells);
  return *grid_;
}

void SurfaceRenderer::buildMacrocellsFor(double time) { candidateGrid().buildSlicesFor(time); }

void SurfaceRenderer::updateCandidates() {
  candidateGrid().setTime(scene_.time);
  const std::vector<float>& mn = grid_->workingMin();
  const std::vector<float>& mx = grid_->workingMax();
  candidates_.cell.assign(mn.size(), 0.f);
  for (std::size_t c = 0; c < mn.size(); ++c) {
    bool candidate = !options_.skipCells;
    for (float iso : isovalues_) candidate = candidate || (mn[c] <= iso && iso <= mx[c]);
    candidates_.cell[c] = candidate ? 1.f : 0.f;
  }
  const int shift = grid_->blockShift();
  if (shift >= 0) {
    candidates_.block.assign(std::size_t(grid_->blockCount()), 0.f);
    computeBlockMajorants(grid_->dims(), shift, candidates_.cell.data(), candidates_.block.data());
  } else {
    candidates_.block.clear();
  }
  candidatesValid_ = true;
}

void SurfaceRenderer::resetAccumulation() {
  std::fill(accum_.begin(), accum_.end(), Vec4f{0, 0, 0, 0});
  std::fill(depth_.begin(), depth_.end(), INFINITY);
  frameIndex_ = 0;
  partNext_ = 0;  // a frame in progress is dropped with the accumulation it was adding to
  isoChunkN_ = 0;
}

FrameStats SurfaceRenderer::renderFrame() {
  FrameStats st;
  renderFramePart(std::numeric_limits<double>::infinity(), &st);
  return st;
}

bool SurfaceRenderer::renderFramePart(double budgetMs, FrameStats* stats) {
  if (!haveScene_) throw std::logic_error("renderFrame: setScene first");
  const auto start = Clock::now();
  const int n = settings_.width * settings_.height;
  if (!framePartStarted()) {
    partStats_ = FrameStats{};
    partStats_.method = blend_.mode == BlendMode::Slice ? "slice" : "isosurface";
    partStats_.frame = frameIndex_;
    partStats_.pixels = std::size_t(n);
    partWallMs_ = 0.0;
  }
  if (blend_.mode == BlendMode::Slice)
    renderSliceChunks(start, budgetMs);
  else
    renderIsosurfaceChunks(start, budgetMs);
  partWallMs_ += msSince(start);
  if (partNext_ < n) return false;
  partNext_ = 0;
  FrameStats st = partStats_;
  st.updateMs = pendingUpdateMs_;
  st.closeTiming(pendingUpdateMs_, partWallMs_);
  pendingUpdateMs_ = 0.0;
  ++frameIndex_;
  if (stats) *stats = st;
  return true;
}

double SurfaceRenderer::frameProgress() const {
  const double n = double(settings_.width) * double(settings_.height);
  return n > 0.0 ? double(partNext_) / n : 0.0;
}

namespace {

// The constants both modes share, from the frame constants every renderer builds.
template <typename Constants>
void fillCommon(Constants& k, const FrameConstants& fc, const Box3f& clipBox, const TransferFunctionView& tf,
                const RenderScene& scene, const RenderSettings& settings, std::uint32_t frame) {
  k.camera = fc.camera;
  k.clipBox = clipBox;
  k.tf = tf;
  k.time = fc.time;
  k.shade = scene.shading.enabled ? 1 : 0;
  k.shading = fc.shading;
  k.ambient = fc.ambient;
  k.toLight = fc.toLight;
  k.depthLimit = fc.depthLimit;
  k.frame = frame;
  k.seed = settings.seed;
  k.jitter = settings.pixelJitter ? 1 : 0;
  k.windowX = fc.windowX;
  k.windowY = fc.windowY;
  k.fullWidth = settings.window.fullWidth == 0 ? 0 : fc.fullWidth;
}

}  // namespace

SliceConstants SurfaceRenderer::sliceConstants() const {
  const CameraView cam = scene_.camera.view(settings_.width, settings_.height);
  const FrameConstants fc = makeFrameConstants(cam, box_, scene_, settings_,
                                               scene_.depthLimit.empty() ? nullptr : scene_.depthLimit.data(),
                                               std::uint32_t(frameIndex_));
  SliceConstants sc;
  const Box3f clip = blend_.crop ? intersectBoxes(box_, blend_.cropBox) : box_;
  fillCommon(sc, fc, clip, tfTable_->view(), scene_, settings_, std::uint32_t(frameIndex_));
  sc.opaque = blend_.sliceOpaque ? 1 : 0;
  // The plane in model space: the origin mapped as a point, the normal as a covector (the
  // transposed world-from-model map: a plane n.(x - o) = 0 in world is (A^T n).(p - p_o) = 0).
  Vec3f origin = toVec3(blend_.sliceOrigin), normal = toVec3(blend_.sliceNormal);
  if (cam.transformed) {
    origin = applyPoint(cam.modelFromWorld, origin);
    const Affine3f& a = cam.worldFromModel;
    normal = a.row0 * normal.x + a.row1 * normal.y + a.row2 * normal.z;
  }
  sc.origin = origin;
  sc.normal = normal;
  return sc;
}

void SurfaceRenderer::renderSliceChunks(Clock::time_point start, double budgetMs) {
  FrameStats& st = partStats_;
  const SliceConstants sc = sliceConstants();
  const int n = settings_.width * settings_.height;
  std::vector<QueryPoint> points;
  std::vector<int> pixelOf;
  std::vector<float> values, gradients;
  const bool shade = sc.shade != 0;
  const int chunkMax = std::max(1, options_.chunkPixels);
  std::vector<std::uint8_t> hit(std::size_t(std::min(n, chunkMax)));
  std::vector<Vec3f> hitPoint(hit.size());
  const int firstChunk = partNext_;  // rendered whatever the budget: every call makes progress
  for (int chunk0 = firstChunk; chunk0 < n && (chunk0 == firstChunk || msSince(start) < budgetMs);) {
    const int chunkN = std::min(chunkMax, n - chunk0);
    auto t0 = Clock::now();
#pragma omp parallel for schedule(static) if (chunkN >= kParallelMinItems)
    for (int k = 0; k < chunkN; ++k) hit[k] = slicePixelPoint(sc, chunk0 + k, hitPoint[k]) ? 1 : 0;
    points.clear();
    pixelOf.clear();
    for (int k = 0; k < chunkN; ++k) {
      if (!hit[k]) continue;
      points.push_back(QueryPoint{hitPoint[k].x, hitPoint[k].y, hitPoint[k].z, sc.time});
      pixelOf.push_back(k);
    }
    st.initMs += msSince(t0);
    t0 = Clock::now();
    const std::size_t q = points.size();
    values.resize(q);
    if (q > 0) {
      if (shade) {
        gradients.resize(3 * q);
        evaluator_.evaluateWithGradient(points.data(), q, values.data(), gradients.data());
        st.shadingQueries += q;
      } else {
        evaluator_.evaluate(points.data(), q, values.data());
      }
      st.queries += q;
      st.iterations += 1;
    }
    st.rays += q;
    st.evaluateMs += msSince(t0);
    t0 = Clock::now();
    const CameraView& camera = sc.camera;
    for (int k = 0; k < chunkN; ++k) depth_[chunk0 + k] = INFINITY;
#pragma omp parallel for schedule(static) if (q >= std::size_t(kParallelMinItems))
    for (long j = 0; j < long(q); ++j) {
      const int k = pixelOf[j];
      const Vec3f p = hitPoint[k];
      const Vec3f g = shade ? Vec3f{gradients[3 * j], gradients[3 * j + 1], gradients[3 * j + 2]} : Vec3f{0.f, 0.f, 0.f};
      const Vec4f c = sliceColour(sc, p, values[j], g);
      const int i = chunk0 + k;
      if (c.w > 0.f) {  // world distance along the pixel's world ray (the depth limit's measure)
        const Vec3f fromEye = modelToWorld(camera, p) - camera.position;
        depth_[i] = camera.parallel ? dot(fromEye, camera.forward) : length(fromEye);
      }
      accum_[i] = accumulateMean(accum_[i], c, frameIndex_);
    }
    // Pixels whose ray missed the plane add an empty sample to their mean.
    for (int k = 0; k < chunkN; ++k)
      if (!hit[k]) accum_[chunk0 + k] = accumulateMean(accum_[chunk0 + k], Vec4f{0, 0, 0, 0}, frameIndex_);
    st.finalizeMs += msSince(t0);
    partNext_ = chunk0 + chunkN;
    chunk0 += chunkN;
  }
}

SurfaceConstants SurfaceRenderer::surfaceConstants() const {
  if (!grid_ || !candidatesValid_) throw std::logic_error("surfaceConstants: no isosurface scene");
  const CameraView cam = scene_.camera.view(settings_.width, settings_.height);
  const FrameConstants fc = makeFrameConstants(cam, box_, scene_, settings_,
                                               scene_.depthLimit.empty() ? nullptr : scene_.depthLimit.data(),
                                               std::uint32_t(frameIndex_));
  SurfaceConstants sc;
  const Box3f clip = blend_.crop ? intersectBoxes(box_, blend_.cropBox) : box_;
  fillCommon(sc, fc, clip, tfTable_->view(), scene_, settings_, std::uint32_t(frameIndex_));
  sc.cells = grid_->view(candidates_);
  sc.isovalues = isovalues_.data();
  sc.isoCount = int(isovalues_.size());
  sc.step = step_;
  sc.tolerance = tolerance_;
  sc.samplesPerIteration = options_.samplesPerIteration;
  sc.maxMarchSamples = options_.maxMarchSamples > 0 ? options_.maxMarchSamples : options_.samplesPerIteration;
  sc.refinePoints = options_.refinePoints > 0 ? options_.refinePoints : options_.samplesPerIteration;
  sc.maxRefinements = options_.maxRefinements;
  sc.opaqueTransmittance = options_.opaqueTransmittance;
  return sc;
}

void SurfaceRenderer::renderIsosurfaceChunks(Clock::time_point start, double budgetMs) {
  FrameStats& st = partStats_;
  const SurfaceConstants sc = surfaceConstants();
  const int n = settings_.width * settings_.height;
  const int K = sc.samplesPerIteration;
  const int chunkMax = std::max(1, options_.chunkPixels);
  const std::size_t slots = std::size_t(std::min(n, chunkMax));
  std::vector<SurfaceRay>& rays = isoRays_;
  std::vector<int>& active = isoActive_;
  rays.resize(slots);
  std::vector<float> ts(slots * K);
  std::vector<std::uint8_t> breaks(slots * K);
  std::vector<int> counts(slots), first(slots);
  std::vector<int> shading;
  std::vector<QueryPoint> points, gradientPoints;
  std::vector<float> values, gradientValues, gradients;

  // One march iteration (one evaluator batch) at least per call: every call makes progress.
  for (bool firstStep = true; partNext_ < n && (firstStep || msSince(start) < budgetMs); firstStep = false) {
    const int chunk0 = partNext_;
    auto t0 = Clock::now();
    if (isoChunkN_ == 0) {  // a new chunk of pixels: its rays
      isoChunkN_ = std::min(chunkMax, n - chunk0);
      const int chunkN = isoChunkN_;
#pragma omp parallel for schedule(static) if (chunkN >= kParallelMinItems)
      for (int k = 0; k < chunkN; ++k) surfaceInitRay(sc, chunk0 + k, rays[k]);
      active.clear();
      for (int k = 0; k < chunkN; ++k)
        if (rays[k].phase != kSurfaceDone) active.push_back(k);
      st.rays += active.size();
      st.initMs += msSince(t0);
    }

    std::size_t total = 0;
    int M = K;
    if (!active.empty()) {
      // Emit: each active ray's samples into its slots (M of them: the march samples per ray this
      // iteration, K or more as the chunk's rays finish), then packed into one batch.
      t0 = Clock::now();
      const long m = long(active.size());
      M = surfaceMarchSamples(K, sc.maxMarchSamples, isoChunkN_, m);
#pragma omp parallel for schedule(dynamic, 256) if (m >= kParallelMinItems / 4)
      for (long a = 0; a < m; ++a)
        counts[a] = surfaceEmit(sc, rays[active[a]], &ts[std::size_t(a) * M], &breaks[std::size_t(a) * M], M);
      for (long a = 0; a < m; ++a) {
        first[a] = int(total);
        total += std::size_t(counts[a]);
      }
      points.resize(total);
#pragma omp parallel for schedule(static) if (m >= kParallelMinItems / 4)
      for (long a = 0; a < m; ++a) {
        const SurfaceRay& r = rays[active[a]];
        const int refinePoints = surfaceRefinePointsAsked(sc, r);
        for (int j = 0; j < counts[a]; ++j) {
          const Vec3f p = surfacePoint(r, surfaceSampleT(r, &ts[std::size_t(a) * M], j, refinePoints));
          points[std::size_t(first[a] + j)] = QueryPoint{p.x, p.y, p.z, sc.time};
        }
      }
      st.traverseMs += msSince(t0);
    }
    if (total > 0) {
      t0 = Clock::now();
      values.resize(total);
      evaluator_.evaluate(points.data(), total, values.data());
      st.queries += total;
      st.iterations += 1;
      st.evaluateMs += msSince(t0);

      // Consume; hits that need their gradient wait for the shading batch.
      t0 = Clock::now();
      const long m = long(active.size());
#pragma omp parallel for schedule(static) if (m >= kParallelMinItems / 4)
      for (long a = 0; a < m; ++a) {
        if (counts[a] > 0)
          surfaceConsume(sc, rays[active[a]], &ts[std::size_t(a) * M], &breaks[std::size_t(a) * M], &values[first[a]],
                         counts[a]);
      }
      shading.clear();
      for (int k : active)
        if (rays[k].pendingShade) shading.push_back(k);
      st.traverseMs += msSince(t0);
      if (!shading.empty()) {
        t0 = Clock::now();
        const std::size_t q = shading.size();
        gradientPoints.resize(q);
        for (std::size_t j = 0; j < q; ++j) {
          const SurfaceRay& r = rays[shading[j]];
          const Vec3f p = surfacePoint(r, r.hitT);
          gradientPoints[j] = QueryPoint{p.x, p.y, p.z, sc.time};
        }
        gradientValues.resize(q);
        gradients.resize(3 * q);
        evaluator_.evaluateWithGradient(gradientPoints.data(), q, gradientValues.data(), gradients.data());
        st.shadingQueries += q;
        const long qn = long(q);
#pragma omp parallel for schedule(static) if (qn >= kParallelMinItems)
        for (long j = 0; j < qn; ++j)
          surfaceShadeHit(sc, rays[shading[j]], Vec3f{gradients[3 * j], gradients[3 * j + 1], gradients[3 * j + 2]});
        st.shadingMs += msSince(t0);
      }
      std::size_t kept = 0;
      for (int k : active)
        if (rays[k].phase != kSurfaceDone) active[kept++] = k;
      active.resize(kept);
    }
    if (total > 0 && !active.empty()) continue;  // the chunk's march goes on

    // Every ray of the chunk finished its walk: its pixels.
    t0 = Clock::now();
    for (int k = 0; k < isoChunkN_; ++k) {
      const int i = chunk0 + k;
      accum_[i] = accumulateMean(accum_[i], surfaceEstimate(rays[k]), frameIndex_);
      depth_[i] = rays[k].firstHitWorld;
    }
    st.finalizeMs += msSince(t0);
    partNext_ = chunk0 + isoChunkN_;
    isoChunkN_ = 0;
  }
}

ImageRGBA SurfaceRenderer::premultipliedImage() const {
  return accumulationImage(accum_, settings_.width, settings_.height, nullptr);
}

ImageRGBA SurfaceRenderer::image() const {
  return accumulationImage(accum_, settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
