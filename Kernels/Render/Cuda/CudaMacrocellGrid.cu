#include "Render/Cuda/CudaMacrocellGrid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "Common/Cuda/DeviceBuffer.h"
#include "Common/DeviceMemory.h"
#include "Evaluator/Cuda/DeviceFieldEvaluator.h"
#include "Render/Cuda/DeviceRefine.cuh"
#include "Render/Cuda/DeviceTransferFunction.h"

namespace inr {

namespace {

// Lattice points [first, first + count) of the planes from plane0 on, in MacrocellGrid::
// buildSlice's order and arithmetic (MacrocellLayout's slabLatticePoint).
__global__ void latticePointsKernel(MacrocellLayout layout, int plane0, long long first, long long count, float time,
                                    float4* points) {
  const long long q = (long long)blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= count) return;
  const Vec3f x = slabLatticePoint(layout, plane0, first + q);
  points[q] = make_float4(x.x, x.y, x.z, time);
}

// One thread per cell of the slab (linear indices [cell0, cell1)): MacrocellLayout's stencil reduction.
__global__ void latticeReduceKernel(MacrocellLayout layout, LatticeSlab slab, const float* values, CellBoundsArrays out) {
  const long long c = slab.cell0 + (long long)blockIdx.x * blockDim.x + threadIdx.x;
  if (c >= slab.cell1) return;
  out.store(int(c), reduceCellStencil(layout, values, slab.plane0, cellCoordinates(layout.dims, int(c))));
}

// MacrocellGrid::interpolateWorkingGrid, per cell (MacrocellLayout's interpolateCell).
__global__ void interpolateKernel(int cells, CellBoundsView a, CellBoundsView b, float w, float pad,
                                  CellBoundsArrays out) {
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (c < cells) out.store(c, interpolateCell(a.at(c), b.at(c), w, pad));
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
      const Int3 cc = cellCoordinates(dims, c);
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
  cuda::DeviceBuffer<float> expected;  // pruning's s^_c per working cell
  cuda::DeviceBuffer<unsigned> dirtyMask;
  cuda::DeviceBuffer<int> dirtyList;
  cuda::DeviceBuffer<unsigned> dirtyCount;
  cuda::DeviceBuffer<unsigned long long> refinements;
  cuda::DeviceBuffer<float> range;
  cuda::DeviceBuffer<float4> points;
  cuda::DeviceBuffer<float> values;
};

CudaMacrocellGrid::CudaMacrocellGrid(const DeviceFieldEvaluator& evaluator, const Box3f& box, double timeBegin,
                                     double timeEnd, MacrocellOptions options, cudaStream_t stream)
    : MacrocellGridBase(box, timeBegin, timeEnd, options), evaluator_(evaluator), stream_(stream),
      impl_(std::make_unique<Impl>()) {
  const int n = layout_.cellCount;
  Impl& I = *impl_;
  I.slices.resize(layout_.temporalSlices);
  const DeviceAllocationPurpose purpose(
      "the working macrocell grid (" + gridSize() + ", 7 values per cell)",
      "lower the macrocell resolution (Macrocell Resolution; inr render --macrocells)");
  I.workMin.resize(n);
  I.workMax.resize(n);
  I.workMean.resize(n);
  I.workMin.zero(stream_);
  I.workMax.zero(stream_);
  I.workMean.zero(stream_);
  I.expected.resize(n);
  I.expected.zero(stream_);
  I.dirtyMask.resize(n);
  I.dirtyMask.zero(stream_);
  I.dirtyList.resize(n);
  I.dirtyCount.resize(1);
  I.dirtyCount.zero(stream_);
  I.refinements.resize(1);
  I.refinements.zero(stream_);
  I.range.resize(2);
  if (!options_.lazySlices) buildAllSlices();
}

CudaMacrocellGrid::~CudaMacrocellGrid() = default;

std::string CudaMacrocellGrid::gridSize() const {
  const Int3 d = layout_.dims;
  return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z) + " cells";
}

