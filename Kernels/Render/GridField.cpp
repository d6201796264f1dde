#include "Render/GridField.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace inr {

GridField::GridField(const Box3f& box, Int3 dims, std::vector<float> values, std::string source)
    : box_(box), dims_(dims), values_(std::move(values)), source_(std::move(source)) {
  if (dims.x < 1 || dims.y < 1 || dims.z < 1)
    throw std::invalid_argument("GridField: dimensions must be at least 1 per axis");
  const std::size_t count = std::size_t(dims.x) * std::size_t(dims.y) * std::size_t(dims.z);
  if (values_.size() != count)
    throw std::invalid_argument("GridField: " + std::to_string(values_.size()) + " values for " +
                                std::to_string(count) + " cells");
  if (!(box.hi.x > box.lo.x && box.hi.y > box.lo.y && box.hi.z > box.lo.z))
    throw std::invalid_argument("GridField: the box is empty");
}

namespace {
// Cell-centre coordinate of world coordinate w along one axis of `n` cells: the lower centre's
// index and the weight of the upper one, clamped to [0, n - 1]; `dfdw` the weight's derivative
// with respect to w (0 where clamped).
void axisWeights(float w, float lo, float hi, int n, int& i0, int& i1, float& f, float& dfdw) {
  const float perWorld = float(n) / (hi - lo);
  const float c = (w - lo) * perWorld - 0.5f;
  const float clamped = std::min(std::max(c, 0.f), float(n - 1));
  i0 = std::min(int(clamped), n - 1);
  i1 = std::min(i0 + 1, n - 1);
  f = clamped - float(i0);
  dfdw = (c > 0.f && c < float(n - 1)) ? perWorld : 0.f;
}
}  // namespace

float GridField::at(float x, float y, float z, float* gradient) const {
  int x0, x1, y0, y1, z0, z1;
  float fx, fy, fz, dx, dy, dz;
  axisWeights(x, box_.lo.x, box_.hi.x, dims_.x, x0, x1, fx, dx);
  axisWeights(y, box_.lo.y, box_.hi.y, dims_.y, y0, y1, fy, dy);
  axisWeights(z, box_.lo.z, box_.hi.z, dims_.z, z0, z1, fz, dz);
  const auto v = [&](int i, int j, int k) {
    return values_[(std::size_t(k) * std::size_t(dims_.y) + std::size_t(j)) * std::size_t(dims_.x) + std::size_t(i)];
  };
  // A neighbour of weight 0 (an axis clamped at the border, or a point on a centre) does not
  // contribute, NaN or not.
  const auto lerp = [](float a, float b, float t) { return t == 0.f ? a : a + (b - a) * t; };
  const float v000 = v(x0, y0, z0), v100 = v(x1, y0, z0), v010 = v(x0, y1, z0), v110 = v(x1, y1, z0);
  const float v001 = v(x0, y0, z1), v101 = v(x1, y0, z1), v011 = v(x0, y1, z1), v111 = v(x1, y1, z1);
  const float c00 = lerp(v000, v100, fx), c10 = lerp(v010, v110, fx);
  const float c01 = lerp(v001, v101, fx), c11 = lerp(v011, v111, fx);
  const float c0 = lerp(c00, c10, fy), c1 = lerp(c01, c11, fy);
  if (gradient) {
    const float e0 = lerp(v100 - v000, v110 - v010, fy), e1 = lerp(v101 - v001, v111 - v011, fy);
    gradient[0] = dx == 0.f ? 0.f : lerp(e0, e1, fz) * dx;
    gradient[1] = dy == 0.f ? 0.f : lerp(c10 - c00, c11 - c01, fz) * dy;
    gradient[2] = dz == 0.f ? 0.f : (c1 - c0) * dz;
  }
  return lerp(c0, c1, fz);
}

void GridField::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  for (std::size_t i = 0; i < n; ++i) out[i] = at(points[i].x, points[i].y, points[i].z);
}

void GridField::evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values, float* gradients) const {
  for (std::size_t i = 0; i < n; ++i) values[i] = at(points[i].x, points[i].y, points[i].z, gradients + 3 * i);
}

std::string GridField::name() const {
  return "grid " + std::to_string(dims_.x) + "x" + std::to_string(dims_.y) + "x" + std::to_string(dims_.z) +
         (source_.empty() ? "" : " (" + source_ + ")");
}

}  // namespace inr
