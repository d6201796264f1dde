#include "Render/WavefrontRenderer.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <string>

#include "Render/AccumulationImage.h"
#include "Common/Stopwatch.h"

namespace inr {

const char* primaryEstimatorName(PrimaryEstimator e) {
  switch (e) {
    case PrimaryEstimator::Ratio: return "ratio";
    case PrimaryEstimator::March: return "march";
    case PrimaryEstimator::Preintegrated: return "preintegrated";
    case PrimaryEstimator::Debiased: return "debiased";
    default: return "delta";
  }
}

PrimaryEstimator parsePrimaryEstimator(const std::string& name) {
  if (name == "delta") return PrimaryEstimator::Delta;
  if (name == "ratio") return PrimaryEstimator::Ratio;
  if (name == "march") return PrimaryEstimator::March;
  if (name == "preintegrated") return PrimaryEstimator::Preintegrated;
  if (name == "debiased") return PrimaryEstimator::Debiased;
  throw std::invalid_argument("estimator must be delta, ratio, march, preintegrated or debiased, got '" + name + "'");
}

std::uint32_t rngDrawBudget(int maxCollisionsPerRay) {
  const std::uint64_t k = std::uint64_t(std::max(1, maxCollisionsPerRay));
  return std::uint32_t(std::min<std::uint64_t>(0xffffffffu, 2 + 2 * k + 32));
}

void TrackingOptions::validate() const {
  if (maxCollisionsPerRay < 1) throw std::invalid_argument("maxCollisionsPerRay must be >= 1");
  if (maxIterations < 1) throw std::invalid_argument("maxIterations must be >= 1");
  if (jitterControlFrames < 0 || jitterControlFrames > kMaxJitterControlFrames)
    throw std::invalid_argument("jitter control frames must be in [0, " + std::to_string(kMaxJitterControlFrames) +
                                "], got " + std::to_string(jitterControlFrames));
  if (ghostPassesOnUpdate < 0 || ghostPassesOnUpdate > kMaxGhostPasses) {
    throw std::invalid_argument("ghost passes must be in [0, " + std::to_string(kMaxGhostPasses) + "], got " +
                                std::to_string(ghostPassesOnUpdate));
  }
  if (ghostPixelStride < 1) throw std::invalid_argument("ghostPixelStride must be >= 1");
  if (estimator != PrimaryEstimator::Delta && estimator != PrimaryEstimator::Ratio &&
      estimator != PrimaryEstimator::March && estimator != PrimaryEstimator::Preintegrated &&
      estimator != PrimaryEstimator::Debiased)
    throw std::invalid_argument("estimator must be delta (0), ratio (1), march (2), preintegrated (3) or debiased (4), got " +
                                std::to_string(int(estimator)));
  if (!(levelRatio > 0.0 && levelRatio < 1.0))
    throw std::invalid_argument("level ratio must be in (0, 1), got " + std::to_string(levelRatio));
  if (maxLevel < 0 || maxLevel > kMaxDebiasedLevel)
    throw std::invalid_argument("max level must be in [0, " + std::to_string(kMaxDebiasedLevel) + "], got " +
                                std::to_string(maxLevel));
  if (!(residualScale >= 0.0 && residualScale <= 1024.0))
    throw std::invalid_argument("residual scale must be in [0, 1024], got " + std::to_string(residualScale));
  if (!(majorantScale >= 1.0 && majorantScale <= 1024.0))
    throw std::invalid_argument("majorant scale must be in [1, 1024], got " + std::to_string(majorantScale));
  if (!(fallbackMajorantScale == 0.0 || (fallbackMajorantScale >= 1.0 && fallbackMajorantScale <= 1024.0)))
    throw std::invalid_argument("fallback majorant scale must be 0 or in [1, 1024], got " +
                                std::to_string(fallbackMajorantScale));
  if (!(combMinimumSteps >= 0.0 && combMinimumSteps <= 65536.0))
    throw std::invalid_argument("comb minimum steps must be in [0, 65536], got " + std::to_string(combMinimumSteps));
  if (!(combFloorDepth >= 0.0 && combFloorDepth <= 16.0))
    throw std::invalid_argument("comb floor depth must be in [0, 16], got " + std::to_string(combFloorDepth));
  if (pointsPerIteration < 1 || pointsPerIteration > kMaxPointsPerIteration)
    throw std::invalid_argument("points per iteration must be in [1, " + std::to_string(kMaxPointsPerIteration) +
                                "], got " + std::to_string(pointsPerIteration));
  if (!(rouletteThreshold > 0.0 && rouletteThreshold <= 1.0))
    throw std::invalid_argument("roulette threshold must be in (0, 1], got " + std::to_string(rouletteThreshold));
}

TrackingOptions TrackingOptions::recommended() {
  TrackingOptions t;
  t.estimator = PrimaryEstimator::Debiased;
  t.majorantScale = 2.0;
  t.levelRatio = 0.25;
  t.maxLevel = 5;
  t.combMinimumSteps = 192.0;
  t.stratifiedJitter = true;
  t.jitterControlFrames = 32;
  t.pointsPerIteration = 32;
  t.fallbackMajorantScale = 8.0;
  return t;
}

TrackingOptions TrackingOptions::recommendedFor(PrimaryEstimator e) {
  TrackingOptions t = recommended();
  t.estimator = e;
  if (e == PrimaryEstimator::Ratio || e == PrimaryEstimator::March) t.majorantScale = t.fallbackMajorantScale;
  return t;
}

WavefrontRenderer::WavefrontRenderer(TrackingOptions options) : options_(options) {
  options_.validate();
  warn_ = [](const std::string& message) { std::fprintf(stderr, "INR Volume: warning: %s\n", message.c_str()); };
}

void WavefrontRenderer::setTrackingOptions(const TrackingOptions& options) {
  options.validate();
  options_ = options;
}

void WavefrontRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  validateImageWindow(settings.window, settings.width, settings.height);
  if (settings.clipToBrick) {
    const Box3f& b = settings.brick;
    const bool valid = b.lo.x < b.hi.x && b.lo.y < b.hi.y && b.lo.z < b.hi.z && isFiniteValue(b.lo.x + b.lo.y + b.lo.z) &&
                       isFiniteValue(b.hi.x + b.hi.y + b.hi.z);
    if (!valid) throw std::invalid_argument("brick: the box to clip primary rays to must be finite with lo < hi");
  }
  validateSplit(settings);
  const bool sizeChanged = settings.width != settings_.width || settings.height != settings_.height;
  settings_ = settings;
  if (sizeChanged) {
    const std::size_t n = std::size_t(settings_.width) * settings_.height;
    resizePixels(n);
    if (haveScene_ && !scene_.depthLimit.empty() && scene_.depthLimit.size() != n) {
      scene_.depthLimit.clear();  // stale: the next setScene must bring one of the new size
      depthLimitChanged(scene_.depthLimit);
    }
  }
  if (haveScene_) cameraView_ = scene_.camera.view(settings_.width, settings_.height);
  resetAccumulation();
}

