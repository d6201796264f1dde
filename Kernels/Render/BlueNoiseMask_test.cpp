// The shipped spatiotemporal blue-noise mask and its generator (Docs/blue-noise.md). Every
// statistical check on the shipped mask is also run on a white-noise control — the same bytes
// randomly permuted, so the histogram is identical — and the control must fail the checks that
// claim "blue", so they measure the arrangement and not the value distribution.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "Render/BlueNoiseMask.h"
#include "StbnGenerator.h"

namespace inr {
namespace {

constexpr double kRhos[] = {0.25, 0.5, 0.75};
// For the per-pixel counts: multiples of 1/64 and two that are not (0.3 * 64 = 19.2,
// 0.61 * 64 = 39.04).
constexpr double kCountRhos[] = {0.1, 0.25, 0.3, 0.5, 0.61, 0.75, 0.9};

std::uint8_t at(const BlueNoiseMask& m, int x, int y, int z) {
  return m.texels[(std::size_t(z) * m.height + y) * m.width + x];
}

// The same bytes in a random order (Fisher-Yates over mt19937 with a rejection draw): white noise
// with exactly the shipped mask's histogram.
BlueNoiseMask whiteNoiseControl(const BlueNoiseMask& m, std::uint32_t seed) {
  BlueNoiseMask w = m;
  std::mt19937 rng(seed);
  for (std::size_t i = w.texels.size() - 1; i > 0; --i) {
    const std::uint64_t bound = i + 1, limit = (std::uint64_t(1) << 32) - (std::uint64_t(1) << 32) % bound;
    std::uint64_t r;
    do r = rng(); while (r >= limit);
    std::swap(w.texels[i], w.texels[std::size_t(r % bound)]);
  }
  return w;
}

// In-place radix-2 FFT (size a power of two); the test's own, sign convention irrelevant here
// since only |F|^2 is used.
void fft(std::vector<std::complex<double>>& a) {
  const std::size_t n = a.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(a[i], a[j]);
  }
  const double pi = std::acos(-1.0);
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const std::complex<double> step = std::polar(1.0, -2.0 * pi / double(len));
    for (std::size_t i = 0; i < n; i += len) {
      std::complex<double> w = 1.0;
      for (std::size_t k = 0; k < len / 2; ++k, w *= step) {
        const std::complex<double> u = a[i + k], v = a[i + k + len / 2] * w;
        a[i + k] = u + v;
        a[i + k + len / 2] = u - v;
      }
    }
  }
}

// Signed frequency index of DFT bin k of an n-point transform, in [-n/2, n/2).
int signedFrequency(int k, int n) { return k < n / 2 ? k : k - n; }

// Per slice: mean power of the spatial spectrum (2D DFT of the mean-removed slice) at radial
// frequencies below 1/8 of Nyquist (|f| < 1/16 cycles per texel), over the mean power of all
// non-DC bins. White noise gives about 1; blue noise, which has little energy at low frequencies,
// much less.
std::vector<double> spatialLowFrequencyRatios(const BlueNoiseMask& m) {
  const int w = m.width, h = m.height;
  std::vector<double> ratios;
  std::vector<std::complex<double>> img(std::size_t(w) * h), line;
  for (int z = 0; z < m.depth; ++z) {
    double mean = 0.0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) mean += at(m, x, y, z);
    mean /= double(w) * h;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) img[std::size_t(y) * w + x] = at(m, x, y, z) - mean;
    line.resize(std::size_t(w));
    for (int y = 0; y < h; ++y) {
      std::copy(img.begin() + std::ptrdiff_t(y) * w, img.begin() + std::ptrdiff_t(y + 1) * w, line.begin());
      fft(line);
      std::copy(line.begin(), line.end(), img.begin() + std::ptrdiff_t(y) * w);
    }
    line.resize(std::size_t(h));
    for (int x = 0; x < w; ++x) {
      for (int y = 0; y < h; ++y) line[std::size_t(y)] = img[std::size_t(y) * w + x];
      fft(line);
      for (int y = 0; y < h; ++y) img[std::size_t(y) * w + x] = line[std::size_t(y)];
    }
    double lowPower = 0.0, allPower = 0.0;
    std::size_t lowBins = 0, allBins = 0;
    for (int ky = 0; ky < h; ++ky)
      for (int kx = 0; kx < w; ++kx) {
        if (kx == 0 && ky == 0) continue;
        const double fx = double(signedFrequency(kx, w)) / w, fy = double(signedFrequency(ky, h)) / h;
        const double p = std::norm(img[std::size_t(ky) * w + kx]);
        allPower += p;
        ++allBins;
        if (std::sqrt(fx * fx + fy * fy) < 1.0 / 16.0) {
          lowPower += p;
          ++lowBins;
        }
      }
    ratios.push_back((lowPower / double(lowBins)) / (allPower / double(allBins)));
  }
  return ratios;
}

