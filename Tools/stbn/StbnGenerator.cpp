#include "StbnGenerator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace inr {
namespace {

// One axis of the separable kernel: g(i) = exp(-i^2 / 2 sigma^2) for |i| <= radius, every entry
// divided by sum_{i=1..radius} g(i). The radius keeps the Gaussian's tail above 0.5% of its peak,
// and never exceeds half the axis, so the wrapped kernel does not reach around onto itself.
struct AxisKernel {
  int radius = 0;
  std::vector<double> weight;  // weight[i + radius], i in [-radius, radius]
  double at(int i) const { return weight[std::size_t(i + radius)]; }
};

AxisKernel makeAxisKernel(double sigma, int size) {
  AxisKernel k;
  const int full = int(std::floor(std::sqrt(-2.0 * sigma * sigma * std::log(0.005))));
  k.radius = std::min(full, size / 2);
  double tail = 0.0;
  for (int i = 1; i <= k.radius; ++i) tail += std::exp(-double(i) * i / (2.0 * sigma * sigma));
  k.weight.resize(std::size_t(2 * k.radius + 1));
  for (int i = -k.radius; i <= k.radius; ++i) {
    const double g = i == 0 ? 1.0 : std::exp(-double(i) * i / (2.0 * sigma * sigma));
    // A one-texel axis has no neighbours (tail 0): only the self term, which cancels in every
    // comparison.
    k.weight[std::size_t(i + k.radius)] = tail > 0.0 ? g / tail : g;
  }
  return k;
}

// Tournament tree over texel indices holding, per subtree, the on-texel of largest energy (the
// tightest cluster) and the off-texel of smallest energy (the largest void). Leaves of the other
// class hold -inf / +inf, so one tree answers both questions. Ties go to the left child, i.e. the
// lower texel index. Node i has children 2i and 2i + 1; leaves start at `leaves`.
class ExtremumTree {
 public:
  void reset(std::size_t count) {
    leaves_ = 1;
    while (leaves_ < count) leaves_ *= 2;
    nodes_.assign(2 * leaves_, Node{});
  }

  // Rebuilds every node from the energies and the pattern: O(N).
  void build(const std::vector<double>& energy, const std::vector<std::uint8_t>& on) {
    for (std::size_t i = 0; i < energy.size(); ++i) nodes_[leaves_ + i] = leaf(i, energy[i], on[i]);
    for (std::size_t i = leaves_ - 1; i >= 1; --i) nodes_[i] = combine(nodes_[2 * i], nodes_[2 * i + 1]);
  }

  void setLeaf(std::size_t i, double energy, bool on) { nodes_[leaves_ + i] = leaf(i, energy, on); }

  // Recomputes the ancestors of the leaves in the given sorted, disjoint index ranges [first, last]
  // (after setLeaf on them). Neighbouring ranges share ancestors a few levels up, so walking the
  // ranges level by level and merging them touches far fewer nodes than walking every leaf to the
  // root on its own.
  void refresh(std::vector<std::pair<std::size_t, std::size_t>>& ranges) {
    for (auto& r : ranges) r = {r.first + leaves_, r.second + leaves_};
    while (ranges.front().first > 1) {
      std::size_t kept = 0;
      for (std::size_t k = 0; k < ranges.size(); ++k) {
        const std::size_t a = ranges[k].first / 2, b = ranges[k].second / 2;
        if (kept > 0 && a <= ranges[kept - 1].second + 1) {
          ranges[kept - 1].second = std::max(ranges[kept - 1].second, b);
        } else {
          ranges[kept++] = {a, b};
        }
      }
      ranges.resize(kept);
      for (const auto& r : ranges)
        for (std::size_t p = r.first; p <= r.second; ++p)
          nodes_[p] = combine(nodes_[2 * p], nodes_[2 * p + 1]);
    }
  }

  std::size_t tightestCluster() const { return nodes_[1].onIndex; }
  std::size_t largestVoid() const { return nodes_[1].offIndex; }

 private:
  struct Node {
    double onEnergy = -std::numeric_limits<double>::infinity();
    double offEnergy = std::numeric_limits<double>::infinity();
    std::uint32_t onIndex = std::numeric_limits<std::uint32_t>::max();
    std::uint32_t offIndex = std::numeric_limits<std::uint32_t>::max();
  };

  static Node leaf(std::size_t i, double energy, bool on) {
    Node n;
    if (on) {
      n.onEnergy = energy;
      n.onIndex = std::uint32_t(i);
    } else {
      n.offEnergy = energy;
      n.offIndex = std::uint32_t(i);
    }
    return n;
  }

