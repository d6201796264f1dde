#pragma once
// Image files for the CLI, tests and benchmarks: PNG (8-bit, through libpng) for people, PFM
// (linear float RGB, Portable Float Map) for accurate comparisons. Errors throw
// std::runtime_error naming the file.
#include <cstdint>
#include <string>
#include <vector>

namespace inr {

// Linear float RGBA image, row 0 at the top, pixel (x, y) at data[4 * (y * width + x)].
struct ImageRGBA {
  int width = 0, height = 0;
  std::vector<float> data;
  ImageRGBA() = default;
  ImageRGBA(int w, int h) : width(w), height(h), data(std::size_t(4) * w * h, 0.f) {}
  float* pixel(int x, int y) { return &data[std::size_t(4) * (std::size_t(y) * width + x)]; }
  const float* pixel(int x, int y) const { return &data[std::size_t(4) * (std::size_t(y) * width + x)]; }
};

// 8-bit sRGB-less PNG of the RGB(A) values clamped to [0,1] (no gamma: values are written as is).
void writePng(const std::string& path, const ImageRGBA& image, bool withAlpha = false);
// 8-bit PNG from raw bytes, `channels` 1, 3 or 4.
void writePng8(const std::string& path, int width, int height, int channels,
               const std::uint8_t* pixels);
ImageRGBA readPng(const std::string& path);  // alpha = 1 when the file has none
void writePfm(const std::string& path, const ImageRGBA& image);  // RGB, alpha dropped
ImageRGBA readPfm(const std::string& path);                      // alpha = 1
// Writes PNG or PFM by the extension of `path` (.png, .pfm); anything else is an error.
void writeImage(const std::string& path, const ImageRGBA& image);

// Peak signal-to-noise ratio over RGB with peak 1 (infinite for identical images).
double psnrRgb(const ImageRGBA& a, const ImageRGBA& b);

}  // namespace inr
