#include "Render/SceneInputs.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "Common/ImageIO.h"

namespace inr {

// ---------------------------------------------------------------- camera

Camera Camera::framing(const Box3f& box, double viewAngleDegrees) {
  Camera c;
  const double cx = 0.5 * (double(box.lo.x) + box.hi.x), cy = 0.5 * (double(box.lo.y) + box.hi.y),
               cz = 0.5 * (double(box.lo.z) + box.hi.z);
  const double hx = 0.5 * (double(box.hi.x) - box.lo.x), hy = 0.5 * (double(box.hi.y) - box.lo.y),
               hz = 0.5 * (double(box.hi.z) - box.lo.z);
  const double radius = std::sqrt(hx * hx + hy * hy + hz * hz);
  const double pi = 3.14159265358979323846;
  const double distance = radius / std::sin(0.5 * viewAngleDegrees * pi / 180.0);
  c.focalPoint = {cx, cy, cz};
  c.position = {cx, cy, cz + distance};
  c.viewUp = {0, 1, 0};
  c.viewAngle = viewAngleDegrees;
  c.parallelScale = radius;
  return c;
}

namespace {

// Integral over one table interval (unit length) of -ln(1 - alpha), alpha going linearly from a0
// to a1 and clamped to [0, kMaxTableOpacity] as the lookup clamps it: with beta = 1 - alpha, an
// antiderivative of -ln beta in beta is beta - beta ln beta.
double linearOpacityDepth(double a0, double a1) {
  const double cap = kMaxTableOpacity;
  auto mean = [](double x0, double x1) {  // x0, x1 in [0, cap]
    const double b0 = 1.0 - x0, b1 = 1.0 - x1;
    if (std::fabs(b1 - b0) < 1e-9) return -std::log(0.5 * (b0 + b1));
    auto g = [](double b) { return b - b * std::log(b); };
    return (g(b1) - g(b0)) / (b1 - b0);
  };
  a0 = std::max(a0, 0.0);
  a1 = std::max(a1, 0.0);
  if (a0 <= cap && a1 <= cap) return mean(a0, a1);
  if (a0 >= cap && a1 >= cap) return -std::log(1.0 - cap);
  const double lo = std::min(a0, a1), unclamped = (cap - lo) / std::fabs(a1 - a0);
  return unclamped * mean(lo, cap) + (1.0 - unclamped) * -std::log(1.0 - cap);
}

// Finite, and finite once converted to float (the per-ray code's precision).
bool finiteInFloat(const std::array<double, 3>& a) {
  for (double v : a)
    if (!(std::abs(v) <= double(std::numeric_limits<float>::max()))) return false;  // also NaN
  return true;
}

// a / |a| computed in double, for vectors whose float length overflows (|a| > ~1.8e19); infinite
// components give the direction of the infinities ((0, -inf, 0) -> (0, -1, 0)).
Vec3f unitInDouble(std::array<double, 3> a) {
  if (std::isinf(a[0]) || std::isinf(a[1]) || std::isinf(a[2])) {
    for (double& v : a) v = std::isinf(v) ? std::copysign(1.0, v) : 0.0;
  }
  const double s = std::max({std::abs(a[0]), std::abs(a[1]), std::abs(a[2])});
  if (!(s > 0.0)) return Vec3f{0.f, 0.f, 0.f};
  const double x = a[0] / s, y = a[1] / s, z = a[2] / s, l = std::sqrt(x * x + y * y + z * z);
  return Vec3f{float(x / l), float(y / l), float(z / l)};
}

}  // namespace

namespace {

// The model <-> world maps of a row-major model-to-world matrix, in the view. Inverted in double
// (a scale of 1e-3 and a translation of 1e3 lose nothing that matters in float).
void setModelTransform(const std::array<double, 16>& m, CameraView& v) {
  const Affine3f identity{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
  v.modelFromWorld = v.worldFromModel = identity;
  v.transformed = 0;
  bool isIdentity = true;
  for (int k = 0; k < 16; ++k) {
    if (!(std::abs(m[k]) <= double(std::numeric_limits<float>::max()))) {
      throw std::invalid_argument("camera: the volume's model matrix is not finite (element " + std::to_string(k) + ")");
    }
    isIdentity = isIdentity && m[k] == ((k % 5 == 0) ? 1.0 : 0.0);
  }
  if (isIdentity) return;
  if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0) {
    throw std::invalid_argument("camera: the volume's model matrix is not affine (its last row must be 0 0 0 1)");
  }
  const double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], h = m[9], i = m[10];
  const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  // Relative to the matrix's scale: a volume flattened to nothing has no inside to render.
  double norm = 0.0;
  for (double x : {a, b, c, d, e, f, g, h, i}) norm = std::max(norm, std::abs(x));
  if (!(std::abs(det) > 1e-12 * norm * norm * norm)) {
    throw std::invalid_argument("camera: the volume's model matrix is singular (a zero scale?)");
  }
  const double inv[9] = {(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det,
                         (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
                         (d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det};
  const double t[3] = {m[3], m[7], m[11]};
  auto row = [](double x, double y, double z) { return Vec3f{float(x), float(y), float(z)}; };
  v.worldFromModel = Affine3f{row(a, b, c), row(d, e, f), row(g, h, i), row(t[0], t[1], t[2])};
  v.modelFromWorld.row0 = row(inv[0], inv[1], inv[2]);
  v.modelFromWorld.row1 = row(inv[3], inv[4], inv[5]);
  v.modelFromWorld.row2 = row(inv[6], inv[7], inv[8]);
  v.modelFromWorld.offset = row(-(inv[0] * t[0] + inv[1] * t[1] + inv[2] * t[2]),
                                -(inv[3] * t[0] + inv[4] * t[1] + inv[5] * t[2]),
                                -(inv[6] * t[0] + inv[7] * t[1] + inv[8] * t[2]));
  v.transformed = 1;
}

}  // namespace

CameraView Camera::view(int width, int height) const {
  if (width <= 0 || height <= 0) throw std::invalid_argument("camera: image size must be positive");
  // Non-finite inputs are named as such (they used to surface as "position equals focal point" or
  // "view-up is parallel to the view direction").
  if (!finiteInFloat(position)) throw std::invalid_argument("camera: position is not finite (or beyond float range)");
  if (!finiteInFloat(focalPoint)) {
    throw std::invalid_argument("camera: focal point is not finite (or beyond float range)");
  }
  if (!(std::isfinite(viewUp[0]) && std::isfinite(viewUp[1]) && std::isfinite(viewUp[2]))) {
    throw std::invalid_argument("camera: view-up is not finite");
  }
  const Vec3f pos{float(position[0]), float(position[1]), float(position[2])};
  const Vec3f focal{float(focalPoint[0]), float(focalPoint[1]), float(focalPoint[2])};
  Vec3f upHint{float(viewUp[0]), float(viewUp[1]), float(viewUp[2])};
  Vec3f toFocal = focal - pos;
  // A camera ~1e19 or more from its focal point (or a huge view-up) overflows float's dot product,
  // one ~1e-19 from it underflows: normalise those in double (other inputs take the float path
  // unchanged, bit for bit).
  const float focalDistance = length(toFocal);
  if (!std::isfinite(focalDistance) || focalDistance == 0.f) {
    toFocal = unitInDouble({focalPoint[0] - position[0], focalPoint[1] - position[1], focalPoint[2] - position[2]});
  }
  const float upLength = length(upHint);
  if (!std::isfinite(upLength) || upLength == 0.f) upHint = unitInDouble(viewUp);
  if (!(length(toFocal) > 0.f)) throw std::invalid_argument("camera: position equals focal point");
  CameraView v{};
  v.forward = normalize(toFocal);
  const Vec3f r = cross(v.forward, upHint);
  if (!(length(r) > 1e-6f * length(upHint))) {
    throw std::invalid_argument("camera: view-up is parallel to the view direction (or zero)");
  }
  v.right = normalize(r);
  v.up = cross(v.right, v.forward);
  v.position = pos;
  if (parallelProjection) {
    if (!(parallelScale > 0.0 && parallelScale <= double(std::numeric_limits<float>::max()))) {
      throw std::invalid_argument("camera: parallel scale must be > 0 and finite");
    }
    v.halfHeight = float(parallelScale);
  } else {
    if (!(viewAngle > 0.0 && viewAngle < 180.0)) {
      throw std::invalid_argument("camera: view angle must be in (0, 180) degrees");
    }
    v.halfHeight = float(std::tan(0.5 * viewAngle * 3.14159265358979323846 / 180.0));
  }
  v.aspect = float(width) / float(height);
  v.width = width;
  v.height = height;
  v.parallel = parallelProjection ? 1 : 0;
  if (!(std::abs(windowCenter[0]) <= 1e6 && std::abs(windowCenter[1]) <= 1e6)) {
    throw std::invalid_argument("camera: window centre must be finite (and within +-1e6)");
  }
  v.centerX = float(windowCenter[0]);
  v.centerY = float(windowCenter[1]);
  setModelTransform(modelToWorld, v);
  return v;
}

bool Camera::hasModelTransform() const {
  for (int k = 0; k < 16; ++k) {
    if (modelToWorld[k] != ((k % 5 == 0) ? 1.0 : 0.0)) return true;
  }
  return false;
}

void validateImageWindow(const ImageWindow& w, int width, int height) {
  if (w.fullWidth == 0 && w.fullHeight == 0 && w.x == 0 && w.y == 0) return;
  if (w.fullWidth <= 0 || w.fullHeight <= 0 || w.x < 0 || w.y < 0 || w.x > w.fullWidth - width ||
      w.y > w.fullHeight - height) {
    throw std::invalid_argument("image window: a " + std::to_string(width) + "x" + std::to_string(height) +
                                " image at (" + std::to_string(w.x) + ", " + std::to_string(w.y) +
                                ") does not fit in the " + std::to_string(w.fullWidth) + "x" +
                                std::to_string(w.fullHeight) + " picture");
  }
  if (double(w.fullWidth) * double(w.fullHeight) > 4294967295.0) {
    throw std::invalid_argument("image window: the full picture has more than 2^32 pixels");
  }
  // The per-ray key arithmetic (RayState.h pixelStreamKey) is exact below this.
  if (double(width) * double(height) * double(width) >= 4398046511104.0) {
    throw std::invalid_argument("image window: a tile of " + std::to_string(width) + "x" + std::to_string(height) +
                                " is too large to key by the full picture (pixels x width must stay below 2^42)");
  }
}

void validateSplit(const RenderSettings& settings) {
  const auto checkShare = [](const char* what, int index, int count) {
    if (count < 1 || index < 0 || index >= count)
      throw std::invalid_argument(std::string(what) + " " + std::to_string(index) + "/" + std::to_string(count) +
                                  ": need a count of at least 1 and 0 <= index < count");
  };
  checkShare("pixel share", settings.pixelShare.index, settings.pixelShare.count);
  checkShare("sample share", settings.sampleShare.index, settings.sampleShare.count);
  const int splits = int(settings.clipToBrick) + int(settings.pixelShare.count > 1) + int(settings.sampleShare.count > 1);
  if (splits > 1)
    throw std::invalid_argument("bricks (clipToBrick), a pixel share and a sample share are three ways to split a "
                                "render over ranks: choose one");
}

std::array<double, 3> defaultLightDirection(const Camera& camera) {
  const CameraView v = camera.view(1, 1);
  const Vec3f d = normalize(v.forward * -1.f + v.up * 0.8f + v.right * -0.5f);
  return {d.x, d.y, d.z};
}

// ---------------------------------------------------------------- transfer function

namespace {

double piecewiseSegment(double s, double y1, double y2, double midpoint, double sharpness) {
  // vtkPiecewiseFunction's node semantics: the midpoint moves where the value is halfway, the
  // sharpness blends from linear (0) through a Hermite curve to a step (1).
  midpoint = std::clamp(midpoint, 0.00001, 0.99999);
  s = s < midpoint ? 0.5 * s / midpoint : 0.5 + 0.5 * (s - midpoint) / (1.0 - midpoint);
  if (sharpness > 0.99) return s < 0.5 ? y1 : y2;
  if (sharpness < 0.01) return (1.0 - s) * y1 + s * y2;
  if (s < 0.5) {
    s = 0.5 * std::pow(s * 2.0, 1.0 + 10.0 * sharpness);
  } else if (s > 0.5) {
    s = 1.0 - 0.5 * std::pow((1.0 - s) * 2.0, 1.0 + 10.0 * sharpness);
  }
  const double ss = s * s, sss = ss * s;
  const double h1 = 2 * sss - 3 * ss + 1, h2 = -2 * sss + 3 * ss, h3 = sss - 2 * ss + s,
               h4 = sss - ss;
  const double tangent = (1.0 - sharpness) * (y2 - y1);
  const double v = h1 * y1 + h2 * y2 + h3 * tangent + h4 * tangent;
  return std::clamp(v, std::min(y1, y2), std::max(y1, y2));
}

std::vector<double> numberArray(const nlohmann::json& j, const char* key, std::size_t tuple,
                                const std::string& label) {
  const auto& a = j.at(key);
  if (!a.is_array()) throw std::runtime_error(label + ": '" + key + "' must be an array of numbers");
  std::vector<double> v;
  for (const auto& e : a) {
    if (!e.is_number()) throw std::runtime_error(label + ": '" + key + "' must hold numbers only");
    v.push_back(e.get<double>());
    if (!std::isfinite(v.back())) throw std::runtime_error(label + ": '" + key + "' holds NaN/Inf");
  }
  if (v.empty() || v.size() % tuple != 0) {
    throw std::runtime_error(label + ": '" + key + "' must hold groups of " + std::to_string(tuple) +
                             " numbers, found " + std::to_string(v.size()));
  }
  return v;
}

}  // namespace

TransferFunction TransferFunction::fromParaViewJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open transfer function file");
  std::stringstream ss;
  ss << in.rdbuf();
  return fromParaViewJson(ss.str(), path);
}

TransferFunction::Transfer2D TransferFunction::transfer2DFromJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open 2D transfer function file");
  std::stringstream ss;
  ss << in.rdbuf();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(ss.str());
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": not valid JSON (" + e.what() + ")");
  }
  if (!j.is_object()) throw std::runtime_error(path + ": expected a JSON object (a 2D transfer function)");
  auto range = [&](const char* key) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 2 || !j[key][0].is_number() ||
        !j[key][1].is_number())
      throw std::runtime_error(path + ": '" + key + "' must be a list of two numbers [lo, hi]");
    const double lo = j[key][0].get<double>(), hi = j[key][1].get<double>();
    if (!(std::isfinite(lo) && std::isfinite(hi) && hi > lo))
      throw std::runtime_error(path + ": '" + key + "' must be finite with hi > lo");
    return std::array<double, 2>{lo, hi};
  };
  Transfer2D t;
  const auto sr = range("ScalarRange"), gr = range("GradientRange");
  t.scalarLo = sr[0];
  t.scalarHi = sr[1];
  t.gradientLo = gr[0];
  t.gradientHi = gr[1];
  if (j.contains("Image")) {
    if (!j["Image"].is_string()) throw std::runtime_error(path + ": 'Image' must be a file name (an RGBA PNG)");
    std::string image = j["Image"].get<std::string>();
    const auto slash = path.find_last_of('/');
    if (!image.empty() && image[0] != '/' && slash != std::string::npos) image = path.substr(0, slash + 1) + image;
    const ImageRGBA png = readPng(image);  // (throws naming the image)
    t.width = png.width;
    t.height = png.height;
    t.rgba.resize(std::size_t(4) * png.width * png.height);
    for (int y = 0; y < png.height; ++y)  // the PNG's bottom row is row 0 (the smallest magnitude)
      for (int x = 0; x < png.width; ++x)
        for (int c = 0; c < 4; ++c)
          t.rgba[std::size_t(4) * (std::size_t(png.height - 1 - y) * png.width + x) + c] = png.pixel(x, y)[c];
    return t;
  }
  if (!j.contains("Width") || !j["Width"].is_number_integer() || !j.contains("Height") ||
      !j["Height"].is_number_integer())
    throw std::runtime_error(path + ": needs 'Image' (a PNG) or integer 'Width' and 'Height' with 'RGBA'");
  const long long w = j["Width"].get<long long>(), h = j["Height"].get<long long>();
  if (w < 1 || h < 1 || w * h > TransferFunctionTable::kMaxTransfer2DPixels)
    throw std::runtime_error(path + ": 'Width' x 'Height' must be at least 1 x 1 and at most " +
                             std::to_string(TransferFunctionTable::kMaxTransfer2DPixels) + " pixels");
  if (!j.contains("RGBA") || !j["RGBA"].is_array() || j["RGBA"].size() != std::size_t(4 * w * h))
    throw std::runtime_error(path + ": 'RGBA' must be a list of Width x Height x 4 = " + std::to_string(4 * w * h) +
                             " numbers");
  t.width = int(w);
  t.height = int(h);
  t.rgba.reserve(std::size_t(4 * w * h));
  for (const auto& v : j["RGBA"]) {
    if (!v.is_number()) throw std::runtime_error(path + ": 'RGBA' entry " + std::to_string(t.rgba.size()) + " is not a number");
    t.rgba.push_back(v.get<float>());
  }
  return t;
}

