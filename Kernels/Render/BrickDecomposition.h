#pragma once
// Sub-domain rendering (scale-out across processes or MPI ranks): the model's box split into N
// bricks, one per rank. Each rank clips its primary rays to its brick (RenderSettings::brick) and
// outputs premultiplied RGBA (alpha = 1 - transmittance through the brick); shadow rays still
// cross the whole box, since every rank holds the whole network. Compositing the ranks' images
// front to back with the over operator, in the bricks' visibility order from the camera, gives
// the single-rank image (ParaView's ordered compositing does it from each rank's bounds;
// Benchmarks/composite_bricks.py does it for `inr render --brick`).
//
// The split is a k-d split: the box is halved recursively along the axis with the largest world
// extent, into ceil(n/2) and floor(n/2) bricks with volumes in that ratio, every cut on a
// macrocell boundary (so a brick's cells are whole cells of the grid, and a ray's DDA over a
// brick walks exactly the cells of the whole-box DDA). Bricks tile the box without gaps or
// overlaps: a cut plane is computed once and shared, bit for bit, by the bricks on either side.
#include <cstdint>
#include <string>
#include <vector>

#include "Render/RenderMath.h"

namespace inr {

struct Brick {
  Box3f box;           // model space
  Int3 cellLo, cellHi;  // the macrocells it covers: [cellLo, cellHi) per axis
};

// Splits `box` (with a `cells` macrocell grid) into `count` bricks, in brick order (brick i is
// what rank i renders). Throws std::invalid_argument when count < 1 or the grid has fewer cells
// than bricks along the axes a split would need.
std::vector<Brick> brickDecomposition(const Box3f& box, Int3 cells, int count);

// "i/N" (0 <= i < N, N >= 1) as {i, N}; throws std::invalid_argument naming the text otherwise.
struct BrickIndex {
  int index = 0, count = 1;
};
BrickIndex parseBrickIndex(const std::string& text);

// The front-to-back order of `bricks` (a brickDecomposition) seen from `eye` (model space), for
// a perspective camera; for a parallel projection pass the eye far back along the view
// direction. A k-d split is a BSP tree: at every cut the side holding the eye comes first, and
// that order is correct for every ray from the eye.
std::vector<int> brickVisibilityOrder(const std::vector<Brick>& bricks, Vec3f eye);

// The random seed of brick `index` from the user's seed: different per brick, so the ranks'
// noise is independent, and equal to `seed` for brick 0 (one brick renders what the whole box
// renders with the same seed).
std::uint32_t brickSeed(std::uint32_t seed, int index);

}  // namespace inr