bool CudaMacrocellGrid::sliceBuilt(int k) const { return impl_->slices.at(k).built; }

void CudaMacrocellGrid::setSlice(int k, const std::vector<float>& mn, const std::vector<float>& mx,
                                 const std::vector<float>& mean) {
  layout_.checkSliceArrays(mn.size(), mx.size(), mean.size());
  Impl::Slice& s = impl_->slices.at(k);
  s.min.upload(mn, stream_);
  s.max.upload(mx, stream_);
  s.mean.upload(mean, stream_);
  INR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the host arrays may go away on return
  s.built = true;
}

void CudaMacrocellGrid::buildSlice(int k) {
  Impl& I = *impl_;
  const MacrocellLayout& l = layout_;
  const int layers = latticeSlabLayers(l, (long long)options_.gpuMaxBatch);
  const std::size_t batch = std::size_t(latticeSlabPoints(l, layers));
  const float time = float(sliceTime(k));
  Impl::Slice& s = I.slices[k];
  try {
    const DeviceAllocationPurpose purpose(
        "temporal macrocell slice " + std::to_string(k + 1) + " of " + std::to_string(layout_.temporalSlices) +
            " (" + gridSize() + "; every slice built stays on the GPU)",
        "lower the macrocell resolution or the temporal slices (Macrocell Resolution, Temporal Slices; inr "
        "render --macrocells, --time-slices)");
    s.min.resize(layout_.cellCount);
    s.max.resize(layout_.cellCount);
    s.mean.resize(layout_.cellCount);
    if (I.points.size() < batch) {
      I.points.resize(batch);
      I.values.resize(batch);
    }
  } catch (const DeviceOutOfMemory&) {
    s = Impl::Slice{};  // nothing half-built stays allocated; a later build tries again
    throw;
  }
  const CellBoundsArrays out{s.min.get(), s.max.get(), s.mean.get()};
  for (int z0 = 0; z0 < l.dims.z; z0 += layers) {
    const LatticeSlab slab = latticeSlab(l, layers, z0);
    if (slab.carryFrom >= 0)
      INR_CUDA_CHECK(cudaMemcpyAsync(I.values.get(), I.values.get() + slab.carryFrom,
                                     sizeof(float) * l.latticePlanePoints, cudaMemcpyDeviceToDevice, stream_));
    latticePointsKernel<<<blocksFor(slab.count, 256), 256, 0, stream_>>>(l, slab.plane0, slab.first, slab.count, time,
                                                                         I.points.get());
    INR_CUDA_CHECK_LAUNCH("latticePointsKernel");
    evaluator_.evaluateDevice(I.points.get(), int(slab.count), I.values.get() + slab.first, nullptr, stream_);
    latticeReduceKernel<<<blocksFor(slab.cell1 - slab.cell0, 256), 256, 0, stream_>>>(l, slab, I.values.get(), out);
    INR_CUDA_CHECK_LAUNCH("latticeReduceKernel");
    stats_.evaluations += std::size_t(slab.count);
  }
  INR_CUDA_CHECK(cudaStreamSynchronize(stream_));
  s.built = true;
}

void CudaMacrocellGrid::clearDirtyCells() {
  impl_->dirtyMask.zero(stream_);
  impl_->dirtyCount.zero(stream_);
}

