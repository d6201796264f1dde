/**
 * @class InrSceneTranslator
 * @brief VTK -> engine scene translation for vtkInrVolumeMapper (plain C++, not wrapped).
 *
 * Each piece works alone, without a render window:
 *  - camera: vtkCamera -> inr::Camera (a horizontal view angle becomes the vertical one; the
 *    window centre, which tiled rendering shifts per tile); the volume's matrix (position,
 *    orientation, scale, origin, user matrix / transform) -> Camera::modelToWorld; the camera
 *    features the engine does not reproduce (stereo, off-axis or explicit projections, camera
 *    user/model transforms), named for a warning;
 *  - tiles: where the renderer's part of the current tile lies in the full picture (tile scale
 *    and tile viewport: screenshots larger than the view, tile-display mode) -> ImageWindow;
 *  - depth: depth-buffer values -> per-pixel world distances along each pixel's ray (the engine's
 *    RenderScene::depthLimit), a pure function of the depth values, the inverse composite
 *    projection matrix, the eye, the direction of projection and the image size;
 *  - field data: the model's value range ("InrValueRange") and the time ("InrTime", else the
 *    data's DATA_TIME_STEP);
 *  - transfer function: vtkVolumeProperty -> inr::TransferFunction (the colour function sampled
 *    at 256 points so every VTK colour space and log scale is reproduced by the engine's RGB
 *    interpolation; the scalar-opacity nodes with midpoint/sharpness; the scalar opacity unit
 *    distance), or the engine's default TF over the value range; UpdateTransferFunction converts
 *    only when its inputs changed (modification times, value range, default or not);
 *  - shading: vtkVolumeProperty's Shade, Ambient, Diffuse, Specular, SpecularPower (ParaView's
 *    representation properties of those names) -> inr::RenderScene::shading and its ambient.
 */
#ifndef InrSceneTranslator_h
#define InrSceneTranslator_h

#include "vtkType.h"

#include "Render/SceneInputs.h"

#include <array>
#include <string>
#include <vector>

class vtkCamera;
class vtkDataSet;
class vtkFieldData;
class vtkProp3D;
class vtkRenderWindow;
class vtkRenderer;
class vtkVolumeProperty;

class InrSceneTranslator
{
public:
  /// Samples of the colour function (over its range; 1 when the range is empty).
  static constexpr int ColorSamples = 256;

  ///@{
  /// Camera. VerticalViewAngle: the vertical angle (degrees) of a view whose horizontal angle is
  /// `horizontalDegrees`, for an image of aspect width / height.
  static double VerticalViewAngle(double horizontalDegrees, double aspect);
  /// With an explicit projection matrix (ParaView's IceT compositing sets one on every parallel
  /// or tile-display render: a tile's frustum), the view angle / parallel scale and the window
  /// centre come from that matrix when it is a plain frustum or box (ProjectionToCamera).
  static inr::Camera TranslateCamera(vtkCamera* camera, int width, int height);
  /// A projection matrix (row-major, acting on column vectors) of the form VTK's Frustum / Ortho
  /// build: sets `camera`'s projection type, vertical view angle or parallel scale and window
  /// centre. False (camera untouched) when the matrix has any other form (stereo shear,
  /// off-axis, rotation) or its horizontal extent does not match the image aspect width / height.
  static bool ProjectionToCamera(const double projection[16], int width, int height, inr::Camera& camera);
  /// The prop's model-to-world matrix (vtkProp3D::GetMatrix), row-major.
  static std::array<double, 16> ModelToWorld(vtkProp3D* prop);
  /// The camera / window features that the engine's camera does not reproduce, as a readable
  /// list ("" when none): stereo (the volume is drawn for the centre eye), off-axis projection,
  /// an explicit projection matrix that ProjectionToCamera cannot follow, a camera user transform
  /// or model transform matrix.
  static std::string UnsupportedCameraFeatures(
    vtkCamera* camera, vtkRenderWindow* window, int width, int height);
  ///@}

  ///@{
  /// Tiled rendering. The renderer's viewport (normalized, of the whole picture), the window's
  /// tile viewport, the window's size including the tile scale (vtkWindow::GetSize) and the size
  /// of the renderer's part of the current tile (vtkViewport::GetTiledSizeAndOrigin): where that
  /// part lies in the renderer's full picture (rows from the top). The whole-picture window
  /// (fullWidth 0) when the tile is the whole picture or the numbers do not fit together.
  static inr::ImageWindow TileWindow(const double viewport[4], const double tileViewport[4],
    const int tiledWindowSize[2], int tileWidth, int tileHeight);
  ///@}

