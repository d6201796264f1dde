// `inr-stbn`: generates a spatiotemporal blue-noise mask (Docs/blue-noise.md) and writes its raw
// 8-bit texels, texel (x, y, z) at byte (z * H + y) * W + x.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

#include "StbnGenerator.h"

namespace {

const char* kUsage =
    "usage: inr-stbn --out FILE [--size W H D] [--seed S] [--sigma X] [--quiet]\n"
    "  --size W H D   mask size in texels (default 128 128 64; D = frames of the cycle,\n"
    "                 at most 256)\n"
    "  --seed S       seed of the random initial pattern (default 1)\n"
    "  --sigma X      Gaussian sigma of the energy, every axis (default 1.9)\n"
    "  --out FILE     raw 8-bit output, W*H*D bytes\n"
    "  --quiet        no progress lines\n";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

long parseInt(const char* s, const char* what) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end) throw UsageError(std::string(what) + ": not an integer: " + s);
  return v;
}

double parseDouble(const char* s, const char* what) {
  char* end = nullptr;
  const double v = std::strtod(s, &end);
  if (end == s || *end) throw UsageError(std::string(what) + ": not a number: " + s);
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  int w = 128, h = 128, d = 64;
  long seed = 1;
  double sigma = 1.9;
  std::string out;
  bool quiet = false;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto need = [&](int count) {
        if (i + count >= argc) throw UsageError(a + " needs " + std::to_string(count) + " value(s)");
      };
      if (a == "--help" || a == "-h") {
        std::fputs(kUsage, stdout);
        return 0;
      } else if (a == "--size") {
        need(3);
        w = int(parseInt(argv[++i], "--size"));
        h = int(parseInt(argv[++i], "--size"));
        d = int(parseInt(argv[++i], "--size"));
        if (w <= 0 || h <= 0 || d <= 0 || w > 4096 || h > 4096 || d > 256)
          throw UsageError("--size: W and H must be in [1, 4096], D in [1, 256]");
      } else if (a == "--seed") {
        need(1);
        seed = parseInt(argv[++i], "--seed");
        if (seed < 0 || seed > 0xffffffffL) throw UsageError("--seed: must be in [0, 4294967295]");
      } else if (a == "--sigma") {
        need(1);
        sigma = parseDouble(argv[++i], "--sigma");
        if (!(sigma > 0.0 && sigma < 100.0)) throw UsageError("--sigma: must be in (0, 100)");
      } else if (a == "--out" || a == "-o") {
        need(1);
        out = argv[++i];
      } else if (a == "--quiet") {
        quiet = true;
      } else {
        throw UsageError("unknown option '" + a + "'");
      }
    }
    if (out.empty()) throw UsageError("--out FILE is required");
  } catch (const UsageError& e) {
    std::fprintf(stderr, "inr-stbn: %s\n%s", e.what(), kUsage);
    return 2;
  }

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  std::printf("inr-stbn: %dx%dx%d, seed %ld, sigma %g\n", w, h, d, seed, sigma);
  std::fflush(stdout);
  // One line per tenth of each phase (and per 100k swaps of the initial one): readable in a log.
  std::string lastPhase;
  std::size_t lastStep = 0;
  auto progress = [&](const inr::StbnProgress& p) {
    if (quiet) return;
    const std::size_t step = p.total == 0 ? p.done / 100000 : 10 * p.done / p.total;
    if (p.phase == lastPhase && step == lastStep) return;
    lastPhase = p.phase;
    lastStep = step;
    if (p.total == 0) {
      std::printf("  %-7s %9zu swaps  %7.1f s\n", p.phase, p.done, seconds());
    } else {
      std::printf("  %-7s %3d%%  %9zu / %zu  %7.1f s\n", p.phase, int(10 * step), p.done, p.total,
                  seconds());
    }
    std::fflush(stdout);
  };

  try {
    const inr::BlueNoiseMask mask = inr::generateStbnMask(w, h, d, std::uint32_t(seed), sigma, progress);
    std::FILE* f = std::fopen(out.c_str(), "wb");
    if (!f) {
      std::fprintf(stderr, "inr-stbn: cannot open '%s' for writing\n", out.c_str());
      return 1;
    }
    const std::size_t written = std::fwrite(mask.texels.data(), 1, mask.texels.size(), f);
    if (std::fclose(f) != 0 || written != mask.texels.size()) {
      std::fprintf(stderr, "inr-stbn: writing '%s' failed\n", out.c_str());
      return 1;
    }
    std::printf("inr-stbn: wrote %zu bytes to %s in %.1f s\n", written, out.c_str(), seconds());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "inr-stbn: %s\n", e.what());
    return 1;
  }
  return 0;
}
