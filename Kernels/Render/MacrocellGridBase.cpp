#include "Render/MacrocellGridBase.h"

#include <algorithm>
#include <chrono>

namespace inr {

MacrocellGridBase::MacrocellGridBase(const Box3f& box, double timeBegin, double timeEnd,
                                     const MacrocellOptions& options)
    : options_(options), layout_(MacrocellLayout::make(box, timeBegin, timeEnd, options)), time_(timeBegin) {}

void MacrocellGridBase::setTime(double t) {
  // The slices first: if one cannot be built (a GPU out of memory), the grid stays at its old
  // time, so that the renderer, whose scene keeps the old time too, asks for this one again.
  int k0 = 0, k1 = 0;
  float w = 0.f;
  layout_.interpolationWeights(t, k0, k1, w);
  buildSlices(w > 0.f ? std::vector<int>{k0, k1} : std::vector<int>{k0});
  time_ = t;
  k0_ = k0;
  k1_ = k1;
  w_ = w;
  interpolateWorkingGrid();
  clearDirtyCells();
  workingGridSet_ = true;
}

void MacrocellGridBase::buildSlicesFor(double t) {
  int k0 = 0, k1 = 0;
  float w = 0.f;
  layout_.interpolationWeights(t, k0, k1, w);
  buildSlices(w > 0.f ? std::vector<int>{k0, k1} : std::vector<int>{k0});
}

void MacrocellGridBase::buildAllSlices() {
  std::vector<int> all(std::size_t(layout_.temporalSlices));
  for (int k = 0; k < layout_.temporalSlices; ++k) all[std::size_t(k)] = k;
  buildSlices(all);
}

void MacrocellGridBase::buildSlices(const std::vector<int>& needed) {
  std::vector<int> missing;
  for (int k : needed) {
    if (!sliceBuilt(k) && std::find(missing.begin(), missing.end(), k) == missing.end()) missing.push_back(k);
  }
  if (missing.empty()) return;
  buildCount_ = int(missing.size());
  buildSlot_ = 0;
  lastReported_ = -1.0;
  if (progress_) {
    const Int3 d = layout_.dims;
    phase_ = "building macrocells: " + std::to_string(missing.size()) + " of " +
             std::to_string(layout_.temporalSlices) + " time slice" + (layout_.temporalSlices == 1 ? "" : "s") +
             ", " + std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z) + " cells";
    reportProgress(0.0);
  }
  for (int k : missing) {
    const auto start = std::chrono::steady_clock::now();
    buildSlice(k);
    stats_.slicesBuilt += 1;
    stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ++buildSlot_;
    if (progress_) reportProgress(double(buildSlot_) / double(buildCount_));
  }
  buildCount_ = 0;
}

void MacrocellGridBase::reportSliceProgress(double sliceFraction) {
  if (!progress_ || buildCount_ == 0) return;
  const double f = std::min(std::max(sliceFraction, 0.0), 1.0);
  reportProgress((double(buildSlot_) + f) / double(buildCount_));
}

void MacrocellGridBase::reportProgress(double fraction) {
  // Only forward: a batch's end and the slice's end are the same point, reported once.
  if (fraction <= lastReported_) return;
  lastReported_ = fraction;
  progress_(fraction, phase_);
}

}  // namespace inr
