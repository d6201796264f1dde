#include "Render/CpuWavefrontRenderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Render/CpuParallel.h"
#include "Render/Evaluate.h"
#include "Render/Finalize.h"
#include "Render/RayInit.h"
#include "Render/Reproject.h"
#include "Render/Shade.h"
#include "Render/Shadows.h"
#include "Render/DebiasedMarch.h"
#include "Render/PreintegratedMarch.h"
#include "Render/RatioTracking.h"
#include "Render/Traverse.h"
#include "Common/Stopwatch.h"

namespace inr {

namespace {


// Candidates pruned this frame, over all rays (RayStateView::pruned, both legs).
std::size_t sumPruned(const RayStateView& rs) {
  const int n = rs.count;
  std::size_t sum = 0;
#pragma omp parallel for schedule(static) reduction(+ : sum) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) sum += rs.pruned[i];
  return sum;
}

}  // namespace

FrameStats& FrameStats::operator+=(const FrameStats& o) {
  frame = o.frame;
  residualSum = o.residualSum;
  varianceSum = o.varianceSum;
  coveredPixels = o.coveredPixels;
  pixels += o.pixels;
  rays += o.rays;
  queries += o.queries;
  iterations += o.iterations;
  shadowRays += o.shadowRays;
  shadowQueries += o.shadowQueries;
  shadowIterations += o.shadowIterations;
  shadingQueries += o.shadingQueries;
  gradientOpacityQueries += o.gradientOpacityQueries;
  refinements += o.refinements;
  cappedRays += o.cappedRays;
  budgetSkipped += o.budgetSkipped;
  pruned += o.pruned;
  updateMs += o.updateMs;
  setupMs += o.setupMs;
  initMs += o.initMs;
  traverseMs += o.traverseMs;
  evaluateMs += o.evaluateMs;
  shadowTraverseMs += o.shadowTraverseMs;
  shadowEvaluateMs += o.shadowEvaluateMs;
  shadingMs += o.shadingMs;
  finalizeMs += o.finalizeMs;
  otherMs += o.otherMs;
  totalMs += o.totalMs;
  traversalBuildMs += o.traversalBuildMs;
  traversalPrimitives = o.traversalPrimitives;  // state: the structure after the later frame
  traversalBytes = o.traversalBytes;
  return *this;
}

CpuWavefrontRenderer::CpuWavefrontRenderer(const FieldEvaluator& evaluator,
                                             MacrocellGrid& macrocells, TrackingOptions options)
    : WavefrontRenderer(options), evaluator_(evaluator), macrocells_(macrocells) {
  allocatePixels();
}

void CpuWavefrontRenderer::resizePixels(std::size_t n) {
  rays_.resize(n);
  pixels_.resize(n);
}

void CpuWavefrontRenderer::clearAccumulation() {
  const AccumulationView acc = pixels_.view();
  const int n = acc.count;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) resetPixel(acc, i);
}

double CpuWavefrontRenderer::applyDirtyMajorants() {
  const auto t0 = Clock::now();
  const std::vector<int> dirty = macrocells_.takeDirtyCells();
  if (!dirty.empty()) macrocells_.updateMajorants(tfTable_->view(), dirty, majorants_);
  return msSince(t0);
}

