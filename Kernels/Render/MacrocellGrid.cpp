#include "Render/MacrocellGrid.h"

#include <algorithm>
#include <cmath>

#include "Render/CpuParallel.h"

namespace inr {

void computeBlockMajorants(const Int3& dims, int shift, const float* majorants, float* blocks) {
  const Int3 bd = blockGridDims(dims, shift);
  const int n = bd.x * bd.y * bd.z;
#pragma omp parallel for schedule(static) if (n >= kParallelMinTiles)
  for (int b = 0; b < n; ++b) {
    const Int3 bc{b % bd.x, (b / bd.x) % bd.y, b / (bd.x * bd.y)};
    blocks[b] = blockMaxMajorant(majorants, dims, shift, bc);
  }
}

MacrocellGrid::MacrocellGrid(const FieldEvaluator& evaluator, const Box3f& box, double timeBegin,
                             double timeEnd, MacrocellOptions options)
    : MacrocellGridBase(box, timeBegin, timeEnd, options), evaluator_(evaluator) {
  const int n = layout_.cellCount;
  slices_.resize(layout_.temporalSlices);
  workMin_.assign(n, 0.f);
  workMax_.assign(n, 0.f);
  workMean_.assign(n, 0.f);
  expected_.assign(n, 0.f);
  dirtyMask_.assign(n, 0);
  if (!options_.lazySlices) buildAllSlices();
}

void MacrocellGrid::setSlice(int k, std::vector<float> mn, std::vector<float> mx,
                             std::vector<float> mean) {
  layout_.checkSliceArrays(mn.size(), mx.size(), mean.size());
  Slice& s = slices_.at(k);
  s.min = std::move(mn);
  s.max = std::move(mx);
  s.mean = std::move(mean);
  s.built = true;
}

// Lattice sampling of one temporal slice (MacrocellLayout's tiles, points and stencil). Tiles
// are independent (the GPU build runs them as kernels over device arrays); here they are batched
// into large evaluator calls.
void MacrocellGrid::buildSlice(int k) {
  constexpr int P = MacrocellLayout::kTilePoints;
  const long long tiles = layout_.tileCount;
  const long long tilesPerBatch = std::max<long long>(1, (long long)(options_.maxBatch / P));
  const float t = float(sliceTime(k));
  const int cells = layout_.cellCount;

  Slice& s = slices_[k];
  s.min.assign(cells, 0.f);
  s.max.assign(cells, 0.f);
  s.mean.assign(cells, 0.f);
  const CellBoundsArrays out{s.min.data(), s.max.data(), s.mean.data()};
  std::vector<QueryPoint> points(std::size_t(std::min(tiles, tilesPerBatch)) * P);
  std::vector<float> values(points.size());

  for (long long first = 0; first < tiles; first += tilesPerBatch) {
    const long long count = std::min(tilesPerBatch, tiles - first);
#pragma omp parallel for schedule(static) if (count >= kParallelMinTiles)
    for (long long b = 0; b < count; ++b) {
      QueryPoint* tilePoints = &points[std::size_t(b) * P];
      for (int q = 0; q < P; ++q) {
        const Vec3f x = latticePoint(layout_, first + b, q);
        tilePoints[q] = QueryPoint{x.x, x.y, x.z, t};
      }
    }
    evaluator_.evaluate(points.data(), std::size_t(count) * P, values.data());
    stats_.evaluations += std::size_t(count) * P;
#pragma omp parallel for schedule(static) if (count >= kParallelMinTiles)
    for (long long b = 0; b < count; ++b) {
      const float* tileValues = &values[std::size_t(b) * P];
      for (int local = 0; local < MacrocellLayout::kTileCellCount; ++local) {
        int idx;
        if (tileCellIndex(layout_, first + b, local, idx)) out.store(idx, reduceCellStencil(tileValues, local));
      }
    }
    reportSliceProgress(double(first + count) / double(tiles));  // per batch of maxBatch points
  }
  s.built = true;
}

void MacrocellGrid::clearDirtyCells() {
  std::fill(dirtyMask_.begin(), dirtyMask_.end(), 0);
  dirty_.clear();
}

void MacrocellGrid::interpolateWorkingGrid() {
  const Slice& a = slices_[k0_];
  const Slice& b = slices_[w_ > 0.f ? k1_ : k0_];
  const int cells = layout_.cellCount;
  float pad = 0.f;
  if (options_.boundsPadding > 0.0) {
    float lo = INFINITY, hi = -INFINITY;
    for (const Slice* s : {&a, &b})
      for (int c = 0; c < cells; ++c) {
        if (s->min[c] <= s->max[c]) lo = std::min(lo, s->min[c]), hi = std::max(hi, s->max[c]);
      }
    pad = layout_.boundsPad(lo, hi);
  }
  const CellBoundsView av{a.min.data(), a.max.data(), a.mean.data()};
  const CellBoundsView bv{b.min.data(), b.max.data(), b.mean.data()};
  const CellBoundsArrays out{workMin_.data(), workMax_.data(), workMean_.data()};
  const float w = w_;
#pragma omp parallel for schedule(static) if (cells >= kParallelMinItems)
  for (int c = 0; c < cells; ++c) out.store(c, interpolateCell(av.at(c), bv.at(c), w, pad));
  // A new working grid restarts pruning's estimates from its lattice means (the old time's
  // refinements describe another field).
  expected_ = workMean_;
}

PruneView MacrocellGrid::pruneView(PruneView thresholds) {
  thresholds.cellMin = workMin_.data();
  thresholds.cellMax = workMax_.data();
  thresholds.expected = expected_.data();
  return thresholds;
}

std::array<float, 2> MacrocellGrid::workingValueRange() const {
  float lo = INFINITY, hi = -INFINITY;
  for (int c = 0; c < layout_.cellCount; ++c) {
    if (workMin_[c] <= workMax_[c]) lo = std::min(lo, workMin_[c]), hi = std::max(hi, workMax_[c]);
  }
  if (!(lo <= hi)) return {0.f, 1.f};
  return {lo, hi};
}

void MacrocellGrid::computeMajorants(const TransferFunctionView& tf,
                                     std::vector<float>& majorants) const {
  majorants.resize(layout_.cellCount);
#pragma omp parallel for schedule(static) if (layout_.cellCount >= kParallelMinItems)
  for (int c = 0; c < layout_.cellCount; ++c) majorants[c] = maxExtinctionOver(tf, workMin_[c], workMax_[c]);
}

void MacrocellGrid::updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                                    std::vector<float>& majorants) const {
  for (int c : cells) majorants[c] = maxExtinctionOver(tf, workMin_[c], workMax_[c]);
}