// The same over time: the 1D DFT of each pixel's mean-removed D values, low band |f| < 1/16
// cycles per frame (bins 1..3 and their mirrors for D = 64), over all non-DC bins.
double temporalLowFrequencyRatio(const BlueNoiseMask& m) {
  const int d = m.depth;
  double lowPower = 0.0, allPower = 0.0;
  std::size_t lowBins = 0, allBins = 0;
  std::vector<std::complex<double>> seq(static_cast<std::size_t>(d));
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      double mean = 0.0;
      for (int z = 0; z < d; ++z) mean += at(m, x, y, z);
      mean /= d;
      for (int z = 0; z < d; ++z) seq[std::size_t(z)] = at(m, x, y, z) - mean;
      fft(seq);
      for (int k = 1; k < d; ++k) {
        const double p = std::norm(seq[std::size_t(k)]);
        allPower += p;
        ++allBins;
        if (std::abs(double(signedFrequency(k, d)) / d) < 1.0 / 16.0) {
          lowPower += p;
          ++lowBins;
        }
      }
    }
  return (lowPower / double(lowBins)) / (allPower / double(allBins));
}

// Per pixel, frames of the cycle with u < rho, minus round(rho * D).
struct PixelCountSpread {
  int minDeviation = 0, maxDeviation = 0;
  double withinOne = 0.0;  // fraction of pixels with |deviation| <= 1
  double withinTwo = 0.0;  // fraction of pixels with |deviation| <= 2
  double rms = 0.0;
};

PixelCountSpread pixelCountSpread(const BlueNoiseMask& m, double rho) {
  PixelCountSpread s;
  const int expected = int(std::lround(rho * m.depth));
  std::size_t within = 0, withinOne = 0;
  double sumSq = 0.0;
  bool first = true;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      int count = 0;
      for (int z = 0; z < m.depth; ++z) count += at(m, x, y, z) < rho * 256.0;
      const int dev = count - expected;
      s.minDeviation = first ? dev : std::min(s.minDeviation, dev);
      s.maxDeviation = first ? dev : std::max(s.maxDeviation, dev);
      first = false;
      within += std::abs(dev) <= 2;
      withinOne += std::abs(dev) <= 1;
      sumSq += double(dev) * dev;
    }
  const double pixels = double(m.width) * m.height;
  s.withinTwo = double(within) / pixels;
  s.withinOne = double(withinOne) / pixels;
  s.rms = std::sqrt(sumSq / pixels);
  return s;
}

// Every threshold at once. A pixel is on in frame z iff its byte v < 256 rho, i.e. v < k for
// k = ceil(256 rho) in 1..256; every rho in ((k - 1) / 256, k / 256] gives the same count c_k. The
// count is floor(rho D) or ceil(rho D) for every such rho iff
// floor(k D / 256) <= c_k <= floor((k - 1) D / 256) + 1. Returns the (pixel, k) pairs breaking it.
std::size_t floorCeilViolations(const BlueNoiseMask& m) {
  std::size_t violations = 0;
  std::vector<int> histogram(256);
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      std::fill(histogram.begin(), histogram.end(), 0);
      for (int z = 0; z < m.depth; ++z) ++histogram[at(m, x, y, z)];
      int below = 0;  // c_k: frames with v < k
      for (int k = 1; k <= 256; ++k) {
        below += histogram[std::size_t(k - 1)];
        violations += below < k * m.depth / 256 || below > (k - 1) * m.depth / 256 + 1;
      }
    }
  return violations;
}