  static Node combine(const Node& l, const Node& r) {
    Node n;
    const bool rightOn = r.onEnergy > l.onEnergy;
    n.onEnergy = rightOn ? r.onEnergy : l.onEnergy;
    n.onIndex = rightOn ? r.onIndex : l.onIndex;
    const bool rightOff = r.offEnergy < l.offEnergy;
    n.offEnergy = rightOff ? r.offEnergy : l.offEnergy;
    n.offIndex = rightOff ? r.offIndex : l.offIndex;
    return n;
  }

  std::size_t leaves_ = 1;
  std::vector<Node> nodes_;
};

// The binary pattern, its energy field and the tree over both, kept consistent by toggle().
class VoidAndCluster {
 public:
  VoidAndCluster(int width, int height, int depth, double sigma)
      : w_(width), h_(height), d_(depth),
        n_(std::size_t(width) * std::size_t(height) * std::size_t(depth)),
        kx_(makeAxisKernel(sigma, width)), ky_(makeAxisKernel(sigma, height)),
        kt_(makeAxisKernel(sigma, depth)), energy_(n_, 0.0), on_(n_, 0) {
    tree_.reset(n_);
  }

  std::size_t size() const { return n_; }
  bool on(std::size_t i) const { return on_[i] != 0; }

  // Replaces the pattern, recomputes the energy from scratch and rebuilds the tree.
  void assign(const std::vector<std::uint8_t>& pattern) {
    on_ = pattern;
    std::fill(energy_.begin(), energy_.end(), 0.0);
    for (std::size_t i = 0; i < n_; ++i)
      if (on_[i]) splat(i, +1.0, /*refreshTree=*/false);
    tree_.build(energy_, on_);
  }
  const std::vector<std::uint8_t>& pattern() const { return on_; }

  void toggle(std::size_t i) {
    on_[i] = !on_[i];
    splat(i, on_[i] ? +1.0 : -1.0, /*refreshTree=*/true);
  }

  std::size_t tightestCluster() const { return tree_.tightestCluster(); }
  std::size_t largestVoid() const { return tree_.largestVoid(); }

 private:
  // Adds sign x the on-texel i's footprint: the 2D kernel over its own slice and the 1D kernel
  // along time at its own pixel (the pixel itself counted once, in the 2D part). That is
  // (2r+1)^2 + 2r texels for radius r, each then re-entered in the tree.
  void splat(std::size_t i, double sign, bool refreshTree) {
    const int x = int(i % std::size_t(w_));
    const int y = int(i / std::size_t(w_) % std::size_t(h_));
    const int z = int(i / (std::size_t(w_) * std::size_t(h_)));
    const std::size_t slice = std::size_t(z) * std::size_t(h_) * std::size_t(w_);
    ranges_.clear();
    for (int dy = -ky_.radius; dy <= ky_.radius; ++dy) {
      const int yy = ((y + dy) % h_ + h_) % h_;
      const double gy = sign * ky_.at(dy);
      const std::size_t row = slice + std::size_t(yy) * std::size_t(w_);
      for (int dx = -kx_.radius; dx <= kx_.radius; ++dx) {
        const int xx = ((x + dx) % w_ + w_) % w_;
        energy_[row + std::size_t(xx)] += gy * kx_.at(dx);
      }
      if (refreshTree) addRowRanges(row, x);
    }
    for (int dz = -kt_.radius; dz <= kt_.radius; ++dz) {
      if (dz == 0) continue;
      const int zz = ((z + dz) % d_ + d_) % d_;
      const std::size_t j = (std::size_t(zz) * std::size_t(h_) + std::size_t(y)) * std::size_t(w_) + std::size_t(x);
      energy_[j] += sign * kt_.at(dz);
      if (refreshTree) ranges_.push_back({j, j});
    }
    if (!refreshTree) return;
    for (const auto& r : ranges_)
      for (std::size_t j = r.first; j <= r.second; ++j) tree_.setLeaf(j, energy_[j], on_[j] != 0);
    std::sort(ranges_.begin(), ranges_.end());
    // Merge overlaps (a kernel radius of half an axis wraps onto the same texels).
    std::size_t kept = 0;
    for (std::size_t k = 0; k < ranges_.size(); ++k) {
      if (kept > 0 && ranges_[k].first <= ranges_[kept - 1].second + 1) {
        ranges_[kept - 1].second = std::max(ranges_[kept - 1].second, ranges_[k].second);
      } else {
        ranges_[kept++] = ranges_[k];
      }
    }
    ranges_.resize(kept);
    tree_.refresh(ranges_);
  }

