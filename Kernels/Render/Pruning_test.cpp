// Homogeneity-based query pruning (paper §4.2.2): the stage functions of Render/Pruning.h and
// the CPU renderer with pruning on.
#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/Evaluate.h"
#include "Render/Pruning.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

const Box3f kBox = test::kCubeBox;

// A view over cells whose bounds are [0, range[c]] (or given explicitly).
struct Cells {
  std::vector<float> mn, mx, expected;
  PruneView view(float epsilon, float falloff) {
    PruneView v;
    v.epsilon = epsilon;
    v.falloff = falloff;
    v.cellMin = mn.data();
    v.cellMax = mx.data();
    expected.assign(mn.size(), 0.5f);
    v.expected = expected.data();
    return v;
  }
  int add(float lo, float hi) {
    mn.push_back(lo);
    mx.push_back(hi);
    return int(mn.size()) - 1;
  }
};

TEST(Pruning, ProbabilityFollowsTheBand) {
  Cells c;
  // epsilon = 0.25, falloff = 0.5: 1 below 0.25, ramp to 0 at 0.75 (exact binary fractions).
  const int zero = c.add(2.f, 2.f), below = c.add(1.f, 1.2f), atEps = c.add(-1.f, -0.75f),
            mid = c.add(0.f, 0.5f), quarter = c.add(0.f, 0.625f), atTop = c.add(0.f, 0.75f),
            above = c.add(0.f, 3.f), empty = c.add(INFINITY, -INFINITY), reversed = c.add(1.f, 0.f),
            nan = c.add(NAN, 1.f), inf = c.add(-INFINITY, INFINITY);
  const PruneView v = c.view(0.25f, 0.5f);
  EXPECT_EQ(pruneProbability(v, zero), 1.f);
  EXPECT_EQ(pruneProbability(v, below), 1.f);
  EXPECT_EQ(pruneProbability(v, atEps), 1.f);  // the ramp starts at 1
  EXPECT_EQ(pruneProbability(v, mid), 0.5f);
  EXPECT_EQ(pruneProbability(v, quarter), 0.25f);
  EXPECT_EQ(pruneProbability(v, atTop), 0.f);  // epsilon + falloff is outside the band
  EXPECT_EQ(pruneProbability(v, above), 0.f);
  // Empty or invalid bounds say nothing about uniformity: never pruned.
  EXPECT_EQ(pruneProbability(v, empty), 0.f);
  EXPECT_EQ(pruneProbability(v, reversed), 0.f);
  EXPECT_EQ(pruneProbability(v, nan), 0.f);
  EXPECT_EQ(pruneProbability(v, inf), 0.f);

  // No falloff: a hard threshold, no division by zero at the edge.
  const PruneView hard = c.view(0.25f, 0.f);
  EXPECT_EQ(pruneProbability(hard, below), 1.f);
  EXPECT_EQ(pruneProbability(hard, atEps), 0.f);
  EXPECT_EQ(pruneProbability(hard, mid), 0.f);
  // Everything off: only a zero-width cell is not below 0.
  const PruneView off = c.view(0.f, 0.f);
  for (int k = 0; k < int(c.mn.size()); ++k) EXPECT_EQ(pruneProbability(off, k), 0.f) << k;
}

TEST(Pruning, DecisionDrawsOnlyInsideTheBand) {
  Cells c;
  const int certain = c.add(0.f, 0.1f), band = c.add(0.f, 0.625f), outside = c.add(0.f, 1.f);
  const PruneView v = c.view(0.25f, 0.5f);
  RngStream rng{7u, 3u, 11u, 5u};
  EXPECT_TRUE(prunes(v, certain, rng));
  EXPECT_EQ(rng.counter, 5u);  // p = 1: no draw
  EXPECT_FALSE(prunes(v, outside, rng));
  EXPECT_EQ(rng.counter, 5u);  // p = 0: no draw
  PruneView off = v;
  off.expected = nullptr;
  EXPECT_FALSE(prunes(off, certain, rng));
  EXPECT_EQ(rng.counter, 5u);  // off: no draw

  // Inside the band: one draw per decision, pruned with probability p = 0.25.
  const int n = 20000;
  int pruned = 0;
  for (int k = 0; k < n; ++k) pruned += prunes(v, band, rng) ? 1 : 0;
  EXPECT_EQ(rng.counter, 5u + std::uint32_t(n));
  const double p = 0.25, bound = 5.0 * std::sqrt(p * (1 - p) / n);
  EXPECT_NEAR(double(pruned) / n, p, bound);
}

