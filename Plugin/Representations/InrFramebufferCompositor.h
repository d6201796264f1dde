/**
 * @class InrFramebufferCompositor
 * @brief The OpenGL side of vtkInrVolumeMapper (plain C++, not wrapped): reads the depth buffer
 * of the viewport, keeps the engine's image in a float RGBA texture (uploaded only when the image
 * changed) and draws it over the framebuffer with a full-screen quad. The image is premultiplied
 * (volume only), so the blend is ONE / ONE_MINUS_SRC_ALPHA for colour and alpha; depth test and
 * depth writes are off while drawing, and the GL state is restored afterwards. The isosurface and
 * slice blend modes also write their depth where they are opaque (UploadDepth, then Blend with
 * `writeDepth`), as opaque geometry does: a second full-screen pass with colour writes off.
 */
#ifndef InrFramebufferCompositor_h
#define InrFramebufferCompositor_h

#include "vtkSmartPointer.h"

#include <memory>
#include <string>
#include <vector>

class vtkOpenGLQuadHelper;
class vtkOpenGLRenderWindow;
class vtkRenderWindow;
class vtkTextureObject;
class vtkWindow;

class InrFramebufferCompositor
{
public:
  InrFramebufferCompositor();
  ~InrFramebufferCompositor();
  InrFramebufferCompositor(const InrFramebufferCompositor&) = delete;
  InrFramebufferCompositor& operator=(const InrFramebufferCompositor&) = delete;

  /// The window depth values of the viewport (x0, y0, width, height), GL row order (row 0 at the
  /// bottom), into `depth` (resized to width * height).
  static void ReadDepth(
    vtkRenderWindow* window, int x0, int y0, int width, int height, std::vector<float>& depth);

  /// Whether the texture must be (re)loaded before drawing: no valid texture for this window, a
  /// new size, a different frame count than the one uploaded, or `imageChanged` (frames were
  /// rendered since the last upload).
  bool NeedsUpload(vtkOpenGLRenderWindow* window, int width, int height, int frames,
    bool imageChanged) const;
  /// Loads width * height premultiplied RGBA floats (row 0 at the top) holding `frames` frames.
  /// `linear`: the image is smaller than the viewport (a level-of-detail frame) and is magnified
  /// with linear filtering; otherwise each pixel maps to one texel (nearest). `rgba` null: only
  /// makes the texture (RGBA 32-bit float, that size) for a device copy into TextureHandle().
  void Upload(vtkOpenGLRenderWindow* window, int width, int height, int frames, const float* rgba,
    bool linear = false);
  /// Whether the texture exists for `window` at this size (an Upload then keeps its storage).
  bool Fits(vtkOpenGLRenderWindow* window, int width, int height) const
  {
    return this->TextureValid && this->Context == window && this->Width == width &&
      this->Height == height;
  }
  /// Window depth values (0 near .. 1 far, row 0 at the top, the size of the last Upload) to
  /// write where the image is opaque; 1 or more where nothing is to be written.
  void UploadDepth(vtkOpenGLRenderWindow* window, int width, int height, const float* depth);
  /// The window depth values of an image of `width` x `height` pixels (engine order, row 0 at
  /// the top): for each pixel whose premultiplied alpha (`rgba`, 4 floats a pixel) is at least
  /// `opaqueAlpha` and whose ray distance `distance` is finite, the depth of the point that far
  /// along the pixel's ray (from `eye` through the pixel centre; parallel: along `direction`,
  /// the distance measured along it from the eye's plane), through `projection` (world to
  /// normalised device coordinates, the matrix whose inverse InrSceneTranslator::
  /// DepthToRayDistances unprojects with); 1 (nothing written) elsewhere. The inverse of that
  /// function on the pixels it covers.
  static std::vector<float> RayDistancesToDepth(const float* distance, const float* rgba,
    int width, int height, float opaqueAlpha, const double projection[16],
    const double eye[3], const double direction[3], bool parallel);
  /// The GL name of the image texture (0 before the first Upload).
  unsigned TextureHandle() const;
  /// Draws the texture over the framebuffer; with `writeDepth`, then writes the depth of
  /// UploadDepth where it is below 1 and nearer than the depth buffer's. False (with `error`
  /// set) when a shader cannot be built or nothing was uploaded.
  bool Blend(vtkOpenGLRenderWindow* window, std::string* error = nullptr, bool writeDepth = false);

  void ReleaseGraphicsResources(vtkWindow* window);

private:
  std::unique_ptr<vtkOpenGLQuadHelper> Quad;
  std::unique_ptr<vtkOpenGLQuadHelper> DepthQuad;
  vtkSmartPointer<vtkTextureObject> Texture;
  vtkSmartPointer<vtkTextureObject> DepthTexture;
  int DepthWidth = 0, DepthHeight = 0;
  bool DepthValid = false;
  vtkOpenGLRenderWindow* Context = nullptr;  // the window the texture was made for
  int Width = 0, Height = 0;
  int UploadedFrames = -1;
  bool TextureValid = false;
};

#endif
