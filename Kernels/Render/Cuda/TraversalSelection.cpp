// Which DeviceTraversal a renderer runs (TraversalOptions::kind) and why.
#include <stdexcept>
#include <string>

#include "Render/Cuda/DeviceTraversal.h"

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
  // Auto: OptiX only where it traverses on RT cores. Without them (H100, H200) OptiX traverses
  // in software, 6.5-8x slower than the DDA (Benchmarks/RESULTS.md, "OptiX traversal"), so the
  // DDA runs there. The OptiX path renders the DDA's images and passes the stress scenes
  // (`ctest -L optix` on the H100/H200); its speed on RT cores is the paper's, not measured here.
  try {
    bool rtCores = false;
    auto t = makeOptixTraversal(options, &rtCores);
    if (rtCores) {
      reason = "optix (auto: OptiX initialised and the GPU has RT cores)";
      return t;
    }
    reason = "dda (auto: the GPU has no RT cores, OptiX would traverse in software)";
  } catch (const std::exception& e) {
    reason = std::string("dda (auto: OptiX unavailable: ") + e.what() + ")";
  }
  return makeDdaTraversal();
}

}  // namespace inr