TEST(Pruning, CentreWeightIsOneAtTheCentreAndZeroOnTheFaces) {
  MajorantGridView g;
  g.box = Box3f{{0.f, 0.f, 0.f}, {4.f, 2.f, 2.f}};
  g.dims = Int3{4, 2, 2};
  g.cellSize = Vec3f{1.f, 1.f, 1.f};
  const Int3 c{2, 1, 0};  // spans [2,3] x [1,2] x [0,1], centre (2.5, 1.5, 0.5)
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{2.5f, 1.5f, 0.5f}), 1.f);
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{2.75f, 1.5f, 0.5f}), 0.5f);   // halfway to a face
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{2.75f, 1.25f, 0.375f}), 0.5f);  // the max norm
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{3.f, 1.5f, 0.5f}), 0.f);     // on a face
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{2.f, 1.f, 0.f}), 0.f);       // a corner
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{3.5f, 1.5f, 0.5f}), 0.f);    // outside (rounding): clamped
  EXPECT_EQ(cellCentreWeight(g, c, Vec3f{NAN, 1.5f, 0.5f}), 0.f);
}

TEST(Pruning, EmaMovesTowardTheSamples) {
  // Eq. ev_ema with alpha = 0.1 max(w, 0.01).
  EXPECT_FLOAT_EQ(emaExpected(0.f, 1.f, 1.f), 0.1f);
  EXPECT_FLOAT_EQ(emaExpected(0.f, 1.f, 0.5f), 0.05f);
  EXPECT_FLOAT_EQ(emaExpected(0.f, 1.f, 0.f), 0.001f);  // face samples still count a little
  EXPECT_EQ(emaExpected(NAN, 0.75f, 1.f), 0.75f);       // a broken estimate restarts

  // Samples alternating 1 and 3 from 0: centre samples settle near their mean 2 (the EMA
  // oscillates by about alpha around it); face samples barely leave the start.
  float centre = 0.f, face = 0.f;
  for (int k = 0; k < 400; ++k) {
    const float s = (k & 1) ? 3.f : 1.f;
    centre = emaExpected(centre, s, 1.f);
    face = emaExpected(face, s, 0.f);
  }
  EXPECT_NEAR(centre, 2.f, 0.15f);
  EXPECT_GT(face, 0.f);
  EXPECT_LT(face, 0.9f);
  EXPECT_LT(std::abs(centre - 2.f), std::abs(face - 2.f));
}

// expectedAfterQuery reads the pending query's point and cell from the ray state.
TEST(Pruning, EvaluatedQueriesUpdateTheirCellsEstimate) {
  std::vector<Vec3f> origin{{-1.f, 0.5f, 0.5f}, {-1.f, 0.5f, 0.5f}}, direction{{1.f, 0.f, 0.f}, {1.f, 0.f, 0.f}};
  std::vector<float> t{1.25f, 1.5f};  // (0.25, 0.5, 0.5): the cell's centre; x = 0.5: its face
  std::vector<Int3> cell{{2, 1, 1}, {2, 1, 1}};
  RayStateView rs;
  rs.count = 2;
  rs.origin = origin.data();
  rs.direction = direction.data();
  rs.t = t.data();
  rs.cell = cell.data();
  TrackingMedium medium;
  medium.grid.box = kBox;
  medium.grid.dims = Int3{4, 2, 2};
  medium.grid.cellSize = Vec3f{0.5f, 1.f, 1.f};
  std::vector<float> expected(16, 0.f);
  medium.prune.expected = expected.data();
  int c = -1;
  float s = 0.f;
  ASSERT_TRUE(expectedAfterQuery(medium, rs, 0, 1.f, c, s));
  EXPECT_EQ(c, linearCellIndex(medium.grid.dims, Int3{2, 1, 1}));
  EXPECT_FLOAT_EQ(s, 0.1f);  // centre: alpha = 0.1
  ASSERT_TRUE(expectedAfterQuery(medium, rs, 1, 1.f, c, s));
  EXPECT_FLOAT_EQ(s, 0.001f);  // face: alpha = 0.001
  EXPECT_FALSE(expectedAfterQuery(medium, rs, 0, NAN, c, s));
  EXPECT_FALSE(expectedAfterQuery(medium, rs, 0, INFINITY, c, s));
}

// --- the renderer with pruning ---------------------------------------------------------------

