#pragma once
// The backend-neutral half of the wavefront renderer (paper §4.1), written once: the frame's
// script (renderFrame) and a leg's traverse-evaluate loop (runTrackingLoop), image settings, the
// scene-change policy (SceneChange.h: what a new scene costs), frame numbering, the
// accumulation's reset rules, the ghost-pass sweep and the counters of the work scene changes
// did. The CPU (CpuWavefrontRenderer) and CUDA (CudaWavefrontRenderer) backends derive from it:
// they own the storage (ray and pixel state from Render/RayState.h, majorant grids), run the
// INR_HD stage code over it and implement the hooks below (the frame's stages among them).
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "Common/ImageIO.h"
#include "Render/QueryReduction.h"
#include "Render/RayState.h"
#include "Render/RenderStats.h"
#include "Render/SceneChange.h"
#include "Render/SceneInputs.h"

namespace inr {

struct TrackingOptions {
  static constexpr int kMaxGhostPasses = 1000;  // bounded work per scene change
  bool refineMacrocells = true;  // widen under-estimated cells from evaluated samples
  int ghostPassesOnUpdate = 0;   // ghost passes run after each time / TF change (0..kMaxGhostPasses)
  int ghostPixelStride = 4;      // ghost passes trace every n-th pixel in x and y
  // Bounded work per frame, whatever the scene: candidate collisions (real or null) per ray and
  // frame, both legs (primary, shadow) together, before the ray is cut off, and traverse-evaluate
  // iterations per loop before the rays still pending are. The collision cap is a budget of the
  // ray's random draws (rngDrawBudget: two per delta-tracking candidate, one per ratio-tracking
  // candidate, 32 draws of slack for roulette): k + 16 delta-tracking candidates, or up to
  // 2k + 32 for ratio-tracked shadow legs. Neither cap is reached by sensible settings (a few
  // tens of collisions per ray); a tiny opacity unit distance or opacity 1 over a coarse grid
  // reaches them, and the renderer then says so once (setWarningHandler) and counts the rays
  // (FrameStats::cappedRays, RendererCounters::truncatedFrames).
  int maxCollisionsPerRay = 4096;
  int maxIterations = 1 << 14;
  // The primary estimator (RatioTracking.h) and ratio tracking's knobs; shadow legs keep
  // RenderScene::shadowEstimator, ghost passes always delta-track. Ratio tracking draws its
  // tentative collisions at majorantScale x the cell majorant (>= 1: more queries, less
  // variance), hands the evaluator up to pointsPerIteration of a ray's points per wavefront
  // iteration (1..kMaxPointsPerIteration: fewer, fuller iterations; the image does not depend on
  // it) and plays Russian roulette below rouletteThreshold (0 < threshold <= 1). Each point is
  // one draw of the ray's stream, so the collision cap allows it 2 * maxCollisionsPerRay points.
  static constexpr int kMaxPointsPerIteration = 64;
  // Memory bound of the point storage: a frame holds at most this many point slots (rays x
  // points per iteration; ~21 bytes each, plus the query batch), so large images hand the
  // evaluator fewer points per ray per iteration instead (the image does not change).
  static constexpr long long kMaxPointSlots = 1ll << 25;
  // The pre-integrated march hands the evaluator at least this many points per ray and iteration
  // (whatever pointsPerIteration says, unless kMaxPointSlots allows fewer): its batches end at comb
  // points, and a segment (Poisson(residualScale / majorantScale) residual points and a comb
  // point) that does not fit in one cuts the ray off (PreintegratedMarch.h).
  static constexpr int kMinPreintegratedPoints = 16;
  // March (unbiased ray marching, UnbiasedMarch.h) puts a comb of majorantScale points per unit
  // of majorant optical depth in each macrocell and residual ratio-tracking points at
  // residualScale x the majorant (0: none: a plain jittered marcher, biased). Preintegrated
  // (PreintegratedMarch.h) takes the same two scales for its comb and its residual points; with
  // shadows, shading or gradient opacity the renderer runs ratio tracking instead.
  PrimaryEstimator estimator = PrimaryEstimator::Delta;
  double majorantScale = 1.0;
  double residualScale = 1.0;
  // Preintegrated: comb points at least every (box diagonal / combMinimumSteps) along a ray inside
  // non-empty macrocells, whatever their majorant (0: the majorant's density alone). Why: where
  // the majorant is low the majorant-density comb leaves cells without a comb point, and the
  // control there is the last comb value carried from elsewhere, which the residual points must
  // then correct; a floor on the density lets the control follow the network everywhere the
  // transfer function shows something, as a ray marcher's step does.
  double combMinimumSteps = 0.0;
  // The comb floor follows the transfer function: in a macrocell whose majorant optical depth over
  // a floor interval (diagonal / combMinimumSteps) is below combFloorDepth, the floor's density
  // falls to majorant / combFloorDepth (0: the floor everywhere). Why: the floor exists to resolve
  // the network where the transfer function shows something; a faint cell's whole optical depth
  // bounds what a coarser comb can miss there, so floor points in it cost queries for error
  // nobody sees (DebiasedMarch.h, combDensity). In [0, 16].
  double combFloorDepth = 0.0;
  // Debiased (DebiasedMarch.h): the comb takes majorantScale points per unit of majorant optical
  // depth (and combMinimumSteps); each comb interval is refined (its step halved) once more with
  // probability levelRatio, at most maxLevel times. Below 1/2 the expected points per interval are
  // (1 - r) / (1 - 2 r); larger ratios cost more and weigh the refinements less. The expectation
  // is the march at 2^-maxLevel of the comb step (see the header).
  static constexpr int kMaxDebiasedLevel = 6;  // 2^6 points per interval fit a batch (kMaxPointsPerIteration)
  double levelRatio = 0.3;
  int maxLevel = 5;
  int pointsPerIteration = 16;
  double rouletteThreshold = 0.05;
  // Sub-pixel jitter (when RenderSettings::pixelJitter is on) from a low-discrepancy sequence over
  // each pixel's frames instead of independent draws (RayInit.h, stratifiedJitter): every frame
  // stays unbiased, and the antialiasing's share of the error falls about as 1 / frames.
  bool stratifiedJitter = false;
  // With sub-pixel jitter, in an accumulation's first jitterControlFrames frames, each frame's
  // pixel estimate minus the image's slope (a plane through the 8 neighbours' estimates of the
  // same frame) times the sample's offset from the pixel centre (Finalize.h, jitterControlled):
  // the same expectation, without the part of the jitter's noise that is linear across the
  // pixel. Only the first frames: the slope carries the neighbours' own noise, which the
  // stratified jitter's later frames would not have (RESULTS-archive, "The sub-pixel jitter's
  // control variate", "A plane through the 8 neighbours"). Not with pixel shares (the neighbours
  // are another image's) or in the naive frame (its neighbours are not traced yet). 0 = off; at
  // most kMaxJitterControlFrames.
  static constexpr int kMaxJitterControlFrames = 1 << 20;
  int jitterControlFrames = 0;
  // Ratio tracking's majorant scale where a march (preintegrated, debiased) renders a scene as
  // ratio tracking instead (shadows, shading; for preintegrated also gradient opacity and 2D
  // transfer functions); 0 = majorantScale. Why: a march's comb density (majorantScale) is chosen
  // for the march, and ratio tracking's best density is another (0 or in [1, 1024]).
  double fallbackMajorantScale = 0.0;
  // Throws std::invalid_argument naming the first option out of its range.
  void validate() const;
  // What `inr render`, pvpython and the ParaView GUI use: the struct's own defaults (the paper's
  // delta tracking, which the regression fingerprints and the delta-specific tests pin) with the
  // estimator chosen by the time-to-a-clean-image benchmark (Benchmarks/RESULTS.md, "Time to a
  // clean image"): the debiased march (majorant scale 2, level ratio 0.25, at most 5 levels, a
  // comb floor of 192 steps per box diagonal, stratified jitter with its control variate in the
  // first 32 frames, 32 points per iteration), and
  // ratio tracking at majorant scale 8 where it falls back (shadows, shading).
  static TrackingOptions recommended();
  // recommended() with estimator `e` at its own majorant scale: fallbackMajorantScale for ratio
  // tracking and the march (RESULTS-archive, "The debiased march as the default"), majorantScale
  // for the debiased and pre-integrated marches (whose comb floor sets most of their density). What `inr render --estimator E` and the
  // plugin's Sample Density 0 give.
  static TrackingOptions recommendedFor(PrimaryEstimator e);
};

// "delta" / "ratio" / "march" / "preintegrated" / "debiased" (the CLI's --estimator, the plugin's InrEstimator); parse throws
// std::invalid_argument naming the accepted names.
const char* primaryEstimatorName(PrimaryEstimator e);
PrimaryEstimator parsePrimaryEstimator(const std::string& name);

// Histogram budgeting's threshold tau (paper §4.2.1): the centre of the bin where the cumulative
// fraction of `histogram` (kResidualBins counts) reaches 1 - rho; 0 (everything renders) for
// rho >= 1 or an empty histogram.
float residualThreshold(const std::uint32_t* histogram, double rho);

// The stream-draw budget per ray and frame for `maxCollisionsPerRay`: the two jitter draws, two
// per collision, and 32 of slack for ratio tracking's roulette.
std::uint32_t rngDrawBudget(int maxCollisionsPerRay);

// One leg's traverse-evaluate loop (a frame's primary or shadow leg, a ghost pass), written once
// (runTrackingLoop); a backend's steps execute it over its storage. Pass 0 traverses every ray of
// the leg, each later pass the rays whose queries the pass before listed.
class TrackingLoopSteps {
public:
  virtual ~TrackingLoopSteps() = default;
  // How many queries traversal pass `iteration` listed (0: the leg is done, or a stop request
  // ended it). `belowCap`: the loop will consume them if there are any (the iteration cap is not
  // reached). The GPU's steps run a pass ahead: below the cap, when this returns, the listed
  // queries' evaluation and the next traversal pass are already queued, so the host waits for a
  // count while the GPU works.
  virtual std::size_t listedQueries(int iteration, bool belowCap) = 0;
  // The listed queries' values reach their rays (and the macrocells' refinement, pruning's
  // expected scalars); false: a stop request ended the leg.
  virtual bool consume(int iteration, std::size_t queries) = 0;
  // The iteration cap: the rays with listed queries stop where they are (no collision recorded).
  virtual void cutOff(int iteration) = 0;
};

struct TrackingLoopOutcome {
  int iterations = 0;
  std::size_t queries = 0;
  bool truncated = false;  // the cap cut rays off
};

// Runs `steps` until no query is pending, a stop request, or `maxIterations` passes (bounded
// work: the rays still pending then are cut off).
TrackingLoopOutcome runTrackingLoop(TrackingLoopSteps& steps, int maxIterations);

// Work the scene-change policy did (what tests and benchmarks check).
struct RendererCounters {
  int workingGridUpdates = 0;   // time changes
  int majorantUpdates = 0;      // full majorant recomputations (time or TF changes)
  int transferFunctionUploads = 0;
  int accumulationResets = 0;
  int reprojections = 0;        // camera moves that reprojected the accumulation instead
  int truncatedFrames = 0;      // frames where the iteration cap cut rays off
  std::size_t cappedRays = 0;   // rays cut off by the collision cap, all frames
};

class WavefrontRenderer {
public:
  virtual ~WavefrontRenderer() = default;
  WavefrontRenderer(const WavefrontRenderer&) = delete;
  WavefrontRenderer& operator=(const WavefrontRenderer&) = delete;

