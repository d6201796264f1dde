#include "InrCudaGlInterop.h"

#include "Backends/RenderSession.h"

#include <cstdlib>
#include <cstring>
#include <exception>

#ifdef INR_HAVE_CUDA
#include "vtk_glew.h"  // before cuda_gl_interop.h, which includes GL/gl.h

#include <cuda_gl_interop.h>
#include <cuda_runtime.h>
#endif

namespace
{
#ifdef INR_HAVE_CUDA
bool cudaFailed(cudaError_t e, const char* what, std::string* why)
{
  if (e == cudaSuccess)
  {
    return false;
  }
  if (why)
  {
    *why = std::string(what) + ": " + cudaGetErrorString(e);
  }
  return true;
}
#endif
}

bool InrCudaGlInterop::Enabled(std::string* why)
{
#ifdef INR_HAVE_CUDA
  const char* env = std::getenv("INR_CUDA_GL_INTEROP");
  if (env && std::strcmp(env, "0") == 0)
  {
    if (why)
    {
      *why = "INR_CUDA_GL_INTEROP=0 in the environment";
    }
    return false;
  }
  return true;
#else
  if (why)
  {
    *why = "this build has no CUDA";
  }
  return false;
#endif
}

InrCudaGlInterop::~InrCudaGlInterop()
{
  this->Release();
}

void InrCudaGlInterop::Release()
{
#ifdef INR_HAVE_CUDA
  if (this->Resource)
  {
    cudaGraphicsUnregisterResource(this->Resource);  // nothing to do about a failure here
  }
#endif
  this->Resource = nullptr;
  this->Texture = 0;
  this->Width = this->Height = 0;
}

bool InrCudaGlInterop::Copy(
  const inr::RenderSession& session, unsigned texture, int width, int height, std::string* why)
{
  if (!Enabled(why))
  {
    return false;
  }
#ifdef INR_HAVE_CUDA
  if (session.backend() != inr::RenderBackend::Cuda)
  {
    if (why)
    {
      *why = "the image is not on a GPU (CPU backend)";
    }
    return false;
  }
  // A texture of another handle or size has other storage: register it again.
  if (this->Resource && (this->Texture != texture || this->Width != width || this->Height != height))
  {
    this->Release();
  }
  if (!this->Resource)
  {
    if (cudaFailed(cudaGraphicsGLRegisterImage(&this->Resource, texture, GL_TEXTURE_2D,
                     cudaGraphicsRegisterFlagsWriteDiscard),
          "registering the image texture with CUDA (is the OpenGL context on the session's GPU?)",
          why))
    {
      this->Resource = nullptr;
      cudaGetLastError();  // clear the error so that the engine's next check does not see it
      return false;
    }
    this->Texture = texture;
    this->Width = width;
    this->Height = height;
  }
  if (cudaFailed(cudaGraphicsMapResources(1, &this->Resource, nullptr), "mapping the texture", why))
  {
    cudaGetLastError();
    this->Release();
    return false;
  }
  bool copied = false;
  cudaArray_t array = nullptr;
  if (!cudaFailed(cudaGraphicsSubResourceGetMappedArray(&array, this->Resource, 0, 0),
        "the texture's CUDA array", why))
  {
    try
    {
      copied = session.copyPremultipliedImage(array);
      if (!copied && why)
      {
        *why = "the session holds no image on a GPU";
      }
    }
    catch (const std::exception& e)
    {
      if (why)
      {
        *why = std::string("copying the image into the texture: ") + e.what();
      }
    }
  }
  cudaGetLastError();
  cudaGraphicsUnmapResources(1, &this->Resource, nullptr);
  return copied;
#else
  (void)session;
  (void)texture;
  (void)width;
  (void)height;
  return false;
#endif
}