// Near-uniform almost everywhere: a plateau at 0.3 with a tiny ripple, and one Gaussian blob.
float plateauField(const QueryPoint& p) {
  const float dx = p.x - 0.2f, dy = p.y + 0.1f, dz = p.z - 0.1f * p.t;
  return 0.3f + 0.6f * std::exp(-(dx * dx + dy * dy + dz * dz) / 0.08f) +
         0.002f * std::sin(5.f * p.x + 3.f * p.y + 2.f * p.z);
}

// Oblique view; the plateau is translucent (opacity 0.15), so rays take many candidates in it.
test::SceneSetup plateauScene(int size, bool shadows, ShadowEstimator estimator = ShadowEstimator::Ratio) {
  test::SceneSetup s = test::obliqueCubeScene(size, 5);
  s.scene.transferFunction = TransferFunction::preset(0.25, 0.95, 0.8);
  s.scene.transferFunction.opacity = {{0.25, 0.15}, {0.95, 0.8}};
  s.scene.transferFunction.unitDistance = 0.5;
  test::lightScene(s.scene, shadows, estimator);
  return s;
}

MacrocellOptions cells16() { return test::cubeMacrocells(16, 4); }

using test::pruningAt;

struct RenderRun {
  ImageRGBA premultiplied;
  FrameStats stats;
};

RenderRun render(const FieldEvaluator& f, const test::SceneSetup& s, const QueryReductionSettings& q, int frames) {
  MacrocellGrid grid(f, kBox, 0, 1, cells16());
  CpuWavefrontRenderer r(f, grid);
  r.setSettings(s.settings);
  r.setQueryReduction(q);
  r.setScene(s.scene);
  RenderRun out;
  for (int k = 0; k < frames; ++k) out.stats += r.renderFrame();
  out.premultiplied = r.premultipliedImage();
  return out;
}

// PSNR of the premultiplied RGB over the pixels the volume covers in either image (background
// pixels would inflate it).
double coveredPsnr(const ImageRGBA& a, const ImageRGBA& b) {
  double se = 0.0;
  std::size_t n = 0;
  for (int i = 0; i < a.width * a.height; ++i) {
    if (!(a.data[4 * i + 3] > 0.f || b.data[4 * i + 3] > 0.f)) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.data[4 * i + c]) - double(b.data[4 * i + c]);
      se += d * d;
    }
    ++n;
  }
  if (n == 0) return 0.0;
  const double mse = se / double(3 * n);
  return mse == 0.0 ? INFINITY : 10.0 * std::log10(1.0 / mse);
}

// With thresholds that put every cell outside the band (epsilon = delta = 0, or thresholds
// below every cell's range) nothing is pruned and no random number is drawn: the images and
// every count are bit-identical to pruning off, although the EMA runs (its estimates are read
// only by pruned candidates).
TEST(Pruning, NoCellInTheBandIsBitIdenticalToOff) {
  test::FunctionField f(test::smoothField);
  for (const ShadowEstimator est : {ShadowEstimator::Delta, ShadowEstimator::Ratio}) {
    const test::SceneSetup s = plateauScene(40, true, est);
    const RenderRun off = render(f, s, QueryReductionSettings{}, 3);
    EXPECT_GT(off.stats.queries, 0u);
    for (const QueryReductionSettings& q : {pruningAt(0.0, 0.0), pruningAt(1e-7, 0.0), pruningAt(0.0, 1e-7),
                                            pruningAt(1e-7, 1e-7)}) {
      const RenderRun on = render(f, s, q, 3);
      EXPECT_TRUE(on.premultiplied.data == off.premultiplied.data)
          << "epsilon " << q.pruneEpsilon << " falloff " << q.pruneFalloff;
      EXPECT_EQ(on.stats.pruned, 0u);
      EXPECT_EQ(on.stats.queries, off.stats.queries);
      EXPECT_EQ(on.stats.shadowQueries, off.stats.shadowQueries);
      EXPECT_EQ(on.stats.iterations, off.stats.iterations);
      EXPECT_EQ(on.stats.refinements, off.stats.refinements);
    }
  }
}

