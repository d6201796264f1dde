#include "Render/DeltaTrackingRenderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Render/CpuParallel.h"
#include "Render/Evaluate.h"
#include "Render/RayInit.h"
#include "Render/Shadows.h"
#include "Render/Traverse.h"
#include "Render/AccumulationImage.h"

namespace inr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

bool sameCamera(const Camera& a, const Camera& b) {
  return a.position == b.position && a.focalPoint == b.focalPoint && a.viewUp == b.viewUp &&
         a.viewAngle == b.viewAngle && a.parallelProjection == b.parallelProjection &&
         a.parallelScale == b.parallelScale;
}

bool sameTransferFunction(const TransferFunction& a, const TransferFunction& b) {
  if (a.unitDistance != b.unitDistance || a.colorSpace != b.colorSpace ||
      a.color.size() != b.color.size() || a.opacity.size() != b.opacity.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.color.size(); ++i) {
    const auto &p = a.color[i], &q = b.color[i];
    if (p.x != q.x || p.r != q.r || p.g != q.g || p.b != q.b) return false;
  }
  for (std::size_t i = 0; i < a.opacity.size(); ++i) {
    const auto &p = a.opacity[i], &q = b.opacity[i];
    if (p.x != q.x || p.alpha != q.alpha || p.midpoint != q.midpoint || p.sharpness != q.sharpness) {
      return false;
    }
  }
  return true;
}

}  // namespace

FrameStats& FrameStats::operator+=(const FrameStats& o) {
  frame = o.frame;
  pixels += o.pixels;
  rays += o.rays;
  queries += o.queries;
  iterations += o.iterations;
  shadowRays += o.shadowRays;
  shadowQueries += o.shadowQueries;
  shadowIterations += o.shadowIterations;
  refinements += o.refinements;
  updateMs += o.updateMs;
  initMs += o.initMs;
  traverseMs += o.traverseMs;
  evaluateMs += o.evaluateMs;
  shadowTraverseMs += o.shadowTraverseMs;
  shadowEvaluateMs += o.shadowEvaluateMs;
  finalizeMs += o.finalizeMs;
  totalMs += o.totalMs;
  return *this;
}

DeltaTrackingRenderer::DeltaTrackingRenderer(const FieldEvaluator& evaluator,
                                             MacrocellGrid& macrocells, TrackingOptions options)
    : evaluator_(evaluator), macrocells_(macrocells), options_(options) {
  resize();
}

void DeltaTrackingRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) {
    throw std::invalid_argument("image size must be positive");
  }
  const bool sizeChanged = settings.width != settings_.width || settings.height != settings_.height;
  settings_ = settings;
  if (sizeChanged) resize();
  if (haveScene_) cameraView_ = scene_.camera.view(settings_.width, settings_.height);
  resetAccumulation();
}

void DeltaTrackingRenderer::resize() {
  const std::size_t n = std::size_t(settings_.width) * settings_.height;
  origin_.assign(n, Vec3f{0, 0, 0});
  direction_.assign(n, Vec3f{0, 0, 1});
  tNext_.assign(n, Vec3f{0, 0, 0});
  t_.assign(n, 0.f);
  tEnd_.assign(n, 0.f);
  sample_.assign(n, NAN);
  collisionProduct_.assign(n, 0.f);
  visibility_.assign(n, 1.f);
  rngCounter_.assign(n, 0u);
  flags_.assign(n, 0);
  cell_.assign(n, Int3{0, 0, 0});
  radiance_.assign(n, Vec4f{0, 0, 0, 0});
  accum_.assign(n, Vec4f{0, 0, 0, 0});
  sampleCount_.assign(n, 0u);
  residual_.assign(n, 1.f);
}

void DeltaTrackingRenderer::resetAccumulation() {
  std::fill(accum_.begin(), accum_.end(), Vec4f{0, 0, 0, 0});
  std::fill(sampleCount_.begin(), sampleCount_.end(), 0u);
  std::fill(residual_.begin(), residual_.end(), 1.f);
  frameIndex_ = 0;
}

void DeltaTrackingRenderer::setScene(const RenderScene& scene) {
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels) {
    throw std::invalid_argument("depth limit must have one value per pixel (" +
                                std::to_string(pixels) + "), got " +
                                std::to_string(scene.depthLimit.size()));
  }
  const Vec3f light = toVec3(scene.toLight);
  if (scene.shadows && !(length(light) > 0.f)) {
    throw std::invalid_argument("light direction must be non-zero");
  }
  const CameraView view = scene.camera.view(settings_.width, settings_.height);  // validates
  const bool timeChanged = !haveScene_ || scene.time != scene_.time ||
                           macrocells_.time() != scene.time;
  const bool tfChanged = !haveScene_ || !sameTransferFunction(scene.transferFunction, scene_.transferFunction);
  const auto t0 = Clock::now();
  if (tfChanged) tfTable_ = std::make_unique<TransferFunctionTable>(scene.transferFunction);
  if (timeChanged) macrocells_.setTime(scene.time);
  if (timeChanged || tfChanged) macrocells_.computeMajorants(tfTable_->view(), majorants_);
  pendingUpdateMs_ += msSince(t0);
  const bool viewChanged = !haveScene_ || !sameCamera(scene.camera, scene_.camera) ||
                           scene.background != scene_.background ||
                           scene.depthLimit != scene_.depthLimit || scene.shadows != scene_.shadows ||
                           scene.toLight != scene_.toLight || scene.ambient != scene_.ambient ||
                           scene.shadowEstimator != scene_.shadowEstimator;
  scene_ = scene;
  cameraView_ = view;
  haveScene_ = true;
  // An identical scene (a host re-sending its state every render) keeps accumulating.
  if (timeChanged || tfChanged || viewChanged) resetAccumulation();
  if ((timeChanged || tfChanged) && options_.ghostPassesOnUpdate > 0) {
    runGhostPasses(options_.ghostPassesOnUpdate);
  }
}