void CudaMacrocellGrid::interpolateWorkingGrid() {
  Impl& I = *impl_;
  const Impl::Slice& a = I.slices[k0_];
  const Impl::Slice& b = I.slices[w_ > 0.f ? k1_ : k0_];
  const int cells = layout_.cellCount;
  float pad = 0.f;
  const int blocks = blocksFor(cells, 256);
  if (options_.boundsPadding > 0.0) {
    initRangeKernel<<<1, 1, 0, stream_>>>(I.range.get());
    rangeKernel<<<blocks, 256, 0, stream_>>>(cells, a.min.get(), a.max.get(), I.range.get());
    rangeKernel<<<blocks, 256, 0, stream_>>>(cells, b.min.get(), b.max.get(), I.range.get());
    INR_CUDA_CHECK_LAUNCH("rangeKernel");
    const std::vector<float> r = I.range.download(stream_);
    pad = layout_.boundsPad(r[0], r[1]);
  }
  interpolateKernel<<<blocks, 256, 0, stream_>>>(cells, CellBoundsView{a.min.get(), a.max.get(), a.mean.get()},
                                                  CellBoundsView{b.min.get(), b.max.get(), b.mean.get()}, w_, pad,
                                                  CellBoundsArrays{I.workMin.get(), I.workMax.get(), I.workMean.get()});
  INR_CUDA_CHECK_LAUNCH("interpolateKernel");
  // A new working grid restarts pruning's estimates from its lattice means.
  INR_CUDA_CHECK(cudaMemcpyAsync(I.expected.get(), I.workMean.get(), std::size_t(cells) * sizeof(float),
                                 cudaMemcpyDeviceToDevice, stream_));
}

PruneView CudaMacrocellGrid::pruneView(PruneView thresholds) {
  thresholds.cellMin = impl_->workMin.get();
  thresholds.cellMax = impl_->workMax.get();
  thresholds.expected = impl_->expected.get();
  return thresholds;
}

std::vector<float> CudaMacrocellGrid::downloadExpected() const { return impl_->expected.download(stream_); }

std::array<float, 2> CudaMacrocellGrid::workingValueRange() const {
  Impl& I = *impl_;
  initRangeKernel<<<1, 1, 0, stream_>>>(I.range.get());
  const int cells = layout_.cellCount;
  rangeKernel<<<blocksFor(cells, 256), 256, 0, stream_>>>(cells, I.workMin.get(), I.workMax.get(), I.range.get());
  INR_CUDA_CHECK_LAUNCH("rangeKernel");
  const std::vector<float> r = I.range.download(stream_);
  if (!(r[0] <= r[1])) return {0.f, 1.f};
  return {r[0], r[1]};
}

void CudaMacrocellGrid::computeMajorants(const TransferFunctionView& tf, float* majorants,
                                         float* blockMajorants) const {
  const Impl& I = *impl_;
  const MacrocellLayout& l = layout_;
  majorantKernel<<<blocksFor(l.cellCount, 256), 256, 0, stream_>>>(l.cellCount, tf, I.workMin.get(), I.workMax.get(),
                                                                   majorants);
  INR_CUDA_CHECK_LAUNCH("majorantKernel");
  if (blockMajorants && l.blockShift >= 0) {
    blockMajorantKernel<<<blocksFor(l.blockCount(), 128), 128, 0, stream_>>>(l.dims, l.blockShift, l.blockDims,
                                                                             majorants, blockMajorants);
    INR_CUDA_CHECK_LAUNCH("blockMajorantKernel");
  }
}

void CudaMacrocellGrid::updateDirtyMajorants(const TransferFunctionView& tf, float* majorants,
                                             float* blockMajorants) const {
  const Impl& I = *impl_;
  const MacrocellLayout& l = layout_;
  const int blocks = std::max(1, std::min(blocksFor(l.cellCount, 256), 264));
  dirtyMajorantKernel<<<blocks, 256, 0, stream_>>>(tf, I.workMin.get(), I.workMax.get(), majorants, I.dirtyList.get(),
                                                   I.dirtyCount.get(), I.dirtyMask.get(), l.dims,
                                                   std::max(l.blockShift, 0), l.blockDims,
                                                   l.blockShift >= 0 ? blockMajorants : nullptr);
  INR_CUDA_CHECK_LAUNCH("dirtyMajorantKernel");
  INR_CUDA_CHECK(cudaMemsetAsync(I.dirtyCount.get(), 0, sizeof(unsigned), stream_));
}

MajorantGridView CudaMacrocellGrid::view(const float* majorants, const float* blockMajorants) const {
  return layout_.majorantView(majorants, blockMajorants);
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
  r.cells = layout_.cellCount;
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
