#include "Common/ImageIO.h"

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

namespace inr {
namespace {

struct FileCloser {
  void operator()(FILE* f) const {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;

std::uint8_t toByte(float v) {
  if (!(v >= 0.f)) return 0;  // also NaN
  if (v >= 1.f) return 255;
  return static_cast<std::uint8_t>(std::lround(v * 255.f));
}

std::string extensionOf(const std::string& path) {
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos) return "";
  std::string e = path.substr(dot + 1);
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

}  // namespace

void writePng8(const std::string& path, int width, int height, int channels, const std::uint8_t* pixels) {
  if (width <= 0 || height <= 0 || (channels != 1 && channels != 3 && channels != 4))
    throw std::runtime_error(path + ": invalid image size or channel count for PNG");
  FilePtr f(std::fopen(path.c_str(), "wb"));
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error(path + ": libpng initialisation failed");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw std::runtime_error(path + ": libpng write error");
  }
  png_init_io(png, f.get());
  const int type = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  png_set_IHDR(png, info, width, height, 8, type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < height; ++y)
    png_write_row(png, const_cast<png_bytep>(pixels + std::size_t(y) * width * channels));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
}

void writePng(const std::string& path, const ImageRGBA& image, bool withAlpha) {
  const int channels = withAlpha ? 4 : 3;
  std::vector<std::uint8_t> bytes(std::size_t(image.width) * image.height * channels);
  for (std::size_t i = 0, n = std::size_t(image.width) * image.height; i < n; ++i)
    for (int c = 0; c < channels; ++c) bytes[i * channels + c] = toByte(image.data[4 * i + c]);
  writePng8(path, image.width, image.height, channels, bytes.data());
}

ImageRGBA readPng(const std::string& path) {
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str()))
    throw std::runtime_error(path + ": cannot read PNG: " + img.message);
  img.format = PNG_FORMAT_RGBA;
  std::vector<std::uint8_t> bytes(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, bytes.data(), 0, nullptr))
    throw std::runtime_error(path + ": cannot decode PNG: " + img.message);
  ImageRGBA out(static_cast<int>(img.width), static_cast<int>(img.height));
  for (std::size_t i = 0; i < bytes.size(); ++i) out.data[i] = bytes[i] / 255.f;
  return out;
}

void writePfm(const std::string& path, const ImageRGBA& image) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  // Negative scale = little-endian. PFM stores rows bottom to top.
  out << "PF\n" << image.width << ' ' << image.height << "\n-1.0\n";
  std::vector<float> row(std::size_t(3) * image.width);
  for (int y = image.height - 1; y >= 0; --y) {
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < 3; ++c) row[3 * x + c] = image.pixel(x, y)[c];
    out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size() * sizeof(float)));
  }
  if (!out) throw std::runtime_error(path + ": write error");
}

ImageRGBA readPfm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::string magic;
  int w = 0, h = 0;
  double scale = 0;
  in >> magic >> w >> h >> scale;
  in.get();  // the single whitespace byte before the raster
  if (!in || (magic != "PF" && magic != "Pf") || w <= 0 || h <= 0 || w > 65536 || h > 65536 || scale == 0)
    throw std::runtime_error(path + ": not a valid PFM header");
  if (scale > 0) throw std::runtime_error(path + ": big-endian PFM is not supported");
  const int channels = magic == "PF" ? 3 : 1;
  ImageRGBA image(w, h);
  std::vector<float> row(std::size_t(channels) * w);
  for (int y = h - 1; y >= 0; --y) {
    if (!in.read(reinterpret_cast<char*>(row.data()), std::streamsize(row.size() * sizeof(float))))
      throw std::runtime_error(path + ": PFM raster is truncated");
    for (int x = 0; x < w; ++x) {
      float* p = image.pixel(x, y);
      for (int c = 0; c < 3; ++c) p[c] = row[std::size_t(channels) * x + (channels == 3 ? c : 0)];
      p[3] = 1.f;
    }
  }
  return image;
}

void writeImage(const std::string& path, const ImageRGBA& image) {
  const std::string ext = extensionOf(path);
  if (ext == "png") writePng(path, image);
  else if (ext == "pfm") writePfm(path, image);
  else throw std::runtime_error(path + ": unknown image extension (use .png or .pfm)");
}

double psnrRgb(const ImageRGBA& a, const ImageRGBA& b) {
  if (a.width != b.width || a.height != b.height)
    throw std::runtime_error("psnrRgb: image sizes differ");
  double se = 0;
  const std::size_t n = std::size_t(a.width) * a.height;
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const double d = double(a.data[4 * i + c]) - double(b.data[4 * i + c]);
      se += d * d;
    }
  const double mse = se / double(3 * n);
  if (mse == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(1.0 / mse);
}

}  // namespace inr