TEST(ShippedBlueNoiseMask, HasTheDocumentedSizeAndEveryLevelEquallyOften) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  ASSERT_EQ(m.width, 128);
  ASSERT_EQ(m.height, 128);
  ASSERT_EQ(m.depth, 64);
  ASSERT_EQ(m.texels.size(), std::size_t(128) * 128 * 64);
  EXPECT_EQ(&m, &shippedBlueNoiseMask());  // one shared instance
  // Per-pixel stratification puts one texel per pixel into each 4-level bin and spreads each bin's
  // 128 * 128 texels evenly over its 4 levels (Docs/blue-noise.md): each of the 256 levels exactly
  // N / 256 times.
  std::vector<std::size_t> count(256, 0);
  for (std::uint8_t v : m.texels) ++count[v];
  for (int v = 0; v < 256; ++v) EXPECT_EQ(count[std::size_t(v)], m.texels.size() / 256) << "level " << v;
}

TEST(ShippedBlueNoiseMask, EachSliceHasANearUniformHistogram) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const std::size_t sliceTexels = std::size_t(m.width) * m.height;
  // 16 bins of 16 levels: 1024 texels each if uniform.
  double worst = 0.0;
  for (int z = 0; z < m.depth; ++z) {
    std::vector<std::size_t> bins(16, 0);
    for (int y = 0; y < m.height; ++y)
      for (int x = 0; x < m.width; ++x) ++bins[at(m, x, y, z) / 16];
    for (std::size_t b = 0; b < 16; ++b) {
      const double rel = double(bins[b]) / (double(sliceTexels) / 16.0) - 1.0;
      worst = std::max(worst, std::abs(rel));
      // The per-pixel stratification trades some per-slice evenness for exact per-pixel counts:
      // worst 6.3% after it, 3.8% before (white noise, binomial estimate: rms about 3%).
      EXPECT_LT(std::abs(rel), 0.08) << "slice " << z << " bin " << b;
    }
  }
  std::printf("[ figures  ] slice 16-bin histogram: worst deviation %.2f%%\n", 100.0 * worst);
}

TEST(ShippedBlueNoiseMask, ThresholdingASliceTurnsOnRhoOfIt) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const BlueNoiseMaskView view = m.view();
  for (double rho : kRhos) {
    double lo = 1.0, hi = 0.0;
    for (int z = 0; z < m.depth; ++z) {
      std::size_t on = 0;
      for (int y = 0; y < m.height; ++y)
        for (int x = 0; x < m.width; ++x) on += blueNoiseValue(view, x, y, std::uint32_t(z)) < rho;
      const double fraction = double(on) / (double(m.width) * m.height);
      lo = std::min(lo, fraction);
      hi = std::max(hi, fraction);
      EXPECT_NEAR(fraction, rho, 0.02) << "slice " << z << " rho " << rho;
    }
    std::printf("[ figures  ] rho %.2f: slice on-fraction %.4f .. %.4f\n", rho, lo, hi);
  }
}

