#pragma once
// OpenMP policy of the CPU backend.
namespace inr {

// Loops over fewer items than this run on the calling thread: a frame of a small image is a few
// dozen parallel regions of microseconds each, where waking (or, on a loaded machine, waiting
// for) worker threads costs far more than the work (on a busy machine, small test scenes ran many
// times slower with every loop parallel).
constexpr int kParallelMinItems = 8192;
// Lattice tiles (729 queries each) per parallel region worth splitting.
constexpr int kParallelMinTiles = 16;

}  // namespace inr
