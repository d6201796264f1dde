#include "InrFramebufferCompositor.h"

#include "vtkMatrix4x4.h"
#include "vtkOpenGLQuadHelper.h"
#include "vtkOpenGLRenderUtilities.h"
#include "vtkOpenGLRenderWindow.h"
#include "vtkOpenGLShaderCache.h"
#include "vtkOpenGLState.h"
#include "vtkShaderProgram.h"
#include "vtkTextureObject.h"
#include "vtk_glew.h"

#include <cmath>

namespace
{
// The engine's row 0 is the top of the image, GL's is the bottom.
const char* const kFragmentImpl =
  "  gl_FragData[0] = texture2D(inrImage, vec2(texCoord.x, 1.0 - texCoord.y));\n";
// The depth pass: colour writes are off; pixels with nothing to write (depth 1) are discarded.
const char* const kDepthFragmentImpl =
  "  float d = texture2D(inrDepth, vec2(texCoord.x, 1.0 - texCoord.y)).r;\n"
  "  if (d >= 1.0) { discard; }\n"
  "  gl_FragDepth = d;\n"
  "  gl_FragData[0] = vec4(0.0);\n";

std::unique_ptr<vtkOpenGLQuadHelper> makeQuad(
  vtkOpenGLRenderWindow* window, const char* sampler, const char* impl)
{
  std::string fs = vtkOpenGLRenderUtilities::GetFullScreenQuadFragmentShaderTemplate();
  vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Decl", std::string("uniform sampler2D ") + sampler + ";\n");
  vtkShaderProgram::Substitute(fs, "//VTK::FSQ::Impl", impl);
  return std::make_unique<vtkOpenGLQuadHelper>(
    window, vtkOpenGLRenderUtilities::GetFullScreenQuadVertexShader().c_str(), fs.c_str(), "");
}

// Builds `quad` on first use, else makes its program current; whether it can draw.
bool readyQuad(std::unique_ptr<vtkOpenGLQuadHelper>& quad, vtkOpenGLRenderWindow* window,
  const char* sampler, const char* impl)
{
  if (!quad)
  {
    quad = makeQuad(window, sampler, impl);
  }
  else
  {
    window->GetShaderCache()->ReadyShaderProgram(quad->Program);
  }
  return quad->Program && quad->Program->GetCompiled();
}
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

void InrFramebufferCompositor::UploadDepth(
  vtkOpenGLRenderWindow* window, int width, int height, const float* depth)
{
  if (!this->DepthTexture)
  {
    this->DepthTexture = vtkSmartPointer<vtkTextureObject>::New();
    this->DepthValid = false;
  }
  if (this->DepthTexture->GetContext() != window)
  {
    this->DepthValid = false;  // SetContext releases the texture made for another window
  }
  this->DepthTexture->SetContext(window);
  if (this->DepthValid && this->DepthWidth == width && this->DepthHeight == height)
  {
    this->DepthTexture->Bind();
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RED, GL_FLOAT, depth);
  }
  else
  {
    this->DepthTexture->Create2DFromRaw(
      width, height, 1, VTK_FLOAT, const_cast<void*>(static_cast<const void*>(depth)));
    this->DepthWidth = width;
    this->DepthHeight = height;
  }
  // Depth is not filtered: a magnified (level-of-detail) image writes each texel's own depth.
  this->DepthTexture->SetMinificationFilter(vtkTextureObject::Nearest);
  this->DepthTexture->SetMagnificationFilter(vtkTextureObject::Nearest);
  this->DepthValid = true;
}

