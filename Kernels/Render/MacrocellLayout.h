#pragma once
// What the CPU grid (MacrocellGrid) and the GPU grid (CudaMacrocellGrid) share: the options,
// the validated geometry of the 4D macrocell grid (MacrocellLayout: cells, slices, tiles,
// coarse skip level) and the per-point / per-cell arithmetic of a slice build and of the
// working-grid interpolation, written once as INR_HD functions. Both grids call these, so their
// lattice points and working bounds are computed the same way, bit for bit.
//
// Rounding: each float operation below is rounded on its own (addRn / mulRn / subRn), never
// fused into an FMA. On the device they are the _rn intrinsics (nvcc would otherwise contract
// a * b + c). On the host they are plain operations, and the translation units that call them
// (MacrocellGrid.cpp) are compiled with -ffp-contract=off (Render/CMakeLists.txt): GCC
// contracts across inlined calls by default, even in ISO C++ mode, wherever the target has FMA.
#include "Common/HostDevice.h"
#include "Render/MajorantGrid.h"

#include <cstddef>

namespace inr {

struct MacrocellOptions {
  Int3 dims{32, 32, 32};
  // Slices at times timeBegin + k (timeEnd - timeBegin) / (T - 1); T = 1 means one slice at the
  // middle of the time range, used for every time (right for static models).
  int temporalSlices = 16;
  // Build a slice only when a working grid needs it (start-up cost: at most 2 slices instead of T).
  bool lazySlices = true;
  // Safety padding: each working cell's [min, max] is widened by this fraction of the field's
  // value range (over the built slices). Lattice sampling and time interpolation can miss
  // extrema; padding trades looser majorants (more null collisions, more queries) for fewer
  // under-estimated cells before refinement catches them. 0 = off (the paper's default).
  double boundsPadding = 0.0;
  // Lattice points per evaluator call, on the CPU and on the GPU (whole cell layers: at least one
  // layer's three planes). The GPU's is larger: it fills the device and still fits any grid (64 MiB
  // of points).
  std::size_t maxBatch = std::size_t(1) << 18;
  std::size_t gpuMaxBatch = std::size_t(1) << 22;
  // Empty-space skipping: cells per edge of the blocks of the coarse level computed with every
  // majorant grid (the maximum majorant of each block of B^3 cells). A ray reaching an empty
  // block steps a DDA over the blocks to the next non-empty one instead of walking every cell;
  // images and query counts are bit-identical either way. A power of two (4 and 8 are the
  // useful sizes: larger blocks are rarely empty, smaller ones save few steps); 0 = no coarse
  // level (cell-by-cell DDA).
  int skipBlockCells = 4;
};

// Validates MacrocellOptions::skipBlockCells (throws std::invalid_argument) and returns log2 B,
// or -1 for 0 (off).
int skipBlockShift(int skipBlockCells);

// The grid's geometry, validated once (MacrocellLayout::make) and copied by value into kernels.
// A slice samples one lattice at the cells' boundaries and half-cell offsets, (2 dims + 1) points
// per axis, shared by neighbouring cells; each cell reduces the 3^3 lattice points covering it (its
// corners, edge and face midpoints and centre). Slices are built in slabs of whole cell layers
// along z (latticeSlabLayers), each slab's first lattice plane the previous slab's last, so every
// lattice point is evaluated once.
struct MacrocellLayout {
  Box3f box;
  Int3 dims{0, 0, 0};
  Vec3f cellSize{0.f, 0.f, 0.f};  // (box.hi - box.lo) / dims
  double timeBegin = 0.0, timeEnd = 0.0;
  int temporalSlices = 0;
  int cellCount = 0;
  int blockShift = -1;            // coarse level: log2 of the block edge in cells, -1 = off
  Int3 blockDims{0, 0, 0};        // blocks per axis (0 when off)
  Int3 latticeDims{0, 0, 0};      // lattice points per axis: 2 dims + 1
  long long latticePlanePoints = 0;  // lattice points per plane of constant z
  double boundsPadding = 0.0;

