#include "Render/MacrocellGridBase.h"

#include <chrono>

namespace inr {

MacrocellGridBase::MacrocellGridBase(const Box3f& box, double timeBegin, double timeEnd,
                                     const MacrocellOptions& options)
    : options_(options), layout_(MacrocellLayout::make(box, timeBegin, timeEnd, options)), time_(timeBegin) {}

void MacrocellGridBase::setTime(double t) {
  time_ = t;
  layout_.interpolationWeights(t, k0_, k1_, w_);
  ensureSlice(k0_);
  if (w_ > 0.f) ensureSlice(k1_);
  interpolateWorkingGrid();
  clearDirtyCells();
}

void MacrocellGridBase::buildAllSlices() {
  for (int k = 0; k < layout_.temporalSlices; ++k) ensureSlice(k);
}

void MacrocellGridBase::ensureSlice(int k) {
  if (sliceBuilt(k)) return;
  const auto start = std::chrono::steady_clock::now();
  buildSlice(k);
  stats_.slicesBuilt += 1;
  stats_.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace inr