// The scene pruning is for: a moderate epsilon prunes most candidates in the plateau, cuts the
// queries, and the converged image stays close to the unpruned one. Both renders use the same
// seed (common random numbers: outside the pruned cells the rays draw the same streams), so
// the PSNR measures what pruning changed, not two independent noise patterns; the noise floor
// of the unpruned renderer at this frame count is printed alongside for scale.
TEST(Pruning, PrunesNearUniformRegionsAndConvergesCloseToUnpruned) {
  test::FunctionField f(plateauField);
  const int frames = 256;
  const test::SceneSetup s = plateauScene(48, true);
  const RenderRun ref = render(f, s, QueryReductionSettings{}, frames);
  const RenderRun on = render(f, s, pruningAt(0.02, 0.01), frames);
  test::SceneSetup other = s;
  other.settings.seed = 77;
  const RenderRun noise = render(f, other, QueryReductionSettings{}, frames);
  const double psnr = coveredPsnr(on.premultiplied, ref.premultiplied);
  const double floor = coveredPsnr(noise.premultiplied, ref.premultiplied);
  const std::size_t refQueries = ref.stats.totalQueries(), onQueries = on.stats.totalQueries();
  const double prunedFraction = double(on.stats.pruned) / double(on.stats.pruned + onQueries);
  std::printf("pruning 0.02 + 0.01: queries %zu -> %zu (%.1f%%), pruned %.1f%% of candidates; covered PSNR vs "
              "unpruned %.2f dB (independent-seed noise floor %.2f dB)\n",
              refQueries, onQueries, 100.0 * double(onQueries) / double(refQueries), 100.0 * prunedFraction, psnr,
              floor);
  EXPECT_GT(prunedFraction, 0.5);
  EXPECT_LT(double(onQueries), 0.6 * double(refQueries));
  EXPECT_GE(psnr, 50.0);  // the line above prints the measured value
  EXPECT_EQ(test::nonFinitePixels(on.premultiplied), 0u);

  // The metric sees a wrong substitution: pruning every cell (the blob too) is far off.
  const RenderRun all = render(f, s, pruningAt(1.0, 0.0), frames / 4);
  const RenderRun refShort = render(f, s, QueryReductionSettings{}, frames / 4);
  const double psnrAll = coveredPsnr(all.premultiplied, refShort.premultiplied);
  std::printf("pruning everything: %zu queries, covered PSNR %.2f dB\n", all.stats.totalQueries(), psnrAll);
  EXPECT_LT(psnrAll, psnr - 5.0);
}

// Epsilon = 1 prunes every valid cell: no candidate reaches the network (only the empty cells
// never prune, and they have no candidates), and the counts add up to the candidates.
TEST(Pruning, EverythingPrunedCostsNoQueries) {
  test::FunctionField f(plateauField);
  const test::SceneSetup s = plateauScene(32, true);
  const RenderRun all = render(f, s, pruningAt(1.0, 0.0), 2);
  EXPECT_EQ(all.stats.totalQueries(), 0u);
  EXPECT_GT(all.stats.pruned, all.stats.rays / 2);
  EXPECT_EQ(test::nonFinitePixels(all.premultiplied), 0u);
}

// The EMA runs serially in batch order: with pruning inside the band (random decisions and
// estimates that change between passes) the image still does not depend on the thread count.
TEST(Pruning, IdenticalImagesForOneAndManyThreads) {
  test::FunctionField f(plateauField);
  const test::SceneSetup s = plateauScene(40, true);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const RenderRun one = render(f, s, pruningAt(0.01, 0.02), 4);
  omp_set_num_threads(std::max(2, threads));
  const RenderRun many = render(f, s, pruningAt(0.01, 0.02), 4);
  omp_set_num_threads(threads);
  EXPECT_GT(one.stats.pruned, 0u);
  EXPECT_EQ(one.stats.pruned, many.stats.pruned);
  EXPECT_EQ(one.stats.queries, many.stats.queries);
  EXPECT_TRUE(one.premultiplied.data == many.premultiplied.data);
}

// The grid's estimates start at the working means, learn from evaluations while pruning is on,
// and restart at the means when the working grid is re-interpolated (a time change).
TEST(Pruning, EstimatesStartAtTheMeansAndRestartAtTimeChanges) {
  test::FunctionField f(plateauField);
  MacrocellGrid grid(f, kBox, 0, 1, cells16());
  CpuWavefrontRenderer r(f, grid);
  const test::SceneSetup s = plateauScene(32, false);
  r.setSettings(s.settings);
  r.setQueryReduction(pruningAt(0.01, 0.01));
  r.setScene(s.scene);
  EXPECT_TRUE(grid.expected() == grid.workingMean());
  for (int k = 0; k < 4; ++k) r.renderFrame();
  int moved = 0;
  for (int c = 0; c < grid.cellCount(); ++c) moved += grid.expected()[c] != grid.workingMean()[c] ? 1 : 0;
  EXPECT_GT(moved, grid.cellCount() / 20);
  RenderScene later = s.scene;
  later.time = 0.8;
  r.setScene(later);
  EXPECT_TRUE(grid.expected() == grid.workingMean());
}

}  // namespace
}  // namespace inr
