#pragma once
// Host-side scene inputs shared by every renderer (delta tracking, naive, ray marching): a camera
// with VTK's conventions, a transfer function with VTK's semantics, the light, the background and
// an optional depth limit. The renderers turn them into the device-facing views.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "Render/CameraView.h"
#include "Render/RayState.h"
#include "Render/TransferFunctionTable.h"

namespace inr {

// A vtkCamera's parameters. The view plane normal is position - focal point; the vertical view
// angle is in degrees (VTK's default 30); parallel projection shows 2 * parallelScale world units
// vertically. `windowCenter` is vtkCamera's window centre: the image's centre on the view plane in
// half-extents (vtkWindowToImageFilter shifts it, with a narrower angle, to render one tile of a
// larger image). `modelToWorld` is the volume's model-to-world matrix (vtkProp3D::GetMatrix:
// position, orientation, scale, origin, user matrix), row-major; it must be affine (last row
// 0 0 0 1) and invertible. The engine renders in model space (CameraView.h).
struct Camera {
  std::array<double, 3> position{0, 0, 1};
  std::array<double, 3> focalPoint{0, 0, 0};
  std::array<double, 3> viewUp{0, 1, 0};
  double viewAngle = 30.0;
  bool parallelProjection = false;
  double parallelScale = 1.0;
  std::array<double, 2> windowCenter{0, 0};
  std::array<double, 16> modelToWorld{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

  // vtkRenderer::ResetCamera's framing of a box from the default direction (+z, up +y): focal
  // point at the centre, the bounding sphere exactly filling the view angle.
  static Camera framing(const Box3f& box, double viewAngleDegrees = 30.0);
  // Throws std::invalid_argument when degenerate (coincident points, up parallel to the view,
  // a model matrix that is not affine, not finite or not invertible).
  CameraView view(int width, int height) const;
  bool hasModelTransform() const;  // modelToWorld differs from the identity
};

// Piecewise-linear colour and scalar-opacity functions (vtkColorTransferFunction and
// vtkPiecewiseFunction), over scalar values. Opacity is per `unitDistance` (VTK's scalar opacity
// unit distance, in world units).
struct TransferFunction {
  struct ColorPoint {
    double x, r, g, b;
  };
  struct OpacityPoint {
    double x, alpha, midpoint = 0.5, sharpness = 0.0;  // vtkPiecewiseFunction node semantics
  };
  std::vector<ColorPoint> color;
  std::vector<OpacityPoint> opacity;
  // Gradient opacity (vtkVolumeProperty's gradient opacity function): a piecewise function of the
  // gradient magnitude |grad f| (scalar units per model-space unit: the data's own coordinates,
  // whatever the actor's transform), with values in [0, 1] that multiply the scalar opacity at
  // each sample, so flat regions fade. Empty: off (VTK's DisableGradientOpacity), no gradient is
  // asked for. On, every sample the renderers take needs the network's gradient as well as its
  // value (Render/Evaluate.h), and homogeneity pruning stands down (its estimates carry no gradient).
  std::vector<OpacityPoint> gradientOpacity;
  // 2D transfer function (vtkVolumeProperty's TF_2D mode: ParaView's Use Transfer2D with Use
  // Gradient For Transfer2D): colour and opacity as an RGBA image over (scalar, gradient magnitude
  // |grad f|, model space as for gradient opacity), looked up bilinearly, clamped at the edges. On
  // (width and height > 0) it replaces `color`, `opacity` and `gradientOpacity`; the opacity is
  // per `unitDistance`, as the scalar opacity's. Pixel (i, j) is rgba[4 (j width + i) ...]: colour
  // (not premultiplied) and opacity, row j = 0 the smallest magnitude. The pixels are samples
  // spread over the ranges end to end, as the engine's 1D table and VTK's GPU mapper (which
  // resamples the image to its texture with the first and last pixels at the ends of the range)
  // place them: column i at scalarLo + i (scalarHi - scalarLo) / (width - 1), row j at gradientLo +
  // j (gradientHi - gradientLo) / (height - 1); one column or row is constant along its axis.
  struct Transfer2D {
    int width = 0, height = 0;
    std::vector<float> rgba;
    double scalarLo = 0.0, scalarHi = 1.0;
    double gradientLo = 0.0, gradientHi = 1.0;
    bool operator==(const Transfer2D& o) const {
      return width == o.width && height == o.height && rgba == o.rgba && scalarLo == o.scalarLo &&
             scalarHi == o.scalarHi && gradientLo == o.gradientLo && gradientHi == o.gradientHi;
    }
  };
  Transfer2D transfer2D;
  double unitDistance = 1.0;
  // ParaView's "ColorSpace" (RGB, Lab, Diverging, HSV...). Only RGB interpolation is
  // implemented; others are interpolated in RGB and `colorSpaceWarning` says so.
  std::string colorSpace = "RGB";