  ///@{
  /// Depth buffer -> ray distances. `depth`: width * height window depth values in [0, 1], GL
  /// row order (row 0 at the bottom). `inverseProjection`: the inverse of the camera's composite
  /// projection matrix (aspect width / height, z range [-1, 1]), row-major, acting on column
  /// vectors (vtkMatrix4x4::GetData of the inverted matrix). Returns the distances in the
  /// engine's row order (row 0 at the top): Euclidean distance from the eye (perspective) or
  /// distance along `direction` (parallel, unit length) to the unprojected pixel centre;
  /// FLT_MAX where the depth is 1 (nothing drawn). Empty when no pixel has a depth below 1.
  static std::vector<float> DepthToRayDistances(const float* depth, int width, int height,
    const double inverseProjection[16], const double eye[3], const double direction[3],
    bool parallel);
  /// The same with the matrix, eye and direction taken from `camera`.
  static std::vector<float> DepthToRayDistances(
    const std::vector<float>& depth, int width, int height, vtkCamera* camera);
  ///@}

  ///@{
  /// Field data. ValueRange: "InrValueRange" (2 tuples), else [0, 1]. Time: "InrTime" when the
  /// field data has it (its first value; `fallback` when empty), else the data's
  /// DATA_TIME_STEP, else `fallback`.
  static void ValueRange(vtkFieldData* fieldData, double range[2]);
  static double Time(vtkDataSet* input, double fallback);
  ///@}

  ///@{
  /// Transfer function. SampleTransferFunction: the property's colour function (component 0)
  /// sampled at ColorSamples points over its range (the value range when it has no nodes), its
  /// opacity nodes (a zero opacity over the colour range when it has none), its unit distance.
  /// DefaultTransferFunction: the engine's preset over the value range with the given unit
  /// distance.
  static inr::TransferFunction SampleTransferFunction(
    vtkVolumeProperty* property, const double valueRange[2]);
  /// The property's gradient opacity nodes (|grad f|, factor): none where it is disabled, unset
  /// or 1 everywhere (VTK's default). UpdateTransferFunction adds them to either TF.
  static std::vector<inr::TransferFunction::OpacityPoint> GradientOpacity(vtkVolumeProperty* prop);
  static inr::TransferFunction DefaultTransferFunction(
    const double valueRange[2], double unitDistance);
  /// The property's 2D transfer function (vtkVolumeProperty::TF_2D, ParaView's Use Transfer2D):
  /// its image (GetTransferFunction2D: RGBA, one value per pixel) over the image's own extent,
  /// origin + [0, dimensions] x spacing (vtkPVTransferFunction2D's Range), x the value and y the
  /// gradient magnitude |grad f|. None (width 0) when the property is in another mode; also when
  /// the image is missing or unusable, `problem` then says why (else it is cleared). The y axis is
  /// always the gradient magnitude: the network has no second array (Use Gradient For Transfer2D
  /// off falls back to it, as VTK's mapper does where the array is missing).
  static inr::TransferFunction::Transfer2D Transfer2D(vtkVolumeProperty* property, std::string& problem);
  /// Cached: the default TF when `useDefault` or there is no property (unit distance 1 then),
  /// else the sampled one; converts again only when the inputs changed.
  const inr::TransferFunction& UpdateTransferFunction(
    vtkVolumeProperty* property, bool useDefault, const double valueRange[2]);
  const inr::TransferFunction& GetTransferFunction() const { return this->TF; }
  /// Why the property's 2D transfer function was left out at the last UpdateTransferFunction
  /// (Transfer2D), or "".
  const std::string& GetTransfer2DProblem() const { return this->Transfer2DProblem; }
  /// How many times UpdateTransferFunction converted (cache misses).
  int GetTransferFunctionConversions() const { return this->Conversions; }
  ///@}

  ///@{
  /// Shading. The property's Shade, Diffuse, Specular and SpecularPower (component 0) become
  /// scene.shading; with Shade on its Ambient becomes scene.ambient, the engine's one ambient
  /// (shadows included), as vtkVolumeProperty has one. `viewLights`: the renderer whose lights
  /// light the volume, as VTK's GPU ray-cast mapper takes them (its switched-on lights; one
  /// headlight of intensity 1 is VTK's default lighting, with its colour; anything else its
  /// light-list lighting: ParaView's light kit, additional lights; a positional light counts as
  /// directional, along its axis); null: the one light of scene.toLight. Shade off or no
  /// property: shading off, scene.ambient untouched. Returns how many switched-on lights were
  /// left out: beyond inr::kMaxShadingLights, or refused by the engine (no direction, a negative
  /// or huge intensity).
  static int TranslateShading(vtkVolumeProperty* property, vtkRenderer* viewLights, inr::RenderScene& scene);
  ///@}

private:
  inr::TransferFunction TF;
  int Conversions = 0;
  int CachedDefault = -1;  // -1 nothing yet, 1 default, 0 sampled
  double CachedRange[2] = { 0, 0 };
  double CachedUnitDistance = 0;
  vtkMTimeType ColorTime = 0, OpacityTime = 0, PropertyTime = 0;
  // The 2D transfer function, converted again only when its image or the property changed.
  inr::TransferFunction::Transfer2D Cached2D;
  std::string Transfer2DProblem;
  const void* Image2D = nullptr;
  vtkMTimeType Image2DTime = 0, Property2DTime = 0;
};

#endif