  // Validates (std::invalid_argument: non-positive dims, slices or box extent, negative padding,
  // bad skip block size) and fills the layout.
  static MacrocellLayout make(const Box3f& box, double timeBegin, double timeEnd, const MacrocellOptions& options);

  double sliceTime(int k) const;
  // The two slices and weight the working grid interpolates: (1 - w) * slice k0 + w * slice k1.
  void interpolationWeights(double t, int& k0, int& k1, float& w) const;
  int blockCount() const { return blockDims.x * blockDims.y * blockDims.z; }
  // Padding of working bounds for slices whose valid bounds span [lo, hi] (0 when lo > hi).
  float boundsPad(float lo, float hi) const;
  // Throws std::invalid_argument unless each array of a slice has one entry per cell.
  void checkSliceArrays(std::size_t min, std::size_t max, std::size_t mean) const;
  // The traversal's view of majorant arrays (host or device). No coarse level when `blocks` is
  // null or skipping is off.
  MajorantGridView majorantView(const float* cells, const float* blocks) const;
};

// ---- Per-point / per-cell arithmetic shared by the CPU and GPU grids ----------------------

INR_HD float addRn(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __fadd_rn(a, b);
#else
  return a + b;
#endif
}
INR_HD float subRn(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __fsub_rn(a, b);
#else
  return a - b;
#endif
}
INR_HD float mulRn(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __fmul_rn(a, b);
#else
  return a * b;
#endif
}

// Bounds of one macrocell. An empty range (min > max: +INF / -INF) means no finite value seen.
struct CellBounds {
  float min, max, mean;
};
INR_HD bool validBounds(const CellBounds& b) { return b.min <= b.max; }

// Read / write access to one slice's (or the working grid's) per-cell arrays.
struct CellBoundsView {
  const float* min;
  const float* max;
  const float* mean;
  INR_HD CellBounds at(int c) const { return CellBounds{min[c], max[c], mean[c]}; }
};
struct CellBoundsArrays {
  float* min;
  float* max;
  float* mean;
  INR_HD void store(int c, const CellBounds& b) const {
    min[c] = b.min;
    max[c] = b.max;
    mean[c] = b.mean;
  }
};

// Lattice point (gx, gy, gz), each in [0, 2 dims]: half-cell steps from the box's low corner,
// clamped to the box (the last point's rounding may pass it).
INR_HD Vec3f latticePoint(const MacrocellLayout& l, int gx, int gy, int gz) {
  const float x = addRn(l.box.lo.x, mulRn(0.5f * float(gx), l.cellSize.x));
  const float y = addRn(l.box.lo.y, mulRn(0.5f * float(gy), l.cellSize.y));
  const float z = addRn(l.box.lo.z, mulRn(0.5f * float(gz), l.cellSize.z));
  return Vec3f{minf(l.box.hi.x, x), minf(l.box.hi.y, y), minf(l.box.hi.z, z)};
}

// Point q (x fastest) of the lattice planes from plane0 on.
INR_HD Vec3f slabLatticePoint(const MacrocellLayout& l, int plane0, long long q) {
  const long long inPlane = q % l.latticePlanePoints;
  return latticePoint(l, int(inPlane % l.latticeDims.x), int(inPlane / l.latticeDims.x),
                      plane0 + int(q / l.latticePlanePoints));
}

// Cell layers per slab so a slab's lattice planes (2 layers + 1) hold at most maxPoints points
// (at least one layer), and at most the grid's.
INR_HD int latticeSlabLayers(const MacrocellLayout& l, long long maxPoints) {
  const long long planes = maxPoints / l.latticePlanePoints;
  const long long layers = (planes - 1) / 2;
  return layers < 1 ? 1 : (layers > l.dims.z ? l.dims.z : int(layers));
}

// Lattice values a slab of `layers` cell layers holds: its 2 layers + 1 planes.
INR_HD long long latticeSlabPoints(const MacrocellLayout& l, int layers) {
  return (2ll * layers + 1) * l.latticePlanePoints;
}

// The slab of a slice build starting at cell layer z0 (of at most `layers` layers; every slab but
// the last is full), in a buffer of latticeSlabPoints(l, layers) values holding its planes from
// plane0 = 2 z0 on. After the first slab, the first plane is the previous slab's last: carried
// from `carryFrom` in the buffer to its front (-1: nothing carried). The points to evaluate are
// [first, first + count) of the slab's; its cells are the linear indices [cell0, cell1).
struct LatticeSlab {
  int z0 = 0, z1 = 0, plane0 = 0;
  long long carryFrom = -1;
  long long first = 0, count = 0;
  int cell0 = 0, cell1 = 0;
};
INR_HD LatticeSlab latticeSlab(const MacrocellLayout& l, int layers, int z0) {
  LatticeSlab s;
  s.z0 = z0;
  s.z1 = z0 + layers < l.dims.z ? z0 + layers : l.dims.z;
  s.plane0 = 2 * z0;
  const long long plane = l.latticePlanePoints;
  if (z0 > 0) s.carryFrom = 2ll * layers * plane;
  s.first = z0 > 0 ? plane : 0;
  s.count = (2ll * (s.z1 - z0) + 1) * plane - s.first;
  s.cell0 = z0 * l.dims.x * l.dims.y;
  s.cell1 = s.z1 * l.dims.x * l.dims.y;
  return s;
}

// Bounds of cell `cell` from the values of the lattice planes from plane0 on (x fastest; the
// cell's planes 2 cell.z .. 2 cell.z + 2 among them): min, max and mean over its 3^3 stencil,
// skipping non-finite values (a NaN output says nothing about bounds); no finite value gives an
// empty range (majorant 0 until refinement sees a value).
INR_HD CellBounds reduceCellStencil(const MacrocellLayout& l, const float* slabValues, int plane0, Int3 cell) {
  const long long X = l.latticeDims.x, plane = l.latticePlanePoints;
  float mn = INFINITY, mx = -INFINITY;
  double sum = 0.0;
  int n = 0;
  for (int c = 2 * cell.z; c <= 2 * cell.z + 2; ++c)
    for (int b = 2 * cell.y; b <= 2 * cell.y + 2; ++b)
      for (int a = 2 * cell.x; a <= 2 * cell.x + 2; ++a) {
        const float s = slabValues[(c - plane0) * plane + b * X + a];
        if (!isFiniteValue(s)) continue;
        mn = minf(s, mn);
        mx = maxf(s, mx);
        sum += s;
        ++n;
      }
  if (n == 0) return CellBounds{INFINITY, -INFINITY, 0.f};
  return CellBounds{mn, mx, float(sum / n)};
}

// One working cell: (1 - w) * a + w * b, [min, max] widened by pad; a slice with an empty
// range (no finite value seen) gives way to the other; both empty stay empty.
INR_HD CellBounds interpolateCell(const CellBounds& a, const CellBounds& b, float w, float pad) {
  const bool aValid = validBounds(a), bValid = validBounds(b);
  if (aValid && bValid) {
    const float u = 1.f - w;
    return CellBounds{subRn(addRn(mulRn(u, a.min), mulRn(w, b.min)), pad),
                      addRn(addRn(mulRn(u, a.max), mulRn(w, b.max)), pad),
                      addRn(mulRn(u, a.mean), mulRn(w, b.mean))};
  }
  if (aValid || bValid) {
    const CellBounds& s = aValid ? a : b;
    return CellBounds{subRn(s.min, pad), addRn(s.max, pad), s.mean};
  }
  return CellBounds{INFINITY, -INFINITY, 0.f};
}

}  // namespace inr