  // Image size and seed; restarts accumulation.
  void setSettings(const RenderSettings& settings);
  // Applies a scene doing only the work its changes need (SceneChange.h).
  void setScene(const RenderScene& scene);
  // One wavefront frame, accumulated: the frame's script, written once (WavefrontRenderer.cpp)
  // over the backend's stages below.
  FrameStats renderFrame();
  // Ghost passes: primary passes with cosine-bump TFs sweeping the value range, not displayed,
  // so under-estimated macrocells get visited and refined. Returns their summed stats.
  FrameStats runGhostPasses(int count);

  // Query reduction (QueryReduction.h): validates (std::invalid_argument naming the parameter).
  // Changing the pruning thresholds restarts accumulation (they change what converges);
  // budgeting and reprojection settings do not (they change which pixels get rays, not the image
  // the accumulation converges to).
  void setQueryReduction(const QueryReductionSettings& settings);
  const QueryReductionSettings& queryReduction() const { return queryReduction_; }

  // Replaces the tracking options after validating them (the old ones stay on error). They apply
  // from the next frame (refinement, caps) or scene change (ghost passes); the accumulation is
  // kept: none of them changes the image the accumulation converges to.
  void setTrackingOptions(const TrackingOptions& options);
  const TrackingOptions& trackingOptions() const { return options_; }

