#include "Render/QueryBatch.h"

#include <algorithm>

#include "Render/CpuParallel.h"
#include "Render/Evaluate.h"
#include "Render/Shade.h"

namespace inr {

namespace {
// Fixed compaction chunk (never derived from the thread count, so the batch order is fixed).
constexpr int kChunk = 4096;
}  // namespace

template <typename Count, typename Write>
std::size_t QueryBatch::compact(int n, Count&& count, Write&& write) {
  const int chunks = (n + kChunk - 1) / kChunk;
  chunkOffsets_.assign(std::size_t(chunks) + 1, 0);
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int c = 0; c < chunks; ++c) {
    std::size_t k = 0;
    const int end = std::min(n, (c + 1) * kChunk);
    for (int i = c * kChunk; i < end; ++i) k += count(i);
    chunkOffsets_[c + 1] = k;
  }
  for (int c = 0; c < chunks; ++c) chunkOffsets_[c + 1] += chunkOffsets_[c];
  count_ = chunkOffsets_[chunks];
  if (points_.size() < count_) {
    points_.resize(count_);
    rays_.resize(count_);
    values_.resize(count_);
  }
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int c = 0; c < chunks; ++c) {
    std::size_t k = chunkOffsets_[c];
    const int end = std::min(n, (c + 1) * kChunk);
    for (int i = c * kChunk; i < end; ++i) write(i, k);
  }
  return count_;
}

std::size_t QueryBatch::gather(const RayStateView& rs, float time) {
  return compact(
      rs.count, [&](int i) -> std::size_t { return (rs.flags[i] & kRayPending) ? 1 : 0; },
      [&](int i, std::size_t& k) {
        if (!(rs.flags[i] & kRayPending)) return;
        points_[k] = pendingQuery(rs, i, time);
        rays_[k] = i;
        ++k;
      });
}

std::size_t QueryBatch::gatherPoints(const RayStateView& rs, const PointStateView& pts, float time) {
  const int n = rs.count;
  auto pending = [&](int i) { return (rs.flags[i] & kRayPending) ? int(rs.pointCount[i]) : 0; };
  return compact(
      n,
      [&](int i) -> std::size_t {
        std::size_t k = 0;
        for (int j = 0, m = pending(i); j < m; ++j) k += (pts.kind[pointSlot(pts, n, i, j)] & kPointPruned) ? 0 : 1;
        return k;
      },
      [&](int i, std::size_t& k) {
        for (int j = 0, m = pending(i); j < m; ++j) {
          const int slot = pointSlot(pts, n, i, j);
          if (pts.kind[slot] & kPointPruned) continue;  // answered already
          points_[k] = ratioPointQuery(rs, pts, i, slot, time);
          rays_[k] = slot;
          ++k;
        }
      });
}

void QueryBatch::scatterPoints(const PointStateView& pts) const {
  const long long n = (long long)count_;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (long long k = 0; k < n; ++k) {
    pts.sample[rays_[k]] = values_[k];
    if (withOpacityScales_) pts.opacityScale[rays_[k]] = opacityScales_[k];
  }
}

std::size_t QueryBatch::gatherShading(const FrameConstants& fc, const RayStateView& rs) {
  return compact(
      rs.count, [&](int i) -> std::size_t { return needsShading(fc, rs, i) ? 1 : 0; },
      [&](int i, std::size_t& k) {
        if (!needsShading(fc, rs, i)) return;
        points_[k] = shadingQuery(fc, rs, i);
        rays_[k] = i;
        ++k;
      });
}

void QueryBatch::shade(const FieldEvaluator& evaluator, const FrameConstants& fc, const RayStateView& rs) {
  if (count_ == 0) return;
  gradients_.resize(3 * count_);
  evaluator.evaluateWithGradient(points_.data(), count_, values_.data(), gradients_.data());
  const long long n = (long long)count_;
  const float* g = gradients_.data();
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (long long k = 0; k < n; ++k) shadeRay(fc, rs, rays_[k], Vec3f{g[3 * k], g[3 * k + 1], g[3 * k + 2]});
}

bool QueryBatch::evaluate(const FieldEvaluator& evaluator, const std::atomic<bool>* stop) {
  withOpacityScales_ = false;
  const std::size_t step = stop ? kStoppableQueries : count_;
  for (std::size_t first = 0; first < count_; first += step) {
    if (stop && stop->load(std::memory_order_relaxed)) return false;
    const std::size_t n = std::min(step, count_ - first);
    evaluator.evaluate(points_.data() + first, n, values_.data() + first);
  }
  return true;
}

template <typename Needs>
void QueryBatch::evaluateOpacityScalesWhere(const FieldEvaluator& evaluator, const TransferFunctionView& tf,
                                            Needs&& needs) {
  withOpacityScales_ = true;
  opacityScales_.assign(count_, emptyGradientTerm(tf));  // (the queries no gradient can change: Evaluate.h)
  needGradient_.clear();
  for (std::size_t k = 0; k < count_; ++k)  // serial: in batch order, whatever the thread count
    if (needs(k)) needGradient_.push_back(k);
  const std::size_t m = needGradient_.size();
  gradientQueries_ = m;
  if (m == 0) return;
  gradientPoints_.resize(m);
  gradientValues_.resize(m);
  gradients_.resize(3 * m);
  for (std::size_t j = 0; j < m; ++j) gradientPoints_[j] = points_[needGradient_[j]];
  evaluator.evaluateWithGradient(gradientPoints_.data(), m, gradientValues_.data(), gradients_.data());
  const float* g = gradients_.data();
  for (std::size_t j = 0; j < m; ++j)
    opacityScales_[needGradient_[j]] = gradientTermOf(tf, Vec3f{g[3 * j], g[3 * j + 1], g[3 * j + 2]});
}

void QueryBatch::evaluateOpacityScales(const FieldEvaluator& evaluator, const FrameConstants& fc,
                                       const TransferFunctionView& tf, const RayStateView& rs) {
  evaluateOpacityScalesWhere(evaluator, tf,
                             [&](std::size_t k) { return candidateNeedsOpacityScale(fc, tf, rs, rays_[k], values_[k]); });
}

void QueryBatch::evaluatePointOpacityScales(const FieldEvaluator& evaluator, const TransferFunctionView& tf) {
  evaluateOpacityScalesWhere(evaluator, tf, [&](std::size_t k) { return sampleNeedsOpacityScale(tf, values_[k]); });
}

void QueryBatch::scatter(const RayStateView& rs) const {
  const long long n = (long long)count_;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (long long k = 0; k < n; ++k) {
    storeQueryResult(rs, rays_[k], values_[k]);
    if (withOpacityScales_) rs.opacityScale[rays_[k]] = opacityScales_[k];
  }
}

}  // namespace inr
