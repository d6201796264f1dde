// Sub-domain rendering: the k-d brick split, its visibility order, and bricks rendered one by one
// and composited front to back equal the whole box rendered at once (with and without shadows);
// the image-space split (pixel shares) adds up to the whole image exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "Render/BrickDecomposition.h"
#include "Render/CpuWavefrontRenderer.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

double volume(const Box3f& b) { return double(b.hi.x - b.lo.x) * (b.hi.y - b.lo.y) * (b.hi.z - b.lo.z); }

TEST(BrickDecomposition, TilesTheBoxOnCellBoundariesBalanced) {
  const Box3f box{{-1.f, -0.5f, 0.f}, {3.f, 0.5f, 1.5f}};  // longest along x
  const Int3 cells{32, 8, 12};
  for (int n = 1; n <= 9; ++n) {
    const std::vector<Brick> bricks = brickDecomposition(box, cells, n);
    ASSERT_EQ(int(bricks.size()), n);
    long long cellSum = 0;
    double largest = 0, smallest = 1e30;
    for (const Brick& b : bricks) {
      const long long c = (long long)(b.cellHi.x - b.cellLo.x) * (b.cellHi.y - b.cellLo.y) * (b.cellHi.z - b.cellLo.z);
      ASSERT_GT(c, 0);
      cellSum += c;
      largest = std::max(largest, double(c));
      smallest = std::min(smallest, double(c));
      // Faces on cell boundaries of the whole grid.
      for (int a = 0; a < 3; ++a) {
        const double size = (component(box.hi, a) - component(box.lo, a)) / component(cells, a);
        EXPECT_NEAR(component(b.box.lo, a), component(box.lo, a) + size * component(b.cellLo, a), 1e-5);
        EXPECT_NEAR(component(b.box.hi, a), component(box.lo, a) + size * component(b.cellHi, a), 1e-5);
      }
    }
    EXPECT_EQ(cellSum, (long long)cells.x * cells.y * cells.z) << n << " bricks";
    // Balanced: within one cell layer of the ideal share (cuts are rounded to cells).
    EXPECT_LE(largest / smallest, 1.35) << n << " bricks";
    // No overlaps: every pair is separated along some axis, with the shared plane bit-identical.
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) {
        const Box3f &a = bricks[i].box, &b = bricks[j].box;
        bool separated = false;
        for (int ax = 0; ax < 3; ++ax)
          separated = separated || component(a.hi, ax) <= component(b.lo, ax) || component(b.hi, ax) <= component(a.lo, ax);
        EXPECT_TRUE(separated) << "bricks " << i << " and " << j << " of " << n << " overlap";
      }
  }
  EXPECT_EQ(brickDecomposition(box, cells, 2)[0].box.hi.x, 1.f);  // the first cut halves the longest axis
  EXPECT_THROW(brickDecomposition(box, Int3{1, 1, 2}, 3), std::invalid_argument);
  EXPECT_THROW(brickDecomposition(box, cells, 0), std::invalid_argument);
}

TEST(BrickDecomposition, ParsesIndex) {
  const BrickIndex b = parseBrickIndex("3/4");
  EXPECT_EQ(b.index, 3);
  EXPECT_EQ(b.count, 4);
  for (const char* bad : {"4/4", "-1/2", "1/0", "1", "/2", "1/", "a/2", "1/2x"})
    EXPECT_THROW(parseBrickIndex(bad), std::invalid_argument) << bad;
  EXPECT_EQ(brickSeed(7, 0), 7u);
  EXPECT_NE(brickSeed(7, 1), brickSeed(7, 2));
}

