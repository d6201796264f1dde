#pragma once
// OpenMP policy of the CPU backend.
namespace inr {

// Loops over fewer items than this run on the calling thread: a frame of a small image is a few
// dozen parallel regions of microseconds each, where waking (or, on a loaded machine, waiting
// for) worker threads costs far more than the work (on a busy machine, small test scenes ran many
// times slower with every loop parallel).
constexpr int kParallelMinItems = 8192;
// Skip blocks (each a maximum over up to 64 cells) per parallel region worth splitting.
constexpr int kParallelMinBlocks = 16;

}  // namespace inr
