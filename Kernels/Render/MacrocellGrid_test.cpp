#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Render/MacrocellGrid.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/TestFields.h"

namespace inr {
namespace {

const Box3f kBox{{-1, -1, -1}, {1, 1, 1}};

MacrocellOptions options(int n, int T) {
  MacrocellOptions o;
  o.dims = Int3{n, n, n};
  o.temporalSlices = T;
  return o;
}

TEST(MacrocellGrid, LatticeBoundsExactForLinearField) {
  // A linear field's extrema over a cell are at its corners, which are lattice points: the
  // lattice bounds are exact, and the 27-point mean is the cell-centre value.
  test::FunctionField f([](const QueryPoint& p) { return 2.f * p.x - p.y + 0.5f * p.z + p.t; });
  MacrocellGrid grid(f, kBox, 0.0, 1.0, options(6, 2));
  grid.setTime(0.0);
  const Vec3f cs = grid.cellSize();
  for (int z = 0; z < 6; ++z)
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 6; ++x) {
        const int c = linearCellIndex(grid.dims(), Int3{x, y, z});
        const float x0 = -1 + x * cs.x, y0 = -1 + y * cs.y, z0 = -1 + z * cs.z;
        const float lo = 2 * x0 - (y0 + cs.y) + 0.5f * z0;
        const float hi = 2 * (x0 + cs.x) - y0 + 0.5f * (z0 + cs.z);
        ASSERT_NEAR(grid.workingMin()[c], lo, 1e-5);
        ASSERT_NEAR(grid.workingMax()[c], hi, 1e-5);
        ASSERT_NEAR(grid.workingMean()[c], 0.5f * (lo + hi), 1e-5);
      }
}

// A slice built slab by slab (each lattice point evaluated once, a slab's first plane taken from
// the last slab) holds each cell's min / max / mean over its own 27 stencil points, evaluated
// directly here (up to the field's own float rounding, which the compiler may contract differently
// in this loop); and the same bounds bit for bit whatever the slab size (one layer, several, a
// partial last slab, the whole grid in one). The lattice is shared: (2 n + 1)^3 points per slice,
// not 27 per cell.
TEST(MacrocellGrid, SlabBuildEqualsEachCellsOwnStencil) {
  test::FunctionField f(test::smoothField);
  const Int3 dims{5, 3, 7};
  std::vector<float> wholeMin, wholeMax, wholeMean;
  for (const std::size_t planes : {std::size_t(1000), std::size_t(1), std::size_t(5), std::size_t(9)}) {
    MacrocellOptions o = options(1, 1);
    o.dims = dims;
    o.maxBatch = planes * 11 * 7;  // lattice planes of 11 x 7 points
    f.resetCounts();
    MacrocellGrid grid(f, kBox, 0.0, 1.0, o);
    grid.setTime(0.5);
    EXPECT_EQ(f.points(), std::size_t(11 * 7 * 15)) << planes << " planes a batch";
    const MacrocellGrid::Slice& s = grid.slice(0);
    if (wholeMin.empty()) {  // the first: the whole grid in one batch
      wholeMin = s.min, wholeMax = s.max, wholeMean = s.mean;
    } else {
      EXPECT_EQ(s.min, wholeMin) << planes << " planes a batch";
      EXPECT_EQ(s.max, wholeMax) << planes << " planes a batch";
      EXPECT_EQ(s.mean, wholeMean) << planes << " planes a batch";
    }
    const MacrocellLayout layout = MacrocellLayout::make(kBox, 0.0, 1.0, o);
    for (int z = 0; z < dims.z; ++z)
      for (int y = 0; y < dims.y; ++y)
        for (int x = 0; x < dims.x; ++x) {
          float mn = INFINITY, mx = -INFINITY;
          double sum = 0.0;
          for (int c = 2 * z; c <= 2 * z + 2; ++c)
            for (int b = 2 * y; b <= 2 * y + 2; ++b)
              for (int a = 2 * x; a <= 2 * x + 2; ++a) {
                const Vec3f p = latticePoint(layout, a, b, c);
                const float v = test::smoothField(QueryPoint{p.x, p.y, p.z, 0.5f});
                mn = std::min(mn, v);
                mx = std::max(mx, v);
                sum += v;
              }
          const int cell = linearCellIndex(dims, Int3{x, y, z});
          ASSERT_NEAR(s.min[cell], mn, 1e-6) << x << " " << y << " " << z << ", " << planes << " planes a batch";
          ASSERT_NEAR(s.max[cell], mx, 1e-6);
          ASSERT_NEAR(s.mean[cell], sum / 27.0, 1e-6);
        }
  }
}

TEST(MacrocellGrid, WorkingGridInterpolationExactAndLazy) {
  test::FunctionField f([](const QueryPoint&) { return 0.f; });
  MacrocellGrid grid(f, kBox, 10.0, 20.0, options(2, 3));  // slices at t = 10, 15, 20
  const int n = grid.cellCount();
  std::vector<float> a0(n), a1(n), b0(n), b1(n), m0(n), m1(n);
  for (int c = 0; c < n; ++c) {
    a0[c] = float(c);
    a1[c] = float(c) + 4.f;
    b0[c] = 10.f * c;
    b1[c] = 10.f * c + 8.f;
    m0[c] = 1.f;
    m1[c] = 3.f;
  }
  grid.setSlice(0, a0, a1, m0);
  grid.setSlice(1, b0, b1, m1);
  grid.setTime(11.25);  // a quarter of the way from slice 0 to slice 1
  int k0, k1;
  float w;
  grid.interpolationWeights(11.25, k0, k1, w);
  EXPECT_EQ(k0, 0);
  EXPECT_EQ(k1, 1);
  EXPECT_FLOAT_EQ(w, 0.25f);
  for (int c = 0; c < n; ++c) {
    EXPECT_FLOAT_EQ(grid.workingMin()[c], 0.75f * a0[c] + 0.25f * b0[c]);
    EXPECT_FLOAT_EQ(grid.workingMax()[c], 0.75f * a1[c] + 0.25f * b1[c]);
    EXPECT_FLOAT_EQ(grid.workingMean()[c], 1.5f);
  }
  EXPECT_EQ(f.points(), 0u);  // both slices given: nothing evaluated
  EXPECT_FALSE(grid.slice(2).built);
  grid.setTime(15.0);  // exactly on slice 1: slice 2 still not needed
  EXPECT_FALSE(grid.slice(2).built);
  EXPECT_EQ(f.points(), 0u);
  grid.setTime(25.0);  // clamped to the last slice: built on demand
  EXPECT_TRUE(grid.slice(2).built);
  EXPECT_EQ(f.points(), std::size_t(125));  // 2^3 cells: a lattice of 5^3 points
}

TEST(MacrocellGrid, LazyBuildsOnlyNeededSlicesAndReportsProgress) {
  test::FunctionField f(test::smoothField);
  MacrocellGrid lazy(f, kBox, 0.0, 1.0, options(8, 8));
  std::vector<double> fractions;
  std::string phase;
  lazy.setProgressHandler([&](double fr, const std::string& p) {
    fractions.push_back(fr);
    phase = p;
  });
  lazy.setTime(0.5);  // between slices 3 and 4
  EXPECT_EQ(lazy.buildStats().slicesBuilt, 2);
  EXPECT_EQ(f.points(), 2u * 17u * 17u * 17u);  // 2 slices x a lattice of 17^3 points (8^3 cells)
  // One build over both slices: 0 first, then one report per lattice batch (one batch per slice
  // here), strictly increasing, ending at 1.
  EXPECT_EQ(fractions, (std::vector<double>{0.0, 0.5, 1.0}));
  EXPECT_EQ(phase, "building macrocells: 2 of 8 time slices, 8x8x8 cells");
  fractions.clear();
  lazy.setTime(0.45);  // still between slices 3 and 4: nothing to build, nothing reported
  EXPECT_TRUE(fractions.empty());
  f.resetCounts();
  MacrocellOptions eager = options(8, 8);
  eager.lazySlices = false;
  MacrocellGrid all(f, kBox, 0.0, 1.0, eager);
  EXPECT_EQ(all.buildStats().slicesBuilt, 8);
  EXPECT_EQ(f.points(), 8u * 17u * 17u * 17u);
}

TEST(MacrocellGrid, ProgressPerLatticeBatch) {
  // 16^3 cells: lattice planes of 33^2 points; batches of 5 planes hold slabs of 2 cell layers:
  // 8 reports per slice, evenly spaced.
  test::FunctionField f(test::smoothField);
  MacrocellOptions o = options(16, 4);
  o.maxBatch = 5 * 33 * 33;
  MacrocellGrid grid(f, kBox, 0.0, 1.0, o);
  std::vector<double> fractions;
  grid.setProgressHandler([&](double fr, const std::string&) { fractions.push_back(fr); });
  grid.setTime(0.0);  // exactly on slice 0: one slice
  ASSERT_EQ(fractions.size(), 9u);
  for (std::size_t i = 0; i < fractions.size(); ++i) EXPECT_DOUBLE_EQ(fractions[i], double(i) / 8.0);
  fractions.clear();
  grid.buildAllSlices();  // the three others, as one build
  ASSERT_EQ(fractions.size(), 25u);
  EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
  EXPECT_DOUBLE_EQ(fractions.front(), 0.0);
  EXPECT_DOUBLE_EQ(fractions.back(), 1.0);
  EXPECT_EQ(grid.buildStats().slicesBuilt, 4);
  // The progress handler changes nothing built: same bounds as a grid without one.
  MacrocellGrid plain(f, kBox, 0.0, 1.0, o);
  plain.setTime(0.0);
  EXPECT_EQ(plain.workingMin(), grid.workingMin());
  EXPECT_EQ(plain.workingMax(), grid.workingMax());
}

TEST(MacrocellGrid, MajorantUpdateAfterTfChangeIsExact) {
  test::FunctionField f([](const QueryPoint&) { return 0.f; });
  MacrocellGrid grid(f, kBox, 0.0, 1.0, options(2, 1));
  const int n = grid.cellCount();  // 8 cells with known ranges
  std::vector<float> mn(n), mx(n), mean(n, 0.f);
  for (int c = 0; c < n; ++c) {
    mn[c] = 0.125f * c;
    mx[c] = 0.125f * c + 0.125f;
  }
  grid.setSlice(0, mn, mx, mean);
  grid.setTime(0.0);
  auto expected = [&](const TransferFunction& tf, int c) {
    // Knots on table entries: the maximum over [lo, hi] of the linear pieces is at a knot or an end.
    double a = 0.0;
    for (double x : {double(mn[c]), double(mx[c])}) a = std::max(a, tf.opacityAt(x));
    for (const auto& p : tf.opacity)
      if (p.x >= mn[c] && p.x <= mx[c]) a = std::max(a, p.alpha);
    return -std::log(1.0 - a) / tf.unitDistance;
  };
  TransferFunction tfA;
  tfA.color = {{0, 1, 1, 1}, {1, 1, 1, 1}};
  tfA.opacity = {{0, 0.0}, {1, 0.8}};
  tfA.unitDistance = 0.5;
  TransferFunction tfB = tfA;
  tfB.opacity = {{0, 0.0}, {0.25, 0.0}, {0.5, 0.9}, {0.625, 0.1}, {1, 0.1}};
  std::vector<float> maj;
  for (const TransferFunction* tf : {&tfA, &tfB}) {
    const TransferFunctionTable table(*tf, 1025);  // 1/1024 spacing: every knot is an entry
    grid.computeMajorants(table.view(), maj);
    for (int c = 0; c < n; ++c) EXPECT_NEAR(maj[c], expected(*tf, c), 1e-5) << "cell " << c;
  }
  // Refinement widens a cell and only that cell's majorant is recomputed.
  const TransferFunctionTable tableB(tfB, 1025);
  grid.computeMajorants(tableB.view(), maj);
  EXPECT_TRUE(grid.refine(0, 0.5f));  // cell 0 was [0, 0.125]
  EXPECT_FALSE(grid.refine(0, 0.3f));  // now inside
  const auto dirty = grid.takeDirtyCells();
  ASSERT_EQ(dirty, std::vector<int>{0});
  grid.updateMajorants(tableB.view(), dirty, maj);
  EXPECT_NEAR(maj[0], -std::log(1.0 - 0.9) / 0.5, 1e-5);
  EXPECT_FLOAT_EQ(grid.slice(0).max[0], 0.5f);  // fix kept in the slice for later time changes
}

// A narrow bump between lattice points: lattice sampling under-estimates its cell's maximum.
float bumpField(const QueryPoint& p) {
  const float dx = p.x - 0.31f, dy = p.y + 0.07f, dz = p.z - 0.19f;
  return 0.1f + 0.9f * std::exp(-(dx * dx + dy * dy + dz * dz) / (2.f * 0.06f * 0.06f));
}

float worstUnderestimate(const MacrocellGrid& grid, const FieldEvaluator& f) {
  // Dense sampling (8^3 per cell) of every cell; returns max(value - cell max).
  const Int3 d = grid.dims();
  const Vec3f cs = grid.cellSize();
  float worst = 0.f;
  for (int z = 0; z < d.z; ++z)
    for (int y = 0; y < d.y; ++y)
      for (int x = 0; x < d.x; ++x) {
        std::vector<QueryPoint> pts;
        for (int k = 0; k < 8; ++k)
          for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 8; ++i)
              pts.push_back({-1 + (x + (i + 0.5f) / 8) * cs.x, -1 + (y + (j + 0.5f) / 8) * cs.y,
                             -1 + (z + (k + 0.5f) / 8) * cs.z, 0.f});
        std::vector<float> v(pts.size());
        f.evaluate(pts.data(), pts.size(), v.data());
        const int c = linearCellIndex(d, Int3{x, y, z});
        for (float s : v) {
          worst = std::max(worst, s - grid.workingMax()[c]);
          worst = std::max(worst, grid.workingMin()[c] - s);
        }
      }
  return worst;
}

