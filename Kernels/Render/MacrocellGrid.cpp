#include "Render/MacrocellGrid.h"

#include <algorithm>
#include <cmath>

#include "Render/CpuParallel.h"

namespace inr {

void computeBlockMajorants(const Int3& dims, int shift, const float* majorants, float* blocks) {
  const Int3 bd = blockGridDims(dims, shift);
  const int n = bd.x * bd.y * bd.z;
#pragma omp parallel for schedule(static) if (n >= kParallelMinBlocks)
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

// Lattice sampling of one temporal slice (MacrocellLayout's lattice, slabs and stencil), slab by
// slab; the GPU build runs the same arithmetic as kernels over device arrays.
void MacrocellGrid::buildSlice(int k) {
  const MacrocellLayout& l = layout_;
  const int layers = latticeSlabLayers(l, (long long)options_.maxBatch);
  const float t = float(sliceTime(k));
  const int cells = layout_.cellCount;

  Slice& s = slices_[k];
  s.min.assign(cells, 0.f);
  s.max.assign(cells, 0.f);
  s.mean.assign(cells, 0.f);
  const CellBoundsArrays out{s.min.data(), s.max.data(), s.mean.data()};
  std::vector<QueryPoint> points(std::size_t(latticeSlabPoints(l, layers)));
  std::vector<float> values(points.size());

  for (int z0 = 0; z0 < l.dims.z; z0 += layers) {
    const LatticeSlab slab = latticeSlab(l, layers, z0);
    if (slab.carryFrom >= 0) std::copy_n(values.begin() + std::ptrdiff_t(slab.carryFrom), l.latticePlanePoints, values.begin());
#pragma omp parallel for schedule(static) if (slab.count >= kParallelMinItems)
    for (long long q = 0; q < slab.count; ++q) {
      const Vec3f x = slabLatticePoint(l, slab.plane0, slab.first + q);
      points[std::size_t(q)] = QueryPoint{x.x, x.y, x.z, t};
    }
    evaluator_.evaluate(points.data(), std::size_t(slab.count), values.data() + slab.first);
    stats_.evaluations += std::size_t(slab.count);
#pragma omp parallel for schedule(static) if (slab.cell1 - slab.cell0 >= kParallelMinItems / 8)
    for (int c = slab.cell0; c < slab.cell1; ++c)
      out.store(c, reduceCellStencil(l, values.data(), slab.plane0, cellCoordinates(l.dims, c)));
    reportSliceProgress(double(slab.z1) / double(l.dims.z));  // per slab of at most maxBatch points
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

bool MacrocellGrid::wouldRefine(int cell, float value) const {
  if (!std::isfinite(value) || cell < 0 || cell >= layout_.cellCount) return false;
  const float mn = workMin_[cell], mx = workMax_[cell];
  return !(mn <= mx) || value < mn || value > mx;
}

bool MacrocellGrid::refine(int cell, float value) {
  if (!wouldRefine(cell, value)) return false;
  float& mn = workMin_[cell];
  float& mx = workMax_[cell];
  const bool empty = !(mn <= mx);
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
