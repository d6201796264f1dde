#pragma once
// `inr render`'s command line as a plain value: parseRenderJob reads and checks every option
// (a bad value is a UsageError naming the option) before any model is loaded; runRenderJob
// (CmdRender.cpp) loads the model and renders. Defaults that depend on the model (time, camera,
// transfer function, temporal slices, opacity unit distance, light) stay empty here and are
// filled in by the runner.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Render/BrickDecomposition.h"
#include "Render/QueryReduction.h"
#include "Render/RayMarcher.h"
#include "Render/RayState.h"
#include "Render/SceneInputs.h"
#include "Render/SurfaceRenderer.h"
#include "Render/WavefrontRenderer.h"

namespace inr::cli {

enum class RenderMethod { Delta, RayMarch, Naive };
const char* renderMethodName(RenderMethod method);

// Sub-domain rendering: one brick of the box, one interleaved share of the pixels, or one share
// of the frames (every pixel).
enum class SplitKind { None, Brick, PixelShare, SampleShare };
// "bricks", "pixels", "samples" (the .brick.json's and the statistics' split), "none".
const char* splitKindName(SplitKind split);

struct RenderJob {
  bool help = false;  // --help: print the usage, nothing else is read
  std::string model;
  std::string output;  // .png / .pfm, or .npy with a split
  std::string statsJson;  // empty: none
  bool quiet = false;
  RenderMethod method = RenderMethod::Delta;

  SplitKind split = SplitKind::None;
  BrickIndex splitIndex;  // with a split: which part of how many

  // Image: size, seed (already varied per brick), jitter, pixel or sample share.
  RenderSettings settings;
  long frames = 64;  // with --converge: the most frames
  double convergeTarget = 0.0;  // > 0: stop at this estimated PSNR (dB)
  int threads = 0;  // 0: OpenMP's default

  RenderSessionOptions session;  // backend, traversal, macrocells, tracking (estimator); no progress
  std::optional<int> timeSlices;  // empty: the macrocell default, or 1 for a model without time
  int ghostPasses = 0;
  QueryReductionSettings queryReduction;
  RayMarchOptions rayMarch;

  // Scene: empty optionals take the model's defaults.
  std::optional<double> time;  // default: the start of the model's time range
  std::optional<Camera> camera;  // --camera; default: Camera::framing of the model's box
  std::optional<double> parallelScale;
  std::string transferFunctionFile;  // empty: a preset over the model's value range
  std::optional<std::array<double, 2>> transferFunctionRange;
  // --gradient-opacity G,A,...: gradient opacity nodes (|grad f|, factor), increasing magnitudes;
  // empty: off (TransferFunction::gradientOpacity).
  std::vector<TransferFunction::OpacityPoint> gradientOpacity;
  // --tf2d FILE: a 2D transfer function (TransferFunction::transfer2DFromJsonFile); empty: none.
  std::string transfer2DFile;
  std::optional<double> opacityUnitDistance;  // default: box diagonal / 64
  std::array<float, 3> background{0.f, 0.f, 0.f};
  bool shadows = false;
  std::optional<std::array<double, 3>> toLight;  // default: defaultLightDirection(camera)
  float ambient = 0.2f;  // shadows' and shading's one ambient (Render/Shading.h)
  ShadowEstimator shadowEstimator = ShadowEstimator::Delta;
  ShadingOptions shading;  // --shade, --diffuse, --specular, --specular-power, --light-kit (headlight: the runner)

  // --blend and its options: the mode, --iso, --slice-origin / --slice-normal / --slice-opaque and
  // --crop (for every mode; composite clips its camera rays as a brick does: settings.clipToBrick).
  BlendScene blend;
  bool sliceOriginGiven = false;  // default: the model box's centre (the runner)
  SurfaceOptions surface;         // --iso-step, --iso-tolerance
  bool surfaceBlend() const { return blend.mode != BlendMode::Composite; }

  bool splitIntoBricks() const { return split == SplitKind::Brick; }
  bool writesNpy() const { return split != SplitKind::None; }
  const char* splitOption() const {
    return split == SplitKind::PixelShare ? "--pixel-share" : split == SplitKind::SampleShare ? "--sample-share" : "--brick";
  }
};

// The arguments after `inr render`. Throws UsageError (Args.h) naming the option at fault.
RenderJob parseRenderJob(const std::vector<std::string>& args);

// Loads the model and renders the job (CmdRender.cpp); the process exit code. Usage errors that
// need the model (a brick split finer than the macrocells) throw UsageError here.
int runRenderJob(const RenderJob& job);

// The text `inr render --help` prints (the defaults from the engine's option structs).
std::string renderUsage();

}  // namespace inr::cli