// A size x size view of the whole box with a preset transfer function over [lo, hi].
void frameTheBox(CpuWavefrontRenderer& r, int size, float lo, float hi, float opacity, double unitDistance) {
  RenderSettings s;
  s.width = s.height = size;
  r.setSettings(s);
  RenderScene scene;
  scene.camera = Camera::framing(kBox);
  scene.transferFunction = TransferFunction::preset(lo, hi, opacity);
  scene.transferFunction.unitDistance = unitDistance;
  r.setScene(scene);
}

TEST(MacrocellGrid, GhostPassesAndRefinementMakeBoundsConservative) {
  test::FunctionField f(bumpField);
  MacrocellGrid grid(f, kBox, 0.0, 1.0, options(8, 1));
  TrackingOptions topt;
  topt.ghostPixelStride = 1;
  CpuWavefrontRenderer r(f, grid, topt);
  frameTheBox(r, 64, 0.f, 1.f, 0.2f, 0.1);
  const float before = worstUnderestimate(grid, f);
  EXPECT_GT(before, 0.2f);  // the bump's peak is missed by the lattice
  const FrameStats g = r.runGhostPasses(8);
  EXPECT_GT(g.queries, 0u);
  EXPECT_GT(g.refinements, 0u);
  for (int k = 0; k < 4; ++k) r.renderFrame();
  const float after = worstUnderestimate(grid, f);
  EXPECT_LT(after, 0.5f * before);

  // Padding as a documented alternative: enough padding covers the miss outright.
  MacrocellOptions padded = options(8, 1);
  padded.boundsPadding = 3.0;  // x the sampled value range
  MacrocellGrid pgrid(f, kBox, 0.0, 1.0, padded);
  pgrid.setTime(0.0);
  EXPECT_LE(worstUnderestimate(pgrid, f), 0.f);
}