RayStateView DeltaTrackingRenderer::rayView() {
  RayStateView v;
  v.count = int(flags_.size());
  v.origin = origin_.data();
  v.direction = direction_.data();
  v.t = t_.data();
  v.tEnd = tEnd_.data();
  v.rngCounter = rngCounter_.data();
  v.flags = flags_.data();
  v.sample = sample_.data();
  v.collisionProduct = collisionProduct_.data();
  v.cell = cell_.data();
  v.tNext = tNext_.data();
  v.radiance = radiance_.data();
  v.visibility = visibility_.data();
  return v;
}

AccumulationView DeltaTrackingRenderer::accumulationView() {
  return AccumulationView{accum_.data(), sampleCount_.data(), residual_.data()};
}

FrameConstants DeltaTrackingRenderer::frameConstants(std::uint32_t frame) const {
  return makeFrameConstants(cameraView_, macrocells_.box(), scene_, settings_, scene_.depthLimit.data(), frame);
}

double DeltaTrackingRenderer::applyDirtyMajorants() {
  const auto t0 = Clock::now();
  const std::vector<int> dirty = macrocells_.takeDirtyCells();
  if (!dirty.empty()) macrocells_.updateMajorants(tfTable_->view(), dirty, majorants_);
  return msSince(t0);
}

void DeltaTrackingRenderer::runTrackingLoop(const FrameConstants& fc, const TrackingMedium& medium,
                                            int& iterations, std::size_t& queries,
                                            double& traverseMs, double& evaluateMs,
                                            std::size_t& refinements) {
  const RayStateView rs = rayView();
  const int n = rs.count;
  const Int3 dims = macrocells_.dims();
  for (;;) {
    auto t0 = Clock::now();
#pragma omp parallel for schedule(dynamic, 256) if (n >= kParallelMinItems)
    for (int i = 0; i < n; ++i) traverseRay(fc, medium, rs, i);
    traverseMs += msSince(t0);

    t0 = Clock::now();
    const std::size_t k = batch_.gather(rs, fc.time);
    if (k == 0) {
      evaluateMs += msSince(t0);
      break;
    }
    ++iterations;
    queries += k;
    batch_.evaluate(evaluator_);
    batch_.scatter(rs);
    if (options_.refineMacrocells) {
      // Serial and in batch order: widening is order-independent anyway, and majorants only
      // change between frames, so the image does not depend on the thread count.
      const int* rays = batch_.rayIndices();
      const float* values = batch_.values();
      for (std::size_t q = 0; q < k; ++q) {
        refinements += macrocells_.refine(linearCellIndex(dims, rs.cell[rays[q]]), values[q]) ? 1 : 0;
      }
    }
    evaluateMs += msSince(t0);
  }
}

FrameStats DeltaTrackingRenderer::renderFrame() {
  if (!haveScene_) throw std::logic_error("renderFrame: setScene first");
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "delta";
  st.frame = frameIndex_;
  st.updateMs = pendingUpdateMs_ + applyDirtyMajorants();
  pendingUpdateMs_ = 0.0;

  const FrameConstants fc = frameConstants(std::uint32_t(frameIndex_));
  const TrackingMedium medium{macrocells_.view(majorants_), tfTable_->view()};
  const RayStateView rs = rayView();
  const int n = rs.count;
  st.pixels = std::size_t(n);

  auto t0 = Clock::now();
  std::size_t active = 0;
#pragma omp parallel for schedule(static) reduction(+ : active) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) {
    initPrimaryRay(fc, medium.grid, rs, i);
    active += (rs.flags[i] & kRayActive) ? 1 : 0;
  }
  st.rays = active;
  st.initMs = msSince(t0);

  runTrackingLoop(fc, medium, st.iterations, st.queries, st.traverseMs, st.evaluateMs, st.refinements);

  if (fc.shadows) {
    t0 = Clock::now();
    std::size_t shadowRays = 0;
#pragma omp parallel for schedule(static) reduction(+ : shadowRays) if (n >= kParallelMinItems)
    for (int i = 0; i < n; ++i) {
      spawnShadowRay(fc, medium.grid, rs, i);
      shadowRays += (rs.flags[i] & kRayActive) ? 1 : 0;
    }
    st.shadowRays = shadowRays;
    st.shadowTraverseMs += msSince(t0);
    runTrackingLoop(fc, medium, st.shadowIterations, st.shadowQueries, st.shadowTraverseMs,
                    st.shadowEvaluateMs, st.refinements);
  }

  t0 = Clock::now();
  const AccumulationView acc = accumulationView();
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) finalizePixel(fc, rs, acc, i);
  st.finalizeMs = msSince(t0);
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  return st;
}