  void resetAccumulation();
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;               // composited over the background, alpha = coverage
  ImageRGBA premultipliedImage() const;  // volume only (rgb premultiplied, alpha = coverage)
  virtual std::vector<float> residual() const = 0;
  virtual std::vector<float> majorants() const = 0;
  virtual std::vector<float> blockMajorants() const = 0;  // the coarse skip level; empty when off
  double lastUpdateMs() const { return pendingUpdateMs_; }
  const RendererCounters& counters() const { return counters_; }
  const RenderSettings& settings() const { return settings_; }
  // Where the once-per-cause warnings go (work caps hit); default: stderr.
  void setWarningHandler(std::function<void(const std::string&)> handler) { warn_ = std::move(handler); }
  // A flag another thread may raise to stop the frame in progress (a GUI's worker whose scene is
  // no longer wanted); null: none. The CPU renderer looks at it before each tracking iteration
  // and between sub-batches of an iteration's evaluation (QueryBatch::evaluate) and
  // returns the frame unaccumulated (FrameStats::stopped); the GPU renderer's frames, which take
  // milliseconds, run to their end.
  void setStopRequest(const std::atomic<bool>* stop) { stop_ = stop; }
  bool stopRequested() const { return stop_ && stop_->load(std::memory_order_relaxed); }

protected:
  const std::atomic<bool>* stop_ = nullptr;  // setStopRequest's flag, or none
  explicit WavefrontRenderer(TrackingOptions options);