void WavefrontRenderer::setScene(const RenderScene& scene) {
  const CameraView view = validateScene(scene, settings_);
  if (scene.shading.enabled && !fieldHasGradient())
    throw std::invalid_argument("shading: this renderer's field evaluator computes no gradients");
  if (scene.transferFunction.usesGradient() && !fieldHasGradient())
    throw std::invalid_argument(scene.transferFunction.gradientUseName() +
                                ": this renderer's field evaluator computes no gradients");
  SceneChange change = diffScenes(haveScene_ ? &scene_ : nullptr, scene);
  change.time = change.time || macrocellTime() != scene.time;  // the grid may be shared
  const auto t0 = Clock::now();
  if (change.first || change.transferFunction) {
    tfTable_ = std::make_unique<TransferFunctionTable>(scene.transferFunction);
    transferFunctionChanged();
    ++counters_.transferFunctionUploads;
  }
  if (change.first || change.time) pruneRangeValid_ = false;
  if (change.time) {
    setMacrocellTime(scene.time);
    ++counters_.workingGridUpdates;
  }
  if (change.majorants()) {
    recomputeMajorants();
    ++counters_.majorantUpdates;
  }
  if (change.depthLimit) depthLimitChanged(scene.depthLimit);
  sceneUpdateDone();
  pendingUpdateMs_ += msSince(t0);
  const CameraView oldView = cameraView_;
  scene_ = scene;
  cameraView_ = view;
  haveScene_ = true;
  SceneChange others = change;
  others.camera = false;
  // A pixel share's neighbours belong to other shares (empty here): resampling its accumulation
  // would blend them in, so an image-space split restarts instead.
  if (change.camera && !others.resetsAccumulation() && queryReduction_.reproject && frameIndex_ > 0 &&
      settings_.pixelShare.count == 1) {
    // A sample share keeps its part of the history one renderer keeps (its frames among the
    // last reprojectHistory), so the shares' composite holds reprojectHistory frames after the
    // move as one renderer's image does, and its refinement goes on as long.
    const int history = std::max(1, sampleShareFrameCount(settings_.sampleShare, queryReduction_.reprojectHistory));
    reprojectAccumulation(oldView, view, std::uint32_t(history),
                          Vec3f{scene_.background[0], scene_.background[1], scene_.background[2]});
    frameIndex_ = std::min(frameIndex_, history);
    ++counters_.reprojections;
  } else if (change.resetsAccumulation()) {
    resetAccumulation();
  }
  if (change.majorants() && options_.ghostPassesOnUpdate > 0) runGhostPasses(options_.ghostPassesOnUpdate);
}

