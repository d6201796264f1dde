#include "BlueNoiseMask.h"

#include <cstddef>
#include <stdexcept>

// The shipped mask's bytes, compiled in from Data/stbn_128x128x64.u8 (Data/README.md says how it
// was generated) by cmake/EmbedBytes.cmake.
namespace inr::detail {
extern const unsigned char kShippedStbnTexels[];
extern const std::size_t kShippedStbnTexelsSize;
}  // namespace inr::detail

namespace inr {

const BlueNoiseMask& shippedBlueNoiseMask() {
  // Built on first use (thread-safe static initialisation) and kept: every renderer shares it.
  static const BlueNoiseMask mask = [] {
    BlueNoiseMask m;
    m.width = 128;
    m.height = 128;
    m.depth = 64;
    const std::size_t count = std::size_t(m.width) * std::size_t(m.height) * std::size_t(m.depth);
    // A build that embedded some other file must not pass it off as this mask.
    if (detail::kShippedStbnTexelsSize != count)
      throw std::logic_error("shippedBlueNoiseMask: embedded data has the wrong size");
    m.texels.assign(detail::kShippedStbnTexels, detail::kShippedStbnTexels + count);
    return m;
  }();
  return mask;
}

}  // namespace inr