TransferFunction TransferFunction::fromParaViewJson(const std::string& text,
                                                    const std::string& label) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    throw std::runtime_error(label + ": not valid JSON (" + e.what() + ")");
  }
  if (j.is_array()) {
    if (j.empty()) throw std::runtime_error(label + ": empty preset list");
    j = j[0];  // ParaView exports a list of presets; the first one is the colour map
  }
  if (!j.is_object() || !j.contains("RGBPoints")) {
    throw std::runtime_error(label + ": expected a ParaView colour map with 'RGBPoints'");
  }
  TransferFunction tf;
  const auto rgb = numberArray(j, "RGBPoints", 4, label);
  for (std::size_t i = 0; i < rgb.size(); i += 4) tf.color.push_back({rgb[i], rgb[i + 1], rgb[i + 2], rgb[i + 3]});
  if (j.contains("Points")) {
    const auto pts = numberArray(j, "Points", 4, label);
    for (std::size_t i = 0; i < pts.size(); i += 4) {
      if (pts[i + 1] < 0.0 || pts[i + 1] > 1.0) {
        throw std::runtime_error(label + ": opacity " + std::to_string(pts[i + 1]) +
                                 " in 'Points' is outside [0, 1]");
      }
      tf.opacity.push_back({pts[i], pts[i + 1], pts[i + 2], pts[i + 3]});
    }
  } else {
    const auto r = tf.range();
    tf.opacity = {{r[0], 0.0}, {r[1], 1.0}};
  }
  if (j.contains("ColorSpace") && j["ColorSpace"].is_string()) tf.colorSpace = j["ColorSpace"];
  auto byX = [](const auto& a, const auto& b) { return a.x < b.x; };
  std::stable_sort(tf.color.begin(), tf.color.end(), byX);
  std::stable_sort(tf.opacity.begin(), tf.opacity.end(), byX);
  return tf;
}

