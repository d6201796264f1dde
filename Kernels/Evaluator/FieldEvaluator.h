#pragma once
// The one interface between the renderer and whatever computes the scalar field: a dense batch
// of world-space (x, y, z, t) points in, one scalar per point out. INR evaluators (CPU/Eigen,
// CUDA) implement it; tests implement it with analytic fields.
#include <cstddef>
#include <stdexcept>
#include <string>

namespace inr {

struct QueryPoint {
  float x, y, z, t;  // world space, world time
};

class FieldEvaluator {
public:
  virtual ~FieldEvaluator() = default;
  // out[i] = field(points[i]); must be safe to call from one thread at a time with any n >= 0.
  virtual void evaluate(const QueryPoint* points, std::size_t n, float* out) const = 0;
  virtual std::string name() const = 0;
  // Values and gradients with respect to x, y, z (gradients[3 i + k] = d out[i] / d axis k), for
  // gradient shading. Evaluators without it say so here (shading then refuses to start).
  virtual bool providesGradient() const { return false; }
  virtual void evaluateWithGradient(const QueryPoint* /*points*/, std::size_t /*n*/, float* /*values*/,
                                    float* /*gradients*/) const {
    throw std::logic_error("the evaluator " + name() + " computes no gradients (needed for shading)");
  }
};

}  // namespace inr
