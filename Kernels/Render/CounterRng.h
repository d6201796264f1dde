#pragma once
// Counter-based random numbers: every draw is a pure function of (pixel, frame, seed, draw
// index), so a ray's random sequence does not depend on which thread (or GPU lane) runs it, on
// the order rays are processed, or on how many traverse/evaluate iterations came before. That is
// what makes images identical for 1 and N threads and lets the CUDA backend reproduce the CPU
// image draw for draw. The per-ray state is just the draw counter.
#include <cstdint>

#include "Common/HostDevice.h"

namespace inr {

// SplitMix64 finaliser: a bijective 64-bit mixer with full avalanche.
INR_HD std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

INR_HD std::uint32_t counterHash(std::uint32_t pixel, std::uint32_t frame, std::uint32_t seed,
                                 std::uint32_t draw) {
  const std::uint64_t key = mix64(((std::uint64_t(seed) << 32) | frame) + 0x9e3779b97f4a7c15ULL);
  const std::uint64_t bits = mix64(key ^ ((std::uint64_t(pixel) << 32) | draw));
  return std::uint32_t(bits >> 32);
}

// Uniform in [0, 1): 24 random bits, so 1 - u is never 0 and -log(1 - u) is finite.
INR_HD float counterUniform(std::uint32_t pixel, std::uint32_t frame, std::uint32_t seed,
                            std::uint32_t draw) {
  return float(counterHash(pixel, frame, seed, draw) >> 8) * (1.0f / 16777216.0f);
}

// A ray's stream: the key is fixed for the frame, `counter` is the only mutable state and is
// stored back into the ray state between stages.
struct RngStream {
  std::uint32_t pixel, frame, seed, counter;
  INR_HD float next() { return counterUniform(pixel, frame, seed, counter++); }
};

// Which of the accumulation's two halves frame `frame` belongs to: the parity of its set bits
// (the Thue-Morse sequence). Frames 2j and 2j + 1 always fall in different halves, so one
// renderer's halves stay within one frame of each other, and so do the halves of a sample share
// that takes every 2^k-th frame (SampleShare). The halves are independent estimates of the pixel
// (the stratified jitter, RayInit.h, draws each from its own random start), which is what makes the
// convergence estimate honest under stratification (Finalize.h, pixelConvergence).
INR_HD std::uint32_t frameHalf(std::uint32_t frame) {
  frame ^= frame >> 16;
  frame ^= frame >> 8;
  frame ^= frame >> 4;
  frame ^= frame >> 2;
  frame ^= frame >> 1;
  return frame & 1u;
}

}  // namespace inr