FrameStats DeltaTrackingRenderer::renderFrameNaive() {
  if (!haveScene_) throw std::logic_error("renderFrameNaive: setScene first");
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "naive";
  st.frame = frameIndex_;
  st.updateMs = pendingUpdateMs_ + applyDirtyMajorants();
  pendingUpdateMs_ = 0.0;

  const FrameConstants fc = frameConstants(std::uint32_t(frameIndex_));
  const TrackingMedium medium{macrocells_.view(majorants_), tfTable_->view()};
  const RayStateView rs = rayView();
  const AccumulationView acc = accumulationView();
  const int n = rs.count;
  const Int3 dims = macrocells_.dims();
  st.pixels = std::size_t(n);
  // One ray at a time, the network evaluated inside the tracking loop: what a delta tracker
  // written for voxel data does when its texture fetch becomes a network inference.
  auto track = [&](int i, std::size_t& queries) {
    for (;;) {
      traverseRay(fc, medium, rs, i);
      if (!(rs.flags[i] & kRayPending)) break;
      const QueryPoint q = pendingQuery(rs, i, fc.time);
      float v = 0.f;
      evaluator_.evaluate(&q, 1, &v);
      storeQueryResult(rs, i, v);
      ++queries;
      st.refinements += macrocells_.refine(linearCellIndex(dims, rs.cell[i]), v) ? 1 : 0;
    }
  };
  for (int i = 0; i < n; ++i) {
    initPrimaryRay(fc, medium.grid, rs, i);
    if (!(rs.flags[i] & kRayActive)) {
      finalizePixel(fc, rs, acc, i);
      continue;
    }
    ++st.rays;
    track(i, st.queries);
    if (fc.shadows) {
      spawnShadowRay(fc, medium.grid, rs, i);
      if (rs.flags[i] & kRayActive) {
        ++st.shadowRays;
        track(i, st.shadowQueries);
      }
    }
    finalizePixel(fc, rs, acc, i);
  }
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  st.traverseMs = st.totalMs;  // traversal and evaluation are interleaved; not separable
  return st;
}

FrameStats DeltaTrackingRenderer::runGhostPasses(int count) {
  if (!haveScene_) throw std::logic_error("runGhostPasses: setScene first");
  FrameStats total;
  total.method = "ghost";
  if (count <= 0) return total;
  const auto tStart = Clock::now();
  applyDirtyMajorants();
  const auto range = macrocells_.workingValueRange();
  const double lo = range[0], span = std::max(double(range[1]) - range[0], 1e-6);
  const Vec3f cs = macrocells_.cellSize();
  const double meanCell = (double(cs.x) + cs.y + cs.z) / 3.0;
  const RayStateView rs = rayView();
  const int n = rs.count;
  const int stride = std::max(1, options_.ghostPixelStride);
  MajorantArrays ghostMajorants;
  for (int g = 0; g < count; ++g) {
    // Bumps of half-width span/count centred on a sweep over the range: neighbours overlap, so
    // every scalar value gets a non-zero ghost extinction in some pass. Peak opacity 0.5 per
    // cell size: about one tentative collision per cell, so rays sample the cells they cross.
    const double centre = lo + (g + 0.5) / count * span;
    TransferFunction ghost = TransferFunction::cosineBump(lo, lo + span, centre, span / count, 0.5);
    ghost.unitDistance = meanCell;
    const TransferFunctionTable table(ghost);
    macrocells_.computeMajorants(table.view(), ghostMajorants);
    const TrackingMedium medium{macrocells_.view(ghostMajorants), table.view()};
    FrameConstants fc = frameConstants(0x80000000u + ghostFrame_++);
    fc.shadows = 0;
    fc.depthLimit = nullptr;  // refine what is hidden now too: it may show up after a camera move
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
    for (int i = 0; i < n; ++i) {
      const int px = i % settings_.width, py = i / settings_.width;
      if (px % stride == 0 && py % stride == 0) {
        initPrimaryRay(fc, medium.grid, rs, i);
      } else {
        rs.flags[i] = 0;
      }
    }
    runTrackingLoop(fc, medium, total.iterations, total.queries, total.traverseMs,
                    total.evaluateMs, total.refinements);
  }
  total.updateMs = applyDirtyMajorants();
  total.totalMs = msSince(tStart);
  return total;
}

ImageRGBA DeltaTrackingRenderer::premultipliedImage() const {
  return accumulationImage(accum_, settings_.width, settings_.height, nullptr);
}

ImageRGBA DeltaTrackingRenderer::image() const {
  return accumulationImage(accum_, settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