TEST(BrickDecomposition, VisibilityOrderPutsTheEyeSideFirst) {
  const Box3f box = test::kCubeBox;
  const std::vector<Brick> bricks = brickDecomposition(box, Int3{8, 8, 8}, 6);
  const Vec3f eyes[] = {{3.f, 0.2f, 0.1f}, {-2.f, -3.f, 1.f}, {0.1f, 0.3f, -5.f}, {0.2f, -0.3f, 0.4f}};
  for (const Vec3f& eye : eyes) {
    const std::vector<int> order = brickVisibilityOrder(bricks, eye);
    ASSERT_EQ(order.size(), bricks.size());
    std::vector<int> rank(bricks.size());
    for (std::size_t k = 0; k < order.size(); ++k) rank[std::size_t(order[k])] = int(k);
    // Every pair of bricks sharing a face: the one on the eye's side of the face comes first.
    for (std::size_t i = 0; i < bricks.size(); ++i)
      for (std::size_t j = 0; j < bricks.size(); ++j)
        for (int a = 0; a < 3; ++a) {
          const float p = component(bricks[i].box.hi, a);
          if (p != component(bricks[j].box.lo, a)) continue;
          bool touch = true;
          for (int b = 0; b < 3; ++b)
            if (b != a)
              touch = touch && component(bricks[i].box.lo, b) < component(bricks[j].box.hi, b) &&
                      component(bricks[j].box.lo, b) < component(bricks[i].box.hi, b);
          if (!touch) continue;
          if (component(eye, a) < p) EXPECT_LT(rank[i], rank[j]);
          else EXPECT_GT(rank[i], rank[j]);
        }
  }
}

// Front-to-back over of premultiplied images in `order`.
std::vector<float> compositeOver(const std::vector<ImageRGBA>& images, const std::vector<int>& order) {
  std::vector<float> out(images[0].data.size(), 0.f);
  for (int k : order) {
    const std::vector<float>& src = images[std::size_t(k)].data;
    for (std::size_t p = 0; p < out.size(); p += 4) {
      const float t = 1.f - out[p + 3];
      for (int c = 0; c < 4; ++c) out[p + c] += t * src[p + c];
    }
  }
  return out;
}

double rms(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / double(a.size()));
}

struct BrickRender {
  MacrocellGrid grid;
  CpuWavefrontRenderer renderer;
  BrickRender(const FieldEvaluator& f, Int3 cells) : grid(f, test::kCubeBox, 0, 1, options(cells)), renderer(f, grid) {}
  static MacrocellOptions options(Int3 cells) {
    MacrocellOptions o;
    o.dims = cells;
    o.temporalSlices = 1;
    return o;
  }
  ImageRGBA render(const RenderScene& scene, RenderSettings settings, int frames) {
    renderer.setSettings(settings);
    renderer.setScene(scene);
    for (int k = 0; k < frames; ++k) renderer.renderFrame();
    return renderer.premultipliedImage();
  }
};

// The blob field's scene from an oblique perspective camera, lit from above.
RenderScene obliqueBlobScene() {
  RenderScene scene;
  scene.camera = Camera::framing(test::kCubeBox);
  scene.camera.position = {2.6, 1.9, 3.1};
  scene.transferFunction = TransferFunction::preset(0.2, 0.9, 0.8);
  scene.transferFunction.unitDistance = 0.1;
  scene.toLight = {-0.3, 1.0, 0.2};
  return scene;
}