  // ParaView's exported colour-map JSON (a list with one preset, or the preset object): keys
  // `RGBPoints` (x r g b ...), `Points` (x alpha midpoint sharpness ...), `ColorSpace`. Without
  // `Points` the opacity is a linear ramp 0..1 over the colour range (ParaView's default).
  // Throws std::runtime_error naming the file and the problem.
  static TransferFunction fromParaViewJsonFile(const std::string& path);
  static TransferFunction fromParaViewJson(const std::string& text, const std::string& label);
  // Our default: a cool-to-warm colour ramp with a linear opacity ramp 0..maxOpacity over [lo, hi].
  static TransferFunction preset(double lo, double hi, double maxOpacity = 1.0);
  // A transfer function with zero opacity everywhere (renders the background, costs no queries).
  static TransferFunction transparent(double lo, double hi);
  // Ghost-pass TF: a cosine bump of opacity centred at `centre` with half-width `halfWidth`.
  static TransferFunction cosineBump(double lo, double hi, double centre, double halfWidth,
                                     double peakOpacity);

  // Maps the points linearly so their range becomes [lo, hi] (ParaView's "rescale").
  void rescale(double lo, double hi);
  // Scalar range covered by the points (colour and opacity together).
  std::array<double, 2> range() const;
  std::string colorSpaceWarning() const;  // empty when the colour space is interpolated exactly
  double opacityAt(double x) const;       // the piecewise (midpoint/sharpness) function
  double gradientOpacityAt(double gradientNorm) const;  // 1 without a gradient opacity function
  bool usesGradientOpacity() const { return !gradientOpacity.empty(); }
  bool usesTransfer2D() const { return transfer2D.width > 0 && transfer2D.height > 0; }
  // Whether samples need the network's gradient: gradient opacity or a 2D transfer function.
  bool usesGradient() const { return usesGradientOpacity() || usesTransfer2D(); }
  std::string gradientUseName() const { return usesTransfer2D() ? "2D transfer function" : "gradient opacity"; }
  // A 2D transfer function from a JSON file (Docs/transfer-functions.md): `ScalarRange` [lo, hi],
  // `GradientRange` [lo, hi], and either `Width`, `Height` and `RGBA` (width x height x 4 numbers
  // in [0, 1], row 0 the smallest gradient magnitude) or `Image`, an RGBA PNG (a path relative to
  // the JSON file; its bottom row the smallest magnitude, as ParaView's 2D editor draws it).
  // Throws std::runtime_error naming the file and the problem.
  static Transfer2D transfer2DFromJsonFile(const std::string& path);
  std::array<double, 3> colorAt(double x) const;
};

// Host owner of a TransferFunctionView: the sampled table and its range-max levels. Building it
// is the whole cost of a TF edit besides the majorant update.
class TransferFunctionTable {
public:
  // Throws std::invalid_argument naming the point when a point is not finite, or when the gradient
  // opacity's magnitudes do not increase. Opacities and gradient opacity factors are clamped to
  // [0, 1]. A 2D transfer function (TransferFunction::transfer2D) gives the table its own
  // resolution (its columns are the 1D table's entries, `size` is not used); a malformed one
  // (sizes, non-finite pixels or ranges, an empty range) throws naming the problem.
  explicit TransferFunctionTable(const TransferFunction& tf, int size = 1024);
  // The most pixels a 2D transfer function may have.
  static constexpr long long kMaxTransfer2DPixels = 1ll << 22;
  TransferFunctionView view() const;
  float maxOpacity() const { return maxOpacity_; }

