#include "Render/MacrocellGrid.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "Render/CpuParallel.h"

namespace inr {

int skipBlockShift(int skipBlockCells) {
  if (skipBlockCells == 0) return -1;
  if (skipBlockCells < 0 || skipBlockCells > 1024 || (skipBlockCells & (skipBlockCells - 1)) != 0) {
    throw std::invalid_argument("skip block size must be 0 (off) or a power of two up to 1024, got " +
                                std::to_string(skipBlockCells));
  }
  int shift = 0;
  while ((1 << shift) < skipBlockCells) ++shift;
  return shift;
}

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
    : evaluator_(evaluator), box_(box), timeBegin_(timeBegin), timeEnd_(timeEnd),
      options_(options) {
  const Int3 d = options_.dims;
  if (d.x < 1 || d.y < 1 || d.z < 1) throw std::invalid_argument("macrocell dims must be >= 1");
  if (options_.temporalSlices < 1) throw std::invalid_argument("temporal slices must be >= 1");
  if (!(box.hi.x > box.lo.x && box.hi.y > box.lo.y && box.hi.z > box.lo.z)) {
    throw std::invalid_argument("macrocell box must have positive extent");
  }
  if (!(options_.boundsPadding >= 0.0)) throw std::invalid_argument("bounds padding must be >= 0");
  cellCount_ = d.x * d.y * d.z;
  blockShift_ = skipBlockShift(options_.skipBlockCells);
  if (blockShift_ >= 0) blockDims_ = blockGridDims(d, blockShift_);
  cellSize_ = Vec3f{(box.hi.x - box.lo.x) / d.x, (box.hi.y - box.lo.y) / d.y,
                    (box.hi.z - box.lo.z) / d.z};
  slices_.resize(options_.temporalSlices);
  workMin_.assign(cellCount_, 0.f);
  workMax_.assign(cellCount_, 0.f);
  workMean_.assign(cellCount_, 0.f);
  dirtyMask_.assign(cellCount_, 0);
  time_ = timeBegin;
  if (!options_.lazySlices) buildAllSlices();
}

double MacrocellGrid::sliceTime(int k) const {
  const int T = int(slices_.size());
  if (T == 1) return 0.5 * (timeBegin_ + timeEnd_);
  return timeBegin_ + (timeEnd_ - timeBegin_) * double(k) / double(T - 1);
}

void MacrocellGrid::interpolationWeights(double t, int& k0, int& k1, float& w) const {
  const int T = int(slices_.size());
  if (T == 1 || !(timeEnd_ > timeBegin_)) {
    k0 = k1 = 0;
    w = 0.f;
    return;
  }
  double u = (t - timeBegin_) / (timeEnd_ - timeBegin_) * double(T - 1);
  if (!(u > 0.0)) u = 0.0;  // also NaN
  u = std::min(u, double(T - 1));
  k0 = std::min(int(std::floor(u)), T - 1);
  k1 = std::min(k0 + 1, T - 1);
  w = k1 == k0 ? 0.f : float(u - k0);
}

void MacrocellGrid::buildAllSlices() {
  for (int k = 0; k < int(slices_.size()); ++k) ensureSlice(k);
}

void MacrocellGrid::ensureSlice(int k) {
  if (!slices_[k].built) buildSlice(k);
}

void MacrocellGrid::setSlice(int k, std::vector<float> mn, std::vector<float> mx,
                             std::vector<float> mean) {
  if (int(mn.size()) != cellCount_ || int(mx.size()) != cellCount_ || int(mean.size()) != cellCount_) {
    throw std::invalid_argument("setSlice: arrays must have one entry per cell");
  }
  Slice& s = slices_.at(k);
  s.min = std::move(mn);
  s.max = std::move(mx);
  s.mean = std::move(mean);
  s.built = true;
}

// Lattice sampling of one temporal slice. The grid is covered by tiles of 4³ cells; each tile
// samples a 9³ lattice at its cell boundaries and half-cell offsets, and each cell reduces the
// 3³ lattice points covering it (its corners, edge and face midpoints and centre). Tiles are
// independent (the GPU build gives each tile to one thread block with the lattice in shared
// memory); here they are batched into large evaluator calls.
void MacrocellGrid::buildSlice(int k) {
  const auto start = std::chrono::steady_clock::now();
  const Int3 d = options_.dims;
  constexpr int C = kTileCells, L = kTileLattice, P = L * L * L;
  const int tx = (d.x + C - 1) / C, ty = (d.y + C - 1) / C, tz = (d.z + C - 1) / C;
  const long long tiles = (long long)tx * ty * tz;
  const long long tilesPerBatch = std::max<long long>(1, (long long)(options_.maxBatch / P));
  const float t = float(sliceTime(k));

  Slice& s = slices_[k];
  s.min.assign(cellCount_, 0.f);
  s.max.assign(cellCount_, 0.f);
  s.mean.assign(cellCount_, 0.f);
  std::vector<QueryPoint> points(std::size_t(std::min(tiles, tilesPerBatch)) * P);
  std::vector<float> values(points.size());
  if (progress_) progress_(k, 0.0);

  for (long long first = 0; first < tiles; first += tilesPerBatch) {
    const long long count = std::min(tilesPerBatch, tiles - first);
#pragma omp parallel for schedule(static) if (count >= kParallelMinTiles)
    for (long long b = 0; b < count; ++b) {
      const long long tile = first + b;
      const int ix = int(tile % tx), iy = int((tile / tx) % ty), iz = int(tile / (tx * ty));
      QueryPoint* out = &points[std::size_t(b) * P];
      for (int c = 0; c < L; ++c)
        for (int bb = 0; bb < L; ++bb)
          for (int a = 0; a < L; ++a) {
            // Lattice coordinate in half cells; points past a partial tile's last cell are
            // clamped to the box (evaluated, never used).
            const float x = box_.lo.x + (ix * C + 0.5f * a) * cellSize_.x;
            const float y = box_.lo.y + (iy * C + 0.5f * bb) * cellSize_.y;
            const float z = box_.lo.z + (iz * C + 0.5f * c) * cellSize_.z;
            out[(c * L + bb) * L + a] =
                QueryPoint{std::min(x, box_.hi.x), std::min(y, box_.hi.y), std::min(z, box_.hi.z), t};
          }
    }
    evaluator_.evaluate(points.data(), std::size_t(count) * P, values.data());
    stats_.evaluations += std::size_t(count) * P;
#pragma omp parallel for schedule(static) if (count >= kParallelMinTiles)
    for (long long b = 0; b < count; ++b) {
      const long long tile = first + b;
      const int ix = int(tile % tx), iy = int((tile / tx) % ty), iz = int(tile / (tx * ty));
      const float* v = &values[std::size_t(b) * P];
      for (int cz = 0; cz < C; ++cz)
        for (int cy = 0; cy < C; ++cy)
          for (int cx = 0; cx < C; ++cx) {
            const Int3 cell{ix * C + cx, iy * C + cy, iz * C + cz};
            if (cell.x >= d.x || cell.y >= d.y || cell.z >= d.z) continue;
            float mn = INFINITY, mx = -INFINITY;
            double sum = 0.0;
            int n = 0;
            for (int c = 2 * cz; c <= 2 * cz + 2; ++c)
              for (int bb = 2 * cy; bb <= 2 * cy + 2; ++bb)
                for (int a = 2 * cx; a <= 2 * cx + 2; ++a) {
                  const float s = v[(c * L + bb) * L + a];
                  if (!std::isfinite(s)) continue;  // a NaN output says nothing about bounds
                  mn = std::min(mn, s);
                  mx = std::max(mx, s);
                  sum += s;
                  ++n;
                }
            const int idx = linearCellIndex(d, cell);
            if (n == 0) {
              // No finite sample: an empty range (majorant 0) until refinement sees a value.
              s.min[idx] = INFINITY;
              s.max[idx] = -INFINITY;
              s.mean[idx] = 0.f;
            } else {
              s.min[idx] = mn;
              s.max[idx] = mx;
              s.mean[idx] = float(sum / n);
            }
          }
    }
    if (progress_) progress_(k, double(first + count) / double(tiles));
  }
  s.built = true;
  stats_.slicesBuilt += 1;
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void MacrocellGrid::setTime(double t) {
  time_ = t;
  interpolationWeights(t, k0_, k1_, w_);
  ensureSlice(k0_);
  if (w_ > 0.f) ensureSlice(k1_);
  interpolateWorkingGrid();
  std::fill(dirtyMask_.begin(), dirtyMask_.end(), 0);
  dirty_.clear();
}

void MacrocellGrid::interpolateWorkingGrid() {
  const Slice& a = slices_[k0_];
  const Slice& b = slices_[w_ > 0.f ? k1_ : k0_];
  const float w = w_;
  float pad = 0.f;
  if (options_.boundsPadding > 0.0) {
    float lo = INFINITY, hi = -INFINITY;
    for (const Slice* s : {&a, &b})
      for (int c = 0; c < cellCount_; ++c) {
        if (s->min[c] <= s->max[c]) lo = std::min(lo, s->min[c]), hi = std::max(hi, s->max[c]);
      }
    if (lo <= hi) pad = float(options_.boundsPadding * (double(hi) - lo));
  }
#pragma omp parallel for schedule(static) if (cellCount_ >= kParallelMinItems)
  for (int c = 0; c < cellCount_; ++c) {
    const bool aValid = a.min[c] <= a.max[c], bValid = b.min[c] <= b.max[c];
    if (aValid && bValid) {
      workMin_[c] = (1.f - w) * a.min[c] + w * b.min[c] - pad;
      workMax_[c] = (1.f - w) * a.max[c] + w * b.max[c] + pad;
      workMean_[c] = (1.f - w) * a.mean[c] + w * b.mean[c];
    } else if (aValid || bValid) {  // one slice saw no finite value: use the other's bounds
      const Slice& s = aValid ? a : b;
      workMin_[c] = s.min[c] - pad;
      workMax_[c] = s.max[c] + pad;
      workMean_[c] = s.mean[c];
    } else {
      workMin_[c] = INFINITY;
      workMax_[c] = -INFINITY;
      workMean_[c] = 0.f;
    }
  }
}

std::array<float, 2> MacrocellGrid::workingValueRange() const {
  float lo = INFINITY, hi = -INFINITY;
  for (int c = 0; c < cellCount_; ++c) {
    if (workMin_[c] <= workMax_[c]) lo = std::min(lo, workMin_[c]), hi = std::max(hi, workMax_[c]);
  }
  if (!(lo <= hi)) return {0.f, 1.f};
  return {lo, hi};
}

void MacrocellGrid::computeMajorants(const TransferFunctionView& tf,
                                     std::vector<float>& majorants) const {
  majorants.resize(cellCount_);
#pragma omp parallel for schedule(static) if (cellCount_ >= kParallelMinItems)
  for (int c = 0; c < cellCount_; ++c) majorants[c] = maxExtinctionOver(tf, workMin_[c], workMax_[c]);
}

void MacrocellGrid::updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                                    std::vector<float>& majorants) const {
  for (int c : cells) majorants[c] = maxExtinctionOver(tf, workMin_[c], workMax_[c]);
}

MajorantGridView MacrocellGrid::view(const std::vector<float>& majorants) const {
  MajorantGridView v;
  v.box = box_;
  v.dims = options_.dims;
  v.cellSize = cellSize_;
  v.invCellSize = Vec3f{1.f / cellSize_.x, 1.f / cellSize_.y, 1.f / cellSize_.z};
  v.majorant = majorants.data();
  return v;
}

void MacrocellGrid::computeMajorants(const TransferFunctionView& tf, MajorantArrays& majorants) const {
  computeMajorants(tf, majorants.cell);
  majorants.block.resize(std::size_t(blockShift_ >= 0 ? blockCount() : 0));
  if (blockShift_ >= 0) computeBlockMajorants(options_.dims, blockShift_, majorants.cell.data(), majorants.block.data());
}

void MacrocellGrid::updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                                    MajorantArrays& majorants) const {
  updateMajorants(tf, cells, majorants.cell);
  if (blockShift_ < 0 || cells.empty()) return;
  // Recompute each touched block from its cells (exact, whichever way the majorants moved).
  const Int3 d = options_.dims;
  std::vector<int> blocks;
  blocks.reserve(cells.size());
  for (int c : cells) {
    const Int3 cc{c % d.x, (c / d.x) % d.y, c / (d.x * d.y)};
    blocks.push_back(blockIndexOfCell(blockDims_, blockShift_, cc));
  }
  std::sort(blocks.begin(), blocks.end());
  blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
  for (int b : blocks) {
    const Int3 bc{b % blockDims_.x, (b / blockDims_.x) % blockDims_.y, b / (blockDims_.x * blockDims_.y)};
    majorants.block[b] = blockMaxMajorant(majorants.cell.data(), d, blockShift_, bc);
  }
}

MajorantGridView MacrocellGrid::view(const MajorantArrays& majorants) const {
  MajorantGridView v = view(majorants.cell);
  if (blockShift_ >= 0 && int(majorants.block.size()) == blockCount()) {
    v.blockMajorant = majorants.block.data();
    v.blockDims = blockDims_;
    v.blockShift = blockShift_;
  }
  return v;
}

bool MacrocellGrid::refine(int cell, float value) {
  if (!std::isfinite(value) || cell < 0 || cell >= cellCount_) return false;
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