std::vector<float> InrFramebufferCompositor::RayDistancesToDepth(const float* distance,
  const float* rgba, int width, int height, float opaqueAlpha, const double m[16],
  const double eye[3], const double fwd[3], bool parallel)
{
  std::vector<float> depth(std::size_t(width) * std::size_t(height), 1.0f);
  double inverse[16];
  vtkMatrix4x4::Invert(m, inverse);
  for (int row = 0; row < height; ++row)  // engine row (0 = top)
  {
    const int j = height - 1 - row;  // GL row (0 = bottom)
    const double ny = 2.0 * (j + 0.5) / height - 1.0;
    for (int i = 0; i < width; ++i)
    {
      const std::size_t k = std::size_t(row) * width + i;
      const float dist = distance[k];
      if (!(rgba[4 * k + 3] >= opaqueAlpha) || !std::isfinite(dist))
      {
        continue;
      }
      // The pixel centre on the near plane, and the point `dist` along its ray.
      const double nx = 2.0 * (i + 0.5) / width - 1.0;
      double q[4];
      for (int r = 0; r < 4; ++r)
      {
        q[r] = inverse[4 * r] * nx + inverse[4 * r + 1] * ny - inverse[4 * r + 2] + inverse[4 * r + 3];
      }
      if (q[3] == 0.0)
      {
        continue;
      }
      const double nearPoint[3] = { q[0] / q[3], q[1] / q[3], q[2] / q[3] };
      double p[3];
      if (parallel)
      {
        const double along = (nearPoint[0] - eye[0]) * fwd[0] + (nearPoint[1] - eye[1]) * fwd[1] +
          (nearPoint[2] - eye[2]) * fwd[2];
        for (int a = 0; a < 3; ++a)
        {
          p[a] = nearPoint[a] + (dist - along) * fwd[a];
        }
      }
      else
      {
        const double d[3] = { nearPoint[0] - eye[0], nearPoint[1] - eye[1], nearPoint[2] - eye[2] };
        const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 0.0))
        {
          continue;
        }
        for (int a = 0; a < 3; ++a)
        {
          p[a] = eye[a] + dist * d[a] / len;
        }
      }
      const double z = m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11];
      const double w = m[12] * p[0] + m[13] * p[1] + m[14] * p[2] + m[15];
      if (!(w != 0.0))
      {
        continue;
      }
      const double windowDepth = 0.5 * (z / w) + 0.5;
      if (windowDepth >= 0.0 && windowDepth < 1.0)
      {
        depth[k] = float(windowDepth);
      }
    }
  }
  return depth;
}

unsigned InrFramebufferCompositor::TextureHandle() const
{
  return this->Texture && this->TextureValid ? this->Texture->GetHandle() : 0u;
}

bool InrFramebufferCompositor::Blend(
  vtkOpenGLRenderWindow* window, std::string* error, bool writeDepth)
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
  vtkOpenGLState::ScopedglDepthFunc depthFuncSaver(ostate);
  vtkOpenGLState::ScopedglColorMask colorMaskSaver(ostate);
  ostate->vtkglEnable(GL_BLEND);
  ostate->vtkglDisable(GL_DEPTH_TEST);
  ostate->vtkglDepthMask(GL_FALSE);
  ostate->vtkglBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);

  if (!readyQuad(this->Quad, window, "inrImage", kFragmentImpl))
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

  if (!writeDepth || !this->DepthTexture || !this->DepthValid ||
    this->DepthTexture->GetContext() != window)
  {
    return true;
  }
  // The depth pass: only the depth buffer changes, where the surface is nearer than what it has
  // (the surfaces already stop at opaque geometry's depth; GL_LESS keeps that exact).
  ostate->vtkglDisable(GL_BLEND);
  ostate->vtkglEnable(GL_DEPTH_TEST);
  ostate->vtkglDepthFunc(GL_LESS);
  ostate->vtkglDepthMask(GL_TRUE);
  ostate->vtkglColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  if (!readyQuad(this->DepthQuad, window, "inrDepth", kDepthFragmentImpl))
  {
    if (error)
    {
      *error = "INR Volume: could not build the depth shader.";
    }
    return false;
  }
  this->DepthTexture->Activate();
  this->DepthQuad->Program->SetUniformi("inrDepth", this->DepthTexture->GetTextureUnit());
  this->DepthQuad->Render();
  this->DepthTexture->Deactivate();
  return true;
}

void InrFramebufferCompositor::ReleaseGraphicsResources(vtkWindow* window)
{
  if (this->Quad)
  {
    this->Quad->ReleaseGraphicsResources(window);
    this->Quad.reset();
  }
  if (this->DepthQuad)
  {
    this->DepthQuad->ReleaseGraphicsResources(window);
    this->DepthQuad.reset();
  }
  if (this->Texture)
  {
    this->Texture->ReleaseGraphicsResources(window);
    this->Texture = nullptr;
  }
  if (this->DepthTexture)
  {
    this->DepthTexture->ReleaseGraphicsResources(window);
    this->DepthTexture = nullptr;
  }
  this->TextureValid = false;
  this->DepthValid = false;
  this->Context = nullptr;
}