TransferFunction TransferFunction::preset(double lo, double hi, double maxOpacity) {
  TransferFunction tf;
  const double mid = 0.5 * (lo + hi);
  // ParaView's "Cool to Warm" end and centre colours (interpolated in RGB here).
  tf.color = {{lo, 0.231, 0.298, 0.753}, {mid, 0.865, 0.865, 0.865}, {hi, 0.706, 0.016, 0.150}};
  tf.opacity = {{lo, 0.0}, {hi, maxOpacity}};
  return tf;
}

TransferFunction TransferFunction::transparent(double lo, double hi) {
  TransferFunction tf = preset(lo, hi);
  tf.opacity = {{lo, 0.0}, {hi, 0.0}};
  return tf;
}

TransferFunction TransferFunction::cosineBump(double lo, double hi, double centre,
                                              double halfWidth, double peakOpacity) {
  TransferFunction tf;
  tf.color = {{lo, 1, 1, 1}, {hi, 1, 1, 1}};
  const int n = 17;  // samples of the bump; the table interpolates between them
  const double pi = 3.14159265358979323846;
  tf.opacity.push_back({std::min(lo, centre - halfWidth) - 1e-6, 0.0});
  for (int k = 0; k < n; ++k) {
    const double u = -1.0 + 2.0 * k / (n - 1);
    tf.opacity.push_back({centre + u * halfWidth, peakOpacity * 0.5 * (1.0 + std::cos(pi * u))});
  }
  tf.opacity.push_back({std::max(hi, centre + halfWidth) + 1e-6, 0.0});
  return tf;
}

