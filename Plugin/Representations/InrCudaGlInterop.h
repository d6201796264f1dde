/**
 * @class InrCudaGlInterop
 * @brief The CUDA backend's image into the compositor's OpenGL texture without a trip through
 * host memory (CUDA-OpenGL interop): the texture is registered with CUDA once per texture and
 * size, mapped for each new image, and the engine copies its accumulation into it device to
 * device (inr::RenderSession::copyPremultipliedImage). Plain C++, not wrapped.
 *
 * Where interop is not possible (a build without CUDA, the CPU backend, a GL context that is not
 * on the session's GPU, e.g. Mesa or another card), Copy() says why and the mapper uploads from
 * host memory as before; INR_CUDA_GL_INTEROP=0 in the environment forces that path (for
 * comparisons, or as a workaround).
 */
#ifndef InrCudaGlInterop_h
#define InrCudaGlInterop_h

#include <string>

struct cudaGraphicsResource;

namespace inr
{
class RenderSession;
}

class InrCudaGlInterop
{
public:
  InrCudaGlInterop() = default;
  ~InrCudaGlInterop();
  InrCudaGlInterop(const InrCudaGlInterop&) = delete;
  InrCudaGlInterop& operator=(const InrCudaGlInterop&) = delete;

  /// Whether this build and the environment allow interop at all (false: `why` says why).
  static bool Enabled(std::string* why = nullptr);

  /// Copies the session's premultiplied image (width x height) into the GL texture `texture`
  /// (GL_TEXTURE_2D, RGBA 32-bit float, that size), with the texture's GL context current.
  /// False (and `why` set) when it could not: nothing was copied; the caller uploads instead.
  bool Copy(const inr::RenderSession& session, unsigned texture, int width, int height,
    std::string* why);

  /// Unregisters the texture (call before the texture or its context goes).
  void Release();

private:
  cudaGraphicsResource* Resource = nullptr;
  unsigned Texture = 0;
  int Width = 0, Height = 0;
};

#endif