// A field that records every query (and its value) while `recording`.
struct Recorder : FieldEvaluator {
  explicit Recorder(const FieldEvaluator& f) : inner(f) {}
  const FieldEvaluator& inner;
  mutable std::vector<QueryPoint> pts;
  mutable std::vector<float> vals;
  bool recording = false;
  void evaluate(const QueryPoint* p, std::size_t n, float* out) const override {
    inner.evaluate(p, n, out);
    if (recording) pts.insert(pts.end(), p, p + n), vals.insert(vals.end(), out, out + n);
  }
  std::string name() const override { return "recorder"; }
};

// How many recorded samples lie outside their 8^3 cell's [min, max] (points exactly on a face
// may belong to either neighbour: a rounding slack).
int samplesOutsideTheirCells(const MacrocellGrid& grid, const Recorder& rec) {
  const Vec3f cs = grid.cellSize();
  int outside = 0;
  for (std::size_t i = 0; i < rec.pts.size(); ++i) {
    const Int3 c{std::min(7, int((rec.pts[i].x + 1) / cs.x)), std::min(7, int((rec.pts[i].y + 1) / cs.y)),
                 std::min(7, int((rec.pts[i].z + 1) / cs.z))};
    const int idx = linearCellIndex(grid.dims(), c);
    if (rec.vals[i] > grid.workingMax()[idx] + 1e-3f || rec.vals[i] < grid.workingMin()[idx] - 1e-3f) ++outside;
  }
  return outside;
}

