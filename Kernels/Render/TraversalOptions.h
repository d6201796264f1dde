#pragma once
// Which traversal walks rays through the macrocells on the GPU (the CPU backend always runs the
// DDA): the 3D DDA over the majorant grid, or an OptiX GAS over the non-empty macrocells.
#include <cmath>
#include <stdexcept>
#include <string>

namespace inr {

enum class TraversalKind {
  Auto,   // OptiX when it initialises and the GPU has RT cores, else the DDA (the reason is reported)
  Dda,    // the DDA over the majorant grid (always available)
  Optix,  // the OptiX GAS; an error when this build or the driver has no OptiX
};

struct TraversalOptions {
  TraversalKind kind = TraversalKind::Auto;
  // OptiX: macrocells whose majorant is at most this (extinction per unit length) are left out
  // of the GAS, i.e. treated as empty. 0 (default) keeps every cell that can produce a collision,
  // so the image is the DDA's; a small positive value drops nearly transparent cells (fewer
  // primitives, faster traces) at the price of ignoring their absorption (biased).
  float gasMinMajorant = 0.f;
  // OptiX: the GAS holds the selected cells' boxes only, so it is rebuilt only when the set of
  // selected cells changes (refinements, which widen majorants, rarely change it). true rebuilds
  // on every majorant update (time step, TF edit, refinement): for measuring build times.
  bool rebuildEveryUpdate = false;

  // Throws std::invalid_argument naming the option when gasMinMajorant is negative or not finite.
  void validate() const {
    if (!(std::isfinite(gasMinMajorant) && gasMinMajorant >= 0.f))
      throw std::invalid_argument("traversal: gasMinMajorant must be finite and >= 0, got " +
                                  std::to_string(gasMinMajorant));
  }
};

// "auto", "dda", "optix" (case-sensitive); throws std::invalid_argument naming the choices.
inline TraversalKind parseTraversalKind(const std::string& name) {
  if (name == "auto") return TraversalKind::Auto;
  if (name == "dda") return TraversalKind::Dda;
  if (name == "optix") return TraversalKind::Optix;
  throw std::invalid_argument("traversal: unknown '" + name + "' (choose auto, dda or optix)");
}

inline const char* traversalKindName(TraversalKind kind) {
  switch (kind) {
    case TraversalKind::Dda: return "dda";
    case TraversalKind::Optix: return "optix";
    default: return "auto";
  }
}

}  // namespace inr