  // The gradient opacity function's samples between two nodes with a midpoint or sharpness (a
  // linear segment needs only its nodes), and the most points in all.
  static constexpr int kGradientOpacitySegmentSamples = 256;
  static constexpr int kMaxGradientOpacityPoints = 4096;

private:
  void buildTransfer2D(const TransferFunction& tf);       // the 2D table and its 1D column maxima
  void buildBounds();                                      // from rgba_: range maxima, pre-integration
  void buildGradientOpacity(const TransferFunction& tf);
  std::vector<Vec4f> rgba_;
  std::vector<float> opacityMax_;
  std::vector<float> gradientOpacity_, gradientOpacityX_;  // empty: no gradient opacity
  std::vector<Vec4f> rgba2D_;                                // empty: no 2D transfer function
  int gradientSize_ = 0;
  float gradientLo_ = 0.f, gradientHi_ = 1.f;
  std::vector<float> entryExtinction_;      // pre-integration (TransferFunctionView)
  std::vector<Vec4f> extinctionIntegral_;
  int size_ = 0, levels_ = 0;
  float lo_ = 0.f, hi_ = 1.f, invUnitDistance_ = 1.f, maxOpacity_ = 0.f;
};

// One light of ShadingOptions::lights, as VTK's vtkLight describes it: the direction towards it
// (position minus focal point; any length but zero) and its colours times its intensity. A camera
// light's direction is in camera coordinates (x right, y up, z back towards the viewer: vtkLight's
// camera lights, ParaView's light kit), a scene light's in world coordinates.
struct SceneLight {
  std::array<double, 3> toLight{0.0, 0.0, 1.0};
  bool cameraLight = false;
  std::array<float, 3> ambient{0.f, 0.f, 0.f};  // vtkLight's default: black
  std::array<float, 3> diffuse{1.f, 1.f, 1.f};
  std::array<float, 3> specular{1.f, 1.f, 1.f};
  // Why the engine refuses this light ("direction must be ...", "colours must be ..."), or "".
  std::string problem() const;
  bool operator==(const SceneLight& o) const {
    return toLight == o.toLight && cameraLight == o.cameraLight && ambient == o.ambient && diffuse == o.diffuse &&
           specular == o.specular;
  }
};

// Why the engine refuses a light colour (times its intensity), or "": components in [0, 1e6], so
// that sums over the lights stay finite.
std::string lightColourProblem(const std::array<float, 3>& colour);

// The lights of ParaView's render view by default (5.11: its light kit, vtkLightKit's defaults):
// the kit's headlight, key, fill and two back lights, all camera lights, warm to cool colours.
// What `inr render --shade --light-kit` lights with, to compare with ParaView's own pictures.
std::vector<SceneLight> paraviewLightKit();

// Gradient shading (Render/Shading.h): ParaView's Shade with vtkVolumeProperty's Diffuse,
// Specular and SpecularPower; its Ambient is RenderScene::ambient, shared with shadows. The
// defaults make a sample facing the light keep its colour (ambient 0.2 + diffuse 0.8) with VTK's
// specular highlight (0.2, power 10). headlight: the light sits at the eye, as ParaView's
// headlight (RenderScene::toLight is then not used for shading; shadows still use it).
// oneLightDiffuse / oneLightSpecular: that one light's colours times its intensity (VTK's default
// lighting takes a headlight of intensity 1 whatever its colour). lightList: the lights of
// `lights` (at most kMaxShadingLights; none: the ambient term alone) lit by VTK's light-list
// formula, as VTK lights a volume under ParaView's light kit or any lights but one headlight of
// intensity 1; toLight and headlight are then not used for shading, and shadows are refused (they
// follow the one direction RenderScene::toLight).
struct ShadingOptions {
  bool enabled = false;
  float diffuse = 0.8f;        // >= 0
  float specular = 0.2f;       // >= 0
  float specularPower = 10.f;  // in [0, 128] (vtkVolumeProperty's range)
  bool headlight = false;
  std::array<float, 3> oneLightDiffuse{1.f, 1.f, 1.f}, oneLightSpecular{1.f, 1.f, 1.f};
  bool lightList = false;
  std::vector<SceneLight> lights;
  // Throws std::invalid_argument naming the first option out of its range.
  void validate() const;
  // Whether shading lights along RenderScene::toLight (neither the headlight nor a list).
  bool usesSceneLight() const { return enabled && !headlight && !lightList; }
  bool operator==(const ShadingOptions& o) const {
    return enabled == o.enabled && diffuse == o.diffuse && specular == o.specular &&
           specularPower == o.specularPower && headlight == o.headlight &&
           oneLightDiffuse == o.oneLightDiffuse && oneLightSpecular == o.oneLightSpecular &&
           lightList == o.lightList && lights == o.lights;
  }
  bool operator!=(const ShadingOptions& o) const { return !(*this == o); }
};

// Everything that defines the picture, shared by all renderers. Changing the camera, light,
// background, depth limit or shadow settings restarts accumulation; changing the transfer
// function also recomputes the majorants; changing the time rebuilds the working grid.
struct RenderScene {
  Camera camera;
  TransferFunction transferFunction;
  std::array<float, 3> background{0.f, 0.f, 0.f};
  double time = 0.0;
  // Per-pixel depth limit (row-major, row 0 at the top): world distance along each pixel's world
  // ray (from its origin, unit direction: CameraView's cameraRayWorld) to the first opaque
  // surface. Empty = none.
  std::vector<float> depthLimit;
  bool shadows = false;
  std::array<double, 3> toLight{0.0, 0.0, 1.0};  // world direction towards the directional light
  // The unlit share of the colour: with shadows emission * (ambient + (1 - ambient) * visibility);
  // with shading the ambient term of the lighting (Render/Shading.h).
  float ambient = 0.2f;
  ShadowEstimator shadowEstimator = ShadowEstimator::Delta;
  ShadingOptions shading;
};

// Where the rendered image lies in a larger picture (one tile of a tiled render): the image is
// the window [x, x + width) x [y, y + height) (row 0 at the top) of a fullWidth x fullHeight
// picture. Each pixel's random stream is keyed by its position in the full picture, so tiles
// rendered one by one equal the full picture rendered at once. fullWidth = 0: the image is the
// whole picture. (The camera describes the tile's own view: Camera::windowCenter.)
struct ImageWindow {
  int fullWidth = 0, fullHeight = 0, x = 0, y = 0;
  bool operator==(const ImageWindow& o) const {
    return fullWidth == o.fullWidth && fullHeight == o.fullHeight && x == o.x && y == o.y;
  }
  bool operator!=(const ImageWindow& o) const { return !(*this == o); }
};

// Image-space split over ranks (sub-domain rendering under MPI, `inr render --pixel-share`):
// pixel (x, y) of the full picture belongs to share (x + y) mod count, and an image rendered with
// share `index` traces that share's pixels only. The others stay empty (premultiplied zero, as if
// opaque geometry stood at depth 0), so the shares' premultiplied images add up, in any order, to
// the whole picture. count = 1: every pixel.
struct PixelShare {
  int index = 0, count = 1;
  bool operator==(const PixelShare& o) const { return index == o.index && count == o.count; }
  bool operator!=(const PixelShare& o) const { return !(*this == o); }
};

// Sample-space split over ranks (`inr render --sample-share`): every rank renders the whole
// picture, each its own frames. This share's local frame f is frame f * count + index of one
// renderer (sampleShareFrame) wherever a frame number keys random numbers, so N shares of F
// frames each draw exactly the numbers one renderer draws over N * F frames, and the mean of their
// accumulations (weighted by their frames) is its accumulation at N * F frames up to float
// rounding, while the macrocells and the query reduction do not adapt to the samples (no
// refinement, no budgeting or pruning). With them each share adapts to its own samples: still an
// unbiased estimate, no longer the same numbers. Why samples and not pixels: a frame is a chain of
// latency-bound iterations over the whole image whatever share of its pixels a rank traces, so
// ranks that each trace every pixel of fewer frames scale where pixel shares cannot. count = 1:
// every frame is this renderer's own. Exclusive with PixelShare and bricks.
struct SampleShare {
  int index = 0, count = 1;
  bool operator==(const SampleShare& o) const { return index == o.index && count == o.count; }
  bool operator!=(const SampleShare& o) const { return !(*this == o); }
};

// The single-renderer frame number of `share`'s local frame `local`: the one mapping every
// backend's displayed frames go through (WavefrontRenderer::frameKey, the ray marchers).
inline std::uint32_t sampleShareFrame(const SampleShare& share, std::uint32_t local) {
  return local * std::uint32_t(share.count) + std::uint32_t(share.index);
}

// How many of one renderer's frames 0..total-1 are `share`'s: what share r of N keeps of a
// history of `total` frames, so that the N shares together keep `total`.
inline int sampleShareFrameCount(const SampleShare& share, int total) {
  const int n = (total - share.index + share.count - 1) / share.count;
  return n > 0 ? n : 0;
}

struct RenderSettings {
  int width = 256, height = 256;
  std::uint32_t seed = 1;
  bool pixelJitter = true;  // sub-pixel jitter per frame (antialiasing through accumulation)
  ImageWindow window;
  // Sub-domain rendering (Render/BrickDecomposition.h): with clipToBrick, primary rays are
  // clipped to `brick` (model space, inside the model's box) and the image is this brick's
  // premultiplied RGBA; shadow rays still cross the whole box. Off: the whole box.
  bool clipToBrick = false;
  Box3f brick{};
  PixelShare pixelShare;
  SampleShare sampleShare;
};

// Throws std::invalid_argument naming the setting when a pixel or sample share is out of range
// (count >= 1, 0 <= index < count) or when more than one split (bricks, pixel share, sample
// share) is asked for.
void validateSplit(const RenderSettings& settings);

// The per-frame constants every backend's stages read, from the host scene. `depthLimit` is the
// backend's copy of scene.depthLimit (host or device memory), ignored when the scene has none.
FrameConstants makeFrameConstants(const CameraView& camera, const Box3f& box, const RenderScene& scene,
                                  const RenderSettings& settings, const float* depthLimit, std::uint32_t frame);

// The stages' form of the shading options.
ShadingConstants shadingConstants(const ShadingOptions& shading, const CameraView& camera);
// The shading options (ShadingOptions::validate) and how they combine with shadows; throws
// std::invalid_argument naming the problem. Every renderer's setScene calls it.
void validateLighting(const RenderScene& scene);

inline Vec3f toVec3(const std::array<double, 3>& a) { return Vec3f{float(a[0]), float(a[1]), float(a[2])}; }

// Throws std::invalid_argument naming the problem when `window` does not contain a width x height
// image (fullWidth = 0 is always valid).
void validateImageWindow(const ImageWindow& window, int width, int height);

// A light direction that looks good for most views: from above-left-behind the camera (world).
std::array<double, 3> defaultLightDirection(const Camera& camera);

}  // namespace inr
