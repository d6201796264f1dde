// Which DeviceTraversal a renderer runs (TraversalOptions::kind) and why.
#include <stdexcept>
#include <string>

#include "Cuda/Pipeline/DeviceTraversal.h"

namespace inr {

#ifndef INR_HAVE_OPTIX
std::unique_ptr<DeviceTraversal> makeOptixTraversal(const TraversalOptions&, bool*) {
  throw std::runtime_error(
      "this build has no OptiX traversal (configure with OptiX_INSTALL_DIR pointing at the OptiX 9.0 headers)");
}
#endif

std::unique_ptr<DeviceTraversal> makeDeviceTraversal(const TraversalOptions& options, std::string& reason) {
  options.validate();
  if (options.kind == TraversalKind::Dda) {
    reason = "dda (requested)";
    return makeDdaTraversal();
  }
  if (options.kind == TraversalKind::Optix) {
    bool rtCores = false;
    auto t = makeOptixTraversal(options, &rtCores);  // throws, saying why, when OptiX cannot run
    reason = std::string("optix (requested; ") + (rtCores ? "RT cores)" : "no RT cores: software traversal)");
    return t;
  }
  // Auto: OptiX only where it traverses on RT cores (without them, on the H100 and H200, OptiX
  // traverses in software), and only once the OptiX traversal has rendered the DDA's images on a
  // GPU: on the H100 it produced no candidate collisions (Benchmarks/RESULTS.md, "OptiX
  // traversal"), so until a run of `ctest -L optix` passes, auto keeps the DDA everywhere.
  constexpr bool kOptixValidated = false;
  try {
    bool rtCores = false;
    auto t = makeOptixTraversal(options, &rtCores);
    if (rtCores && kOptixValidated) {
      reason = "optix (auto: OptiX initialised and the GPU has RT cores)";
      return t;
    }
    reason = rtCores ? "dda (auto: the OptiX traversal is not validated yet; --traversal optix to try it)"
                     : "dda (auto: the GPU has no RT cores, OptiX would traverse in software)";
  } catch (const std::exception& e) {
    reason = std::string("dda (auto: OptiX unavailable: ") + e.what() + ")";
  }
  return makeDdaTraversal();
}

}  // namespace inr