TEST(MacrocellGrid, EverySampleTheRendererEvaluatedLiesInsideItsCell) {
  // After rendering, the refined bounds contain every value the renderer has seen.
  const test::FunctionField bump(bumpField);
  Recorder rec(bump);
  MacrocellGrid grid(rec, kBox, 0.0, 1.0, options(8, 1));
  CpuWavefrontRenderer r(rec, grid);
  rec.recording = true;
  frameTheBox(r, 48, 0.f, 1.f, 0.3f, 0.2);
  for (int k = 0; k < 3; ++k) r.renderFrame();
  ASSERT_GT(rec.pts.size(), 1000u);
  EXPECT_LE(samplesOutsideTheirCells(grid, rec), int(rec.pts.size() / 1000));
}

// The layout and the per-point / per-cell helpers both grids run (Render/MacrocellLayout.h).
TEST(MacrocellLayout, ValidatesAndSharesTheLatticeArithmetic) {
  MacrocellOptions o = options(4, 3);
  o.dims = Int3{5, 9, 4};
  o.skipBlockCells = 4;
  const MacrocellLayout l = MacrocellLayout::make(kBox, 0.0, 2.0, o);
  EXPECT_EQ(l.cellCount, 5 * 9 * 4);
  EXPECT_EQ(l.latticeDims.x, 11);
  EXPECT_EQ(l.latticeDims.y, 19);
  EXPECT_EQ(l.latticeDims.z, 9);
  EXPECT_EQ(l.latticePlanePoints, 11 * 19);
  EXPECT_EQ(l.blockCount(), 2 * 3 * 1);
  EXPECT_EQ(l.sliceTime(1), 1.0);
  EXPECT_EQ(l.majorantView(nullptr, nullptr).blockMajorant, nullptr);
  const float blocks[6] = {};
  EXPECT_EQ(l.majorantView(nullptr, blocks).blockMajorant, blocks);
  for (auto bad : {Int3{0, 1, 1}, Int3{1, -1, 1}}) {
    MacrocellOptions b = o;
    b.dims = bad;
    EXPECT_THROW(MacrocellLayout::make(kBox, 0.0, 1.0, b), std::invalid_argument);
  }
  MacrocellOptions b = o;
  b.boundsPadding = -0.1;
  EXPECT_THROW(MacrocellLayout::make(kBox, 0.0, 1.0, b), std::invalid_argument);
  EXPECT_THROW(MacrocellLayout::make(Box3f{{0, 0, 0}, {1, 0, 1}}, 0.0, 1.0, o), std::invalid_argument);
  EXPECT_THROW(l.checkSliceArrays(l.cellCount, l.cellCount, 1), std::invalid_argument);

  // Half-cell lattice steps from the box's corner, the last point on the box's far corner; a
  // slab's point q counts from its first plane, x fastest.
  const Vec3f first = latticePoint(l, 0, 0, 0);
  EXPECT_EQ(first.x, kBox.lo.x);
  EXPECT_EQ(first.z, kBox.lo.z);
  const Vec3f mid = latticePoint(l, 3, 8, 2);
  EXPECT_EQ(mid.x, kBox.lo.x + 1.5f * l.cellSize.x);
  EXPECT_EQ(mid.y, kBox.lo.y + 4.f * l.cellSize.y);
  EXPECT_EQ(mid.z, kBox.lo.z + 1.f * l.cellSize.z);
  const Vec3f far = latticePoint(l, 10, 18, 8);
  EXPECT_EQ(far.x, kBox.hi.x);
  EXPECT_EQ(far.y, kBox.hi.y);
  EXPECT_EQ(far.z, kBox.hi.z);
  const Vec3f q = slabLatticePoint(l, 2, 3 + 8 * 11);
  EXPECT_EQ(q.x, mid.x);
  EXPECT_EQ(q.y, mid.y);
  EXPECT_EQ(q.z, mid.z);
  // Slabs: whole cell layers whose 2 layers + 1 planes fit the batch, at least one, at most all.
  EXPECT_EQ(latticeSlabLayers(l, 5 * l.latticePlanePoints), 2);
  EXPECT_EQ(latticeSlabLayers(l, 6 * l.latticePlanePoints - 1), 2);
  EXPECT_EQ(latticeSlabLayers(l, 1), 1);
  EXPECT_EQ(latticeSlabLayers(l, 1000 * l.latticePlanePoints), 4);
  const long long X = l.latticeDims.x, P = l.latticePlanePoints;
  // Slabs of 3 layers over 4: the first evaluates its 7 planes; the second (one layer) carries
  // the first's last plane to its front and evaluates the 2 planes after it.
  EXPECT_EQ(latticeSlabPoints(l, 3), 7 * P);
  const LatticeSlab s0 = latticeSlab(l, 3, 0), s1 = latticeSlab(l, 3, 3);
  EXPECT_EQ(s0.carryFrom, -1);
  EXPECT_EQ(s0.first, 0);
  EXPECT_EQ(s0.count, 7 * P);
  EXPECT_EQ(s0.cell0, 0);
  EXPECT_EQ(s0.cell1, 3 * 5 * 9);
  EXPECT_EQ(s1.z1, 4);
  EXPECT_EQ(s1.plane0, 6);
  EXPECT_EQ(s1.carryFrom, 6 * P);
  EXPECT_EQ(s1.first, P);
  EXPECT_EQ(s1.count, 2 * P);
  EXPECT_EQ(s1.cell0, 3 * 5 * 9);
  EXPECT_EQ(s1.cell1, l.cellCount);

  // Stencil of cell (1, 2, 1) in a slab starting at plane 2: lattice points (2..4, 4..6, 2..4);
  // non-finite values are skipped.
  std::vector<float> v(std::size_t(3 * P), 100.f);
  auto at = [&](int a, int bb, int c) -> float& { return v[std::size_t((c - 2) * P + bb * X + a)]; };
  for (int c = 2; c < 5; ++c)
    for (int bb = 4; bb < 7; ++bb)
      for (int a = 2; a < 5; ++a) at(a, bb, c) = float((a - 2) + (bb - 4) + (c - 2));
  at(2, 4, 2) = NAN;
  at(3, 4, 2) = INFINITY;
  CellBounds r = reduceCellStencil(l, v.data(), 2, Int3{1, 2, 1});
  EXPECT_EQ(r.min, 1.f);
  EXPECT_EQ(r.max, 6.f);
  EXPECT_FLOAT_EQ(r.mean, (81.f - 0.f - 1.f) / 25.f);
  for (int c = 2; c < 5; ++c)
    for (int bb = 4; bb < 7; ++bb)
      for (int a = 2; a < 5; ++a) at(a, bb, c) = NAN;
  r = reduceCellStencil(l, v.data(), 2, Int3{1, 2, 1});
  EXPECT_FALSE(validBounds(r));

  // Working cells: interpolation, padding, one empty side, both empty.
  const CellBounds a{0.f, 1.f, 0.5f}, bnd{2.f, 4.f, 3.f}, empty{INFINITY, -INFINITY, 0.f};
  r = interpolateCell(a, bnd, 0.25f, 0.125f);
  EXPECT_EQ(r.min, 0.5f - 0.125f);
  EXPECT_EQ(r.max, 1.75f + 0.125f);
  EXPECT_EQ(r.mean, 1.125f);
  r = interpolateCell(empty, bnd, 0.25f, 0.5f);
  EXPECT_EQ(r.min, 1.5f);
  EXPECT_EQ(r.max, 4.5f);
  EXPECT_EQ(r.mean, 3.f);
  EXPECT_FALSE(validBounds(interpolateCell(empty, empty, 0.5f, 1.f)));
}

}  // namespace
}  // namespace inr

