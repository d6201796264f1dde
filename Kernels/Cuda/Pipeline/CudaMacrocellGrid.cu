#include "Cuda/Pipeline/CudaMacrocellGrid.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Cuda/CudaInrEvaluator.h"
#include "Cuda/Pipeline/DeviceBuffer.h"
#include "Cuda/Pipeline/DeviceRefine.cuh"

namespace inr {

namespace {

constexpr int C = MacrocellGrid::kTileCells;
constexpr int L = MacrocellGrid::kTileLattice;
constexpr int P = L * L * L;
// Lattice points per evaluator call on the GPU (64 MiB of float4): large enough to fill the
// device, small enough for any grid.
constexpr long long kGpuLatticeBatch = 1ll << 22;

struct LatticeParams {
  Box3f box;
  Vec3f cellSize;
  Int3 dims;
  int tx, ty;
  long long firstTile, tileCount;
  float time;
};

// Lattice points of a batch of tiles, in MacrocellGrid::buildSlice's order and arithmetic
// (explicit _rn operations: no FMA contraction, so the points are the CPU's bit for bit).
__global__ void latticePointsKernel(LatticeParams p, float4* points) {
  const long long idx = (long long)blockIdx.x * blockDim.x + threadIdx.x;
  if (idx >= p.tileCount * P) return;
  const long long b = idx / P;
  const int q = int(idx - b * P);
  const long long tile = p.firstTile + b;
  const int ix = int(tile % p.tx), iy = int((tile / p.tx) % p.ty), iz = int(tile / ((long long)p.tx * p.ty));
  const int a = q % L, bb = (q / L) % L, c = q / (L * L);
  const float x = __fadd_rn(p.box.lo.x, __fmul_rn(__fadd_rn(float(ix * C), 0.5f * a), p.cellSize.x));
  const float y = __fadd_rn(p.box.lo.y, __fmul_rn(__fadd_rn(float(iy * C), 0.5f * bb), p.cellSize.y));
  const float z = __fadd_rn(p.box.lo.z, __fmul_rn(__fadd_rn(float(iz * C), 0.5f * c), p.cellSize.z));
  points[idx] = make_float4(fminf(x, p.box.hi.x), fminf(y, p.box.hi.y), fminf(z, p.box.hi.z), p.time);
}

// One thread per cell of the batch's tiles: min/max/mean over its 3³ lattice stencil.
__global__ void latticeReduceKernel(LatticeParams p, const float* values, float* mn, float* mx, float* mean) {
  const long long idx = (long long)blockIdx.x * blockDim.x + threadIdx.x;
  constexpr int CC = C * C * C;
  if (idx >= p.tileCount * CC) return;
  const long long b = idx / CC;
  const int local = int(idx - b * CC);
  const long long tile = p.firstTile + b;
  const int ix = int(tile % p.tx), iy = int((tile / p.tx) % p.ty), iz = int(tile / ((long long)p.tx * p.ty));
  const int cx = local % C, cy = (local / C) % C, cz = local / (C * C);
  const Int3 cell{ix * C + cx, iy * C + cy, iz * C + cz};
  if (cell.x >= p.dims.x || cell.y >= p.dims.y || cell.z >= p.dims.z) return;
  const float* v = values + b * P;
  float lo = INFINITY, hi = -INFINITY;
  double sum = 0.0;
  int n = 0;
  for (int c = 2 * cz; c <= 2 * cz + 2; ++c)
    for (int bb = 2 * cy; bb <= 2 * cy + 2; ++bb)
      for (int a = 2 * cx; a <= 2 * cx + 2; ++a) {
        const float s = v[(c * L + bb) * L + a];
        if (!isFiniteValue(s)) continue;  // a NaN output says nothing about bounds
        lo = fminf(lo, s);
        hi = fmaxf(hi, s);
        sum += s;
        ++n;
      }
  const int i = linearCellIndex(p.dims, cell);
  if (n == 0) {
    mn[i] = INFINITY;
    mx[i] = -INFINITY;
    mean[i] = 0.f;
  } else {
    mn[i] = lo;
    mx[i] = hi;
    mean[i] = float(sum / n);
  }
}

__device__ inline float lerpRn(float a, float b, float w) {
  return __fadd_rn(__fmul_rn(1.f - w, a), __fmul_rn(w, b));
}

// MacrocellGrid::interpolateWorkingGrid, per cell.
__global__ void interpolateKernel(int cells, const float* aMin, const float* aMax, const float* aMean, const float* bMin,
                                  const float* bMax, const float* bMean, float w, float pad, float* wMin, float* wMax,
                                  float* wMean) {
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (c >= cells) return;
  const bool aValid = aMin[c] <= aMax[c], bValid = bMin[c] <= bMax[c];
  if (aValid && bValid) {
    wMin[c] = __fsub_rn(lerpRn(aMin[c], bMin[c], w), pad);
    wMax[c] = __fadd_rn(lerpRn(aMax[c], bMax[c], w), pad);
    wMean[c] = lerpRn(aMean[c], bMean[c], w);
  } else if (aValid || bValid) {
    const float* sMin = aValid ? aMin : bMin;
    const float* sMax = aValid ? aMax : bMax;
    const float* sMean = aValid ? aMean : bMean;
    wMin[c] = __fsub_rn(sMin[c], pad);
    wMax[c] = __fadd_rn(sMax[c], pad);
    wMean[c] = sMean[c];
  } else {
    wMin[c] = INFINITY;
    wMax[c] = -INFINITY;
    wMean[c] = 0.f;
  }
}

// range[0] = min over valid cells' minima, range[1] = max over their maxima.
__global__ void rangeKernel(int cells, const float* mn, const float* mx, float* range) {
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (c >= cells) return;
  if (mn[c] <= mx[c]) {
    cuda::atomicMinFloat(&range[0], mn[c]);
    cuda::atomicMaxFloat(&range[1], mx[c]);
  }
}

__global__ void initRangeKernel(float* range) {
  range[0] = INFINITY;
  range[1] = -INFINITY;
}

__global__ void majorantKernel(int cells, TransferFunctionView tf, const float* mn, const float* mx, float* majorant) {
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (c < cells) majorant[c] = maxExtinctionOver(tf, mn[c], mx[c]);
}

// One thread per block of the coarse level: the block's maximum cell majorant (the same
// INR_HD reduction as the CPU's computeBlockMajorants).
__global__ void blockMajorantKernel(Int3 dims, int shift, Int3 blockDims, const float* majorant, float* blocks) {
  const int b = blockIdx.x * blockDim.x + threadIdx.x;
  if (b >= blockDims.x * blockDims.y * blockDims.z) return;
  const Int3 bc{b % blockDims.x, (b / blockDims.x) % blockDims.y, b / (blockDims.x * blockDims.y)};
  blocks[b] = blockMaxMajorant(majorant, dims, shift, bc);
}

// Fixed grid, count read on the device: no read-back of the dirty list's length. A refined
// cell's majorant only grows, so raising its block to it keeps the coarse level conservative.
__global__ void dirtyMajorantKernel(TransferFunctionView tf, const float* mn, const float* mx, float* majorant,
                                    const int* list, const unsigned* count, unsigned* mask, Int3 dims, int shift,
                                    Int3 blockDims, float* blocks) {
  const unsigned n = *count;
  for (unsigned k = blockIdx.x * blockDim.x + threadIdx.x; k < n; k += gridDim.x * blockDim.x) {
    const int c = list[k];
    const float m = maxExtinctionOver(tf, mn[c], mx[c]);
    majorant[c] = m;
    mask[c] = 0u;
    if (blocks && m > 0.f) {
      const Int3 cc{c % dims.x, (c / dims.x) % dims.y, c / (dims.x * dims.y)};
      cuda::atomicMaxFloat(&blocks[blockIndexOfCell(blockDims, shift, cc)], m);
    }
  }
}

int blocksFor(long long n, int threads) { return int((n + threads - 1) / threads); }

}  // namespace

struct CudaMacrocellGrid::Impl {
  struct Slice {
    cuda::DeviceBuffer<float> min, max, mean;
    bool built = false;
  };
  std::vector<Slice> slices;
  cuda::DeviceBuffer<float> workMin, workMax, workMean;
  cuda::DeviceBuffer<unsigned> dirtyMask;
  cuda::DeviceBuffer<int> dirtyList;
  cuda::DeviceBuffer<unsigned> dirtyCount;
  cuda::DeviceBuffer<unsigned long long> refinements;
  cuda::DeviceBuffer<float> range;
  cuda::DeviceBuffer<float4> points;
  cuda::DeviceBuffer<float> values;
};

CudaMacrocellGrid::CudaMacrocellGrid(const CudaInrEvaluator& evaluator, const Box3f& box, double timeBegin,
                                     double timeEnd, MacrocellOptions options, cudaStream_t stream)
    : evaluator_(evaluator), box_(box), timeBegin_(timeBegin), timeEnd_(timeEnd), options_(options),
      stream_(stream), impl_(std::make_unique<Impl>()) {
  const Int3 d = options_.dims;
  if (d.x < 1 || d.y < 1 || d.z < 1) throw std::invalid_argument("macrocell dims must be >= 1");
  if (options_.temporalSlices < 1) throw std::invalid_argument("temporal slices must be >= 1");
  if (!(box.hi.x > box.lo.x && box.hi.y > box.lo.y && box.hi.z > box.lo.z))
    throw std::invalid_argument("macrocell box must have positive extent");
  if (!(options_.boundsPadding >= 0.0)) throw std::invalid_argument("bounds padding must be >= 0");
  cellCount_ = d.x * d.y * d.z;
  blockShift_ = skipBlockShift(options_.skipBlockCells);
  if (blockShift_ >= 0) blockDims_ = blockGridDims(d, blockShift_);
  cellSize_ = Vec3f{(box.hi.x - box.lo.x) / d.x, (box.hi.y - box.lo.y) / d.y, (box.hi.z - box.lo.z) / d.z};
  Impl& I = *impl_;
  I.slices.resize(options_.temporalSlices);
  I.workMin.resize(cellCount_);
  I.workMax.resize(cellCount_);
  I.workMean.resize(cellCount_);
  I.workMin.zero(stream_);
  I.workMax.zero(stream_);
  I.workMean.zero(stream_);
  I.dirtyMask.resize(cellCount_);
  I.dirtyMask.zero(stream_);
  I.dirtyList.resize(cellCount_);
  I.dirtyCount.resize(1);
  I.dirtyCount.zero(stream_);
  I.refinements.resize(1);
  I.refinements.zero(stream_);
  I.range.resize(2);
  time_ = timeBegin;
  if (!options_.lazySlices) buildAllSlices();
}

CudaMacrocellGrid::~CudaMacrocellGrid() = default;

double CudaMacrocellGrid::sliceTime(int k) const {
  const int T = options_.temporalSlices;
  if (T == 1) return 0.5 * (timeBegin_ + timeEnd_);
  return timeBegin_ + (timeEnd_ - timeBegin_) * double(k) / double(T - 1);
}

bool CudaMacrocellGrid::sliceBuilt(int k) const { return impl_->slices.at(k).built; }

void CudaMacrocellGrid::interpolationWeights(double t, int& k0, int& k1, float& w) const {
  const int T = options_.temporalSlices;
  if (T == 1 || !(timeEnd_ > timeBegin_)) {
    k0 = k1 = 0;
    w = 0.f;
    return;
  }
  double u = (t - timeBegin_) / (timeEnd_ - timeBegin_) * double(T - 1);
  if (!(u > 0.0)) u = 0.0;
  u = std::min(u, double(T - 1));
  k0 = std::min(int(std::floor(u)), T - 1);
  k1 = std::min(k0 + 1, T - 1);
  w = k1 == k0 ? 0.f : float(u - k0);
}

void CudaMacrocellGrid::buildAllSlices() {
  for (int k = 0; k < options_.temporalSlices; ++k) ensureSlice(k);
}

void CudaMacrocellGrid::ensureSlice(int k) {
  if (!impl_->slices[k].built) buildSlice(k);
}

void CudaMacrocellGrid::buildSlice(int k) {
  const auto start = std::chrono::steady_clock::now();
  Impl& I = *impl_;
  const Int3 d = options_.dims;
  LatticeParams p;
  p.box = box_;
  p.cellSize = cellSize_;
  p.dims = d;
  p.tx = (d.x + C - 1) / C;
  p.ty = (d.y + C - 1) / C;
  const int tz = (d.z + C - 1) / C;
  const long long tiles = (long long)p.tx * p.ty * tz;
  const long long tilesPerBatch = std::max<long long>(1, kGpuLatticeBatch / P);
  p.time = float(sliceTime(k));
  Impl::Slice& s = I.slices[k];
  s.min.resize(cellCount_);
  s.max.resize(cellCount_);
  s.mean.resize(cellCount_);
  const long long batchTiles = std::min(tiles, tilesPerBatch);
  if (I.points.size() < std::size_t(batchTiles * P)) {
    I.points.resize(std::size_t(batchTiles * P));
    I.values.resize(std::size_t(batchTiles * P));
  }
  for (long long first = 0; first < tiles; first += tilesPerBatch) {
    p.firstTile = first;
    p.tileCount = std::min(tilesPerBatch, tiles - first);
    const long long n = p.tileCount * P;
    latticePointsKernel<<<blocksFor(n, 256), 256, 0, stream_>>>(p, I.points.get());
    INR_CUDA_CHECK_LAUNCH("latticePointsKernel");
    evaluator_.evaluateDevice(I.points.get(), int(n), I.values.get(), nullptr, stream_);
    latticeReduceKernel<<<blocksFor(p.tileCount * C * C * C, 256), 256, 0, stream_>>>(p, I.values.get(), s.min.get(),
                                                                                       s.max.get(), s.mean.get());
    INR_CUDA_CHECK_LAUNCH("latticeReduceKernel");
    stats_.evaluations += std::size_t(n);
  }
  INR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  s.built = true;
  stats_.slicesBuilt += 1;
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void CudaMacrocellGrid::setTime(double t) {
  time_ = t;
  interpolationWeights(t, k0_, k1_, w_);
  ensureSlice(k0_);
  if (w_ > 0.f) ensureSlice(k1_);
  interpolateWorkingGrid();
  impl_->dirtyMask.zero(stream_);
  impl_->dirtyCount.zero(stream_);
}

void CudaMacrocellGrid::interpolateWorkingGrid() {
  Impl& I = *impl_;
  const Impl::Slice& a = I.slices[k0_];
  const Impl::Slice& b = I.slices[w_ > 0.f ? k1_ : k0_];
  float pad = 0.f;
  const int blocks = blocksFor(cellCount_, 256);
  if (options_.boundsPadding > 0.0) {
    initRangeKernel<<<1, 1, 0, stream_>>>(I.range.get());
    rangeKernel<<<blocks, 256, 0, stream_>>>(cellCount_, a.min.get(), a.max.get(), I.range.get());
    rangeKernel<<<blocks, 256, 0, stream_>>>(cellCount_, b.min.get(), b.max.get(), I.range.get());
    INR_CUDA_CHECK_LAUNCH("rangeKernel");
    const std::vector<float> r = I.range.download(stream_);
    if (r[0] <= r[1]) pad = float(options_.boundsPadding * (double(r[1]) - r[0]));
  }
  interpolateKernel<<<blocks, 256, 0, stream_>>>(cellCount_, a.min.get(), a.max.get(), a.mean.get(), b.min.get(),
                                                  b.max.get(), b.mean.get(), w_, pad, I.workMin.get(),
                                                  I.workMax.get(), I.workMean.get());
  INR_CUDA_CHECK_LAUNCH("interpolateKernel");
}

std::array<float, 2> CudaMacrocellGrid::workingValueRange() const {
  Impl& I = *impl_;
  initRangeKernel<<<1, 1, 0, stream_>>>(I.range.get());
  rangeKernel<<<blocksFor(cellCount_, 256), 256, 0, stream_>>>(cellCount_, I.workMin.get(), I.workMax.get(),
                                                               I.range.get());
  INR_CUDA_CHECK_LAUNCH("rangeKernel");
  const std::vector<float> r = I.range.download(stream_);
  if (!(r[0] <= r[1])) return {0.f, 1.f};
  return {r[0], r[1]};
}

void CudaMacrocellGrid::computeMajorants(const TransferFunctionView& tf, float* majorants,
                                         float* blockMajorants) const {
  const Impl& I = *impl_;
  majorantKernel<<<blocksFor(cellCount_, 256), 256, 0, stream_>>>(cellCount_, tf, I.workMin.get(), I.workMax.get(),
                                                                   majorants);
  INR_CUDA_CHECK_LAUNCH("majorantKernel");
  if (blockMajorants && blockShift_ >= 0) {
    blockMajorantKernel<<<blocksFor(blockCount(), 128), 128, 0, stream_>>>(options_.dims, blockShift_, blockDims_,
                                                                           majorants, blockMajorants);
    INR_CUDA_CHECK_LAUNCH("blockMajorantKernel");
  }
}

void CudaMacrocellGrid::updateDirtyMajorants(const TransferFunctionView& tf, float* majorants,
                                             float* blockMajorants) const {
  const Impl& I = *impl_;
  const int blocks = std::max(1, std::min(blocksFor(cellCount_, 256), 264));
  dirtyMajorantKernel<<<blocks, 256, 0, stream_>>>(tf, I.workMin.get(), I.workMax.get(), majorants,
                                                   I.dirtyList.get(), I.dirtyCount.get(), I.dirtyMask.get(),
                                                   options_.dims, std::max(blockShift_, 0), blockDims_,
                                                   blockShift_ >= 0 ? blockMajorants : nullptr);
  INR_CUDA_CHECK_LAUNCH("dirtyMajorantKernel");
  INR_CUDA_CHECK(cudaMemsetAsync(I.dirtyCount.get(), 0, sizeof(unsigned), stream_));
}

MajorantGridView CudaMacrocellGrid::view(const float* majorants, const float* blockMajorants) const {
  MajorantGridView v;
  v.box = box_;
  v.dims = options_.dims;
  v.cellSize = cellSize_;
  v.invCellSize = Vec3f{1.f / cellSize_.x, 1.f / cellSize_.y, 1.f / cellSize_.z};
  v.majorant = majorants;
  if (blockMajorants && blockShift_ >= 0) {
    v.blockMajorant = blockMajorants;
    v.blockDims = blockDims_;
    v.blockShift = blockShift_;
  }
  return v;
}

DeviceRefineView CudaMacrocellGrid::refineView() {
  Impl& I = *impl_;
  DeviceRefineView r;
  r.workMin = I.workMin.get();
  r.workMax = I.workMax.get();
  Impl::Slice& a = I.slices[k0_];
  if (!a.built) throw std::logic_error("CudaMacrocellGrid::refineView: setTime first");
  r.slice0Min = a.min.get();
  r.slice0Max = a.max.get();
  if (w_ > 0.f) {
    Impl::Slice& b = I.slices[k1_];
    r.slice1Min = b.min.get();
    r.slice1Max = b.max.get();
  }
  r.dirtyMask = I.dirtyMask.get();
  r.dirtyList = I.dirtyList.get();
  r.dirtyCount = I.dirtyCount.get();
  r.refinements = I.refinements.get();
  r.cells = cellCount_;
  return r;
}

unsigned long long CudaMacrocellGrid::refinementCount() const { return impl_->refinements.download(stream_)[0]; }

void CudaMacrocellGrid::downloadSlice(int k, std::vector<float>& mn, std::vector<float>& mx,
                                      std::vector<float>& mean) const {
  const Impl::Slice& s = impl_->slices.at(k);
  if (!s.built) throw std::logic_error("CudaMacrocellGrid::downloadSlice: slice not built");
  mn = s.min.download(stream_);
  mx = s.max.download(stream_);
  mean = s.mean.download(stream_);
}

void CudaMacrocellGrid::downloadWorking(std::vector<float>& mn, std::vector<float>& mx,
                                        std::vector<float>& mean) const {
  mn = impl_->workMin.download(stream_);
  mx = impl_->workMax.download(stream_);
  mean = impl_->workMean.download(stream_);
}

}  // namespace inr