  // The row's touched span [x - r, x + r], split in two where it wraps around.
  void addRowRanges(std::size_t row, int x) {
    const int a = x - kx_.radius, b = x + kx_.radius;
    if (b - a + 1 >= w_) {
      ranges_.push_back({row, row + std::size_t(w_ - 1)});
    } else if (a < 0) {
      ranges_.push_back({row, row + std::size_t(b)});
      ranges_.push_back({row + std::size_t(a + w_), row + std::size_t(w_ - 1)});
    } else if (b >= w_) {
      ranges_.push_back({row, row + std::size_t(b - w_)});
      ranges_.push_back({row + std::size_t(a), row + std::size_t(w_ - 1)});
    } else {
      ranges_.push_back({row + std::size_t(a), row + std::size_t(b)});
    }
  }

  int w_, h_, d_;
  std::size_t n_;
  AxisKernel kx_, ky_, kt_;
  std::vector<double> energy_;
  std::vector<std::uint8_t> on_;
  ExtremumTree tree_;
  std::vector<std::pair<std::size_t, std::size_t>> ranges_;
};

// Uniform in [0, bound) from mt19937's standardised 32-bit output by rejection:
// std::uniform_int_distribution's algorithm differs between standard libraries.
std::uint32_t drawBelow(std::mt19937& rng, std::uint32_t bound) {
  const std::uint64_t range = std::uint64_t(1) << 32;
  const std::uint64_t limit = range - range % bound;
  for (;;) {
    const std::uint64_t r = rng();
    if (r < limit) return std::uint32_t(r % bound);
  }
}

// 5. Per-pixel temporal stratification. The global ranking leaves a pixel's D values only near
// evenly spaced, so thresholding at rho can turn a pixel on a few frames more or fewer than
// rho * D. Here each pixel's D texels are ranked among themselves by their global rank (all
// distinct, so no ties: the order in time is the global ranking's), and the texel of temporal
// rank r gets a level from r's own bin [ceil(256 r / D), ceil(256 (r + 1) / D) - 1]; with
// D <= 256 every bin is non-empty, and the bins are in order and cover 0..255. Each bin holds
// exactly W * H texels (one per pixel); within it the levels go by global rank: the j-th of them
// (j = 0 .. W H - 1, in global rank order) gets level lo + floor(j * bin size / (W H)). So every
// level still occurs equally often (exactly N / 256 times when D divides 256 and W H divides by
// 256 / D), and within a slice the texels of one bin keep the global ranking's spatial order.
// Docs/blue-noise.md proves the count property: for every rho in (0, 1), thresholding at rho turns
// every pixel on floor(rho D) or ceil(rho D) frames of the cycle. All integer arithmetic.
void stratifyPixelsInTime(const std::vector<std::uint32_t>& rank, int width, int height, int depth,
                          std::vector<std::uint8_t>& texels) {
  const std::size_t plane = std::size_t(width) * std::size_t(height), d = std::size_t(depth);
  const std::size_t n = plane * d;
  // Temporal rank of every texel.
  std::vector<std::uint16_t> temporalRank(n);
  std::vector<std::size_t> order(d);
  for (std::size_t p = 0; p < plane; ++p) {
    for (std::size_t t = 0; t < d; ++t) order[t] = t * plane + p;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return rank[a] < rank[b]; });
    for (std::size_t r = 0; r < d; ++r) temporalRank[order[r]] = std::uint16_t(r);
  }
  // Texels in global rank order (rank is a permutation of 0 .. N-1), each numbered within its bin.
  std::vector<std::uint32_t> byRank(n);
  for (std::size_t i = 0; i < n; ++i) byRank[rank[i]] = std::uint32_t(i);
  std::vector<std::uint64_t> seen(d, 0);
  for (std::size_t g = 0; g < n; ++g) {
    const std::size_t i = byRank[g];
    const std::uint64_t r = temporalRank[i];
    const std::uint64_t lo = (256 * r + d - 1) / d, hi = (256 * (r + 1) + d - 1) / d;
    texels[i] = std::uint8_t(lo + seen[r]++ * (hi - lo) / plane);
  }
}

}  // namespace