namespace inr {
namespace {

// A hash-grid model (tiny-cuda-nn's HashGrid) whose finest levels vary much faster than the
// 8^3 macrocells' lattice resolves: lattice sampling misses extremes between its points, and the
// renderer's refinement (ghost passes, then every evaluated sample) must repair the bounds so
// every value the renderer sees lies inside its cell's [min, max].
TEST(MacrocellGrid, HashGridHighFrequencyLevelsKeepRefinedBoundsValid) {
  // 12 levels from base 4 by x1.6: the finest has ~ 4 * 1.6^11 = 700 cells across the box.
  test::HashGridOptions o = test::hashGridMlp(3, 12, 14, 4, 1.6, 32, 1);
  o.tableScale = 1.f;
  o.seed = 34;
  const InrModel model = test::hashGridModel(o);
  const CpuInrEvaluator field(model);
  Recorder rec(field);
  MacrocellGrid grid(rec, kBox, 0.0, 1.0, options(8, 1));
  grid.setTime(0.0);
  const float before = worstUnderestimate(grid, field);
  EXPECT_GT(before, 0.f);  // the lattice misses the fine levels' extremes

  TrackingOptions topt;
  topt.ghostPixelStride = 1;
  CpuWavefrontRenderer r(rec, grid, topt);
  const std::array<float, 2> range = grid.workingValueRange();
  frameTheBox(r, 48, range[0], range[1], 0.3f, 0.2);
  rec.recording = true;
  const FrameStats g = r.runGhostPasses(8);
  EXPECT_GT(g.refinements, 0u);
  for (int k = 0; k < 3; ++k) r.renderFrame();
  ASSERT_GT(rec.pts.size(), 1000u);
  EXPECT_LE(samplesOutsideTheirCells(grid, rec), int(rec.pts.size() / 1000));
  EXPECT_LE(worstUnderestimate(grid, field), before);  // refinement only ever widens bounds

  // Padding, the documented alternative, covers the misses outright.
  MacrocellOptions padded = options(8, 1);
  padded.boundsPadding = 3.0;
  MacrocellGrid pgrid(field, kBox, 0.0, 1.0, padded);
  pgrid.setTime(0.0);
  EXPECT_LE(worstUnderestimate(pgrid, field), 0.f);
}

}  // namespace
}  // namespace inr
