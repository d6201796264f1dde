#pragma once
// Macrocells (paper §4.1.1): per-cell scalar min/max/mean of the field over N³ cells and T
// temporal slices, estimated by lattice sampling through the FieldEvaluator; the working grid for
// the current time (linear interpolation of the two nearest slices); majorants from a transfer
// function; progressive refinement of under-estimated bounds. Host object; the traversal sees it
// through MajorantGridView. Geometry, validation, the per-point / per-cell arithmetic
// (Render/MacrocellLayout.h), the time state, lazy slice builds and the accessors
// (MacrocellGridBase) are shared with the GPU grid.
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/MacrocellGridBase.h"
#include "Render/MacrocellLayout.h"
#include "Render/MajorantGrid.h"
#include "Render/Pruning.h"
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

class MacrocellGrid final : public MacrocellGridBase {
public:
  struct Slice {
    std::vector<float> min, max, mean;
    bool built = false;
  };
  MacrocellGrid(const FieldEvaluator& evaluator, const Box3f& box, double timeBegin,
                double timeEnd, MacrocellOptions options = {});

  // setTime, buildAllSlices, setProgressHandler, time and the layout accessors: MacrocellGridBase.
  const Slice& slice(int k) const { return slices_.at(k); }
  bool sliceBuilt(int k) const override { return slices_.at(k).built; }
  // Replaces a slice's bounds with known values (tests, GPU-built slices).
  void setSlice(int k, std::vector<float> min, std::vector<float> max, std::vector<float> mean);

  const std::vector<float>& workingMin() const { return workMin_; }
  const std::vector<float>& workingMax() const { return workMax_; }
  const std::vector<float>& workingMean() const { return workMean_; }
  // [min, max] over all working cells (finite values only); {0, 1} if none.
  std::array<float, 2> workingValueRange() const;
  // Homogeneity pruning's expected scalar per working cell (paper Eq. ev_ema): the working
  // grid's mean after every (re)interpolation, then refined by the renderer's EMA.
  const std::vector<float>& expected() const { return expected_; }
  // `thresholds` (absolute epsilon and falloff) with this grid's working bounds and expected
  // scalars filled in: what TrackingMedium::prune holds for a pruned frame.
  PruneView pruneView(PruneView thresholds);

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

  // Progressive refinement: an evaluated sample `value` fell in `cell`. If it lies outside the
  // cell's working bounds, widen them (and the contributing slices, so the fix survives time
  // changes) and mark the cell dirty. Not thread-safe: callers run it serially (deterministic).
  bool refine(int cell, float value);
  // Whether refine(cell, value) would widen the cell's bounds now (a finite value in the grid's
  // cells, outside them).
  bool wouldRefine(int cell, float value) const;
  std::vector<int> takeDirtyCells();
  std::size_t refinementCount() const { return refinements_; }

private:
  void buildSlice(int k) override;
  void interpolateWorkingGrid() override;
  void clearDirtyCells() override;

  const FieldEvaluator& evaluator_;
  std::vector<Slice> slices_;
  std::vector<float> workMin_, workMax_, workMean_;
  std::vector<float> expected_;
  std::vector<std::uint8_t> dirtyMask_;
  std::vector<int> dirty_;
  std::size_t refinements_ = 0;
};

}  // namespace inr