void TransferFunction::rescale(double lo, double hi) {
  const auto r = range();
  const double span = r[1] - r[0];
  auto map = [&](double x) { return span > 0 ? lo + (x - r[0]) / span * (hi - lo) : lo; };
  for (auto& p : color) p.x = map(p.x);
  for (auto& p : opacity) p.x = map(p.x);  // (the gradient opacity is over magnitudes: kept)
}

std::array<double, 2> TransferFunction::range() const {
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& p : color) lo = std::min(lo, p.x), hi = std::max(hi, p.x);
  for (const auto& p : opacity) lo = std::min(lo, p.x), hi = std::max(hi, p.x);
  if (!(lo <= hi)) return {0.0, 1.0};
  return {lo, hi};
}

std::string TransferFunction::colorSpaceWarning() const {
  if (colorSpace == "RGB" || color.size() < 2) return {};
  return "colour space '" + colorSpace +
         "' is interpolated in RGB (only RGB is implemented); colours between points may differ "
         "from ParaView's";
}

namespace {
// A vtkPiecewiseFunction's value at x (midpoint and sharpness per node), clamped to the end nodes.
double piecewiseAt(const std::vector<TransferFunction::OpacityPoint>& points, double x) {
  if (x <= points.front().x) return points.front().alpha;
  if (x >= points.back().x) return points.back().alpha;
  for (std::size_t k = 1; k < points.size(); ++k) {
    if (x <= points[k].x) {
      const auto& a = points[k - 1];
      const auto& b = points[k];
      if (b.x <= a.x) return b.alpha;
      return piecewiseSegment((x - a.x) / (b.x - a.x), a.alpha, b.alpha, a.midpoint, a.sharpness);
    }
  }
  return points.back().alpha;
}

// Refuses a piecewise function's non-finite node, naming the function (`what`) and the node.
void checkPiecewiseFinite(const std::vector<TransferFunction::OpacityPoint>& points, const char* what) {
  const double fmax = double(std::numeric_limits<float>::max());
  for (std::size_t k = 0; k < points.size(); ++k) {
    const auto& p = points[k];
    if (!(std::abs(p.x) <= fmax && std::isfinite(p.alpha) && std::isfinite(p.midpoint) && std::isfinite(p.sharpness))) {
      throw std::invalid_argument(std::string("transfer function: ") + what + " point " + std::to_string(k) +
                                  " is not finite (or beyond float range)");
    }
  }
}
}  // namespace