// A homogeneous medium seen along z through 8 bricks (2 along each axis): each pixel's coverage
// is 1 - exp(-2 sigma) in expectation, which only the front-to-back composite of the two bricks
// along z gives.
TEST(BrickDecomposition, HomogeneousBricksCompositeToTheWholeTransmittance) {
  test::FunctionField f([](const QueryPoint&) { return 0.5f; });
  BrickRender r(f, Int3{8, 8, 8});
  RenderScene scene;
  scene.camera = Camera::framing(test::kCubeBox);
  scene.camera.parallelProjection = true;
  scene.camera.parallelScale = 0.9;
  scene.transferFunction.color = {{0, 0.2, 0.6, 1.0}, {1, 0.2, 0.6, 1.0}};
  scene.transferFunction.opacity = {{0, 0.3}, {1, 0.3}};
  scene.transferFunction.unitDistance = 0.5;
  RenderSettings settings;
  settings.width = settings.height = 32;
  const int frames = 40;
  const std::vector<Brick> bricks = brickDecomposition(test::kCubeBox, Int3{8, 8, 8}, 8);
  std::vector<ImageRGBA> images;
  for (std::size_t k = 0; k < bricks.size(); ++k) {
    RenderSettings s = settings;
    s.clipToBrick = true;
    s.brick = bricks[k].box;
    s.seed = brickSeed(settings.seed, int(k));
    images.push_back(r.render(scene, s, frames));
  }
  const Vec3f eye{0.f, 0.f, 1e6f};
  const std::vector<float> composite = compositeOver(images, brickVisibilityOrder(bricks, eye));
  double coverage = 0;
  for (std::size_t p = 3; p < composite.size(); p += 4) coverage += composite[p];
  coverage /= double(composite.size() / 4);
  const double sigma = -std::log(1.0 - 0.3) / 0.5;
  const double p = 1.0 - std::exp(-2.0 * sigma);
  // Each brick's coverage is a mean of 0/1 draws: 4 sigma of the composite's spread.
  const double bound = 4.0 * std::sqrt(2.0 * 0.25 / (32.0 * 32.0 * frames));
  EXPECT_NEAR(coverage, p, bound);
  // One brick alone covers only its own depth: 1 - exp(-sigma).
  double front = 0;
  for (std::size_t q = 3; q < images[0].data.size(); q += 4) front += images[0].data[q];
  front /= double(images[0].data.size() / 4);
  EXPECT_LT(front, 0.5 * p + 0.05);  // brick 0 covers a quarter of the pixels, to half the depth
}

// A blob field from an oblique perspective camera, with and without shadows: 2 and 4 bricks
// composited agree with the whole box as closely as two whole-box renders with different seeds
// agree with each other (shadow rays clipped to the brick would darken or brighten whole regions,
// far beyond that).
TEST(BrickDecomposition, BricksCompositeToTheWholeImageWithAndWithoutShadows) {
  test::FunctionField f(test::smoothField);
  const Int3 cells{8, 8, 8};
  BrickRender r(f, cells);
  RenderScene scene = obliqueBlobScene();
  scene.ambient = 0.1f;
  RenderSettings settings;
  settings.width = settings.height = 24;
  const int frames = 600;
  const Vec3f eye = toVec3(scene.camera.position);
  for (bool shadows : {false, true}) {
    scene.shadows = shadows;
    RenderSettings a = settings, b = settings;
    a.seed = 101;
    b.seed = 202;
    const std::vector<float> wholeA = r.render(scene, a, frames).data, wholeB = r.render(scene, b, frames).data;
    const double noise = rms(wholeA, wholeB);
    double coverage = 0;
    for (std::size_t p = 3; p < wholeA.size(); p += 4) coverage += wholeA[p];
    ASSERT_GT(coverage / double(wholeA.size() / 4), 0.2) << "the test scene must show the volume";
    for (int n : {2, 4}) {
      const std::vector<Brick> bricks = brickDecomposition(test::kCubeBox, cells, n);
      std::vector<ImageRGBA> images;
      for (int k = 0; k < n; ++k) {
        RenderSettings s = settings;
        s.seed = brickSeed(303, k);
        s.clipToBrick = true;
        s.brick = bricks[std::size_t(k)].box;
        images.push_back(r.render(scene, s, frames));
      }
      const std::vector<float> composite = compositeOver(images, brickVisibilityOrder(bricks, eye));
      // The wrong (back-to-front) order must be visibly worse: the test can fail.
      std::vector<int> reversed = brickVisibilityOrder(bricks, eye);
      std::reverse(reversed.begin(), reversed.end());
      const double error = rms(composite, wholeA), wrongOrder = rms(compositeOver(images, reversed), wholeA);
      EXPECT_LT(error, 1.3 * noise) << n << " bricks, shadows " << shadows << ": noise " << noise;
      std::printf("%d bricks, shadows %d: rms vs whole %.4f (two wholes %.4f, wrong order %.4f)\n", n, int(shadows),
                  error, noise, wrongOrder);
      EXPECT_GT(wrongOrder, 1.5 * noise) << n << " bricks, shadows " << shadows;
    }
  }
}

