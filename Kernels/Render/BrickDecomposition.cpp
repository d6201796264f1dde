#include "Render/BrickDecomposition.h"

#include <cmath>
#include <cstdlib>
#include <functional>
#include <stdexcept>

namespace inr {

namespace {

float& comp(Vec3f& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }
int& comp(Int3& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }

// The model-space coordinate of the cell boundary k along `axis` of the whole grid: computed the
// same way for both sides of a cut, so neighbouring bricks share the plane exactly.
float cellPlane(const Box3f& box, Int3 cells, int axis, int k) {
  const int n = component(cells, axis);
  if (k <= 0) return component(box.lo, axis);
  if (k >= n) return component(box.hi, axis);
  const double lo = component(box.lo, axis), hi = component(box.hi, axis);
  return float(lo + (hi - lo) * double(k) / double(n));
}

void split(const Box3f& whole, Int3 cells, Int3 lo, Int3 hi, int count, std::vector<Brick>& out) {
  if (count == 1) {
    Brick b;
    b.cellLo = lo;
    b.cellHi = hi;
    for (int a = 0; a < 3; ++a) {
      comp(b.box.lo, a) = cellPlane(whole, cells, a, component(lo, a));
      comp(b.box.hi, a) = cellPlane(whole, cells, a, component(hi, a));
    }
    out.push_back(b);
    return;
  }
  // The axis with the largest world extent among those that still have two cells or more.
  int axis = -1;
  double extent = -1.0;
  for (int a = 0; a < 3; ++a) {
    const int n = component(hi, a) - component(lo, a);
    if (n < 2) continue;
    const double e = double(n) * (double(component(whole.hi, a)) - double(component(whole.lo, a))) /
                     double(component(cells, a));
    if (e > extent) {
      extent = e;
      axis = a;
    }
  }
  if (axis < 0) {
    throw std::invalid_argument("brick decomposition: " + std::to_string(count) +
                                " bricks need more macrocells than the grid has (" + std::to_string(cells.x) +
                                "x" + std::to_string(cells.y) + "x" + std::to_string(cells.z) + ")");
  }
  const int first = (count + 1) / 2, second = count - first;
  const int n = component(hi, axis) - component(lo, axis);
  // Volumes in the ratio of the brick counts, rounded to a cell boundary, each side at least one cell.
  int cut = int(std::lround(double(n) * double(first) / double(count)));
  if (cut < 1) cut = 1;
  if (cut > n - 1) cut = n - 1;
  Int3 mid = hi;
  comp(mid, axis) = component(lo, axis) + cut;
  Int3 lo2 = lo;
  comp(lo2, axis) = component(lo, axis) + cut;
  split(whole, cells, lo, mid, first, out);
  split(whole, cells, lo2, hi, second, out);
}

}  // namespace

std::vector<Brick> brickDecomposition(const Box3f& box, Int3 cells, int count) {
  if (count < 1) throw std::invalid_argument("brick decomposition: brick count must be >= 1, got " + std::to_string(count));
  if (cells.x < 1 || cells.y < 1 || cells.z < 1) throw std::invalid_argument("brick decomposition: macrocell dims must be >= 1");
  if ((long long)cells.x * cells.y * cells.z < count) {
    throw std::invalid_argument("brick decomposition: " + std::to_string(count) + " bricks need at least as many macrocells");
  }
  std::vector<Brick> out;
  out.reserve(std::size_t(count));
  split(box, cells, Int3{0, 0, 0}, cells, count, out);
  return out;
}

BrickIndex parseBrickIndex(const std::string& text) {
  const auto slash = text.find('/');
  auto bad = [&] {
    return std::invalid_argument("brick '" + text + "' must be i/N with N >= 1 and 0 <= i < N (e.g. 0/2)");
  };
  if (slash == std::string::npos || slash == 0 || slash + 1 >= text.size()) throw bad();
  char* end = nullptr;
  const std::string a = text.substr(0, slash), b = text.substr(slash + 1);
  const long i = std::strtol(a.c_str(), &end, 10);
  if (*end != '\0') throw bad();
  const long n = std::strtol(b.c_str(), &end, 10);
  if (*end != '\0') throw bad();
  if (n < 1 || n > 4096 || i < 0 || i >= n) throw bad();
  return BrickIndex{int(i), int(n)};
}

std::vector<int> brickVisibilityOrder(const std::vector<Brick>& bricks, Vec3f eye) {
  std::vector<int> order;
  std::function<void(const std::vector<int>&)> visit = [&](const std::vector<int>& set) {
    if (set.size() == 1) {
      order.push_back(set[0]);
      return;
    }
    // A plane (a brick face) with every brick of the set entirely on one side or the other: a
    // k-d split always has one.
    for (int a = 0; a < 3; ++a) {
      for (int candidate : set) {
        const float p = component(bricks[std::size_t(candidate)].box.lo, a);
        std::vector<int> below, above;
        for (int k : set) {
          const Box3f& b = bricks[std::size_t(k)].box;
          if (component(b.hi, a) <= p) below.push_back(k);
          else if (component(b.lo, a) >= p) above.push_back(k);
          else break;
        }
        if (below.empty() || above.empty() || below.size() + above.size() != set.size()) continue;
        const bool eyeBelow = component(eye, a) < p;
        visit(eyeBelow ? below : above);
        visit(eyeBelow ? above : below);
        return;
      }
    }
    throw std::invalid_argument("brick visibility order: the bricks are not a k-d split");
  };
  std::vector<int> all(bricks.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = int(k);
  if (!all.empty()) visit(all);
  return order;
}

std::uint32_t brickSeed(std::uint32_t seed, int index) {
  return seed + std::uint32_t(index) * 0x9E3779B9u;  // golden-ratio stride: distinct for every index
}

}  // namespace inr