double TransferFunction::opacityAt(double x) const { return opacity.empty() ? 0.0 : piecewiseAt(opacity, x); }

double TransferFunction::gradientOpacityAt(double gradientNorm) const {
  return gradientOpacity.empty() ? 1.0 : piecewiseAt(gradientOpacity, gradientNorm);
}

std::array<double, 3> TransferFunction::colorAt(double x) const {
  if (color.empty()) return {1, 1, 1};
  auto rgb = [](const ColorPoint& p) { return std::array<double, 3>{p.r, p.g, p.b}; };
  if (x <= color.front().x) return rgb(color.front());
  if (x >= color.back().x) return rgb(color.back());
  for (std::size_t k = 1; k < color.size(); ++k) {
    if (x <= color[k].x) {
      const auto& a = color[k - 1];
      const auto& b = color[k];
      const double f = b.x > a.x ? (x - a.x) / (b.x - a.x) : 1.0;
      return {a.r + f * (b.r - a.r), a.g + f * (b.g - a.g), a.b + f * (b.b - a.b)};
    }
  }
  return rgb(color.back());
}

TransferFunctionTable::TransferFunctionTable(const TransferFunction& tf, int size) {
  if (size < 2) throw std::invalid_argument("transfer function table needs >= 2 entries");
  if (!(tf.unitDistance > 0.0)) {
    throw std::invalid_argument("scalar opacity unit distance must be > 0");
  }
  if (tf.usesTransfer2D()) {  // (colour, opacity and gradient opacity are not used)
    buildTransfer2D(tf);
    return;
  }
  // A NaN/inf point (a script's or a broken pipeline's) would reach the pixels as NaN colours
  // (colour) or silently as empty space (opacity): refuse it, naming it.
  const double fmax = double(std::numeric_limits<float>::max());
  for (std::size_t k = 0; k < tf.color.size(); ++k) {
    const auto& p = tf.color[k];
    if (!(std::abs(p.x) <= fmax && std::isfinite(p.r) && std::isfinite(p.g) && std::isfinite(p.b))) {
      throw std::invalid_argument("transfer function: colour point " + std::to_string(k) +
                                  " is not finite (or beyond float range)");
    }
  }
  checkPiecewiseFinite(tf.opacity, "opacity");
  checkPiecewiseFinite(tf.gradientOpacity, "gradient opacity");
  for (std::size_t k = 1; k < tf.gradientOpacity.size(); ++k) {
    if (!(tf.gradientOpacity[k].x > tf.gradientOpacity[k - 1].x)) {
      throw std::invalid_argument("transfer function: gradient opacity point " + std::to_string(k) +
                                  " does not lie above point " + std::to_string(k - 1) +
                                  " (magnitudes must increase, as a vtkPiecewiseFunction's do)");
    }
  }
  const auto r = tf.range();
  size_ = size;
  lo_ = float(r[0]);
  hi_ = float(r[1]);
  if (!(hi_ > lo_)) hi_ = lo_ + 1.f;  // a single point: constant function, any span works
  // Clamped so extinction stays finite (a unit distance of 1e-300 would give inf, and 0 * inf =
  // NaN majorants for transparent cells): 1e30 per world unit is opaque at any scale.
  invUnitDistance_ = float(std::min(1.0 / tf.unitDistance, 1e30));
  rgba_.resize(size);
  for (int i = 0; i < size; ++i) {
    const double x = double(lo_) + (double(hi_) - lo_) * i / (size - 1);
    const auto c = tf.colorAt(x);
    const float a = float(std::clamp(tf.opacityAt(x), 0.0, 1.0));
    rgba_[i] = Vec4f{float(c[0]), float(c[1]), float(c[2]), a};
  }
  buildBounds();
  buildGradientOpacity(tf);
}

