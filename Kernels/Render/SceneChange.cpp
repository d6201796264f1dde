#include "Render/SceneChange.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace inr {

std::string SceneChange::describe() const {
  std::string s;
  if (first) s += " first";
  if (camera) s += " camera";
  if (time) s += " time";
  if (depthLimit) s += " depth";
  if (light) s += " light";
  if (transferFunction) s += " tf";
  if (background) s += " background";
  return s.empty() ? " nothing" : s;
}

namespace {
// Equal up to a relative 1e-6: far below a pixel for any sensible view. Hosts recompute camera
// parameters without moving the camera: vtkWindowToImageFilter's re-render (every screenshot and
// regression capture) hands back a view angle of 30.000000835 for 30 (a float round trip).
// Treating that as a move restarted (or reprojected) a converged image on every screenshot.
bool nearlyEqual(double a, double b) {
  return std::fabs(a - b) <= 1e-6 * std::max({1.0, std::fabs(a), std::fabs(b)});
}
bool nearlyEqual(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return nearlyEqual(a[0], b[0]) && nearlyEqual(a[1], b[1]) && nearlyEqual(a[2], b[2]);
}
}  // namespace

bool sameCamera(const Camera& a, const Camera& b) {
  return nearlyEqual(a.position, b.position) && nearlyEqual(a.focalPoint, b.focalPoint) &&
         nearlyEqual(a.viewUp, b.viewUp) && nearlyEqual(a.viewAngle, b.viewAngle) &&
         a.parallelProjection == b.parallelProjection && nearlyEqual(a.parallelScale, b.parallelScale) &&
         nearlyEqual(a.windowCenter[0], b.windowCenter[0]) && nearlyEqual(a.windowCenter[1], b.windowCenter[1]) &&
         a.modelToWorld == b.modelToWorld;
}

bool sameTransferFunction(const TransferFunction& a, const TransferFunction& b) {
  if (!(a.transfer2D == b.transfer2D)) return false;
  if (a.unitDistance != b.unitDistance || a.colorSpace != b.colorSpace ||
      a.color.size() != b.color.size() || a.opacity.size() != b.opacity.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.color.size(); ++i) {
    const auto &p = a.color[i], &q = b.color[i];
    if (p.x != q.x || p.r != q.r || p.g != q.g || p.b != q.b) return false;
  }
  auto samePiecewise = [](const std::vector<TransferFunction::OpacityPoint>& u,
                          const std::vector<TransferFunction::OpacityPoint>& v) {
    if (u.size() != v.size()) return false;
    for (std::size_t i = 0; i < u.size(); ++i) {
      const auto &p = u[i], &q = v[i];
      if (p.x != q.x || p.alpha != q.alpha || p.midpoint != q.midpoint || p.sharpness != q.sharpness) return false;
    }
    return true;
  };
  return samePiecewise(a.opacity, b.opacity) && samePiecewise(a.gradientOpacity, b.gradientOpacity);
}

SceneChange diffScenes(const RenderScene* before, const RenderScene& after) {
  SceneChange c;
  if (!before) {
    c.first = c.time = c.transferFunction = c.camera = c.depthLimit = c.light = c.background = true;
    return c;
  }
  const RenderScene& b = *before;
  c.time = b.time != after.time;
  c.transferFunction = !sameTransferFunction(b.transferFunction, after.transferFunction);
  c.camera = !sameCamera(b.camera, after.camera);
  c.depthLimit = b.depthLimit != after.depthLimit;
  // The light only shades through shadows: without them its direction, ambient term and
  // estimator change nothing (ParaView's light follows the camera, so counting it made every
  // camera move a light change, which restarts accumulation and so defeated reprojection).
  // Shading uses the direction unless it has a headlight or a list of lights, and the ambient
  // term. (A camera light of the list turns with the camera: that is a camera change.)
  const bool shaded = after.shading.enabled;
  const bool directionUsed = after.shadows || after.shading.usesSceneLight();
  c.light = b.shadows != after.shadows || b.shading != after.shading ||
            (directionUsed && b.toLight != after.toLight) ||
            ((after.shadows || shaded) && b.ambient != after.ambient) ||
            (after.shadows && b.shadowEstimator != after.shadowEstimator);
  c.background = b.background != after.background;
  return c;
}

CameraView validateScene(const RenderScene& scene, const RenderSettings& settings) {
  const std::size_t pixels = std::size_t(settings.width) * settings.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels) {
    throw std::invalid_argument("depth limit must have one value per pixel (" + std::to_string(pixels) +
                                "), got " + std::to_string(scene.depthLimit.size()));
  }
  for (float c : scene.background) {
    if (!std::isfinite(c)) throw std::invalid_argument("background colour must be finite");
  }
  validateLighting(scene);
  if ((scene.shadows || scene.shading.usesSceneLight()) && !(length(toVec3(scene.toLight)) > 0.f)) {
    throw std::invalid_argument("light direction must be non-zero");
  }
  return scene.camera.view(settings.width, settings.height);  // validates the camera
}

namespace {
// A working-range end as a transfer-function position: a network that overflows (fp16 or fp32)
// leaves +-inf in its cells' value range, which no transfer function may hold; the sweep then
// spans a quarter of the float range each way (its bumps reach up to half the span beyond the
// ends and must stay within float) instead (NaN: 0).
double finiteEnd(float v) {
  const double fmax = 0.25 * double(std::numeric_limits<float>::max());
  return std::isnan(v) ? 0.0 : std::clamp(double(v), -fmax, fmax);
}
}  // namespace

GhostSweep::GhostSweep(const std::array<float, 2>& range, const Vec3f& cellSize, int count)
    : lo_(finiteEnd(range[0])), span_(std::max(finiteEnd(range[1]) - finiteEnd(range[0]), 1e-6)),
      meanCell_((double(cellSize.x) + cellSize.y + cellSize.z) / 3.0), count_(count) {}

TransferFunction GhostSweep::transferFunction(int pass) const {
  const double centre = lo_ + (pass + 0.5) / count_ * span_;
  TransferFunction ghost = TransferFunction::cosineBump(lo_, lo_ + span_, centre, span_ / count_, 0.5);
  ghost.unitDistance = meanCell_;
  return ghost;
}

}  // namespace inr
