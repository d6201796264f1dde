#pragma once
// Spatiotemporal blue-noise mask generator: void-and-cluster over the whole W x H x D volume with
// the "2D x 1D" energy (a Gaussian within each time slice plus a Gaussian along time at each
// pixel, all axes wrapping). Docs/blue-noise.md describes the algorithm and how the shipped mask
// was made. Offline tool code: the renderer only reads the shipped result (Render/BlueNoiseMask.h).
#include <cstddef>
#include <cstdint>
#include <functional>

#include "Render/BlueNoiseMask.h"

namespace inr {

// Where the generator is: phase is "initial" (swapping clusters into voids: total is unknown, 0,
// until the last report, where done == total), "phase1", "phase2" or "phase3"; done out of total
// steps of that phase.
struct StbnProgress {
  const char* phase = "";
  std::size_t done = 0, total = 0;
};
using StbnProgressCallback = std::function<void(const StbnProgress&)>;

// Deterministic for (width, height, depth, seed, sigma): the random initial pattern comes from
// std::mt19937 (its output sequence is fixed by the standard) through our own bounded draw, and
// every argmax / argmin tie goes to the lowest texel index. Texel (x, y, z) at
// texels[(z * height + y) * width + x]. One global ranking of all N = W * H * D texels, then per
// pixel its D texels get levels by their order in time: the r-th lowest of a pixel's texels gets a
// level in [ceil(256 r / D), ceil(256 (r + 1) / D)), so thresholding at any rho in (0, 1) turns
// every pixel on floor(rho D) or ceil(rho D) frames of the cycle (Docs/blue-noise.md).
// Throws std::invalid_argument for non-positive sizes or sigma, or depth > 256.
BlueNoiseMask generateStbnMask(int width, int height, int depth, std::uint32_t seed,
                               double sigma = 1.9, const StbnProgressCallback& progress = {});

}  // namespace inr