void TransferFunctionTable::buildTransfer2D(const TransferFunction& tf) {
  const TransferFunction::Transfer2D& t = tf.transfer2D;
  const double fmax = double(std::numeric_limits<float>::max());
  if ((long long)t.width * t.height > kMaxTransfer2DPixels)
    throw std::invalid_argument("2D transfer function: " + std::to_string(t.width) + " x " + std::to_string(t.height) +
                                " pixels, at most " + std::to_string(kMaxTransfer2DPixels));
  if (t.rgba.size() != std::size_t(4) * t.width * t.height)
    throw std::invalid_argument("2D transfer function: " + std::to_string(t.rgba.size()) + " RGBA values for " +
                                std::to_string(t.width) + " x " + std::to_string(t.height) + " pixels (4 each)");
  auto checkRange = [&](double lo, double hi, const char* what) {
    if (!(std::abs(lo) <= fmax && std::abs(hi) <= fmax && hi > lo))
      throw std::invalid_argument(std::string("2D transfer function: the ") + what +
                                  " range must be finite (in float range) with hi > lo");
  };
  checkRange(t.scalarLo, t.scalarHi, "scalar");
  checkRange(t.gradientLo, t.gradientHi, "gradient magnitude");
  for (std::size_t k = 0; k < t.rgba.size(); ++k) {
    if (!std::isfinite(t.rgba[k]))
      throw std::invalid_argument("2D transfer function: pixel (" + std::to_string((k / 4) % t.width) + ", " +
                                  std::to_string((k / 4) / t.width) + ") is not finite");
  }
  // The pixels are the table's entries, end to end over the ranges (TransferFunction::transfer2D);
  // beyond the ends the lookup clamps. One column or row is doubled so the bilinear lookup has two.
  const int W = std::max(t.width, 2), H = std::max(t.height, 2);
  lo_ = float(t.scalarLo);
  hi_ = float(t.scalarHi);
  if (!(hi_ > lo_)) hi_ = lo_ + std::max(std::abs(lo_) * 1e-6f, 1e-30f);  // (float rounding of a tiny range)
  gradientLo_ = float(t.gradientLo);
  gradientHi_ = float(t.gradientHi);
  if (!(gradientHi_ > gradientLo_)) gradientHi_ = gradientLo_ + std::max(std::abs(gradientLo_) * 1e-6f, 1e-30f);
  size_ = W;
  gradientSize_ = H;
  invUnitDistance_ = float(std::min(1.0 / tf.unitDistance, 1e30));
  rgba2D_.resize(std::size_t(W) * H);
  for (int j = 0; j < H; ++j) {
    for (int i = 0; i < W; ++i) {
      const float* p = &t.rgba[std::size_t(4) * (std::size_t(std::min(j, t.height - 1)) * t.width + std::min(i, t.width - 1))];
      rgba2D_[std::size_t(j) * W + i] = Vec4f{p[0], p[1], p[2], std::clamp(p[3], 0.f, 1.f)};
    }
  }
  // The 1D table: each column's largest opacity (the bound every scalar-only decision uses) with
  // that entry's colour (what the isosurface and slice blend modes, which have no gradient axis,
  // show).
  rgba_.resize(W);
  for (int i = 0; i < W; ++i) {
    Vec4f best = rgba2D_[i];
    for (int j = 1; j < H; ++j) {
      const Vec4f c = rgba2D_[std::size_t(j) * W + i];
      if (c.w > best.w) best = c;
    }
    rgba_[i] = best;
  }
  buildBounds();
}

void TransferFunctionTable::buildBounds() {
  const int size = size_;
  for (int i = 0; i < size; ++i) maxOpacity_ = std::max(maxOpacity_, rgba_[i].w);
  // Sparse table: level L holds max over [i, i + 2^L) (clamped at the end).
  levels_ = floorLog2(unsigned(size)) + 1;
  opacityMax_.resize(std::size_t(levels_) * size);
  for (int i = 0; i < size; ++i) opacityMax_[i] = rgba_[i].w;
  for (int L = 1; L < levels_; ++L) {
    const int half = 1 << (L - 1);
    for (int i = 0; i < size; ++i) {
      const float a = opacityMax_[std::size_t(L - 1) * size + i];
      const float b = opacityMax_[std::size_t(L - 1) * size + std::min(i + half, size - 1)];
      opacityMax_[std::size_t(L) * size + i] = std::max(a, b);
    }
  }
  // Pre-integration: each entry's extinction and the running integrals of the control extinction
  // (the renderer's own: the opacity interpolated linearly, then -ln(1 - alpha) / u; its
  // integral over an interval in closed form) and of extinction times colour (composite Simpson
  // on 64 sub-intervals: close, the colour varies slowly), summed in double.
  entryExtinction_.resize(size);
  extinctionIntegral_.resize(size);
  for (int i = 0; i < size; ++i) entryExtinction_[i] = opacityToExtinction(rgba_[i].w, invUnitDistance_);
  double integral[4] = {0.0, 0.0, 0.0, 0.0};
  for (int i = 0; i < size; ++i) {
    if (i > 0) {
      const Vec4f c0 = rgba_[i - 1], c1 = rgba_[i];
      auto integrand = [&](double f, double out[4]) {
        const double alpha = std::clamp(double(c0.w) + (double(c1.w) - double(c0.w)) * f, 0.0, double(kMaxTableOpacity));
        const double sigma = -std::log1p(-alpha) * invUnitDistance_;
        out[0] = sigma * (c0.x + (c1.x - c0.x) * f);
        out[1] = sigma * (c0.y + (c1.y - c0.y) * f);
        out[2] = sigma * (c0.z + (c1.z - c0.z) * f);
        out[3] = sigma;
      };
      constexpr int kPieces = 64;  // even
      for (int k = 0; k <= kPieces; ++k) {
        double v[4];
        integrand(double(k) / kPieces, v);
        const double weight = (k == 0 || k == kPieces ? 1.0 : (k % 2 ? 4.0 : 2.0)) / (3.0 * kPieces);
        for (int c = 0; c < 3; ++c) integral[c] += weight * v[c];
      }
      integral[3] += linearOpacityDepth(c0.w, c1.w) * invUnitDistance_;
    }
    extinctionIntegral_[i] = Vec4f{float(integral[0]), float(integral[1]), float(integral[2]), float(integral[3])};
  }
}

