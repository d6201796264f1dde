#pragma once
// Macrocells (paper §4.1.1): per-cell scalar min/max/mean of the field over N³ cells and T
// temporal slices, estimated by lattice sampling through the FieldEvaluator; the working grid for
// the current time (linear interpolation of the two nearest slices); majorants from a transfer
// function; progressive refinement of under-estimated bounds. Host object; the traversal sees it
// through MajorantGridView. Geometry, validation and the per-point / per-cell arithmetic are
// MacrocellLayout's (Render/MacrocellLayout.h), shared with the GPU grid.
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/MacrocellLayout.h"
#include "Render/MajorantGrid.h"
#include "Render/TransferFunctionTable.h"

namespace inr {

// Host storage of one majorant grid (what MacrocellGrid::view shows the traversal): per-cell
// majorants and their coarse level, kept consistent by computeMajorants / updateMajorants.
struct MajorantArrays {
  std::vector<float> cell;   // one per macrocell
  std::vector<float> block;  // one per skip block; empty when skipping is off
};

// The coarse level of `majorants` (dims cells) for blocks of 2^shift cells, written to `blocks`
// (blockGridDims(dims, shift) entries). Reference for the GPU's kernel and the tests.
void computeBlockMajorants(const Int3& dims, int shift, const float* majorants, float* blocks);

// Called during slice builds: slice index and the fraction of that slice done, in [0, 1].
using MacrocellProgress = std::function<void(int slice, double fraction)>;

class MacrocellGrid {
public:
  static constexpr int kTileCells = MacrocellLayout::kTileCells;      // cells per tile edge
  static constexpr int kTileLattice = MacrocellLayout::kTileLattice;  // 9 lattice points per tile edge

  struct Slice {
    std::vector<float> min, max, mean;
    bool built = false;
  };
  struct BuildStats {
    int slicesBuilt = 0;
    double seconds = 0.0;          // total time spent building slices
    std::size_t evaluations = 0;   // lattice queries issued
  };

  MacrocellGrid(const FieldEvaluator& evaluator, const Box3f& box, double timeBegin,
                double timeEnd, MacrocellOptions options = {});

  void setProgressCallback(MacrocellProgress cb) { progress_ = std::move(cb); }

  // Makes the working grid for world time t, building the slices it needs first. Clears the
  // dirty-cell list (every majorant must be recomputed after a time change).
  void setTime(double t);
  void buildAllSlices();
  double time() const { return time_; }

  const MacrocellOptions& options() const { return options_; }
  Int3 dims() const { return options_.dims; }
  int cellCount() const { return layout_.cellCount; }
  const Box3f& box() const { return layout_.box; }
  Vec3f cellSize() const { return layout_.cellSize; }
  int temporalSlices() const { return int(slices_.size()); }
  double sliceTime(int k) const { return layout_.sliceTime(k); }
  const MacrocellLayout& layout() const { return layout_; }
  const Slice& slice(int k) const { return slices_.at(k); }
  // Replaces a slice's bounds with known values (tests, GPU-built slices).
  void setSlice(int k, std::vector<float> min, std::vector<float> max, std::vector<float> mean);
  const BuildStats& buildStats() const { return stats_; }
  // The two slices and weight the working grid interpolates: (1 - w) * slice k0 + w * slice k1.
  void interpolationWeights(double t, int& k0, int& k1, float& w) const {
    layout_.interpolationWeights(t, k0, k1, w);
  }

  const std::vector<float>& workingMin() const { return workMin_; }
  const std::vector<float>& workingMax() const { return workMax_; }
  const std::vector<float>& workingMean() const { return workMean_; }
  // [min, max] over all working cells (finite values only); {0, 1} if none.
  std::array<float, 2> workingValueRange() const;

  // majorant[c] = max extinction of the TF over cell c's [min, max].
  void computeMajorants(const TransferFunctionView& tf, std::vector<float>& majorants) const;
  void updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                       std::vector<float>& majorants) const;
  MajorantGridView view(const std::vector<float>& majorants) const;  // no coarse level
  // The same with the coarse level for empty-space skipping (options().skipBlockCells): every
  // block that holds a recomputed cell is recomputed too, so the level stays conservative.
  void computeMajorants(const TransferFunctionView& tf, MajorantArrays& majorants) const;
  void updateMajorants(const TransferFunctionView& tf, const std::vector<int>& cells,
                       MajorantArrays& majorants) const;
  MajorantGridView view(const MajorantArrays& majorants) const;
  // Coarse level: log2 of the block edge in cells (-1: off), blocks per axis, block count.
  int blockShift() const { return layout_.blockShift; }
  Int3 blockDims() const { return layout_.blockDims; }
  int blockCount() const { return layout_.blockCount(); }

  // Progressive refinement: an evaluated sample `value` fell in `cell`. If it lies outside the
  // cell's working bounds, widen them (and the contributing slices, so the fix survives time
  // changes) and mark the cell dirty. Not thread-safe: callers run it serially (deterministic).
  bool refine(int cell, float value);
  std::vector<int> takeDirtyCells();
  std::size_t refinementCount() const { return refinements_; }

private:
  void ensureSlice(int k);
  void buildSlice(int k);
  void interpolateWorkingGrid();

  const FieldEvaluator& evaluator_;
  MacrocellOptions options_;
  MacrocellLayout layout_;
  std::vector<Slice> slices_;
  std::vector<float> workMin_, workMax_, workMean_;
  double time_ = 0.0;
  int k0_ = 0, k1_ = 0;
  float w_ = 0.f;
  std::vector<std::uint8_t> dirtyMask_;
  std::vector<int> dirty_;
  std::size_t refinements_ = 0;
  BuildStats stats_;
  MacrocellProgress progress_;
};

}  // namespace inr
