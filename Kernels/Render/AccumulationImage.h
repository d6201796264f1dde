#pragma once
// Host-side conversion of an accumulation buffer (premultiplied RGB, alpha = coverage) into an
// image, shared by every renderer (CPU delta tracking, ray marching, the CUDA backend after its
// download): either as is, or composited over the background colour.
#include <array>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/Finalize.h"

namespace inr {

// `background` null: premultiplied volume only; otherwise composited over it (alpha kept).
inline ImageRGBA accumulationImage(const std::vector<Vec4f>& accum, int width, int height,
                                   const std::array<float, 3>* background) {
  ImageRGBA img(width, height);
  const Vec3f bg = background ? Vec3f{(*background)[0], (*background)[1], (*background)[2]} : Vec3f{0.f, 0.f, 0.f};
  for (std::size_t i = 0; i < accum.size() && i < std::size_t(width) * height; ++i) {
    const Vec3f c = background ? overBackground(accum[i], bg) : Vec3f{accum[i].x, accum[i].y, accum[i].z};
    img.data[4 * i + 0] = c.x;
    img.data[4 * i + 1] = c.y;
    img.data[4 * i + 2] = c.z;
    img.data[4 * i + 3] = accum[i].w;
  }
  return img;
}

}  // namespace inr