void TransferFunctionTable::buildGradientOpacity(const TransferFunction& tf) {
  // Gradient opacity: its nodes exactly (a ramp however narrow beside a far node), and samples
  // between two nodes whose segment bends (midpoint or sharpness), so linear interpolation between
  // the points follows the function.
  if (tf.usesGradientOpacity()) {
    const auto& nodes = tf.gradientOpacity;
    const int segments = int(nodes.size()) - 1;
    const int bent = segments > 0 ? std::clamp(kMaxGradientOpacityPoints / segments, 1, kGradientOpacitySegmentSamples) : 1;
    auto add = [&](double g) {
      gradientOpacityX_.push_back(float(g));
      gradientOpacity_.push_back(float(std::clamp(tf.gradientOpacityAt(g), 0.0, 1.0)));
    };
    add(nodes.front().x);
    for (int k = 0; k < segments; ++k) {
      const auto &a = nodes[k], &b = nodes[k + 1];
      const int samples = (a.midpoint == 0.5 && a.sharpness == 0.0) ? 1 : bent;
      for (int j = 1; j <= samples; ++j) {
        const double g = j == samples ? b.x : a.x + (b.x - a.x) * j / samples;
        if (float(g) > gradientOpacityX_.back()) add(g);  // (float rounding may merge close nodes)
      }
    }
  }
}

TransferFunctionView TransferFunctionTable::view() const {
  TransferFunctionView v;
  v.rgba = rgba_.data();
  v.opacityMax = opacityMax_.data();
  v.size = size_;
  v.levels = levels_;
  v.lo = lo_;
  v.hi = hi_;
  v.invUnitDistance = invUnitDistance_;
  v.entryExtinction = entryExtinction_.data();
  v.extinctionIntegral = extinctionIntegral_.data();
  if (!gradientOpacity_.empty()) {
    v.gradientOpacity = gradientOpacity_.data();
    v.gradientOpacityX = gradientOpacityX_.data();
    v.gradientOpacitySize = int(gradientOpacity_.size());
  }
  if (!rgba2D_.empty()) {
    v.rgba2D = rgba2D_.data();
    v.gradientSize = gradientSize_;
    v.gradientLo = gradientLo_;
    v.gradientHi = gradientHi_;
  }
  return v;
}

void ShadingOptions::validate() const {
  if (!(diffuse >= 0.f && diffuse < INFINITY))
    throw std::invalid_argument("shading: diffuse must be finite and >= 0, got " + std::to_string(diffuse));
  if (!(specular >= 0.f && specular < INFINITY))
    throw std::invalid_argument("shading: specular must be finite and >= 0, got " + std::to_string(specular));
  if (!(specularPower >= 0.f && specularPower <= 128.f))
    throw std::invalid_argument("shading: specular power must be in [0, 128], got " + std::to_string(specularPower));
  for (const auto* colour : {&oneLightDiffuse, &oneLightSpecular}) {
    const std::string problem = lightColourProblem(*colour);
    if (!problem.empty()) throw std::invalid_argument("shading: the light's " + problem);
  }
  if (!lightList) return;
  if (lights.size() > std::size_t(kMaxShadingLights))
    throw std::invalid_argument("shading: at most " + std::to_string(kMaxShadingLights) + " lights, got " +
                                std::to_string(lights.size()));
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const std::string problem = lights[i].problem();
    if (!problem.empty()) throw std::invalid_argument("shading: light " + std::to_string(i) + "'s " + problem);
  }
}

std::string lightColourProblem(const std::array<float, 3>& colour) {
  // Colours beyond this would overflow when summed over the lights (and NaN through inf * 0).
  constexpr float kMaxColour = 1e6f;
  for (float c : colour)
    if (!(c >= 0.f && c <= kMaxColour)) return "colours must be in [0, 1e6], got " + std::to_string(c);
  return "";
}

std::string SceneLight::problem() const {
  const double len = std::hypot(toLight[0], toLight[1], toLight[2]);
  if (!(len > 0.0 && len < INFINITY)) return "direction must be finite and non-zero";
  for (const auto* colour : {&ambient, &diffuse, &specular}) {
    std::string problem = lightColourProblem(*colour);
    if (!problem.empty()) return problem;
  }
  return "";
}