BlueNoiseMask generateStbnMask(int width, int height, int depth, std::uint32_t seed, double sigma,
                               const StbnProgressCallback& progress) {
  if (width <= 0 || height <= 0 || depth <= 0)
    throw std::invalid_argument("generateStbnMask: sizes must be positive");
  // More frames than the 256 byte levels could not give each of a pixel's frames its own level.
  if (depth > 256) throw std::invalid_argument("generateStbnMask: depth must be at most 256");
  if (!(sigma > 0.0)) throw std::invalid_argument("generateStbnMask: sigma must be positive");
  const std::size_t n = std::size_t(width) * std::size_t(height) * std::size_t(depth);
  if (n > std::numeric_limits<std::uint32_t>::max() / 2)
    throw std::invalid_argument("generateStbnMask: mask too large");
  auto report = [&](const char* phase, std::size_t done, std::size_t total) {
    if (progress) progress(StbnProgress{phase, done, total});
  };
  // Progress about a thousand times per phase: often enough to watch, rare enough not to cost.
  auto every = [](std::size_t total) { return std::max<std::size_t>(1, total / 1000); };

  VoidAndCluster vc(width, height, depth, sigma);

  // 0. About 10% of the texels on, chosen by a partial Fisher-Yates shuffle (at least one on).
  std::vector<std::uint8_t> pattern(n, 0);
  {
    std::mt19937 rng(seed);
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
    const std::size_t initialOnes = std::max<std::size_t>(1, n / 10);
    for (std::size_t k = 0; k < initialOnes; ++k) {
      const std::size_t j = k + drawBelow(rng, std::uint32_t(n - k));
      std::swap(order[k], order[j]);
      pattern[order[k]] = 1;
    }
  }
  vc.assign(pattern);
  std::size_t ones = std::size_t(std::count(pattern.begin(), pattern.end(), 1));

  // 1. Move the tightest cluster to the largest void until removing it leaves its own spot as the
  // largest void. Void-and-cluster converges; the cap only guards against a floating-point cycle.
  {
    const std::size_t cap = 100 * n;
    std::size_t swaps = 0;
    for (; swaps < cap; ++swaps) {
      const std::size_t cluster = vc.tightestCluster();
      vc.toggle(cluster);
      const std::size_t hole = vc.largestVoid();
      vc.toggle(hole);
      if (hole == cluster) break;
      if (swaps % 1000 == 0) report("initial", swaps, 0);
    }
    report("initial", swaps, swaps);
  }
  const std::vector<std::uint8_t> initial = vc.pattern();

  std::vector<std::uint32_t> rank(n, 0);

  // 2. Phase 1: remove the tightest clusters from the initial pattern; a removed texel's rank is
  // the number of ones left.
  {
    const std::size_t total = ones;
    for (std::size_t done = 0; ones > 0; ++done) {
      const std::size_t cluster = vc.tightestCluster();
      vc.toggle(cluster);
      --ones;
      rank[cluster] = std::uint32_t(ones);
      if (done % every(total) == 0) report("phase1", done, total);
    }
    report("phase1", total, total);
    ones = total;
  }

  // 3. Phase 2: from the initial pattern, fill the largest voids until half the texels are on; an
  // inserted texel's rank is the number of ones before it.
  vc.assign(initial);
  {
    const std::size_t half = n / 2, start = ones, total = half > start ? half - start : 0;
    while (ones < half) {
      const std::size_t hole = vc.largestVoid();
      vc.toggle(hole);
      rank[hole] = std::uint32_t(ones);
      ++ones;
      if ((ones - start) % every(total) == 0) report("phase2", ones - start, total);
    }
    report("phase2", total, total);
  }

  // 4. Phase 3: past half, the off texels are the minority. Invert the pattern (off becomes on),
  // recompute its energy, and remove the tightest clusters of the inverse; a removed texel's rank
  // is N minus the inverse's ones before removal (N/2 .. N-1 for the last).
  {
    std::vector<std::uint8_t> inverse = vc.pattern();
    for (auto& b : inverse) b = !b;
    vc.assign(inverse);
    std::size_t left = n - ones;
    const std::size_t total = left;
    while (left > 0) {
      const std::size_t cluster = vc.tightestCluster();
      rank[cluster] = std::uint32_t(n - left);
      vc.toggle(cluster);
      --left;
      if ((total - left) % every(total) == 0) report("phase3", total - left, total);
    }
    report("phase3", total, total);
  }

  BlueNoiseMask mask;
  mask.width = width;
  mask.height = height;
  mask.depth = depth;
  mask.texels.resize(n);
  stratifyPixelsInTime(rank, width, height, depth, mask.texels);
  return mask;
}

}  // namespace inr
