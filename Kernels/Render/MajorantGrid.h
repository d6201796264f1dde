#pragma once
// The majorant grid and the 3D DDA that walks a ray through it, cell by cell, front to back.
// Device-facing: a view of host-owned arrays plus INR_HD functions. The DDA state lives in the
// ray state (current cell and the ray parameter of the next crossing per axis), so traversal can
// be suspended when a query is emitted and resumed after the evaluation stage.
#include "Render/RenderMath.h"

namespace inr {

struct MajorantGridView {
  Box3f box;           // world box covered by the grid (the model's domain)
  Int3 dims;           // cells per axis
  Vec3f cellSize;      // (box.hi - box.lo) / dims
  const float* majorant = nullptr;  // dims.x*dims.y*dims.z extinction upper bounds, x fastest
};

INR_HD int linearCellIndex(const Int3& dims, const Int3& c) {
  return (c.z * dims.y + c.y) * dims.x + c.x;
}

// Ray parameter at which the ray leaves cell c through its far face along `axis`
// (INFINITY when the ray is parallel to that axis). Computed from the face position rather
// than accumulated, so long walks do not drift.
INR_HD float nextCrossing(const MajorantGridView& g, Vec3f origin, Vec3f dir, Int3 c, int axis) {
  const float d = component(dir, axis);
  if (d == 0.f) return INFINITY;
  const int face = component(c, axis) + (d > 0.f ? 1 : 0);
  const float plane = component(g.box.lo, axis) + float(face) * component(g.cellSize, axis);
  return (plane - component(origin, axis)) / d;
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

}  // namespace inr
