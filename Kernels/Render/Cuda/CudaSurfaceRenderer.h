#pragma once
// The isosurface and slice blend modes on the GPU: the per-ray code of Render/SurfaceMarch.h (the
// CPU renderer's, unchanged) run by kernels, the queries evaluated through
// CudaInrEvaluator::evaluateDevice. The scene's host side (validation, the transfer function
// table, the candidate macrocells at the time, the per-frame constants) is the CPU renderer's
// (SurfaceRenderer, whose macrocell grid samples the network through the evaluator's host
// interface); this class uploads it and drives the frame:
//   slice: a kernel finds each pixel's plane point and appends it to a dense batch (one query per
//          covered pixel; with shading, value and gradient in one pass), a kernel colours and
//          accumulates every pixel;
//   isosurface: every pixel's SurfaceRay lives on the device; per iteration a kernel emits each
//          ray's samples (counts), a device prefix sum (CUB) places them, a kernel writes the
//          points, the evaluator fills the values, a kernel consumes them and appends the hits
//          that need lighting to a gradient batch, evaluated and composited by a last kernel;
//          the loop ends when no ray emits (one count read back per iteration).
#include <memory>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/RenderStats.h"
#include "Render/SurfaceRenderer.h"

namespace inr {

class CudaInrEvaluator;
class DeviceFieldEvaluator;

class CudaSurfaceRenderer {
public:
  CudaSurfaceRenderer(const CudaInrEvaluator& evaluator, const Box3f& box, double timeBegin, double timeEnd,
                      SurfaceOptions options = {});
  // A field with both interfaces (the macrocells sample it through the host one; tests pass an
  // analytic field).
  CudaSurfaceRenderer(const FieldEvaluator& hostField, const DeviceFieldEvaluator& deviceField, const Box3f& box,
                      double timeBegin, double timeEnd, SurfaceOptions options = {});
  ~CudaSurfaceRenderer();
  void setSettings(const RenderSettings& settings);
  void setScene(const RenderScene& scene, const BlendScene& blend);
  FrameStats renderFrame();
  void resetAccumulation();
  int accumulatedFrames() const { return host_.accumulatedFrames(); }
  bool macrocellsBuiltFor(double time) const { return host_.macrocellsBuiltFor(time); }
  void buildMacrocellsFor(double time) { host_.buildMacrocellsFor(time); }
  ImageRGBA image() const;
  ImageRGBA premultipliedImage() const;
  std::vector<float> surfaceDepth() const;
  float step() const { return host_.step(); }
  float tolerance() const { return host_.tolerance(); }
  const SurfaceRenderer& host() const { return host_; }

private:
  struct Impl;
  FrameStats renderSlice();
  FrameStats renderIsosurface();
  const DeviceFieldEvaluator& evaluator_;
  SurfaceRenderer host_;  // the scene's host side; its own frames are not rendered
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