MajorantGridView MacrocellGrid::view(const std::vector<float>& majorants) const {
  return layout_.majorantView(majorants.data(), nullptr);
}

void MacrocellGrid::computeMajorants(const TransferFunctionView& tf, MajorantArrays& majorants) const {
  computeMajorants(tf, majorants.cell);
  const int shift = layout_.blockShift;
  majorants.block.resize(std::size_t(shift >= 0 ? blockCount() : 0));
  if (shift >= 0) computeBlockMajorants(layout_.dims, shift, majorants.cell.data(), majorants.block.data());
}

void MacrocellGrid::updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                                    MajorantArrays& majorants) const {
  updateMajorants(tf, cells, majorants.cell);
  const int shift = layout_.blockShift;
  if (shift < 0 || cells.empty()) return;
  // Recompute each touched block from its cells (exact, whichever way the majorants moved).
  const Int3 d = layout_.dims, bd = layout_.blockDims;
  std::vector<int> blocks;
  blocks.reserve(cells.size());
  for (int c : cells) {
    const Int3 cc = cellCoordinates(d, c);
    blocks.push_back(blockIndexOfCell(bd, shift, cc));
  }
  std::sort(blocks.begin(), blocks.end());
  blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
  for (int b : blocks) {
    const Int3 bc{b % bd.x, (b / bd.x) % bd.y, b / (bd.x * bd.y)};
    majorants.block[b] = blockMaxMajorant(majorants.cell.data(), d, shift, bc);
  }
}

MajorantGridView MacrocellGrid::view(const MajorantArrays& majorants) const {
  const bool haveBlocks = int(majorants.block.size()) == blockCount();
  return layout_.majorantView(majorants.cell.data(), haveBlocks ? majorants.block.data() : nullptr);
}

bool MacrocellGrid::refine(int cell, float value) {
  if (!std::isfinite(value) || cell < 0 || cell >= layout_.cellCount) return false;
  float& mn = workMin_[cell];
  float& mx = workMax_[cell];
  const bool empty = !(mn <= mx);
  if (!empty && value >= mn && value <= mx) return false;
  mn = empty ? value : std::min(mn, value);
  mx = empty ? value : std::max(mx, value);
  // Widen the contributing slices too: if both slices' bounds contain the value, so does every
  // interpolation between them, so the fix survives moving the time slider between them.
  auto widen = [&](Slice& s) {
    if (!(s.min[cell] <= s.max[cell])) {
      s.min[cell] = s.max[cell] = value;
    } else {
      s.min[cell] = std::min(s.min[cell], value);
      s.max[cell] = std::max(s.max[cell], value);
    }
  };
  widen(slices_[k0_]);
  if (w_ > 0.f) widen(slices_[k1_]);
  ++refinements_;
  if (!dirtyMask_[cell]) {
    dirtyMask_[cell] = 1;
    dirty_.push_back(cell);
  }
  return true;
}

std::vector<int> MacrocellGrid::takeDirtyCells() {
  std::vector<int> out;
  out.swap(dirty_);
  for (int c : out) dirtyMask_[c] = 0;
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace inr
