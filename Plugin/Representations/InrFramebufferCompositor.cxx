#include "InrFramebufferCompositor.h"

#include "vtkOpenGLQuadHelper.h"
#include "vtkOpenGLRenderUtilities.h"
#include "vtkOpenGLRenderWindow.h"
#include "vtkOpenGLShaderCache.h"
#include "vtkOpenGLState.h"
#include "vtkShaderProgram.h"
#include "vtkTextureObject.h"
#include "vtk_glew.h"

namespace
{
// The engine's row 0 is the top of the image, GL's is the bottom.
const char* const kFragmentImpl =
  "  gl_FragData[0] = texture2D(inrImage, vec2(texCoord.x, 1.0 - texCoord.y));\n";
}

InrFramebufferCompositor::InrFramebufferCompositor() = default;
InrFramebufferCompositor::~InrFramebufferCompositor() = default;

void InrFramebufferCompositor::ReadDepth(
  vtkRenderWindow* window, int x0, int y0, int width, int height, std::vector<float>& depth)
{
  depth.resize(std::size_t(width) * std::size_t(height));
  if (auto* glWin = vtkOpenGLRenderWindow::SafeDownCast(window))
  {
    glWin->GetState()->vtkglPixelStorei(GL_PACK_ALIGNMENT, 1);
  }
  glReadPixels(x0, y0, width, height, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
}

bool InrFramebufferCompositor::NeedsUpload(
  vtkOpenGLRenderWindow* window, int width, int height, int frames, bool imageChanged) const
{
  return !this->Texture || !this->TextureValid || this->Context != window ||
    this->Width != width || this->Height != height || this->UploadedFrames != frames ||
    imageChanged;
}

void InrFramebufferCompositor::Upload(vtkOpenGLRenderWindow* window, int width, int height,
  int frames, const float* rgba, bool linear)
{
  if (!this->Texture)
  {
    this->Texture = vtkSmartPointer<vtkTextureObject>::New();
    this->TextureValid = false;
  }
  if (this->Context != window)
  {
    this->TextureValid = false;  // SetContext releases the texture made for another window
    this->Context = window;
  }
  this->Texture->SetContext(window);
  if (this->TextureValid && this->Width == width && this->Height == height)
  {
    if (rgba)
    {
      this->Texture->Bind();
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGBA, GL_FLOAT, rgba);
    }
  }
  else
  {
    this->Texture->Create2DFromRaw(
      width, height, 4, VTK_FLOAT, const_cast<void*>(static_cast<const void*>(rgba)));
    this->Width = width;
    this->Height = height;
    this->TextureValid = true;
  }
  // Applied when the texture is next bound (vtkTextureObject sends modified parameters then).
  const int filter = linear ? vtkTextureObject::Linear : vtkTextureObject::Nearest;
  this->Texture->SetMinificationFilter(filter);
  this->Texture->SetMagnificationFilter(filter);
  this->UploadedFrames = frames;
}

unsigned InrFramebufferCompositor::TextureHandle() const
{
  return this->Texture && this->TextureValid ? this->Texture->GetHandle() : 0u;
}

bool InrFramebufferCompositor::Blend(vtkOpenGLRenderWindow* window, std::string* error)
{
  if (!this->Texture || !this->TextureValid || this->Context != window)
  {
    if (error)
    {
      *error = "INR Volume: no image uploaded for this window.";
    }
    return false;
  }
  vtkOpenGLState* ostate = window->GetState();
  vtkOpenGLState::ScopedglEnableDisable blendSaver(ostate, GL_BLEND);
  vtkOpenGLState::ScopedglEnableDisable depthSaver(ostate, GL_DEPTH_TEST);
  vtkOpenGLState::ScopedglBlendFuncSeparate blendFuncSaver(ostate);
  vtkOpenGLState::ScopedglDepthMask depthMaskSaver(ostate);
  ostate->vtkglEnable(GL_BLEND);
  ostate->vtkglDisable(GL_DEPTH_TEST);
  ostate->vtkglDepthMask(GL_FALSE);
  ostate->vtkglBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);

  if (!this->Quad)
  {
    std::string fs = vtkOpenGLRenderUtilities::GetFullScreenQuadFragmentShaderTemplate();
    vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Decl", "uniform sampler2D inrImage;\n");
    vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Impl", kFragmentImpl);
    this->Quad = std::make_unique<vtkOpenGLQuadHelper>(
      window, vtkOpenGLRenderUtilities::GetFullScreenQuadVertexShader().c_str(), fs.c_str(), "");
  }
  else
  {
    window->GetShaderCache()->ReadyShaderProgram(this->Quad->Program);
  }
  if (!this->Quad->Program || !this->Quad->Program->GetCompiled())
  {
    if (error)
    {
      *error = "INR Volume: could not build the compositing shader.";
    }
    return false;
  }
  this->Texture->Activate();
  this->Quad->Program->SetUniformi("inrImage", this->Texture->GetTextureUnit());
  this->Quad->Render();
  this->Texture->Deactivate();
  return true;
}

void InrFramebufferCompositor::ReleaseGraphicsResources(vtkWindow* window)
{
  if (this->Quad)
  {
    this->Quad->ReleaseGraphicsResources(window);
    this->Quad.reset();
  }
  if (this->Texture)
  {
    this->Texture->ReleaseGraphicsResources(window);
    this->Texture = nullptr;
  }
  this->TextureValid = false;
  this->Context = nullptr;
}
