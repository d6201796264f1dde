/**
 * @class InrFramebufferCompositor
 * @brief The OpenGL side of vtkInrVolumeMapper (plain C++, not wrapped): reads the depth buffer
 * of the viewport, keeps the engine's image in a float RGBA texture (uploaded only when the image
 * changed) and draws it over the framebuffer with a full-screen quad. The image is premultiplied
 * (volume only), so the blend is ONE / ONE_MINUS_SRC_ALPHA for colour and alpha; depth test and
 * depth writes are off while drawing, and the GL state is restored afterwards.
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
  /// The GL name of the image texture (0 before the first Upload).
  unsigned TextureHandle() const;
  /// Draws the texture over the framebuffer. False (with `error` set) when the shader cannot be
  /// built or nothing was uploaded.
  bool Blend(vtkOpenGLRenderWindow* window, std::string* error = nullptr);

  void ReleaseGraphicsResources(vtkWindow* window);

private:
  std::unique_ptr<vtkOpenGLQuadHelper> Quad;
  vtkSmartPointer<vtkTextureObject> Texture;
  vtkOpenGLRenderWindow* Context = nullptr;  // the window the texture was made for
  int Width = 0, Height = 0;
  int UploadedFrames = -1;
  bool TextureValid = false;
};

#endif