void WavefrontRenderer::setQueryReduction(const QueryReductionSettings& settings) {
  settings.validate();
  const bool pruningChanged = settings.pruneEpsilon != queryReduction_.pruneEpsilon ||
                              settings.pruneFalloff != queryReduction_.pruneFalloff;
  queryReduction_ = settings;
  if (pruningChanged) resetAccumulation();
}

bool WavefrontRenderer::pruningActive() const {
  return queryReduction_.pruning() && !scene_.transferFunction.usesGradient();
}

PruneView WavefrontRenderer::pruneThresholds() const {
  PruneView v;
  if (!pruningActive()) return v;
  // The range is read once per working grid (a GPU grid reduces and synchronises for it), not
  // per frame; refinement widening it later leaves the thresholds as they were for that time.
  if (!pruneRangeValid_) {
    pruneRange_ = workingValueRange();
    pruneRangeValid_ = true;
  }
  const double span = double(pruneRange_[1]) - double(pruneRange_[0]);
  v.epsilon = float(queryReduction_.pruneEpsilon * span);
  v.falloff = float(queryReduction_.pruneFalloff * span);
  return v;
}

void WavefrontRenderer::allocatePixels() {
  resizePixels(std::size_t(settings_.width) * settings_.height);
  clearAccumulation();
}

void WavefrontRenderer::resetAccumulation() {
  clearAccumulation();
  frameIndex_ = 0;
  frameKey_ = 0;
  residualThreshold_ = 0.f;
  ++counters_.accumulationResets;
}

FrameConstants WavefrontRenderer::frameConstants(std::uint32_t frame, const float* depthLimit) {
  FrameConstants fc = makeFrameConstants(cameraView_, volumeBox(), scene_, settings_, depthLimit, frame);
  fc.maxRngDraws = rngDrawBudget(options_.maxCollisionsPerRay);
  fc.estimator = options_.estimator;
  // The pre-integrated march has no single emission point for a shadow ray or a lit colour, and
  // no control for a gradient opacity factor or a 2D transfer function's gradient axis
  // (PreintegratedMarch.h): ratio tracking renders those scenes, at fallbackMajorantScale (or the
  // comb density when that is 0). The debiased march has no single emission point either
  // (DebiasedMarch.h).
  if (fc.estimator == PrimaryEstimator::Preintegrated &&
      (fc.shadows || fc.shading.enabled || scene_.transferFunction.usesGradient()))
    fc.estimator = PrimaryEstimator::Ratio;
  if (fc.estimator == PrimaryEstimator::Debiased && (fc.shadows || fc.shading.enabled))
    fc.estimator = PrimaryEstimator::Ratio;
  const bool fellBack = fc.estimator != options_.estimator && options_.fallbackMajorantScale > 0.0;
  if (fc.pixelJitter && options_.stratifiedJitter) fc.pixelJitter = 2;
  // The accumulation's frame as one renderer counts it (a sample share's local frame j is another),
  // so that sample shares add up to one renderer's image.
  const std::uint32_t accumulatedFrame = sampleShareFrame(settings_.sampleShare, std::uint32_t(frameIndex_));
  fc.jitterControl =
      fc.pixelJitter && accumulatedFrame < std::uint32_t(options_.jitterControlFrames) && fc.shareCount == 1 ? 1 : 0;
  fc.levelRatio = float(options_.levelRatio);
  fc.maxLevel = options_.maxLevel;
  fc.majorantScale = float(fellBack ? options_.fallbackMajorantScale : options_.majorantScale);
  fc.residualScale = float(options_.residualScale);
  {
    const Vec3f extent = fc.box.hi - fc.box.lo;
    const float diagonal = std::sqrt(extent.x * extent.x + extent.y * extent.y + extent.z * extent.z);
    fc.combMinimumDensity = diagonal > 0.f ? float(options_.combMinimumSteps) / diagonal : 0.f;
    fc.combFloorDepth = float(options_.combFloorDepth);
  }
  fc.rouletteThreshold = float(options_.rouletteThreshold);
  const long long pixels = std::max(1ll, (long long)settings_.width * settings_.height);
  // The pre-integrated march's batches end at comb points and a segment must fit in one
  // (PreintegratedMarch.h): it takes at least kMinPreintegratedPoints, memory permitting.
  long long points = options_.pointsPerIteration;
  if (fc.estimator == PrimaryEstimator::Preintegrated)
    points = std::max<long long>(points, TrackingOptions::kMinPreintegratedPoints);
  // The debiased march's batches end at comb points and an interval (up to 2^maxLevel points)
  // must fit in one (DebiasedMarch.h).
  if (fc.estimator == PrimaryEstimator::Debiased) points = std::max<long long>(points, 1ll << options_.maxLevel);
  fc.pointsPerIteration = int(std::max(1ll, std::min<long long>(points, TrackingOptions::kMaxPointSlots / pixels)));
  const QueryReductionSettings& q = queryReduction_;
  BudgetConstants& b = fc.budget;
  b.scheme = int(q.budget);
  b.rho = float(q.budgetFraction);
  b.alpha = float(q.budgetAlpha);
  b.maxSkip = std::min(q.budgetMaxSkip, frameIndex_ / 4);  // S_max = min(K, floor(n / 4))
  b.tau = residualThreshold_;
  b.noiseFrame = sampleShareFrame(settings_.sampleShare, noiseFrame_);
  if (q.budget == BudgetScheme::Stbn || q.budget == BudgetScheme::WeightedStbn) {
    b.mask = blueNoiseMask();
    b.rhoFloor = budgetRhoFloor(b.mask.depth);
  }
  return fc;
}