void CpuWavefrontRenderer::runTrackingLoop(const FrameConstants& fc, const TrackingMedium& medium,
                                            const PointStateView* points, int& iterations, std::size_t& queries,
                                            double& traverseMs, double& evaluateMs,
                                            std::size_t& gradientQueries, bool& truncated) {
  const RayStateView rs = rays_.view();
  const int n = rs.count;
  const Int3 dims = macrocells_.dims();
  const bool pruning = medium.prune.expected != nullptr;
  auto noop = [](auto&&...) {};
  // One traversal pass over the rays. Each ray looks at a GUI worker's stop request first, so a
  // stopped frame waits for the rays under way, not for the whole pass.
  auto traverseEach = [&](auto&& traverseOne) {
#pragma omp parallel for schedule(dynamic, 256) if (n >= kParallelMinItems)
    for (int i = 0; i < n; ++i)
      if (!stopRequested()) traverseOne(i);
  };
  for (int loopIterations = 0;; ++loopIterations) {
    if (stopRequested()) break;  // renderFrame returns the frame unaccumulated
    auto t0 = Clock::now();
    if (points && fc.estimator == PrimaryEstimator::Debiased) {
      traverseEach([&](int i) {
        if (pruning)
          traverseDebiasedRayWith<DdaWalker, true>(fc, medium, rs, *points, i, noop, noop);
        else
          traverseDebiasedRayWith<DdaWalker, false>(fc, medium, rs, *points, i, noop, noop);
      });
    } else if (points && fc.estimator == PrimaryEstimator::Preintegrated) {
      traverseEach([&](int i) {
        if (pruning)
          traversePreintegratedRayWith<DdaWalker, true>(fc, medium, rs, *points, i, noop, noop);
        else
          traversePreintegratedRayWith<DdaWalker, false>(fc, medium, rs, *points, i, noop, noop);
      });
    } else if (points) {
      traverseEach([&](int i) {
        if (pruning)
          traverseRatioRayWith<DdaWalker, true>(fc, medium, rs, *points, i, noop, noop);
        else
          traverseRatioRayWith<DdaWalker, false>(fc, medium, rs, *points, i, noop, noop);
      });
    } else {
      traverseEach([&](int i) { traverseRay(fc, medium, rs, i); });
    }
    traverseMs += msSince(t0);
    if (stopRequested()) break;  // mid-pass: the rays' state is the next frame's to set up again

    t0 = Clock::now();
    // Delta tracking: one query per pending ray (batch entries are ray indices); ratio tracking:
    // the rays' points that need the network (entries are point slots, ray = slot mod n).
    const std::size_t k = points ? batch_.gatherPoints(rs, *points, fc.time) : batch_.gather(rs, fc.time);
    if (k == 0) {
      evaluateMs += msSince(t0);
      break;
    }
    const int* entries = batch_.rayIndices();
    auto rayOf = [&](std::size_t q) { return points ? entries[q] % n : entries[q]; };
    if (loopIterations >= options_.maxIterations) {  // bounded work: the pending rays stop here
      for (std::size_t q = 0; q < k; ++q) {
        const int i = rayOf(q);
        rs.flags[i] &= std::uint8_t(~(kRayActive | kRayPending | kRayBadSample));
        rs.sample[i] = NAN;
        rs.pointCount[i] = 0;
      }
      truncated = true;
      evaluateMs += msSince(t0);
      break;
    }
    ++iterations;
    queries += k;
    // A GUI worker's frame (a stop request) is stoppable between sub-batches; a stopped frame is
    // dropped before its values reach the rays or the macrocells.
    if (!batch_.evaluate(evaluator_, stop_)) {
      evaluateMs += msSince(t0);
      break;
    }
    if (usesGradient(medium.tf)) {  // the gradient term where it can change the outcome (Evaluate.h)
      if (points)
        batch_.evaluatePointOpacityScales(evaluator_, medium.tf);
      else
        batch_.evaluateOpacityScales(evaluator_, fc, medium.tf, rs);
      gradientQueries += batch_.gradientQueries();
    }
    if (points)
      batch_.scatterPoints(*points);
    else
      batch_.scatter(rs);
    const float* values = batch_.values();
    if (options_.refineMacrocells) {
      // Serial and in batch order: widening is order-independent anyway, and majorants only
      // change between frames, so the image does not depend on the thread count.
      for (std::size_t q = 0; q < k; ++q) {
        const int cell = points ? points->cell[entries[q]] : linearCellIndex(dims, rs.cell[entries[q]]);
        if (macrocells_.wouldRefine(cell, values[q])) pendingRefinements_.emplace_back(cell, values[q]);
      }
    }
    if (pruning) {
      // Pruning's expected scalars learn from every real evaluation (Eq. ev_ema): serial and in
      // batch (= ray) order, so they and the image do not depend on the thread count. Before
      // the next traversal reads them.
      for (std::size_t q = 0; q < k; ++q) {
        int cell;
        float estimate;
        const bool learned = points ? expectedAfterPoint(medium, rs, *points, rayOf(q), entries[q], values[q], cell, estimate)
                                    : expectedAfterQuery(medium, rs, entries[q], values[q], cell, estimate);
        if (learned) medium.prune.expected[cell] = estimate;
      }
    }
    evaluateMs += msSince(t0);
  }
}

