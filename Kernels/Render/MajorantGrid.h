#pragma once
// The majorant grid and the 3D DDA that walks a ray through it, cell by cell, front to back.
// Device-facing: a view of host-owned arrays plus INR_HD functions. The DDA state lives in the
// ray state (current cell and the ray parameter of the next crossing per axis), so traversal can
// be suspended when a query is emitted and resumed after the evaluation stage.
#include "Render/RenderMath.h"

namespace inr {

// Empty-space skipping: an optional coarse level over blocks of B^3 cells (B = 2^blockShift)
// holds the maximum majorant of each block's cells. A ray in an empty cell whose block is empty
// too jumps over it and the empty blocks after it (ddaSkipEmptyBlocks, a DDA over the blocks)
// instead of stepping cell by cell. Empty cells draw no random numbers, so the jump changes no
// result: it lands on exactly the cell, crossing parameters and ray parameter the cell-by-cell
// walk would reach. The level must be conservative (block value >= every cell majorant in it);
// without it (blockMajorant == nullptr) the walk is cell by cell.

struct MajorantGridView {
  Box3f box;           // world box covered by the grid (the model's domain)
  Int3 dims;           // cells per axis
  Vec3f cellSize;      // (box.hi - box.lo) / dims
  Vec3f invCellSize{0.f, 0.f, 0.f};  // 1 / cellSize: only for estimates (skipping stays exact without)
  const float* majorant = nullptr;  // dims.x*dims.y*dims.z extinction upper bounds, x fastest
  // Coarse level (optional): blockDims.x*blockDims.y*blockDims.z block maxima, x fastest;
  // block b covers cells [b << blockShift, (b + 1) << blockShift) clipped to dims.
  const float* blockMajorant = nullptr;
  Int3 blockDims{0, 0, 0};
  int blockShift = 0;
};

INR_HD int linearCellIndex(const Int3& dims, const Int3& c) {
  return (c.z * dims.y + c.y) * dims.x + c.x;
}
// The inverse of linearCellIndex: a cell's (x, y, z) from its linear index.
INR_HD Int3 cellCoordinates(const Int3& dims, int cell) {
  const int yz = cell / dims.x;
  return Int3{cell % dims.x, yz % dims.y, yz / dims.y};
}

// Blocks per axis for B = 2^shift cells per block edge (partial blocks at the far faces).
INR_HD Int3 blockGridDims(const Int3& dims, int shift) {
  const int b = (1 << shift) - 1;
  return Int3{(dims.x + b) >> shift, (dims.y + b) >> shift, (dims.z + b) >> shift};
}

// Linear index of the block containing cell c.
INR_HD int blockIndexOfCell(const Int3& blockDims, int shift, const Int3& c) {
  return linearCellIndex(blockDims, Int3{c.x >> shift, c.y >> shift, c.z >> shift});
}

// The coarse level's value of block b: the maximum of its cells' majorants, 0 when none is
// positive (NaN majorants count as empty, as in traversal). Used by the CPU and GPU builds.
INR_HD float blockMaxMajorant(const float* majorant, const Int3& dims, int shift, const Int3& b) {
  const int x0 = b.x << shift, y0 = b.y << shift, z0 = b.z << shift;
  const int e = 1 << shift;
  const int x1 = x0 + e < dims.x ? x0 + e : dims.x;
  const int y1 = y0 + e < dims.y ? y0 + e : dims.y;
  const int z1 = z0 + e < dims.z ? z0 + e : dims.z;
  float m = 0.f;
  for (int z = z0; z < z1; ++z)
    for (int y = y0; y < y1; ++y) {
      const float* row = majorant + linearCellIndex(dims, Int3{0, y, z});
      for (int x = x0; x < x1; ++x) m = row[x] > m ? row[x] : m;
    }
  return m;
}

// Ray parameter at which the ray leaves the cell with index cellIndex along `axis` through its
// far face (INFINITY when the ray is parallel to that axis). Computed from the face position
// rather than accumulated, so long walks do not drift.
INR_HD float faceCrossing(const MajorantGridView& g, Vec3f origin, Vec3f dir, int cellIndex,
                          int axis) {
  const float d = component(dir, axis);
  if (d == 0.f) return INFINITY;
  const int face = cellIndex + (d > 0.f ? 1 : 0);
  const float plane = component(g.box.lo, axis) + float(face) * component(g.cellSize, axis);
  return (plane - component(origin, axis)) / d;
}
INR_HD float nextCrossing(const MajorantGridView& g, Vec3f origin, Vec3f dir, Int3 c, int axis) {
  return faceCrossing(g, origin, dir, component(c, axis), axis);
}

// Cell containing the ray point at parameter t (clamped into the grid: t is inside the box up
// to rounding), and the crossing parameters of that cell.
INR_HD void ddaStart(const MajorantGridView& g, Vec3f origin, Vec3f dir, float t, Int3& cell,
                     Vec3f& tNext) {
  const Vec3f p = origin + dir * t;
  cell.x = clampi(int(floorf((p.x - g.box.lo.x) / g.cellSize.x)), 0, g.dims.x - 1);
  cell.y = clampi(int(floorf((p.y - g.box.lo.y) / g.cellSize.y)), 0, g.dims.y - 1);
  cell.z = clampi(int(floorf((p.z - g.box.lo.z) / g.cellSize.z)), 0, g.dims.z - 1);
  tNext.x = nextCrossing(g, origin, dir, cell, 0);
  tNext.y = nextCrossing(g, origin, dir, cell, 1);
  tNext.z = nextCrossing(g, origin, dir, cell, 2);
}

// Parameter where the ray leaves the current cell.
INR_HD float ddaCellExit(const Vec3f& tNext) { return minf(tNext.x, minf(tNext.y, tNext.z)); }

// Steps into the next cell along the ray. Returns false when the ray leaves the grid.
INR_HD bool ddaStep(const MajorantGridView& g, Vec3f origin, Vec3f dir, Int3& cell, Vec3f& tNext) {
  int axis = 0;
  if (tNext.y < tNext.x) axis = 1;
  if (tNext.z < component(tNext, axis)) axis = 2;
  const float d = component(dir, axis);
  if (axis == 0) {
    cell.x += d > 0.f ? 1 : -1;
    if (cell.x < 0 || cell.x >= g.dims.x) return false;
    tNext.x = nextCrossing(g, origin, dir, cell, 0);
  } else if (axis == 1) {
    cell.y += d > 0.f ? 1 : -1;
    if (cell.y < 0 || cell.y >= g.dims.y) return false;
    tNext.y = nextCrossing(g, origin, dir, cell, 1);
  } else {
    cell.z += d > 0.f ? 1 : -1;
    if (cell.z < 0 || cell.z >= g.dims.z) return false;
    tNext.z = nextCrossing(g, origin, dir, cell, 2);
  }
  return true;
}

INR_HD float majorantAt(const MajorantGridView& g, const Int3& cell) {
  return g.majorant[linearCellIndex(g.dims, cell)];
}

// Whether a crossing at parameter tc along axis b comes before one at (tx, axis ax) in
// ddaStep's order (by parameter, ties to the lower axis).
INR_HD bool crossesBefore(float tc, int b, float tx, int ax) { return tc < tx || (tc == tx && b < ax); }

// True when the grid has a coarse level and cell's block has no cell with a positive majorant.
INR_HD bool inEmptyBlock(const MajorantGridView& g, const Int3& cell) {
  if (!g.blockMajorant) return false;
  return !(g.blockMajorant[blockIndexOfCell(g.blockDims, g.blockShift, cell)] > 0.f);
}

// First and last cell, along a ray with direction component d != 0, of block `block` of an axis
// with n cells (blocks of 2^shift cells; the last block may be partial).
INR_HD int blockFirstCell(int block, int shift, int n, float d) {
  const int hi = ((block + 1) << shift) - 1;
  return d > 0.f ? block << shift : (hi < n - 1 ? hi : n - 1);
}
INR_HD int blockLastCell(int block, int shift, int n, float d) {
  const int hi = ((block + 1) << shift) - 1;
  return d > 0.f ? (hi < n - 1 ? hi : n - 1) : block << shift;
}

// Jumps the DDA from `cell`, whose block is empty, over that block and every empty block after
// it: on return `cell` is the first cell of a non-empty block that ddaStep would reach, `tNext`
// its crossings and `t` the parameter where the walk enters it (the exit parameter of the cell
// before it). Returns false, leaving the state unchanged, when the walk would end first: the
// segment ends (a block exit >= tEnd, the test traverseRay makes at every cell exit) or the ray
// leaves the grid.
//
// Why this is the cell walk's state: ddaStep takes crossings in increasing parameter order,
// ties going to the lower axis (x, then y, then z), and per axis the crossings (faceCrossing of
// successive cells) are non-decreasing along the ray. Block faces are cell faces, so the walk
// moves from block to block in the order of the block-face crossings, with the same tie rule:
// a DDA over the blocks whose crossings are the cell walk's own block-face crossings. When it
// enters a non-empty block through axis a* at parameter T, every other axis b has taken exactly
// its crossings ordered before (T, a*); its cell is estimated from the position at T and then
// settled against faceCrossing itself (only the estimate uses invCellSize), so rounding cannot
// put it on the wrong side of a face. All state comes from faceCrossing, as in ddaStep, so it
// is bit for bit the state of the cell walk.
INR_HD bool ddaSkipEmptyBlocks(const MajorantGridView& g, Vec3f origin, Vec3f dir, float tEnd,
                               Int3& cell, Vec3f& tNext, float& t) {
  const int shift = g.blockShift;
  Int3 blk{cell.x >> shift, cell.y >> shift, cell.z >> shift};
  Vec3f bNext;  // crossing of the current block's far face, per axis
  for (int a = 0; a < 3; ++a) {
    const float d = component(dir, a);
    const int c = component(cell, a);
    const int l = d == 0.f ? c : blockLastCell(component(blk, a), shift, component(g.dims, a), d);
    setComponent(bNext, a, l == c ? component(tNext, a) : faceCrossing(g, origin, dir, l, a));
  }
  int axis;
  float tEntry;
  for (;;) {  // block DDA (ddaStep's axis choice) until a non-empty block
    axis = 0;
    if (bNext.y < bNext.x) axis = 1;
    if (bNext.z < component(bNext, axis)) axis = 2;
    tEntry = component(bNext, axis);
    if (minf(tEntry, tEnd) >= tEnd) return false;  // traverseRay's test at a cell exit
    const float d = component(dir, axis);
    const int b = component(blk, axis) + (d > 0.f ? 1 : -1);
    if (b < 0 || b >= component(g.blockDims, axis)) return false;
    setComponent(blk, axis, b);
    if (g.blockMajorant[linearCellIndex(g.blockDims, blk)] > 0.f) break;
    const int l = blockLastCell(b, shift, component(g.dims, axis), d);
    setComponent(bNext, axis, faceCrossing(g, origin, dir, l, axis));
  }

  // Settle each other axis in place (each reads only its own components of the old state).
  for (int b = 0; b < 3; ++b) {
    const float d = component(dir, b);
    if (b == axis || d == 0.f) continue;  // (the entry axis is set below; d == 0: no crossings)
    // The cell along b is the first one, from f (the first cell of b's current block, or the
    // start cell) to l (the block's last; its crossing is not before the entry), whose crossing
    // is not before the entry (tEntry, axis).
    const int c = component(cell, b);
    const int s = d > 0.f ? 1 : -1, n = component(g.dims, b), bb = component(blk, b);
    const int f = bb == (c >> shift) ? c : blockFirstCell(bb, shift, n, d);
    if (f == c && !crossesBefore(component(tNext, b), b, tEntry, axis)) continue;  // no crossing
    const int l = blockLastCell(bb, shift, n, d);
    const float x =
        (component(origin, b) + d * tEntry - component(g.box.lo, b)) * component(g.invCellSize, b);
    const float lo = float(s > 0 ? f : l), hi = float(s > 0 ? l : f);
    int k = int(floorf(x > lo ? (x < hi ? x : hi) : lo));  // estimate (NaN: lo)
    while (k != f && !crossesBefore(faceCrossing(g, origin, dir, k - s, b), b, tEntry, axis)) k -= s;
    float tk = k == c ? component(tNext, b) : faceCrossing(g, origin, dir, k, b);
    while (k != l && crossesBefore(tk, b, tEntry, axis)) {
      k += s;
      tk = faceCrossing(g, origin, dir, k, b);
    }
    setComponent(cell, b, k);
    setComponent(tNext, b, tk);
  }
  const int entryCell =
      blockFirstCell(component(blk, axis), shift, component(g.dims, axis), component(dir, axis));
  setComponent(cell, axis, entryCell);
  // t as traverseRay computes it at the exit of the cell before (ddaCellExit's choice among
  // equal values matters for the sign of a zero).
  setComponent(tNext, axis, tEntry);
  t = minf(ddaCellExit(tNext), tEnd);
  setComponent(tNext, axis, faceCrossing(g, origin, dir, entryCell, axis));
  return true;
}

}  // namespace inr
