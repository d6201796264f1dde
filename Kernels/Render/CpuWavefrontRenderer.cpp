#include "Render/CpuWavefrontRenderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
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

// The traverse-evaluate loop's steps on the CPU: each pass traverses every ray (OpenMP), the
// listed queries go through the query batch, and their values reach the rays in batch order.
class CpuWavefrontRenderer::TrackingSteps final : public TrackingLoopSteps {
public:
  // `points`: the point storage of a ratio-tracked or marched primary leg, else none (one query
  // per pending ray). Times and gradient-opacity queries add to the given counters.
  TrackingSteps(CpuWavefrontRenderer& r, const FrameConstants& fc, const TrackingMedium& medium,
                std::optional<PointStateView> points, double& traverseMs, double& evaluateMs,
                std::size_t& gradientQueries)
      : r_(r), fc_(fc), medium_(medium), points_(points), rs_(r.rays_.view()), traverseMs_(traverseMs),
        evaluateMs_(evaluateMs), gradientQueries_(gradientQueries) {}

  std::size_t listedQueries(int /*iteration*/, bool /*belowCap*/) override {
    if (r_.stopRequested()) return 0;  // renderFrame returns the frame unaccumulated
    auto t0 = Clock::now();
    traversePass();
    traverseMs_ += msSince(t0);
    if (r_.stopRequested()) return 0;  // mid-pass: the rays' state is the next frame's to set up again
    t0 = Clock::now();
    // Delta tracking: one query per pending ray (batch entries are ray indices); ratio tracking
    // and the marches: the rays' points that need the network (entries are point slots, ray =
    // slot mod n).
    const std::size_t k = points_ ? r_.batch_.gatherPoints(rs_, *points_, fc_.time) : r_.batch_.gather(rs_, fc_.time);
    evaluateMs_ += msSince(t0);
    return k;
  }

  bool consume(int /*iteration*/, std::size_t k) override {
    const auto t0 = Clock::now();
    const bool done = evaluate(k);
    evaluateMs_ += msSince(t0);
    return done;
  }

  void cutOff(int /*iteration*/) override {
    const std::size_t k = r_.batch_.size();
    for (std::size_t q = 0; q < k; ++q) {
      const int i = rayOf(q);
      rs_.flags[i] &= std::uint8_t(~(kRayActive | kRayPending | kRayBadSample));
      rs_.sample[i] = NAN;
      rs_.pointCount[i] = 0;
    }
  }

private:
  int rayOf(std::size_t q) const {
    const int* entries = r_.batch_.rayIndices();
    return points_ ? entries[q] % rs_.count : entries[q];
  }

  // One traversal pass over the rays. Each ray looks at a GUI worker's stop request first, so a
  // stopped frame waits for the rays under way, not for the whole pass.
  void traversePass() {
    const int n = rs_.count;
    const bool pruning = medium_.prune.expected != nullptr;
    const FrameConstants& fc = fc_;
    const TrackingMedium& medium = medium_;
    const RayStateView& rs = rs_;
    auto noop = [](auto&&...) {};
    auto traverseEach = [&](auto&& traverseOne) {
#pragma omp parallel for schedule(dynamic, 256) if (n >= kParallelMinItems)
      for (int i = 0; i < n; ++i)
        if (!r_.stopRequested()) traverseOne(i);
    };
    if (points_ && fc.estimator == PrimaryEstimator::Debiased) {
      traverseEach([&](int i) {
        if (pruning)
          traverseDebiasedRayWith<DdaWalker, true>(fc, medium, rs, *points_, i, noop, noop);
        else
          traverseDebiasedRayWith<DdaWalker, false>(fc, medium, rs, *points_, i, noop, noop);
      });
    } else if (points_ && fc.estimator == PrimaryEstimator::Preintegrated) {
      traverseEach([&](int i) {
        if (pruning)
          traversePreintegratedRayWith<DdaWalker, true>(fc, medium, rs, *points_, i, noop, noop);
        else
          traversePreintegratedRayWith<DdaWalker, false>(fc, medium, rs, *points_, i, noop, noop);
      });
    } else if (points_) {
      traverseEach([&](int i) {
        if (pruning)
          traverseRatioRayWith<DdaWalker, true>(fc, medium, rs, *points_, i, noop, noop);
        else
          traverseRatioRayWith<DdaWalker, false>(fc, medium, rs, *points_, i, noop, noop);
      });
    } else {
      traverseEach([&](int i) { traverseRay(fc, medium, rs, i); });
    }
  }