FrameStats CpuWavefrontRenderer::renderFrame() {
  FrameStats st = beginFrame(primaryEstimatorName(options_.estimator), "renderFrame");
  const double updateBeforeFrame = st.updateMs;
  const auto tFrame = Clock::now();
  st.updateMs += applyDirtyMajorants();

  const FrameConstants fc = frameConstants(frameKey());
  const PruneView prune = pruningActive() ? macrocells_.pruneView(pruneThresholds()) : PruneView{};
  const TrackingMedium medium{macrocells_.view(majorants_), tfTable_->view(), prune};
  const RayStateView rs = rays_.view();
  const int n = rs.count;

  const AccumulationView acc = pixels_.view();
  auto t0 = Clock::now();
  std::size_t active = 0, skipped = 0;
#pragma omp parallel for schedule(static) reduction(+ : active, skipped) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) {
    initBudgetedRay(fc, medium.grid, rs, acc, i);
    active += (rs.flags[i] & kRayActive) ? 1 : 0;
    skipped += (rs.flags[i] & kRayBudgetSkipped) ? 1 : 0;
  }
  st.rays = active;
  st.budgetSkipped = skipped;
  st.initMs = msSince(t0);

  bool truncated = false;
  PointStateView pointsView{};
  const bool withPoints = fc.estimator != PrimaryEstimator::Delta;  // ratio tracking, march
  if (withPoints) {
    const std::size_t slots = std::size_t(n) * std::size_t(fc.pointsPerIteration);
    if (points_.count != slots) {
      const auto tSetup = Clock::now();
      points_.resize(slots);
      st.setupMs += msSince(tSetup);
    }
    pointsView = points_.view();
    pointsView.perRay = fc.pointsPerIteration;  // by ray (pointSlot)
  }
  pendingRefinements_.clear();
  // Pruning's expected scalars learn inside the loop (the next traversal reads them): a frame that
  // may be stopped keeps their values from before it, to put back.
  if (prune.expected && stop_) expectedBeforeFrame_ = macrocells_.expected();
  runTrackingLoop(fc, medium, withPoints ? &pointsView : nullptr, st.iterations, st.queries, st.traverseMs, st.evaluateMs,
                  st.gradientOpacityQueries, truncated);

  if (fc.shadows && !stopRequested()) {
    t0 = Clock::now();
    std::size_t shadowRays = 0;
#pragma omp parallel for schedule(static) reduction(+ : shadowRays) if (n >= kParallelMinItems)
    for (int i = 0; i < n; ++i) {
      spawnShadowRay(fc, medium.grid, rs, i);
      shadowRays += (rs.flags[i] & kRayActive) ? 1 : 0;
    }
    st.shadowRays = shadowRays;
    st.shadowTraverseMs += msSince(t0);
    runTrackingLoop(fc, medium, nullptr, st.shadowIterations, st.shadowQueries, st.shadowTraverseMs,
                    st.shadowEvaluateMs, st.gradientOpacityQueries, truncated);
  }
  if (stopRequested()) {
    // Stopped: the rays' state is the next frame's to set up again, the image and the frame
    // counters stay as they were (the next frame draws the same random numbers).
    st.stopped = true;
    pendingRefinements_.clear();
    if (prune.expected) std::copy(expectedBeforeFrame_.begin(), expectedBeforeFrame_.end(), prune.expected);
    st.closeTiming(updateBeforeFrame, msSince(tFrame));
    return st;
  }
  st.refinements += applyPendingRefinements();
  if (fc.shading.enabled) {
    t0 = Clock::now();
    st.shadingQueries = batch_.gatherShading(fc, rs);
    batch_.shade(evaluator_, fc, rs);
    st.shadingMs = msSince(t0);
  }
  if (prune.expected) st.pruned = sumPruned(rs);

  t0 = Clock::now();
  double residualSum = 0.0, varianceSum = 0.0;
  std::size_t capped = 0, covered = 0;
  std::uint32_t histogram[kResidualBins] = {};
#pragma omp parallel for schedule(static) \
    reduction(+ : residualSum, varianceSum, capped, covered, histogram[:kResidualBins]) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) {
    capped += (rs.flags[i] & kRayCapped) ? 1 : 0;
    const PixelConvergence pc = finalizePixel(fc, rs, acc, i);
    residualSum += pc.residual;
    varianceSum += pc.meanVariance;
    covered += std::size_t(pc.covered);
    if (pc.residualBin >= 0) ++histogram[pc.residualBin];
  }
  st.residualSum = residualSum;
  st.varianceSum = varianceSum;
  st.coveredPixels = covered;
  st.cappedRays = capped;
  st.finalizeMs = msSince(t0);
  endFrame(st, truncated, histogram);
  st.closeTiming(updateBeforeFrame, msSince(tFrame));
  return st;
}

