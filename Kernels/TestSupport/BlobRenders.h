#pragma once
// Renders of the Gaussian blob (TestFields.h: spherical level sets, analytic gradient) by the CPU
// renderers, with what the shading and gradient opacity tests check: the images, the summed
// statistics and how many points the field was asked a gradient for.
#include <cstddef>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "Render/CpuWavefrontRenderer.h"
#include "Render/RayMarcher.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr::test {

struct BlobRender {
  ImageRGBA image, premultiplied;
  FrameStats total;
  std::size_t gradientPoints = 0;
};

// The wavefront renderer with `options` and `reduction` over 8^3 macrocells (2 time slices),
// `frames` frames.
inline BlobRender trackedBlob(const SceneSetup& setup, const TrackingOptions& options, int frames,
                              const QueryReductionSettings& reduction = {}) {
  FunctionField f(blobField, "blob", blobGradient);
  MacrocellGrid grid(f, kCubeBox, 0, 1, cubeMacrocells(8, 2));
  CpuWavefrontRenderer r(f, grid, options);
  r.setQueryReduction(reduction);
  f.resetCounts();
  BlobRender out;
  out.total = renderFrames(r, setup.settings, setup.scene, frames);
  out.image = r.image();
  out.premultiplied = r.premultipliedImage();
  out.gradientPoints = f.gradientPoints();
  return out;
}

// The reference: one ray-marched frame with a fine step (2 / 1024; shadow rays 2 / 256).
inline BlobRender marchedBlob(const SceneSetup& setup) {
  FunctionField f(blobField, "blob", blobGradient);
  RayMarchOptions ro;
  ro.step = 2.f / 1024.f;
  ro.shadowStep = 2.f / 256.f;
  RayMarchRenderer rm(f, kCubeBox, ro);
  BlobRender out;
  out.total = renderFrames(rm, setup.settings, setup.scene, 1);
  out.image = rm.image();
  out.premultiplied = rm.premultipliedImage();
  out.gradientPoints = f.gradientPoints();
  return out;
}

// Both CPU renderers refuse `setup` on the blob without its gradient, naming `what` (the feature
// that needs it) in the message.
inline void expectRefusedWithoutGradient(const SceneSetup& setup, const std::string& what) {
  FunctionField f(blobField);  // no gradient
  MacrocellGrid grid(f, kCubeBox, 0, 1, cubeMacrocells(8, 2));
  CpuWavefrontRenderer r(f, grid);
  RayMarchRenderer rm(f, kCubeBox);
  r.setSettings(setup.settings);
  rm.setSettings(setup.settings);
  for (const bool marcher : {false, true}) {
    try {
      marcher ? rm.setScene(setup.scene) : r.setScene(setup.scene);
      ADD_FAILURE() << (marcher ? "the ray marcher" : "the wavefront renderer") << " accepted " << what
                    << " without gradients";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
}

}  // namespace inr::test
