#pragma once
// OpenMP policy of the CPU backend.
namespace inr {

// Loops over fewer items than this run on the calling thread: a frame of a small image is a few
// dozen parallel regions of microseconds each, where waking (or, on a loaded machine, waiting
// for) worker threads costs far more than the work. Measured: a 32x32 test scene went from 30 s
// to 1 s for 1000 frames with other processes busy on a 2-core machine.
constexpr int kParallelMinItems = 8192;
// Lattice tiles (729 queries each) per parallel region worth splitting.
constexpr int kParallelMinTiles = 16;

}  // namespace inr