float residualThreshold(const std::uint32_t* histogram, double rho) {
  if (rho >= 1.0) return 0.f;  // everything renders
  std::uint64_t total = 0;
  for (int b = 0; b < kResidualBins; ++b) total += histogram[b];
  if (total == 0) return 0.f;
  // The bin where the cumulative fraction reaches 1 - rho: the top rho of the pixels lie at or
  // above it.
  const double target = (1.0 - rho) * double(total);
  std::uint64_t cumulative = 0;
  for (int b = 0; b < kResidualBins; ++b) {
    cumulative += histogram[b];
    if (double(cumulative) >= target) return (float(b) + 0.5f) / float(kResidualBins);
  }
  return (float(kResidualBins) - 0.5f) / float(kResidualBins);
}

void WavefrontRenderer::endFrame(const FrameStats& st, bool truncated, const std::uint32_t* residualHistogram) {
  ++noiseFrame_;
  ++frameKey_;
  residualThreshold_ = queryReduction_.budget == BudgetScheme::Histogram && residualHistogram
                           ? residualThreshold(residualHistogram, queryReduction_.budgetFraction)
                           : 0.f;
  counters_.cappedRays += st.cappedRays;
  if (truncated) ++counters_.truncatedFrames;
  const Box3f& box = volumeBox();
  if (st.cappedRays > 0 && !warnedCapped_ && warn_) {
    warnedCapped_ = true;
    std::ostringstream m;
    m << st.cappedRays << " ray(s) took more than " << options_.maxCollisionsPerRay
      << " candidate collisions in one frame and were cut off (shown as empty there). The transfer "
         "function's extinction is extreme for this model: the opacity unit distance ("
      << scene_.transferFunction.unitDistance << ") is tiny against the box (diagonal "
      << length(box.hi - box.lo)
      << "), or opacity is near 1 over coarse macrocells. Raise the Scalar Opacity Unit Distance "
         "(inr render --opacity-unit-distance), lower the opacity, or raise the macrocell resolution.";
    warn_(m.str());
  }
  if (truncated && !warnedTruncated_ && warn_) {
    warnedTruncated_ = true;
    std::ostringstream m;
    m << "a frame hit the cap of " << options_.maxIterations
      << " traverse-evaluate iterations; the rays still pending were cut off (TrackingOptions::maxIterations).";
    warn_(m.str());
  }
  ++frameIndex_;
}

FrameStats WavefrontRenderer::beginFrame(const char* method, const char* caller) {
  if (!haveScene_) throw std::logic_error(std::string(caller) + ": setScene first");
  FrameStats st;
  st.method = method;
  st.frame = frameIndex_;
  st.pixels = std::size_t(settings_.width) * settings_.height;
  st.updateMs = pendingUpdateMs_;
  pendingUpdateMs_ = 0.0;
  return st;
}

