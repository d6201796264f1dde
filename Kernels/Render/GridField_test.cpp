// GridField: trilinear interpolation between cell centres, clamped at the border, NaN kept.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "Render/GridField.h"

namespace inr {
namespace {

const Box3f kBox{Vec3f{-1.f, 0.f, 2.f}, Vec3f{1.f, 4.f, 3.f}};

// A field linear in x, y, z sampled at the cell centres of a dims grid over kBox.
GridField linearGrid(Int3 dims, float a, float b, float c, float d) {
  std::vector<float> v;
  for (int k = 0; k < dims.z; ++k)
    for (int j = 0; j < dims.y; ++j)
      for (int i = 0; i < dims.x; ++i) {
        const float x = kBox.lo.x + (float(i) + 0.5f) * (kBox.hi.x - kBox.lo.x) / float(dims.x);
        const float y = kBox.lo.y + (float(j) + 0.5f) * (kBox.hi.y - kBox.lo.y) / float(dims.y);
        const float z = kBox.lo.z + (float(k) + 0.5f) * (kBox.hi.z - kBox.lo.z) / float(dims.z);
        v.push_back(a * x + b * y + c * z + d);
      }
  return GridField(kBox, dims, v, "test");
}

TEST(GridField, ReproducesALinearFieldBetweenCellCentres) {
  const GridField g = linearGrid(Int3{5, 7, 3}, 2.f, -0.5f, 3.f, 1.f);
  // Points between the outermost centres: trilinear interpolation of a linear field is exact.
  const std::vector<QueryPoint> pts = {{0.f, 2.f, 2.5f, 0.f}, {-0.75f, 0.4f, 2.2f, 7.f}, {0.79f, 3.7f, 2.8f, -1.f},
                                       {0.13f, 1.234f, 2.61f, 0.5f}};
  std::vector<float> out(pts.size());
  g.evaluate(pts.data(), pts.size(), out.data());
  for (std::size_t i = 0; i < pts.size(); ++i)
    EXPECT_NEAR(out[i], 2.f * pts[i].x - 0.5f * pts[i].y + 3.f * pts[i].z + 1.f, 1e-5f) << "point " << i;
}

TEST(GridField, GradientOfTheInterpolant) {
  const GridField g = linearGrid(Int3{5, 7, 3}, 2.f, -0.5f, 3.f, 1.f);
  ASSERT_TRUE(g.providesGradient());
  const std::vector<QueryPoint> pts = {{0.f, 2.f, 2.5f, 0.f}, {0.13f, 1.234f, 2.61f, 0.5f}};
  std::vector<float> v(pts.size()), grad(3 * pts.size());
  g.evaluateWithGradient(pts.data(), pts.size(), v.data(), grad.data());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_NEAR(v[i], 2.f * pts[i].x - 0.5f * pts[i].y + 3.f * pts[i].z + 1.f, 1e-5f);
    EXPECT_NEAR(grad[3 * i + 0], 2.f, 1e-4f) << "point " << i;
    EXPECT_NEAR(grad[3 * i + 1], -0.5f, 1e-4f) << "point " << i;
    EXPECT_NEAR(grad[3 * i + 2], 3.f, 1e-4f) << "point " << i;
  }
  // A curved field: the gradient is the interpolant's, checked against central differences.
  std::vector<float> vals;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) vals.push_back(float(i * i + 2 * j * k + k));
  const GridField c(kBox, Int3{4, 4, 4}, vals, "");
  const float p[3] = {0.1f, 1.7f, 2.4f}, h = 1e-3f;
  float gp[3];
  c.at(p[0], p[1], p[2], gp);
  EXPECT_NEAR(gp[0], (c.at(p[0] + h, p[1], p[2]) - c.at(p[0] - h, p[1], p[2])) / (2 * h), 2e-2f);
  EXPECT_NEAR(gp[1], (c.at(p[0], p[1] + h, p[2]) - c.at(p[0], p[1] - h, p[2])) / (2 * h), 2e-2f);
  EXPECT_NEAR(gp[2], (c.at(p[0], p[1], p[2] + h) - c.at(p[0], p[1], p[2] - h)) / (2 * h), 2e-2f);
  c.at(-5.f, 1.7f, 2.4f, gp);  // clamped in x: flat there
  EXPECT_EQ(gp[0], 0.f);
}

TEST(GridField, ClampsToTheOutermostCentresAndIgnoresTime) {
  const GridField g = linearGrid(Int3{4, 4, 4}, 1.f, 0.f, 0.f, 0.f);  // x only; centres at x = -0.75 ... 0.75
  EXPECT_NEAR(g.at(-1.f, 2.f, 2.5f), -0.75f, 1e-6f);
  EXPECT_NEAR(g.at(-5.f, 2.f, 2.5f), -0.75f, 1e-6f);  // outside the box: the nearest centre's value
  EXPECT_NEAR(g.at(9.f, -3.f, 100.f), 0.75f, 1e-6f);
  const QueryPoint early{0.25f, 1.f, 2.5f, 0.f}, late{0.25f, 1.f, 2.5f, 99.f};
  float a = 0.f, b = 1.f;
  g.evaluate(&early, 1, &a);
  g.evaluate(&late, 1, &b);
  EXPECT_EQ(a, b);
  EXPECT_NEAR(a, 0.25f, 1e-6f);
}

TEST(GridField, SingleCellAxesAndNanCells) {
  std::vector<float> v = {1.f, 3.f};  // 2 x 1 x 1
  GridField g(kBox, Int3{2, 1, 1}, v, "");
  EXPECT_NEAR(g.at(0.f, 0.f, 0.f), 2.f, 1e-6f);  // halfway between the two centres
  v[1] = NAN;
  GridField holes(kBox, Int3{2, 1, 1}, v, "");
  EXPECT_TRUE(std::isnan(holes.at(0.f, 1.f, 2.5f)));  // a NaN sample contributes: empty space
  EXPECT_EQ(holes.at(-1.f, 1.f, 2.5f), 1.f);           // at the first centre it does not
  EXPECT_EQ(holes.name(), "grid 2x1x1");
}

TEST(GridField, RefusesInconsistentInput) {
  EXPECT_THROW(GridField(kBox, Int3{2, 2, 2}, std::vector<float>(7), ""), std::invalid_argument);
  EXPECT_THROW(GridField(kBox, Int3{0, 2, 2}, std::vector<float>(0), ""), std::invalid_argument);
  EXPECT_THROW(GridField(Box3f{kBox.lo, kBox.lo}, Int3{1, 1, 1}, std::vector<float>(1), ""), std::invalid_argument);
}

}  // namespace
}  // namespace inr
