#pragma once
// A scalar field sampled on a regular grid of cells over a box, evaluated by trilinear
// interpolation between cell centres (clamped to the outermost centres; NaN where a contributing
// sample is NaN, so empty space stays empty). The time of a query is ignored: the grid is the
// field at one time. A cheap stand-in for the network where an approximate image will do: the
// plugin draws camera drags on the CPU backend from the fine macrocells' per-cell means
// (RenderSession::workingMeanField), which cost no query.
#include <string>
#include <vector>

#include "Evaluator/FieldEvaluator.h"
#include "Render/RenderMath.h"

namespace inr {

class GridField final : public FieldEvaluator {
public:
  // `values`: dims.x * dims.y * dims.z cell values, x fastest. Throws std::invalid_argument when
  // a dimension is below 1, the count does not match or the box is empty. `source` says where
  // the values came from (name()).
  GridField(const Box3f& box, Int3 dims, std::vector<float> values, std::string source);

  void evaluate(const QueryPoint* points, std::size_t n, float* out) const override;
  std::string name() const override;
  // The interpolant's own gradient (piecewise: 0 along an axis clamped at the border), so that a
  // shaded image of the stand-in costs no network query either.
  bool providesGradient() const override { return true; }
  void evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values, float* gradients) const override;

  const Box3f& box() const { return box_; }
  Int3 dims() const { return dims_; }
  const std::vector<float>& values() const { return values_; }
  // The value at world point (x, y, z), and its gradient (d/dx, d/dy, d/dz) when `gradient`.
  float at(float x, float y, float z, float* gradient = nullptr) const;

private:
  Box3f box_;
  Int3 dims_;
  std::vector<float> values_;
  std::string source_;
};

}  // namespace inr