TrackingLoopOutcome runTrackingLoop(TrackingLoopSteps& steps, int maxIterations) {
  TrackingLoopOutcome out;
  for (int iteration = 0;; ++iteration) {
    const bool belowCap = iteration < maxIterations;
    const std::size_t k = steps.listedQueries(iteration, belowCap);
    if (k == 0) break;
    if (!belowCap) {  // bounded work: the pending rays stop here
      steps.cutOff(iteration);
      out.truncated = true;
      break;
    }
    ++out.iterations;
    out.queries += k;
    if (!steps.consume(iteration, k)) break;
  }
  return out;
}

bool WavefrontRenderer::runLeg(TrackingLoopSteps& steps, Leg leg, FrameStats& st) {
  const TrackingLoopOutcome out = runTrackingLoop(steps, options_.maxIterations);
  (leg == Leg::Shadow ? st.shadowIterations : st.iterations) += out.iterations;
  (leg == Leg::Shadow ? st.shadowQueries : st.queries) += out.queries;
  return out.truncated;
}

bool WavefrontRenderer::traceLeg(const FrameConstants& fc, Leg leg, FrameStats& st) {
  return runLeg(*legSteps(fc, leg, st), leg, st);
}

// The frame's script: every estimator and backend runs these stages in this order (paper §4.1:
// initialise, traverse-evaluate to the end of each leg, shade, finalise).
FrameStats WavefrontRenderer::renderFrame() {
  FrameStats st = beginFrame(primaryEstimatorName(options_.estimator), "renderFrame");
  const double updateBeforeFrame = st.updateMs;
  const auto tFrame = Clock::now();
  const FrameConstants fc = prepareFrame(st);
  initRays(fc, st);
  bool truncated = traceLeg(fc, Leg::Primary, st);
  if (fc.shadows && !stoppedMidFrame()) {
    spawnShadowRays(fc, st);
    truncated = traceLeg(fc, Leg::Shadow, st) || truncated;
  }
  if (stoppedMidFrame()) {
    // Stopped: the rays' state is the next frame's to set up again, the image and the frame
    // counters stay as they were (the next frame draws the same random numbers).
    st.stopped = true;
    dropFrame();
    st.closeTiming(updateBeforeFrame, msSince(tFrame));
    return st;
  }
  keepFrame(st);
  if (fc.shading.enabled) shadeHits(fc, st);
  const std::uint32_t* histogram = finalizePixels(fc, st);
  endFrame(st, truncated, histogram);
  st.closeTiming(updateBeforeFrame, msSince(tFrame));
  return st;
}

FrameStats WavefrontRenderer::runGhostPasses(int count) {
  if (!haveScene_) throw std::logic_error("runGhostPasses: setScene first");
  FrameStats total;
  total.method = "ghost";
  if (count <= 0) return total;
  const auto tStart = Clock::now();
  beginGhostPasses();
  const GhostSweep sweep(workingValueRange(), cellSize(), count);
  const int stride = std::max(1, options_.ghostPixelStride);
  for (int g = 0; g < count; ++g) {
    const TransferFunctionTable table(sweep.transferFunction(g));
    FrameConstants fc = frameConstants(GhostSweep::frameNumber(ghostPasses_++), nullptr);
    fc.budget = BudgetConstants{};  // every stride-th pixel (initGhostRay)
    fc.shadows = 0;
    fc.shading.enabled = 0;
    fc.estimator = PrimaryEstimator::Delta;  // ghost rays only need to visit cells
    fc.depthLimit = nullptr;  // refine what is hidden now too: it may show up after a camera move
    // Ghost rays refine this process's whole macrocell grid, not its pixels: with a pixel share
    // every rank traces all of them (the ghost pixels' pattern would otherwise fall on one share),
    // and with a sample share every rank draws the same ghost frames (their numbers are not
    // mapped by sampleShareFrame), so every rank's grid is the one a single renderer refines.
    fc.shareIndex = 0;
    fc.shareCount = 1;
    traceGhostPass(table, fc, stride, total);
  }
  endGhostPasses(total);
  total.closeTiming(0.0, msSince(tStart));
  return total;
}

ImageRGBA WavefrontRenderer::premultipliedImage() const {
  return accumulationImage(accumulation(), settings_.width, settings_.height, nullptr);
}

ImageRGBA WavefrontRenderer::image() const {
  return accumulationImage(accumulation(), settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
