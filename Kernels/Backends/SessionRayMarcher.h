#pragma once
// The fixed-step ray marcher (the dense baseline: Render/RayMarch.h) on a session's backend: the
// GPU marcher (CudaRayMarcher) when the session runs on CUDA, the CPU marcher
// (RayMarchRenderer) otherwise. Like RenderSession, callers never name a backend's classes.
#include <memory>
#include <string>

#include "Backends/RenderSession.h"
#include "Render/RayMarcher.h"

namespace inr {

class SessionRayMarcher {
public:
  // The marcher for `session`'s backend over `box` with session.evaluator(); both march shadows
  // and gradient shading.
  static std::unique_ptr<SessionRayMarcher> create(const RenderSession& session, const Box3f& box,
                                                   const RayMarchOptions& options);
  virtual ~SessionRayMarcher() = default;

  virtual std::string description() const = 0;  // which marcher runs where, and why
  virtual bool onGpu() const = 0;
  virtual void setSettings(const RenderSettings& settings) = 0;
  virtual void setScene(const RenderScene& scene) = 0;
  virtual FrameStats renderFrame() = 0;
  virtual ImageRGBA image() const = 0;
  virtual float step() const = 0;
  virtual float shadowStep() const = 0;  // world units, both marchers
};

}  // namespace inr
