#include "Render/QueryBatch.h"

#include "Render/CpuParallel.h"
#include "Render/Evaluate.h"

namespace inr {

namespace {
// Fixed compaction chunk (never derived from the thread count, so the batch order is fixed).
constexpr int kChunk = 4096;
}  // namespace

std::size_t QueryBatch::gather(const RayStateView& rs, float time) {
  const int n = rs.count;
  const int chunks = (n + kChunk - 1) / kChunk;
  chunkOffsets_.assign(std::size_t(chunks) + 1, 0);
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (int c = 0; c < chunks; ++c) {
    std::size_t k = 0;
    const int end = std::min(n, (c + 1) * kChunk);
    for (int i = c * kChunk; i < end; ++i) k += (rs.flags[i] & kRayPending) ? 1 : 0;
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
    for (int i = c * kChunk; i < end; ++i) {
      if (!(rs.flags[i] & kRayPending)) continue;
      points_[k] = pendingQuery(rs, i, time);
      rays_[k] = i;
      ++k;
    }
  }
  return count_;
}

void QueryBatch::evaluate(const FieldEvaluator& evaluator) {
  if (count_ > 0) evaluator.evaluate(points_.data(), count_, values_.data());
}

void QueryBatch::scatter(const RayStateView& rs) const {
  const long long n = (long long)count_;
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
  for (long long k = 0; k < n; ++k) storeQueryResult(rs, rays_[k], values_[k]);
}

}  // namespace inr