  // --- backend hooks
  // Ray and pixel state for `pixels` pixels (contents undefined: accumulation is reset after).
  virtual void resizePixels(std::size_t pixels) = 0;
  virtual void clearAccumulation() = 0;  // resetPixel over every pixel
  virtual std::vector<Vec4f> accumulation() const = 0;
  virtual double macrocellTime() const = 0;
  virtual void setMacrocellTime(double t) = 0;
  virtual void transferFunctionChanged() {}  // tfTable_ is new (e.g. upload it)
  virtual void recomputeMajorants() = 0;     // all majorants from tfTable_ and the working grid
  virtual void depthLimitChanged(const std::vector<float>& /*depthLimit*/) {}
  virtual void sceneUpdateDone() {}          // wait for the update work (so it is timed)
  virtual const Box3f& volumeBox() const = 0;
  virtual std::array<float, 2> workingValueRange() const = 0;
  // Whether the field gives gradients (gradient shading needs them; setScene refuses it without).
  virtual bool fieldHasGradient() const = 0;
  virtual Vec3f cellSize() const = 0;
  virtual void beginGhostPasses() = 0;       // bring the displayed majorants up to date
  // One ghost pass with `table`: its majorants, ghost rays (initGhostRay), the tracking loop
  // with refinement; counts into `total`.
  virtual void traceGhostPass(const TransferFunctionTable& table, const FrameConstants& fc, int stride,
                              FrameStats& total) = 0;
  virtual void endGhostPasses(FrameStats& total) = 0;  // apply refinements to the majorants
  // The blue-noise mask in the backend's memory (STBN budgeting; shippedBlueNoiseMask()).
  virtual BlueNoiseMaskView blueNoiseMask() = 0;
  // Reprojection (Reproject.h) of the accumulation rendered from `oldView` into `newView`; the
  // colours are shown over `background`.
  virtual void reprojectAccumulation(const CameraView& oldView, const CameraView& newView, std::uint32_t maxHistory,
                                     const Vec3f& background) = 0;

