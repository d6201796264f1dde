// Empty-space skipping (MacrocellOptions::skipBlockCells): the coarse block level of the
// majorant grid, the DDA's jump over empty blocks, and the renderer with skipping on and off.
// Empty cells draw no random numbers, so skipping must change nothing: every comparison here is
// exact (bitwise images, equal query counts).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/MacrocellGrid.h"
#include "Render/MajorantGrid.h"
#include "TestSupport/TestFields.h"

namespace inr {
namespace {

const Box3f kBox{{-1, -1, -1}, {1, 1, 1}};

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

// TFs whose zero-opacity end is a float: the table's first entry is then exactly 0 and cells
// below it are empty. (At an end such as 0.05, float(0.05) > 0.05 and the entry gets a tiny
// positive opacity, so no cell is ever empty.)
TransferFunction sparseTf() { return TransferFunction::preset(0.0625, 1.0, 0.8); }
TransferFunction denseTf() { return TransferFunction::preset(0.25, 0.875, 0.5); }

// ---------------------------------------------------------------- the coarse level

TEST(EmptySpaceSkipping, OptionValidation) {
  EXPECT_EQ(skipBlockShift(0), -1);
  EXPECT_EQ(skipBlockShift(1), 0);
  EXPECT_EQ(skipBlockShift(4), 2);
  EXPECT_EQ(skipBlockShift(8), 3);
  EXPECT_THROW(skipBlockShift(3), std::invalid_argument);
  EXPECT_THROW(skipBlockShift(-4), std::invalid_argument);
  EXPECT_THROW(skipBlockShift(2048), std::invalid_argument);
  test::FunctionField f([](const QueryPoint&) { return 0.f; });
  MacrocellOptions o;
  o.dims = Int3{4, 4, 4};
  o.skipBlockCells = 6;
  EXPECT_THROW(MacrocellGrid(f, kBox, 0, 1, o), std::invalid_argument);
  EXPECT_EQ(MacrocellOptions{}.skipBlockCells, 4);  // the documented default
}

TEST(EmptySpaceSkipping, BlockLevelIsTheMaxOfItsCells) {
  // Partial blocks on every axis; several block sizes, off included.
  test::FunctionField f(test::sparseField);
  for (int B : {0, 1, 2, 4, 8}) {
    MacrocellOptions o;
    o.dims = Int3{18, 13, 9};
    o.temporalSlices = 1;
    o.skipBlockCells = B;
    MacrocellGrid grid(f, kBox, 0, 1, o);
    grid.setTime(0.0);
    const TransferFunctionTable table(sparseTf());
    MajorantArrays maj;
    grid.computeMajorants(table.view(), maj);
    ASSERT_EQ(int(maj.cell.size()), grid.cellCount());
    const MajorantGridView v = grid.view(maj);
    if (B == 0) {
      EXPECT_TRUE(maj.block.empty());
      EXPECT_EQ(v.blockMajorant, nullptr);
      continue;
    }
    ASSERT_EQ(int(maj.block.size()), grid.blockCount());
    EXPECT_EQ(grid.blockDims().x, (18 + B - 1) / B);
    EXPECT_EQ(v.blockMajorant, maj.block.data());
    EXPECT_EQ(1 << v.blockShift, B);
    EXPECT_TRUE(maj.block == test::bruteBlocks(o.dims, B, maj.cell)) << "B = " << B;
    // The sparse field leaves most blocks of 4 empty (the point of the level), not all.
    const auto empty = std::count(maj.block.begin(), maj.block.end(), 0.f);
    if (B == 4) {
      EXPECT_GT(empty, grid.blockCount() / 3);
      EXPECT_LT(empty, grid.blockCount());
    }
    // The view's lookup agrees with the cells: a block is empty iff all its cells are.
    for (int z = 0; z < o.dims.z; ++z)
      for (int y = 0; y < o.dims.y; ++y)
        for (int x = 0; x < o.dims.x; ++x) {
          const Int3 c{x, y, z};
          if (inEmptyBlock(v, c)) ASSERT_EQ(majorantAt(v, c), 0.f);
        }
  }
}

TEST(EmptySpaceSkipping, RefinementKeepsBlocksConservative) {
  // Cell 0 starts with bounds [0, 0.1] (transparent: its block is empty); refinement with a
  // sample of 0.9 (as a ghost pass would make) must make the block non-empty.
  test::FunctionField f([](const QueryPoint&) { return 0.f; });
  MacrocellOptions o;
  o.dims = Int3{6, 5, 4};
  o.temporalSlices = 1;
  o.skipBlockCells = 2;
  MacrocellGrid grid(f, kBox, 0, 1, o);
  const int n = grid.cellCount();
  std::vector<float> mn(n, 0.f), mx(n, 0.1f), mean(n, 0.05f);
  const int hot = linearCellIndex(o.dims, Int3{5, 4, 3});  // alone in a partial block
  mx[hot] = 0.8f;
  grid.setSlice(0, mn, mx, mean);
  grid.setTime(0.0);
  TransferFunction tf = TransferFunction::preset(0.5, 1.0, 0.9);
  const TransferFunctionTable table(tf);
  MajorantArrays maj;
  grid.computeMajorants(table.view(), maj);
  EXPECT_EQ(std::count_if(maj.block.begin(), maj.block.end(), [](float b) { return b > 0.f; }), 1);
  for (const int cell : {0, linearCellIndex(o.dims, Int3{2, 3, 1}), linearCellIndex(o.dims, Int3{5, 4, 2})}) {
    const Int3 c{cell % 6, (cell / 6) % 5, cell / 30};
    const int b = blockIndexOfCell(grid.blockDims(), grid.blockShift(), c);
    const float before = maj.block[b];
    ASSERT_TRUE(grid.refine(cell, 0.9f));
    grid.updateMajorants(table.view(), grid.takeDirtyCells(), maj);
    EXPECT_GT(maj.cell[cell], 0.f);
    EXPECT_GE(maj.block[b], maj.cell[cell]);
    EXPECT_GE(maj.block[b], before);
    EXPECT_TRUE(maj.block == test::bruteBlocks(o.dims, 2, maj.cell));
  }
  // A TF change recomputes everything, blocks included (and may empty them again).
  const TransferFunctionTable none(TransferFunction::transparent(0.0, 1.0));
  grid.computeMajorants(none.view(), maj);
  for (float b : maj.block) EXPECT_EQ(b, 0.f);
}

// ---------------------------------------------------------------- the DDA over empty blocks

struct Visit {
  Int3 cell;
  Vec3f tNext;
  float t;
};

// traverseRay's walk without the sampling: the DDA state at every non-empty cell it enters
// (where delta tracking would draw), cell by cell or with the jump over empty blocks.
// `steps` counts the walk's loop iterations (cells stepped through, or jumps).
std::vector<Visit> walk(const MajorantGridView& g, Vec3f o, Vec3f d, float t0, float tEnd, bool skip, long* steps) {
  Int3 cell;
  Vec3f tNext;
  ddaStart(g, o, d, t0, cell, tNext);
  float t = t0;
  std::vector<Visit> out;
  for (int guard = 0; guard < 1000000; ++guard) {
    ++*steps;
    const float m = majorantAt(g, cell);
    if (skip && !(m > 0.f) && inEmptyBlock(g, cell)) {
      if (!ddaSkipEmptyBlocks(g, o, d, tEnd, cell, tNext, t)) return out;
      continue;
    }
    const float cellExit = minf(ddaCellExit(tNext), tEnd);
    if (m > 0.f) out.push_back({cell, tNext, t});
    if (cellExit >= tEnd || !ddaStep(g, o, d, cell, tNext)) return out;
    t = cellExit;
  }
  ADD_FAILURE() << "walk did not end";
  return out;
}

bool sameVisits(const std::vector<Visit>& a, const std::vector<Visit>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Visit &p = a[i], &q = b[i];
    if (p.cell.x != q.cell.x || p.cell.y != q.cell.y || p.cell.z != q.cell.z) return false;
    if (!sameBits(p.t, q.t) || !sameBits(p.tNext.x, q.tNext.x) || !sameBits(p.tNext.y, q.tNext.y) ||
        !sameBits(p.tNext.z, q.tNext.z))
      return false;
  }
  return true;
}

TEST(EmptySpaceSkipping, JumpLandsWhereTheCellWalkDoes) {
  // Random grids (partial blocks, an off-centre box with unequal cell sizes) and rays of every
  // awkward kind: axis-aligned (zero direction components), through grid vertices along exact
  // diagonals (crossings tie on two or three axes), grazing (a component of 1e-4..1e-7),
  // starting inside the box (mid-block), and with segments ending inside the box.
  std::mt19937 rng(12345);
  auto uni = [&](float a, float b) { return std::uniform_real_distribution<float>(a, b)(rng); };
  auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  long rays = 0, visits = 0, plainSteps = 0, skipSteps = 0;
  for (int gi = 0; gi < 120; ++gi) {
    const int B = 1 << (1 + pick(3));  // 2, 4, 8
    const Int3 dims{1 + pick(24), 1 + pick(24), 1 + pick(24)};
    MajorantGridView g;
    g.box = Box3f{{-1.3f, -0.7f, 0.2f}, {0.9f, 1.1f, 1.7f}};
    g.dims = dims;
    g.cellSize = Vec3f{(g.box.hi.x - g.box.lo.x) / dims.x, (g.box.hi.y - g.box.lo.y) / dims.y,
                       (g.box.hi.z - g.box.lo.z) / dims.z};
    const int shift = skipBlockShift(B);
    const Int3 bd = blockGridDims(dims, shift);
    std::vector<char> blockOccupied(std::size_t(bd.x) * bd.y * bd.z);
    const float occupancy = uni(0.05f, 0.7f);
    for (auto& b : blockOccupied) b = uni(0, 1) < occupancy;
    std::vector<float> maj(std::size_t(dims.x) * dims.y * dims.z, 0.f);
    for (int z = 0; z < dims.z; ++z)
      for (int y = 0; y < dims.y; ++y)
        for (int x = 0; x < dims.x; ++x) {
          const Int3 c{x, y, z};
          if (blockOccupied[std::size_t(blockIndexOfCell(bd, shift, c))] && uni(0, 1) < 0.3f)
            maj[std::size_t(linearCellIndex(dims, c))] = uni(0.1f, 3.f);
        }
    std::vector<float> blocks(blockOccupied.size());
    computeBlockMajorants(dims, shift, maj.data(), blocks.data());
    // invCellSize only steers an estimate: a wrong one must cost time, never exactness.
    const bool wrongInverse = gi % 4 == 3;
    g.invCellSize = wrongInverse ? Vec3f{0.37f, 50.f, -3.f}
                                 : Vec3f{1.f / g.cellSize.x, 1.f / g.cellSize.y, 1.f / g.cellSize.z};
    g.majorant = maj.data();
    g.blockMajorant = blocks.data();
    g.blockDims = bd;
    g.blockShift = shift;
    MajorantGridView plain = g;
    plain.blockMajorant = nullptr;

    auto facePlane = [&](int axis) {  // a cell face coordinate, as nextCrossing computes it
      const int n = component(dims, axis);
      return component(g.box.lo, axis) + float(pick(n + 1)) * component(g.cellSize, axis);
    };
    for (int ri = 0; ri < 400; ++ri) {
      const int kind = pick(6);
      Vec3f d{uni(-1, 1), uni(-1, 1), uni(-1, 1)};
      Vec3f inside{uni(g.box.lo.x, g.box.hi.x), uni(g.box.lo.y, g.box.hi.y), uni(g.box.lo.z, g.box.hi.z)};
      if (kind == 1) {  // axis-aligned: one or two zero components, origin on face planes
        const int zeros = 1 + pick(2);
        for (int k = 0; k < zeros; ++k) {
          const int a = pick(3);
          setComponent(d, a, 0.f);
          setComponent(inside, a, facePlane(a));
        }
        if (length(d) == 0.f) setComponent(d, pick(3), 1.f);
      } else if (kind == 2) {  // exact diagonal through a grid vertex
        const float s = uni(0.3f, 1.f);
        d = Vec3f{pick(2) ? s : -s, pick(2) ? s : -s, pick(3) ? (pick(2) ? s : -s) : 0.f};
        inside = Vec3f{facePlane(0), facePlane(1), facePlane(2)};
      } else if (kind == 3) {  // grazing
        setComponent(d, pick(3), uni(0, 1) < 0.5f ? 1e-4f : 1e-7f);
      }
      if (kind != 2 || uni(0, 1) < 0.5f) d = normalize(d);
      if (length(d) == 0.f) continue;
      Vec3f o;
      float t0, tEnd;
      if (kind == 4 || (kind == 2 && pick(2))) {  // starts inside the box (on the vertex)
        o = inside;
        float te, tx;
        if (!intersectBox(g.box, o, d, te, tx)) continue;
        t0 = 0.f;
        tEnd = tx;
      } else {  // from outside, through `inside`
        o = inside - d * uni(3.f, 6.f);
        float te, tx;
        if (!intersectBox(g.box, o, d, te, tx)) continue;
        t0 = te;
        tEnd = tx;
      }
      if (kind == 5) tEnd = t0 + (tEnd - t0) * uni(0, 1);  // a depth limit inside the box
      ++rays;
      const auto ref = walk(plain, o, d, t0, tEnd, false, &plainSteps);
      const auto got = walk(g, o, d, t0, tEnd, true, &skipSteps);
      visits += long(ref.size());
      if (!sameVisits(ref, got)) {
        std::printf("dims %d %d %d B %d o %.9g %.9g %.9g d %.9g %.9g %.9g t0 %.9g tEnd %.9g\n", dims.x, dims.y, dims.z, B,
                    o.x, o.y, o.z, d.x, d.y, d.z, t0, tEnd);
        for (auto* v : {&ref, &got}) {
          for (auto& q : *v)
            std::printf("  cell %d %d %d tNext %.9g %.9g %.9g t %.9g\n", q.cell.x, q.cell.y, q.cell.z, q.tNext.x,
                        q.tNext.y, q.tNext.z, q.t);
          std::printf("--\n");
        }
      }
      ASSERT_TRUE(sameVisits(ref, got)) << "grid " << gi << " ray " << ri << " kind " << kind << ": "
                                        << ref.size() << " vs " << got.size() << " visits";
    }
  }
  std::printf("%ld rays, %ld non-empty cell visits: identical walks in %ld steps with skipping, %ld without\n",
              rays, visits, skipSteps, plainSteps);
  EXPECT_GT(rays, 30000);
  EXPECT_LT(skipSteps, plainSteps / 2);  // the jumps were really exercised
}

// ---------------------------------------------------------------- the renderer

struct Scene {
  const char* name;
  float (*field)(const QueryPoint&);
  RenderSettings settings;
  RenderScene scene;
};

Camera lookAt(std::array<double, 3> pos, std::array<double, 3> focal, std::array<double, 3> up,
              double angle = 30.0) {
  Camera c;
  c.position = pos;
  c.focalPoint = focal;
  c.viewUp = up;
  c.viewAngle = angle;
  return c;
}

Camera ortho(std::array<double, 3> pos, std::array<double, 3> up, double scale) {
  Camera c = lookAt(pos, {0, 0, 0}, up);
  c.parallelProjection = true;
  c.parallelScale = scale;
  return c;
}

std::vector<Scene> scenes() {
  std::vector<Scene> out;
  auto add = [&](const char* name, bool sparse, const Camera& cam, bool jitter, ShadowEstimator est,
                 std::array<double, 3> light) {
    Scene s;
    s.name = name;
    s.field = sparse ? test::sparseField : test::smoothField;
    // Odd sizes: with pixel centres (no jitter) the middle row and column are exactly on the
    // view axis, so their rays are axis-aligned or exact diagonals.
    s.settings.width = 33;
    s.settings.height = 31;
    s.settings.seed = 7;
    s.settings.pixelJitter = jitter;
    s.scene.camera = cam;
    s.scene.transferFunction = sparse ? sparseTf() : denseTf();
    s.scene.transferFunction.unitDistance = sparse ? 0.1 : 0.25;
    s.scene.background = {0.1f, 0.2f, 0.3f};
    s.scene.time = 0.3;
    s.scene.shadows = true;
    s.scene.ambient = 0.3f;
    s.scene.shadowEstimator = est;
    s.scene.toLight = light[0] == 0 && light[1] == 0 && light[2] == 0 ? defaultLightDirection(cam) : light;
    out.push_back(s);
  };
  const std::array<double, 3> autoLight{0, 0, 0}, zLight{0, 0, 1}, diagLight{1, 1, 1};
  for (bool sparse : {true, false}) {
    add("oblique", sparse, lookAt({2.2, 1.6, 3.4}, {0, 0, 0}, {0, 1, 0}), true, ShadowEstimator::Delta, autoLight);
    add("top-down ortho", sparse, ortho({0, 0, 4}, {0, 1, 0}, 1.1), false, ShadowEstimator::Ratio, zLight);
    add("diagonal ortho", sparse, ortho({3, 3, 3}, {0, 0, 1}, 1.5), false, ShadowEstimator::Delta, diagLight);
    add("edge-on ortho", sparse, ortho({3, 3, 0}, {0, 0, 1}, 1.5), false, ShadowEstimator::Ratio, zLight);
    add("axis +x", sparse, lookAt({4, 0, 0}, {0, 0, 0}, {0, 0, 1}), false, ShadowEstimator::Delta, diagLight);
    add("grazing y=1", sparse, lookAt({0, 1.0, 4}, {0, 0.93, 0}, {0, 1, 0}, 40), true, ShadowEstimator::Delta,
        autoLight);
    add("inside", sparse, lookAt({0.1, 0.05, 0.3}, {1, 0.4, -1}, {0, 1, 0}, 70), true, ShadowEstimator::Ratio,
        autoLight);
  }
  // A depth limit ending rays inside the box (random per pixel).
  Scene depth = out[0];
  depth.name = "oblique, depth limit";
  std::mt19937 rng(5);
  depth.scene.depthLimit.resize(std::size_t(depth.settings.width) * depth.settings.height);
  for (float& v : depth.scene.depthLimit) v = std::uniform_real_distribution<float>(3.0f, 5.5f)(rng);
  out.push_back(depth);
  return out;
}

struct Result {
  std::vector<float> image, premultiplied;
  FrameStats stats;
  std::vector<float> majorants;
  std::size_t refinements = 0;
  long emptyBlocks = 0;
};

Result render(const Scene& s, Int3 dims, int block, bool naive) {
  test::FunctionField f(s.field);
  MacrocellOptions o;
  o.dims = dims;
  o.temporalSlices = 4;
  o.skipBlockCells = block;
  MacrocellGrid grid(f, kBox, 0, 1, o);
  TrackingOptions topt;
  topt.ghostPassesOnUpdate = 1;  // ghost majorants (own blocks) and refinement of empty cells
  topt.ghostPixelStride = 2;
  CpuWavefrontRenderer r(f, grid, topt);
  r.setSettings(s.settings);
  r.setScene(s.scene);
  Result out;
  for (int k = 0; k < 3; ++k) out.stats += naive ? r.renderFrameNaive() : r.renderFrame();
  out.image = r.image().data;
  out.premultiplied = r.premultipliedImage().data;
  out.majorants = r.majorants();
  out.refinements = grid.refinementCount();
  if (block > 0) {
    const std::vector<float> blocks = r.blockMajorants();
    EXPECT_EQ(int(blocks.size()), grid.blockCount());
    // The level the last frame used is the max of the (refined) cells it covers.
    EXPECT_TRUE(blocks == test::bruteBlocks(dims, block, r.majorants())) << s.name;
    out.emptyBlocks = long(std::count(blocks.begin(), blocks.end(), 0.f));
  }
  return out;
}

bool sameFloats(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

void expectIdentical(const Result& off, const Result& on, const std::string& what) {
  EXPECT_TRUE(sameFloats(off.image, on.image)) << what;
  EXPECT_TRUE(sameFloats(off.premultiplied, on.premultiplied)) << what;
  EXPECT_EQ(off.stats.rays, on.stats.rays) << what;
  EXPECT_EQ(off.stats.queries, on.stats.queries) << what;
  EXPECT_EQ(off.stats.iterations, on.stats.iterations) << what;
  EXPECT_EQ(off.stats.shadowRays, on.stats.shadowRays) << what;
  EXPECT_EQ(off.stats.shadowQueries, on.stats.shadowQueries) << what;
  EXPECT_EQ(off.stats.shadowIterations, on.stats.shadowIterations) << what;
  EXPECT_EQ(off.stats.refinements, on.stats.refinements) << what;
  EXPECT_EQ(off.refinements, on.refinements) << what;
  EXPECT_TRUE(sameFloats(off.majorants, on.majorants)) << what;
}

TEST(EmptySpaceSkipping, ImagesAndQueryCountsIdenticalWithSkippingOnAndOff) {
  for (const Scene& s : scenes()) {
    for (const Int3 dims : {Int3{16, 16, 16}, Int3{18, 13, 9}}) {
      const Result off = render(s, dims, 0, false);
      ASSERT_GT(off.stats.queries, 0u) << s.name;
      ASSERT_GT(off.stats.shadowQueries, 0u) << s.name;
      for (int block : {2, 4, 8}) {
        const std::string what = std::string(s.name) + (s.field == test::sparseField ? " (sparse)" : " (dense)") +
                                 ", " + std::to_string(dims.x) + "x" + std::to_string(dims.y) + "x" +
                                 std::to_string(dims.z) + " cells, blocks of " + std::to_string(block);
        const Result on = render(s, dims, block, false);
        expectIdentical(off, on, what);
        if (s.field == test::sparseField && block <= 4) EXPECT_GT(on.emptyBlocks, 0) << what;  // not vacuous
      }
    }
  }
}

TEST(EmptySpaceSkipping, NaiveTrackerIdenticalWithSkippingOnAndOff) {
  const Scene s = scenes()[0];
  expectIdentical(render(s, Int3{16, 16, 16}, 0, true), render(s, Int3{16, 16, 16}, 4, true), "naive");
}

}  // namespace
}  // namespace inr