TEST(ShippedBlueNoiseMask, EveryPixelIsOnRhoOfTheCycleToWithinOneFrame) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const BlueNoiseMask white = whiteNoiseControl(m, 12345);
  for (double rho : kCountRhos) {
    const PixelCountSpread s = pixelCountSpread(m, rho), w = pixelCountSpread(white, rho);
    std::printf("[ figures  ] rho %.2f: per-pixel count - round(rho*64) in [%d, %d], rms %.2f "
                "(white control: [%d, %d], rms %.2f, %.2f%% within +-1)\n",
                rho, s.minDeviation, s.maxDeviation, s.rms, w.minDeviation, w.maxDeviation, w.rms,
                100.0 * w.withinOne);
    // The stratification makes it exact (Docs/blue-noise.md): every pixel within +-1.
    EXPECT_GE(s.minDeviation, -1) << "rho " << rho;
    EXPECT_LE(s.maxDeviation, 1) << "rho " << rho;
    EXPECT_EQ(s.withinOne, 1.0) << "rho " << rho;
    // The checks discriminate: white noise (binomial, rms sqrt(64 rho (1 - rho)) = 2.4 .. 4)
    // fails each of them.
    EXPECT_TRUE(w.minDeviation < -1 && w.maxDeviation > 1) << "rho " << rho;
    EXPECT_LT(w.withinOne, 0.9) << "rho " << rho;
  }
  // Every rho in (0, 1), not only the listed ones: floor(64 rho) or ceil(64 rho) frames.
  const std::size_t violations = floorCeilViolations(m), whiteViolations = floorCeilViolations(white);
  std::printf("[ figures  ] (pixel, threshold) pairs off floor/ceil(64 rho): %zu (white control %zu "
              "of %zu)\n", violations, whiteViolations, std::size_t(m.width) * m.height * 256);
  EXPECT_EQ(violations, 0u);
  EXPECT_GT(whiteViolations, 0u);
}

// Thresholds: the shipped mask measures about 0.003 (space, every slice) and 0.01 (time);
// white noise about 1. The bounds leave headroom for a regenerated mask yet fail a mask that is
// only mildly blue, and the control must fail them.
TEST(ShippedBlueNoiseMask, EachSliceIsBlueInSpace) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const std::vector<double> blue = spatialLowFrequencyRatios(m);
  const std::vector<double> white = spatialLowFrequencyRatios(whiteNoiseControl(m, 12345));
  ASSERT_EQ(blue.size(), std::size_t(m.depth));
  for (int z = 0; z < m.depth; ++z) {
    EXPECT_LT(blue[std::size_t(z)], 0.02) << "slice " << z;
    EXPECT_GT(white[std::size_t(z)], 0.02) << "white control, slice " << z;  // discriminates
  }
  auto mean = [](const std::vector<double>& v) {
    double sum = 0.0;
    for (double x : v) sum += x;
    return sum / double(v.size());
  };
  std::printf("[ figures  ] spatial low-band (|f| < Nyquist/8) power / mean power: mean %.4f, "
              "slices %.4f .. %.4f (white control: mean %.4f, slices %.4f .. %.4f)\n", mean(blue),
              *std::min_element(blue.begin(), blue.end()), *std::max_element(blue.begin(), blue.end()),
              mean(white), *std::min_element(white.begin(), white.end()),
              *std::max_element(white.begin(), white.end()));
}

TEST(ShippedBlueNoiseMask, EachPixelIsBlueInTime) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const double blue = temporalLowFrequencyRatio(m);
  const double white = temporalLowFrequencyRatio(whiteNoiseControl(m, 12345));
  std::printf("[ figures  ] temporal low-band (|f| < Nyquist/8) power / mean power: %.4f "
              "(white control %.4f)\n", blue, white);
  EXPECT_LT(blue, 0.05);
  EXPECT_GT(white, 0.05);  // discriminates
}

TEST(ShippedBlueNoiseMask, LookupWrapsInSpaceAndCyclesInTime) {
  const BlueNoiseMask& m = shippedBlueNoiseMask();
  const BlueNoiseMaskView view = m.view();
  EXPECT_EQ(blueNoiseValue(view, 5, 7, 3), at(m, 5, 7, 3) / 256.f);
  EXPECT_EQ(blueNoiseValue(view, 5 + 128, 7 + 256, 3 + 64), blueNoiseValue(view, 5, 7, 3));
  EXPECT_EQ(blueNoiseValue(view, 127, 127, 63), at(m, 127, 127, 63) / 256.f);
  for (std::uint8_t v : {std::uint8_t(0), std::uint8_t(255)}) {
    const float u = float(v) / 256.f;
    EXPECT_GE(u, 0.f);
    EXPECT_LT(u, 1.f);
  }
}