  // The batch's values to the rays; false when a stop request ended the evaluation.
  bool evaluate(std::size_t k) {
    QueryBatch& batch = r_.batch_;
    // A GUI worker's frame (a stop request) is stoppable between sub-batches; a stopped frame is
    // dropped before its values reach the rays or the macrocells.
    if (!batch.evaluate(r_.evaluator_, r_.stop_)) return false;
    if (usesGradient(medium_.tf)) {  // the gradient term where it can change the outcome (Evaluate.h)
      if (points_)
        batch.evaluatePointOpacityScales(r_.evaluator_, medium_.tf);
      else
        batch.evaluateOpacityScales(r_.evaluator_, fc_, medium_.tf, rs_);
      gradientQueries_ += batch.gradientQueries();
    }
    if (points_)
      batch.scatterPoints(*points_);
    else
      batch.scatter(rs_);
    const float* values = batch.values();
    const int* entries = batch.rayIndices();
    if (r_.options_.refineMacrocells) {
      // Serial and in batch order: widening is order-independent anyway, and majorants only
      // change between frames, so the image does not depend on the thread count.
      const Int3 dims = r_.macrocells_.dims();
      for (std::size_t q = 0; q < k; ++q) {
        const int cell = points_ ? points_->cell[entries[q]] : linearCellIndex(dims, rs_.cell[entries[q]]);
        if (r_.macrocells_.wouldRefine(cell, values[q])) r_.pendingRefinements_.emplace_back(cell, values[q]);
      }
    }
    if (medium_.prune.expected) {
      // Pruning's expected scalars learn from every real evaluation (Eq. ev_ema): serial and in
      // batch (= ray) order, so they and the image do not depend on the thread count. Before
      // the next traversal reads them.
      for (std::size_t q = 0; q < k; ++q) {
        int cell;
        float estimate;
        const bool learned = points_ ? expectedAfterPoint(medium_, rs_, *points_, rayOf(q), entries[q], values[q], cell, estimate)
                                     : expectedAfterQuery(medium_, rs_, entries[q], values[q], cell, estimate);
        if (learned) medium_.prune.expected[cell] = estimate;
      }
    }
    return true;
  }

  CpuWavefrontRenderer& r_;
  const FrameConstants fc_;
  const TrackingMedium medium_;
  const std::optional<PointStateView> points_;
  const RayStateView rs_;
  double& traverseMs_;
  double& evaluateMs_;
  std::size_t& gradientQueries_;
};

FrameConstants CpuWavefrontRenderer::prepareFrame(FrameStats& st) {
  st.updateMs += applyDirtyMajorants();
  const FrameConstants fc = frameConstants(frameKey());
  const PruneView prune = pruningActive() ? macrocells_.pruneView(pruneThresholds()) : PruneView{};
  medium_ = TrackingMedium{macrocells_.view(majorants_), tfTable_->view(), prune};
  if (fc.estimator != PrimaryEstimator::Delta) {  // ratio tracking and the marches: point storage
    const std::size_t slots = std::size_t(rays_.count) * std::size_t(fc.pointsPerIteration);
    if (points_.count != slots) {
      const auto tSetup = Clock::now();
      points_.resize(slots);
      st.setupMs += msSince(tSetup);
    }
  }
  pendingRefinements_.clear();
  // Pruning's expected scalars learn inside the loop (the next traversal reads them): a frame that
  // may be stopped keeps their values from before it, to put back.
  if (prune.expected && stop_) expectedBeforeFrame_ = macrocells_.expected();
  return fc;
}