  // --- the frame's stages, in the order renderFrame runs them; each adds its counts and times to
  // the frame's statistics. A backend executes them over its storage: OpenMP loops over the
  // INR_HD stage code on the CPU, kernels over the same code on the GPU.
  enum class Leg { Primary, Shadow };
  // Before any of the frame's work: the majorants up to date, the frame's medium chosen, the
  // buffers it grows allocated (a lack of memory throws here, with the image, its accumulation
  // and the ray state as they were). Returns the frame's constants.
  virtual FrameConstants prepareFrame(FrameStats& st) = 0;
  virtual void initRays(const FrameConstants& fc, FrameStats& st) = 0;  // stage I, budgeted
  // The steps of a leg's traverse-evaluate loop (stages II and III), counting into `st`.
  virtual std::unique_ptr<TrackingLoopSteps> legSteps(const FrameConstants& fc, Leg leg, FrameStats& st) = 0;
  virtual void spawnShadowRays(const FrameConstants& fc, FrameStats& st) = 0;
  // Whether a stop request (setStopRequest) ends the frame mid-way (the CPU's frames; the GPU's,
  // which take milliseconds, run to their end). A stopped frame leaves no trace: dropFrame puts
  // back what it learned; a completed one keeps it (keepFrame: the macrocells' widenings).
  virtual bool stopsMidFrame() const { return false; }
  virtual void dropFrame() {}
  virtual void keepFrame(FrameStats& /*st*/) {}
  virtual void shadeHits(const FrameConstants& fc, FrameStats& st) = 0;  // gradient shading (Shade.h)
  // Stage IV and the frame's sums (convergence, pruned candidates, capped rays); returns the
  // residual histogram of this frame's rendered pixels (kResidualBins counts) for the histogram
  // scheme, or null.
  virtual const std::uint32_t* finalizePixels(const FrameConstants& fc, FrameStats& st) = 0;
  // Runs `steps` to the end (runTrackingLoop, at the options' iteration cap) and adds their
  // iterations and queries to `st`'s counts for `leg` (a ghost pass counts as a primary leg);
  // returns whether the cap cut rays off.
  bool runLeg(TrackingLoopSteps& steps, Leg leg, FrameStats& st);

  // Backends call this at the end of their constructor (the hooks are theirs): storage for the
  // default settings' image, accumulation cleared.
  void allocatePixels();
  // The frame constants of frame `frame` for the current scene, with this frame's budgeting
  // constants; `depthLimit` is the backend's copy of the scene's depth limit (ignored when the
  // scene has none). Displayed frames pass frameKey().
  FrameConstants frameConstants(std::uint32_t frame, const float* depthLimit);
  // The random-stream key of the next displayed frame: the accumulated frame index, except that
  // it keeps counting across reprojection (so reprojected history and new samples never share
  // random numbers), mapped to the single renderer's frame under a sample share.
  std::uint32_t frameKey() const { return sampleShareFrame(settings_.sampleShare, frameKey_); }
  // Starts a frame's statistics (method, frame index, the pending update time); throws when no
  // scene has been set.
  FrameStats beginFrame(const char* method, const char* caller);
  // Closes a frame: counts capped rays and truncation, warns once per cause, advances the index;
  // with the histogram scheme, `residualHistogram` (kResidualBins counts of this frame's
  // rendered pixels) gives the next frame's threshold.
  void endFrame(const FrameStats& st, bool truncated, const std::uint32_t* residualHistogram = nullptr);
  // Homogeneity pruning's thresholds in scalar units: the settings' fractions times the span of
  // workingValueRange(). Arrays unset (the backend fills them from its grid); all zero (off)
  // unless pruningActive().
  PruneView pruneThresholds() const;
  // Whether homogeneity pruning runs this frame: asked for, and the TF has no gradient opacity (a
  // pruned candidate's expected scalar comes with no gradient, so gradient opacity stands it down).
  bool pruningActive() const;

  TrackingOptions options_;
  RenderSettings settings_;
  RenderScene scene_;
  bool haveScene_ = false;
  CameraView cameraView_{};
  std::unique_ptr<TransferFunctionTable> tfTable_;
  RendererCounters counters_;
  QueryReductionSettings queryReduction_;

private:
  // A leg of the frame: its steps (legSteps) run to the end; returns whether the iteration cap
  // cut rays off.
  bool traceLeg(const FrameConstants& fc, Leg leg, FrameStats& st);
  bool stoppedMidFrame() const { return stopsMidFrame() && stopRequested(); }

  int frameIndex_ = 0;
  std::uint32_t frameKey_ = 0;
  std::uint32_t noiseFrame_ = 0;   // blue-noise slice counter: never restarts
  float residualThreshold_ = 0.f;  // tau for the next frame (histogram scheme)
  mutable std::array<float, 2> pruneRange_{0.f, 1.f};  // workingValueRange() for pruneThresholds
  mutable bool pruneRangeValid_ = false;
  std::uint32_t ghostPasses_ = 0;
  std::function<void(const std::string&)> warn_;
  bool warnedCapped_ = false, warnedTruncated_ = false;
  double pendingUpdateMs_ = 0.0;  // time/TF update work, reported with the next frame
};

}  // namespace inr