std::vector<SceneLight> paraviewLightKit() {
  // vtkLightKit's defaults: each light at (elevation, azimuth) degrees in camera coordinates, its
  // intensity the key's 0.75 over the light's ratio, its colour from its warmth (0.5 is white);
  // the colours as ParaView 5.11 sets them (read back from its renderer).
  struct KitLight {
    double elevation, azimuth, intensity;
    std::array<float, 3> colour;
    bool headlight;
  };
  const std::array<float, 3> white{0.9998f, 0.9998f, 0.9998f};
  const KitLight kit[] = {{0.0, 0.0, 0.75 / 3.0, white, true},
                          {50.0, 10.0, 0.75, {1.f, 0.97232f, 0.90222f}, false},
                          {-75.0, -10.0, 0.75 / 3.0, {0.90824f, 0.93314f, 1.f}, false},
                          {0.0, 110.0, 0.75 / 3.5, white, false},
                          {0.0, -110.0, 0.75 / 3.5, white, false}};
  std::vector<SceneLight> lights;
  const double rad = 3.14159265358979323846 / 180.0;
  for (const KitLight& k : kit) {
    SceneLight l;
    l.cameraLight = true;
    const double e = k.elevation * rad, a = k.azimuth * rad;
    l.toLight = k.headlight ? std::array<double, 3>{0.0, 0.0, 1.0}
                            : std::array<double, 3>{std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a)};
    for (int c = 0; c < 3; ++c) l.diffuse[c] = l.specular[c] = float(k.colour[c] * k.intensity);
    lights.push_back(l);
  }
  return lights;
}

void validateLighting(const RenderScene& scene) {
  scene.shading.validate();
  if (scene.shadows && scene.shading.enabled && scene.shading.lightList)
    throw std::invalid_argument("shading: a list of lights does not combine with shadows (shadows follow the one light "
                                "direction RenderScene::toLight); turn shadows off or shade with that one light");
}

ShadingConstants shadingConstants(const ShadingOptions& shading, const CameraView& camera) {
  ShadingConstants sc;
  sc.enabled = shading.enabled ? 1 : 0;
  sc.diffuse = shading.diffuse;
  sc.specular = shading.specular;
  sc.specularPower = shading.specularPower;
  sc.headlight = shading.headlight ? 1 : 0;
  const auto vec = [](const std::array<float, 3>& c) { return Vec3f{c[0], c[1], c[2]}; };
  sc.oneLightDiffuse = vec(shading.oneLightDiffuse);
  sc.oneLightSpecular = vec(shading.oneLightSpecular);
  sc.lightList = shading.lightList ? 1 : 0;
  if (!shading.lightList) return sc;
  for (const SceneLight& l : shading.lights) {
    if (sc.numLights == kMaxShadingLights) break;  // validate() refuses more
    ShadingLight& out = sc.lights[sc.numLights++];
    const Vec3f d = unitInDouble(l.toLight);
    // camera coordinates: x right, y up, z back towards the viewer
    out.toLight = l.cameraLight ? normalize(camera.right * d.x + camera.up * d.y - camera.forward * d.z) : d;
    out.diffuse = vec(l.diffuse);
    out.specular = vec(l.specular);
    sc.lightAmbient = sc.lightAmbient + vec(l.ambient);
  }
  return sc;
}

FrameConstants makeFrameConstants(const CameraView& camera, const Box3f& box, const RenderScene& scene,
                                  const RenderSettings& settings, const float* depthLimit, std::uint32_t frame) {
  FrameConstants fc;
  fc.camera = camera;
  fc.box = box;
  fc.primaryBox = settings.clipToBrick ? settings.brick : box;
  fc.shareIndex = settings.pixelShare.index;
  fc.shareCount = settings.pixelShare.count;
  fc.depthLimit = scene.depthLimit.empty() ? nullptr : depthLimit;
  fc.time = float(scene.time);
  fc.frame = frame;
  fc.seed = settings.seed;
  fc.pixelJitter = settings.pixelJitter ? 1 : 0;
  fc.shadows = scene.shadows ? 1 : 0;
  // Ambient outside [0, 1] makes shading negative or brighter in shadow, and NaN makes NaN pixels:
  // clamp it (NaN: the default 0.2).
  fc.ambient = std::isnan(scene.ambient) ? 0.2f : std::clamp(scene.ambient, 0.f, 1.f);
  fc.toLight = normalize(toVec3(scene.toLight));
  if (!isFiniteValue(length(toVec3(scene.toLight)))) {  // beyond float (e.g. 1e39): normalise in double
    fc.toLight = unitInDouble(scene.toLight);
  }
  // A direction in model space (shadow rays are traced there; ray parameters are model distances).
  if (camera.transformed) fc.toLight = normalize(applyLinear(camera.modelFromWorld, fc.toLight));
  const bool whole = settings.window.fullWidth == 0;
  fc.windowX = whole ? 0 : settings.window.x;
  fc.windowY = whole ? 0 : settings.window.y;
  fc.fullWidth = whole ? camera.width : settings.window.fullWidth;
  if (!whole) {
    // pixelStreamKey's division-free row (validateImageWindow keeps pixels * width < 2^42).
    fc.rowMagic = (std::uint64_t(1) << 42) / std::uint64_t(camera.width) + 1u;
    fc.keyBase = std::uint32_t(fc.windowY) * std::uint32_t(fc.fullWidth) + std::uint32_t(fc.windowX);
    fc.keyRowStride = std::uint32_t(fc.fullWidth - camera.width);
  }
  fc.background = Vec3f{scene.background[0], scene.background[1], scene.background[2]};
  fc.shadowEstimator = scene.shadowEstimator;
  fc.shading = shadingConstants(scene.shading, camera);
  return fc;
}

}  // namespace inr