void CpuWavefrontRenderer::initRays(const FrameConstants& fc, FrameStats& st) {
  const RayStateView rs = rays_.view();
  const AccumulationView acc = pixels_.view();
  const MajorantGridView grid = medium_.grid;
  const int n = rs.count;
  const auto t0 = Clock::now();
  std::size_t active = 0, skipped = 0;
#pragma omp parallel for schedule(static) reduction(+ : active, skipped) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) {
    initBudgetedRay(fc, grid, rs, acc, i);
    active += (rs.flags[i] & kRayActive) ? 1 : 0;
    skipped += (rs.flags[i] & kRayBudgetSkipped) ? 1 : 0;
  }
  st.rays = active;
  st.budgetSkipped = skipped;
  st.initMs = msSince(t0);
}

std::unique_ptr<TrackingLoopSteps> CpuWavefrontRenderer::legSteps(const FrameConstants& fc, Leg leg, FrameStats& st) {
  if (leg == Leg::Shadow)
    return std::make_unique<TrackingSteps>(*this, fc, medium_, std::nullopt, st.shadowTraverseMs, st.shadowEvaluateMs,
                                           st.gradientOpacityQueries);
  std::optional<PointStateView> points;
  if (fc.estimator != PrimaryEstimator::Delta) {
    points = points_.view();
    points->perRay = fc.pointsPerIteration;  // by ray (pointSlot)
  }
  return std::make_unique<TrackingSteps>(*this, fc, medium_, points, st.traverseMs, st.evaluateMs,
                                         st.gradientOpacityQueries);
}

void CpuWavefrontRenderer::spawnShadowRays(const FrameConstants& fc, FrameStats& st) {
  const RayStateView rs = rays_.view();
  const MajorantGridView grid = medium_.grid;
  const int n = rs.count;
  const auto t0 = Clock::now();
  std::size_t shadowRays = 0;
#pragma omp parallel for schedule(static) reduction(+ : shadowRays) if (n >= kParallelMinItems)
  for (int i = 0; i < n; ++i) {
    spawnShadowRay(fc, grid, rs, i);
    shadowRays += (rs.flags[i] & kRayActive) ? 1 : 0;
  }
  st.shadowRays = shadowRays;
  st.shadowTraverseMs += msSince(t0);
}

void CpuWavefrontRenderer::dropFrame() {
  pendingRefinements_.clear();
  if (medium_.prune.expected)
    std::copy(expectedBeforeFrame_.begin(), expectedBeforeFrame_.end(), medium_.prune.expected);
}

void CpuWavefrontRenderer::keepFrame(FrameStats& st) { st.refinements += applyPendingRefinements(); }

void CpuWavefrontRenderer::shadeHits(const FrameConstants& fc, FrameStats& st) {
  const auto t0 = Clock::now();
  const RayStateView rs = rays_.view();
  st.shadingQueries = batch_.gatherShading(fc, rs);
  batch_.shade(evaluator_, fc, rs);
  st.shadingMs = msSince(t0);
}

const std::uint32_t* CpuWavefrontRenderer::finalizePixels(const FrameConstants& fc, FrameStats& st) {
  const RayStateView rs = rays_.view();
  const AccumulationView acc = pixels_.view();
  const int n = rs.count;
  if (medium_.prune.expected) st.pruned = sumPruned(rs);
  const auto t0 = Clock::now();
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
  std::copy(histogram, histogram + kResidualBins, residualHistogram_.begin());
  return residualHistogram_.data();
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
  pendingRefinements_.clear();
  TrackingSteps steps(*this, fc, medium, std::nullopt, total.traverseMs, total.evaluateMs, total.gradientOpacityQueries);
  runLeg(steps, Leg::Primary, total);
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