// Image-space split: every share traces its own interleaved pixels at full depth with the same
// seed, and each pixel's random stream is keyed by its place in the picture, so in a first frame
// (fresh renderers: the majorants are refined by what the rays saw, which differs between
// shares after it) the shares' images add up to the single image bit for bit, with shadows too.
// Accumulated, they stay far closer to the whole image than another seed (the same streams). A share's pixels
// outside it stay empty.
TEST(PixelShare, SharesAddUpToTheWholeImage) {
  test::FunctionField f(test::smoothField);
  RenderScene scene = obliqueBlobScene();
  RenderSettings settings;
  settings.width = 23;  // odd: the diagonal pattern wraps across rows
  settings.height = 17;
  const auto render = [&](const RenderSettings& s, int frames) {
    BrickRender r(f, Int3{8, 8, 8});
    return r.render(scene, s, frames).data;
  };
  for (bool shadows : {false, true}) {
    scene.shadows = shadows;
    for (int frames : {1, 300}) {
      RenderSettings other = settings;
      other.seed = 99;
      const std::vector<float> whole = render(settings, frames), otherSeed = render(other, frames);
      double coverage = 0;
      for (std::size_t p = 3; p < whole.size(); p += 4) coverage += whole[p];
      ASSERT_GT(coverage / double(whole.size() / 4), 0.2) << "the test scene must show the volume";
      const double noise = rms(whole, otherSeed);
      for (int n : {2, 3, 4}) {
        std::vector<float> sum(whole.size(), 0.f);
        for (int k = 0; k < n; ++k) {
          RenderSettings s = settings;
          s.pixelShare = PixelShare{k, n};
          const std::vector<float> share = render(s, frames);
          for (int y = 0; y < settings.height; ++y)
            for (int x = 0; x < settings.width; ++x)
              for (int c = 0; c < 4; ++c) {
                const std::size_t p = (std::size_t(y) * settings.width + x) * 4 + c;
                if ((x + y) % n != k) ASSERT_EQ(share[p], 0.f) << "pixel " << x << "," << y << " is not share " << k;
                sum[p] += share[p];
              }
        }
        if (frames == 1) {
          for (std::size_t p = 0; p < whole.size(); ++p)
            ASSERT_EQ(sum[p], whole[p]) << n << " shares, shadows " << shadows << ", value " << p;
        } else {
          EXPECT_LT(rms(sum, whole), 0.5 * noise) << n << " shares, shadows " << shadows;
          std::printf("%d shares, shadows %d: rms vs whole %.4f (two seeds %.4f)\n", n, int(shadows), rms(sum, whole),
                      noise);
        }
      }
    }
  }
  BrickRender r(f, Int3{8, 8, 8});
  RenderSettings bad = settings;
  bad.pixelShare = PixelShare{2, 2};
  EXPECT_THROW(r.renderer.setSettings(bad), std::invalid_argument);
  bad.pixelShare = PixelShare{0, 0};
  EXPECT_THROW(r.renderer.setSettings(bad), std::invalid_argument);
}

// Ghost passes refine the process's whole macrocell grid: with a pixel share they trace every
// ghost pixel as without one (the ghost pixels, every 4th in x and y, all lie on share 0 of 2
// or 4, so a share-filtered ghost pass would leave the other ranks' grids unrefined).
TEST(PixelShare, GhostPassesIgnoreTheShare) {
  test::FunctionField f(test::smoothField);
  const RenderScene scene = obliqueBlobScene();
  RenderSettings settings;
  settings.width = 32;
  settings.height = 24;
  const auto ghost = [&](PixelShare share) {
    BrickRender r(f, Int3{8, 8, 8});
    RenderSettings s = settings;
    s.pixelShare = share;
    r.renderer.setSettings(s);
    r.renderer.setScene(scene);
    return r.renderer.runGhostPasses(3);
  };
  const FrameStats whole = ghost(PixelShare{0, 1});
  ASSERT_GT(whole.queries, 0u);
  for (int n : {2, 4})
    for (int k = 0; k < n; ++k) {
      const FrameStats g = ghost(PixelShare{k, n});
      EXPECT_EQ(g.queries, whole.queries) << "share " << k << " of " << n;
      EXPECT_EQ(g.refinements, whole.refinements) << "share " << k << " of " << n;
    }
}

}  // namespace
}  // namespace inr
