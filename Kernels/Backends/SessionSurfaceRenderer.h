#pragma once
// The isosurface and slice blend modes (Render/SurfaceRenderer.h) on a session's backend, so the
// CLI and the plugin reach them without naming a backend's classes (as SessionRayMarcher does for
// the ray marcher): on a CUDA session the GPU renderer (Render/Cuda/CudaSurfaceRenderer.h), else
// the CPU one (Render/SurfaceRenderer.h); description() says which.
#include <memory>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Render/SurfaceRenderer.h"

namespace inr {

class SessionSurfaceRenderer {
public:
  // The renderer for `session`'s backend over `box` (model space) and the time range
  // [timeBegin, timeEnd] (its candidate macrocells'), with session.evaluator().
  static std::unique_ptr<SessionSurfaceRenderer> create(const RenderSession& session, const Box3f& box,
                                                        double timeBegin, double timeEnd,
                                                        const SurfaceOptions& options = {});
  virtual ~SessionSurfaceRenderer() = default;

  virtual std::string description() const = 0;  // which renderer runs where
  virtual bool onGpu() const = 0;               // the per-ray code runs on the GPU
  virtual void setSettings(const RenderSettings& settings) = 0;
  virtual void setScene(const RenderScene& scene, const BlendScene& blend) = 0;
  virtual FrameStats renderFrame() = 0;
  // The frame in parts within a time budget (SurfaceRenderer::renderFramePart): true once it is
  // complete. The GPU renderer draws a whole frame per call (its frames take milliseconds).
  virtual bool renderFramePart(double budgetMs, FrameStats* stats) = 0;
  virtual double frameProgress() const = 0;  // the share of the frame in progress rendered
  // The isosurface's candidate macrocells at `time`: built (setScene then builds nothing), and
  // their build alone (SurfaceRenderer::buildMacrocellsFor).
  virtual bool macrocellsBuiltFor(double time) const = 0;
  virtual void buildMacrocellsFor(double time) = 0;
  virtual void resetAccumulation() = 0;
  virtual int accumulatedFrames() const = 0;
  virtual ImageRGBA image() const = 0;
  virtual ImageRGBA premultipliedImage() const = 0;
  virtual std::vector<float> surfaceDepth() const = 0;  // world distance per pixel, INFINITY: none
  virtual float step() const = 0;       // the isosurface march's step (model units)
  virtual float tolerance() const = 0;  // a hit's largest distance from a crossing (model units)
  // The candidate macrocells' grid as built (slices, lattice queries, seconds); zero before the
  // first isosurface scene.
  virtual MacrocellBuildStats macrocellBuildStats() const = 0;
};

}  // namespace inr
