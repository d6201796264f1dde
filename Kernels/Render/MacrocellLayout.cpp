#include "Render/MacrocellLayout.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

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

MacrocellLayout MacrocellLayout::make(const Box3f& box, double timeBegin, double timeEnd,
                                      const MacrocellOptions& options) {
  const Int3 d = options.dims;
  if (d.x < 1 || d.y < 1 || d.z < 1) throw std::invalid_argument("macrocell dims must be >= 1");
  if (options.temporalSlices < 1) throw std::invalid_argument("temporal slices must be >= 1");
  if (!(box.hi.x > box.lo.x && box.hi.y > box.lo.y && box.hi.z > box.lo.z)) {
    throw std::invalid_argument("macrocell box must have positive extent");
  }
  if (!(options.boundsPadding >= 0.0)) throw std::invalid_argument("bounds padding must be >= 0");
  MacrocellLayout l;
  l.box = box;
  l.dims = d;
  l.cellSize = Vec3f{(box.hi.x - box.lo.x) / d.x, (box.hi.y - box.lo.y) / d.y, (box.hi.z - box.lo.z) / d.z};
  l.timeBegin = timeBegin;
  l.timeEnd = timeEnd;
  l.temporalSlices = options.temporalSlices;
  l.cellCount = d.x * d.y * d.z;
  l.blockShift = skipBlockShift(options.skipBlockCells);
  if (l.blockShift >= 0) l.blockDims = blockGridDims(d, l.blockShift);
  l.latticeDims = Int3{2 * d.x + 1, 2 * d.y + 1, 2 * d.z + 1};
  l.latticePlanePoints = (long long)l.latticeDims.x * l.latticeDims.y;
  l.boundsPadding = options.boundsPadding;
  return l;
}

double MacrocellLayout::sliceTime(int k) const {
  const int T = temporalSlices;
  if (T == 1) return 0.5 * (timeBegin + timeEnd);
  return timeBegin + (timeEnd - timeBegin) * double(k) / double(T - 1);
}

void MacrocellLayout::interpolationWeights(double t, int& k0, int& k1, float& w) const {
  const int T = temporalSlices;
  if (T == 1 || !(timeEnd > timeBegin)) {
    k0 = k1 = 0;
    w = 0.f;
    return;
  }
  double u = (t - timeBegin) / (timeEnd - timeBegin) * double(T - 1);
  if (!(u > 0.0)) u = 0.0;  // also NaN
  u = std::min(u, double(T - 1));
  k0 = std::min(int(std::floor(u)), T - 1);
  k1 = std::min(k0 + 1, T - 1);
  w = k1 == k0 ? 0.f : float(u - k0);
}

float MacrocellLayout::boundsPad(float lo, float hi) const {
  return lo <= hi ? float(boundsPadding * (double(hi) - lo)) : 0.f;
}

void MacrocellLayout::checkSliceArrays(std::size_t mn, std::size_t mx, std::size_t mean) const {
  const std::size_t n = std::size_t(cellCount);
  if (mn != n || mx != n || mean != n) throw std::invalid_argument("setSlice: arrays must have one entry per cell");
}

MajorantGridView MacrocellLayout::majorantView(const float* cells, const float* blocks) const {
  MajorantGridView v;
  v.box = box;
  v.dims = dims;
  v.cellSize = cellSize;
  v.invCellSize = Vec3f{1.f / cellSize.x, 1.f / cellSize.y, 1.f / cellSize.z};
  v.majorant = cells;
  if (blocks && blockShift >= 0) {
    v.blockMajorant = blocks;
    v.blockDims = blockDims;
    v.blockShift = blockShift;
  }
  return v;
}

}  // namespace inr