FrameStats CpuWavefrontRenderer::renderFrameNaive() {
  FrameStats st = beginFrame("naive", "renderFrameNaive");
  const double updateBeforeFrame = st.updateMs;
  const auto tFrame = Clock::now();
  st.updateMs += applyDirtyMajorants();

  FrameConstants fc = frameConstants(frameKey());
  fc.jitterControl = 0;  // each pixel is finalized before its neighbours are traced
  const TrackingMedium medium{macrocells_.view(majorants_), tfTable_->view(), PruneView{}};
  const RayStateView rs = rays_.view();
  const AccumulationView acc = pixels_.view();
  const int n = rs.count;
  const Int3 dims = macrocells_.dims();
  // One ray at a time, the network evaluated inside the tracking loop: what a delta tracker
  // written for voxel data does when its texture fetch becomes a network inference.
  auto track = [&](int i, std::size_t& queries) {
    for (;;) {
      traverseRay(fc, medium, rs, i);
      if (!(rs.flags[i] & kRayPending)) break;
      const QueryPoint q = pendingQuery(rs, i, fc.time);
      float v = 0.f;
      evaluator_.evaluate(&q, 1, &v);
      // As the wavefront's evaluation stage (Render/Evaluate.h).
      if (usesGradient(medium.tf) && storeCandidateOpacityScale(fc, medium.tf, rs, i, v, [&](float* g) {
            float unused;
            evaluator_.evaluateWithGradient(&q, 1, &unused, g);
          }))
        ++st.gradientOpacityQueries;
      storeQueryResult(rs, i, v);
      ++queries;
      st.refinements += macrocells_.refine(linearCellIndex(dims, rs.cell[i]), v) ? 1 : 0;
    }
  };
  for (int i = 0; i < n; ++i) {
    initPrimaryRay(fc, medium.grid, rs, i);
    if (rs.flags[i] & kRayActive) {
      ++st.rays;
      track(i, st.queries);
      if (fc.shadows) {
        spawnShadowRay(fc, medium.grid, rs, i);
        if (rs.flags[i] & kRayActive) {
          ++st.shadowRays;
          track(i, st.shadowQueries);
        }
      }
      if (needsShading(fc, rs, i)) {
        const QueryPoint q = shadingQuery(fc, rs, i);
        float v = 0.f, g[3];
        evaluator_.evaluateWithGradient(&q, 1, &v, g);
        shadeRay(fc, rs, i, Vec3f{g[0], g[1], g[2]});
        ++st.shadingQueries;
      }
    }
    st.cappedRays += (rs.flags[i] & kRayCapped) ? 1 : 0;
    const PixelConvergence pc = finalizePixel(fc, rs, acc, i);
    st.residualSum += pc.residual;
    st.varianceSum += pc.meanVariance;
    st.coveredPixels += std::size_t(pc.covered);
  }
  endFrame(st, false);
  // Traversal and evaluation are interleaved, not separable: the frame's time past its update
  // counts as traversal.
  const double frameMs = msSince(tFrame);
  st.traverseMs = frameMs - (st.updateMs - updateBeforeFrame);
  st.closeTiming(updateBeforeFrame, frameMs);
  return st;
}

BlueNoiseMaskView CpuWavefrontRenderer::blueNoiseMask() { return shippedBlueNoiseMask().view(); }

void CpuWavefrontRenderer::reprojectAccumulation(const CameraView& oldView, const CameraView& newView,
                                                  std::uint32_t maxHistory, const Vec3f& background) {
  const int n = int(pixels_.count);
  std::swap(history_, pixels_);  // the old accumulation becomes the history
  pixels_.resize(history_.count);  // every pixel is written by the gather below
  reprojectKeys_.assign(pixels_.count, kNoReprojection);
  const AccumulationView history = history_.view(), acc = pixels_.view();
  std::uint64_t* keys = reprojectKeys_.data();
  const Box3f box = volumeBox();
  // Scatter serially: the minimum is order-independent anyway, and it is a few offers per pixel.
  for (int j = 0; j < n; ++j)
    reprojectionOffers(oldView, newView, box, history, j,
                       [&](int i, std::uint64_t key) { keys[i] = std::min(keys[i], key); });
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) reprojectionGather(oldView, newView, box, history, acc, i, keys[i], maxHistory, background);
}

void CpuWavefrontRenderer::traceGhostPass(const TransferFunctionTable& table, const FrameConstants& fc,
                                           int stride, FrameStats& total) {
  MajorantArrays ghostMajorants;
  macrocells_.computeMajorants(table.view(), ghostMajorants);
  const TrackingMedium medium{macrocells_.view(ghostMajorants), table.view(), PruneView{}};
  const RayStateView rs = rays_.view();
  const int n = rs.count;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) initGhostRay(fc, medium.grid, rs, i, stride);
  bool truncated = false;
  pendingRefinements_.clear();
  runTrackingLoop(fc, medium, nullptr, total.iterations, total.queries, total.traverseMs, total.evaluateMs,
                  total.gradientOpacityQueries, truncated);
  if (stopRequested())
    pendingRefinements_.clear();
  else
    total.refinements += applyPendingRefinements();
}

std::size_t CpuWavefrontRenderer::applyPendingRefinements() {
  std::size_t widened = 0;
  for (const auto& [cell, value] : pendingRefinements_) widened += macrocells_.refine(cell, value) ? 1 : 0;
  pendingRefinements_.clear();
  return widened;
}

}  // namespace inr