TEST(StbnGenerator, SmallMaskIsAnEvenlySpacedRankingWithBalancedPixels) {
  const BlueNoiseMask m = generateStbnMask(16, 16, 8, 2024);
  ASSERT_EQ(m.width, 16);
  ASSERT_EQ(m.height, 16);
  ASSERT_EQ(m.depth, 8);
  ASSERT_EQ(m.texels.size(), std::size_t(16 * 16 * 8));
  // N = 2048 texels on 256 levels: every level exactly 8 times.
  std::vector<int> count(256, 0);
  for (std::uint8_t v : m.texels) ++count[v];
  for (int v = 0; v < 256; ++v) EXPECT_EQ(count[std::size_t(v)], 8) << "level " << v;
  for (double rho : kCountRhos) {
    const PixelCountSpread s = pixelCountSpread(m, rho);
    std::printf("[ figures  ] 16x16x8, rho %.2f: per-pixel count - round(rho*8) in [%d, %d]\n", rho,
                s.minDeviation, s.maxDeviation);
    EXPECT_GE(s.minDeviation, -1) << "rho " << rho;
    EXPECT_LE(s.maxDeviation, 1) << "rho " << rho;
  }
  EXPECT_EQ(floorCeilViolations(m), 0u);
  EXPECT_GT(floorCeilViolations(whiteNoiseControl(m, 99)), 0u);  // discriminates
}

// D = 12 does not divide 256: the rank bins have 21 or 22 levels, and the floor/ceil property
// must still hold at every threshold.
TEST(StbnGenerator, DepthNotDividing256KeepsPixelsBalanced) {
  const BlueNoiseMask m = generateStbnMask(16, 16, 12, 5);
  ASSERT_EQ(m.texels.size(), std::size_t(16 * 16 * 12));
  EXPECT_EQ(floorCeilViolations(m), 0u);
  EXPECT_GT(floorCeilViolations(whiteNoiseControl(m, 99)), 0u);
  // Each level 256 / 21 or 256 / 22 times, rounded either way (one texel per pixel per bin).
  std::vector<int> count(256, 0);
  for (std::uint8_t v : m.texels) ++count[v];
  for (int v = 0; v < 256; ++v) {
    EXPECT_GE(count[std::size_t(v)], 256 / 22) << "level " << v;
    EXPECT_LE(count[std::size_t(v)], 256 / 21 + 1) << "level " << v;
  }
}

TEST(StbnGenerator, IsDeterministicForASeed) {
  const BlueNoiseMask a = generateStbnMask(16, 16, 8, 7), b = generateStbnMask(16, 16, 8, 7);
  EXPECT_EQ(a.texels, b.texels);
  const BlueNoiseMask c = generateStbnMask(16, 16, 8, 8);
  EXPECT_NE(a.texels, c.texels);
}

TEST(StbnGenerator, ReportsProgressAndRejectsBadArguments) {
  std::vector<std::string> phases;
  generateStbnMask(8, 8, 4, 1, 1.9, [&](const StbnProgress& p) {
    if (phases.empty() || phases.back() != p.phase) phases.push_back(p.phase);
    EXPECT_TRUE(p.total == 0 || p.done <= p.total);
  });
  EXPECT_EQ(phases, (std::vector<std::string>{"initial", "phase1", "phase2", "phase3"}));
  EXPECT_THROW(generateStbnMask(0, 8, 4, 1), std::invalid_argument);
  EXPECT_THROW(generateStbnMask(8, 8, 4, 1, 0.0), std::invalid_argument);
  EXPECT_THROW(generateStbnMask(1, 1, 257, 1), std::invalid_argument);  // more frames than levels
}

}  // namespace
}  // namespace inr
