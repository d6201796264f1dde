#pragma once
// What MacrocellGrid (CPU) and CudaMacrocellGrid (GPU) share above the per-cell arithmetic of
// MacrocellLayout.h: the options and layout, the time state (the working grid's time and the two
// slices and weight it interpolates), lazy slice builds and their statistics, and the accessors.
// Each grid supplies its storage: building a slice, interpolating the working grid from the
// current slices, clearing its dirty-cell list.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "Render/MacrocellLayout.h"

namespace inr {

struct MacrocellBuildStats {
  int slicesBuilt = 0;
  double seconds = 0.0;          // total time spent building slices
  std::size_t evaluations = 0;   // lattice queries issued
};

// Progress of a macrocell build (all the slices one setTime or buildAllSlices needs, which may
// take seconds on the CPU for a paper-size network): `fraction` of that build in [0, 1],
// non-decreasing, 0 before the first slice and 1 after the last; `phase` says what is built (e.g.
// "building macrocells: 2 of 16 time slices, 32x32x32 cells"). Called on the thread that called
// setTime, between lattice batches (the CPU grid) or per slice (the GPU grid, whose batches run
// asynchronously): a few calls per slice, not per cell. Not called when nothing is built.
using MacrocellProgress = std::function<void(double fraction, const std::string& phase)>;

class MacrocellGridBase {
public:
  using BuildStats = MacrocellBuildStats;
  virtual ~MacrocellGridBase() = default;

  // Makes the working grid for world time t, building the slices it needs first. Clears the
  // dirty-cell list (every majorant must be recomputed after a time change).
  void setTime(double t);
  void buildAllSlices();
  // Builds the slices the working grid for time t needs (those setTime(t) would build), with
  // progress, and changes nothing else: lets a caller do the slow part of a time change first.
  void buildSlicesFor(double t);
  double time() const { return time_; }
  // Whether the working grid was interpolated (setTime called): it is the grid at time() then.
  bool hasWorkingGrid() const { return workingGridSet_; }
  virtual bool sliceBuilt(int k) const = 0;

  const MacrocellOptions& options() const { return options_; }
  const MacrocellLayout& layout() const { return layout_; }
  Int3 dims() const { return layout_.dims; }
  int cellCount() const { return layout_.cellCount; }
  const Box3f& box() const { return layout_.box; }
  Vec3f cellSize() const { return layout_.cellSize; }
  int temporalSlices() const { return layout_.temporalSlices; }
  double sliceTime(int k) const { return layout_.sliceTime(k); }
  // The two slices and weight the working grid interpolates: (1 - w) * slice k0 + w * slice k1.
  void interpolationWeights(double t, int& k0, int& k1, float& w) const {
    layout_.interpolationWeights(t, k0, k1, w);
  }
  // Coarse level: log2 of the block edge in cells (-1: off), blocks per axis, block count (0: off).
  int blockShift() const { return layout_.blockShift; }
  Int3 blockDims() const { return layout_.blockDims; }
  int blockCount() const { return layout_.blockCount(); }
  const BuildStats& buildStats() const { return stats_; }
  // Where slice builds report progress; empty (the default) = nowhere.
  void setProgressHandler(MacrocellProgress handler) { progress_ = std::move(handler); }

protected:
  // Validates (std::invalid_argument, MacrocellLayout::make). Derived constructors build every
  // slice when !options.lazySlices, once their storage exists.
  MacrocellGridBase(const Box3f& box, double timeBegin, double timeEnd, const MacrocellOptions& options);

  // Builds slice k by lattice sampling and marks it built, counting its queries in
  // stats_.evaluations (buildSlices counts the slice and its time).
  virtual void buildSlice(int k) = 0;
  // Working grid from slices k0_ and k1_ with weight w_ (k0_ alone when w_ == 0).
  virtual void interpolateWorkingGrid() = 0;
  virtual void clearDirtyCells() = 0;
  // Builds the slices of `needed` that are not built yet, reporting progress over all of them.
  void buildSlices(const std::vector<int>& needed);
  // buildSlice implementations call this between batches: `sliceFraction` of the slice being
  // built is done. Maps it onto the whole build and reports it when it moved forward.
  void reportSliceProgress(double sliceFraction);

  MacrocellOptions options_;
  MacrocellLayout layout_;
  double time_ = 0.0;
  bool workingGridSet_ = false;
  int k0_ = 0, k1_ = 0;
  float w_ = 0.f;
  BuildStats stats_;

private:
  void reportProgress(double fraction);
  MacrocellProgress progress_;
  std::string phase_;        // of the build in progress
  int buildSlot_ = 0;        // slices of that build done so far
  int buildCount_ = 0;       // slices that build makes
  double lastReported_ = -1.0;
};

}  // namespace inr
