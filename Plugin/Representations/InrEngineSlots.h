// The mapper's engine sessions, without VTK: what the user asked of the engine (InrEngineRequest,
// the mapper's properties already checked), the ONE function that turns it into the options of
// the fine session and of the coarse level-of-detail session (InrSessionOptions), and what the
// mapper keeps per session (InrEngineSlot).
//
// The coarse session (reduced interactive frames: time changes, drags with Reproject on) must
// render what the fine one renders, only on a coarser majorant grid: it honours every user
// setting (backend, GPU traversal, estimator and tracking options, macrocell options, CPU threads,
// query reduction, shadows and seeds through the scene and settings it is handed) and differs only
// where level of detail deliberately differs (InrSessionLevel). It runs the fine session's
// evaluator (weights uploaded and, on CUDA, autotuned once).
#ifndef InrEngineSlots_h
#define InrEngineSlots_h

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "Backends/Refinement.h"
#include "InrBackgroundWorker.h"
#include "Model/InrModel.h"
#include "Backends/RenderSession.h"
#include "Render/QueryReduction.h"
#include "Render/SceneInputs.h"

/// What the user asked of the engine, checked (invalid values already refused by the mapper).
struct InrEngineRequest
{
  inr::RenderBackend backend = inr::RenderBackend::Auto;
  inr::TraversalKind traversal = inr::TraversalKind::Auto;
  int resolution = 32;      // fine macrocells per axis
  int temporalSlices = 16;  // for a model with time (one slice without)
  bool modelUsesTime = true;
  int skipBlockCells = inr::MacrocellOptions{}.skipBlockCells;
  double boundsPadding = inr::MacrocellOptions{}.boundsPadding;
  inr::TrackingOptions tracking = inr::TrackingOptions::recommended();
  int cudaDevice = 0;
  int cpuThreads = 0;

  /// What a session is built from: a difference in any of these rebuilds it (tracking options
  /// change on a live session: inr::RenderSession::setTrackingOptions).
  bool SameBuild(const InrEngineRequest& o) const;
};

/// Where a session's options deliberately differ from the request: the majorant grid's
/// resolution, and for the coarse session the fine session's evaluator (and so its backend and
/// device: the backend that actually runs, after any fallback).
struct InrSessionLevel
{
  int resolution = 0;          // macrocells per axis; 0 = the request's
  inr::SharedEvaluator evaluator;  // empty: the session builds its own

  static InrSessionLevel Fine() { return {}; }
  static InrSessionLevel Coarse(int resolution, const inr::RenderSession& fine)
  {
    return InrSessionLevel{ resolution, fine.sharedEvaluator() };
  }
};

/// The one place session options are built, for the fine and the coarse session alike. A skip
/// block larger than the grid is capped to the largest power of two that fits it.
inr::RenderSessionOptions InrSessionOptions(const InrEngineRequest& request, const InrSessionLevel& level);

/// What a live session runs, read back from it (options it was created with, tracking options
/// and query reduction it holds), one line, e.g. "backend=cpu traversal=dda cuda_device=0
/// cpu_threads=0 dims=8x8x8 slices=16 skip_block=4 bounds_padding=0.1 ghost_passes=0 refine=1
/// estimator=ratio majorant_scale=1 residual_scale=1 points_per_iteration=4 jitter_control_frames=32
/// budget=stbn rho=0.5
/// K=8 alpha=0.5 reproject=1 epsilon=0 delta=0". Fine and coarse lines differ in dims (and
/// skip_block where it was capped) only.
std::string InrDescribeSession(const inr::RenderSession& session);
/// The parts of it about macrocells and tracking (Macrocells In Use) and query reduction.
std::string InrDescribeMacrocells(const inr::RenderSession& session);
std::string InrDescribeQueryReduction(const inr::QueryReductionSettings& q);
bool InrSameQueryReduction(const inr::QueryReductionSettings& a, const inr::QueryReductionSettings& b);

/// One engine session and what the mapper keeps about it: the request it was built from, the
/// render settings and query reduction last handed to it (handed again only when they differ, so
/// a rejected setting is reported once) and its refinement driver.
struct InrEngineSlot
{
  std::unique_ptr<inr::RenderSession> session;
  InrEngineRequest asked;  // the request it was built for (a different one rebuilds it)
  InrEngineRequest built;  // what it was built with (after an OptiX fallback: traversal Auto)
  bool haveSettings = false;
  inr::RenderSettings settings;
  bool haveQueryReduction = false;
  inr::QueryReductionSettings queryReductionTried;
  inr::RefinementDriver refinement;
  /// A new session starts from the engine's defaults: hand it everything again.
  void Started()
  {
    this->haveSettings = false;
    this->haveQueryReduction = false;
    this->refinement.restart();
  }
  /// Hands `settings` to the session when they differ from what it holds.
  void SetSettings(const inr::RenderSettings& settings);
};

/// Ghost passes, macrocell refinement and the estimator changed on a live session, without a
/// rebuild (none of them changes the image the accumulation converges to).
void InrSyncTrackingOptions(inr::RenderSession& session, const inr::TrackingOptions& want);

/// The engine options the properties ask for, kept three times: as asked, the last valid value
/// (what the engine is built or updated with; initially the engine's defaults) and the last value
/// refused per option (each refusal is reported once). Check() validates each asked value as
/// `inr render` does and reports a refusal through `error`, naming the property.
struct InrEngineOptions
{
  inr::MacrocellOptions macrocellsAsked, macrocellsValid, macrocellsRefused;
  // The estimator starts as inr render's (TrackingOptions::recommended()); the XML declares the
  // same defaults (test cli.estimator_xml_defaults). The asked majorant scale 0 is the estimator's
  // own (TrackingOptions::recommendedFor), resolved by Check() whenever the estimator changes.
  inr::TrackingOptions trackingAsked = EstimatorsOwnScale(inr::TrackingOptions::recommended());
  inr::TrackingOptions trackingValid = inr::TrackingOptions::recommended(), trackingRefused = trackingValid;
  // Query reduction: what the user asked for (validated by the engine when pushed).
  inr::QueryReductionSettings queryReduction;
  void Check(const std::function<void(const std::string&)>& error);

private:
  static inr::TrackingOptions EstimatorsOwnScale(inr::TrackingOptions t)
  {
    t.majorantScale = 0.0;
    return t;
  }
};

/// The coarse session's evaluator on the CPU backend: the fine session's network, or, during the
/// frames of a camera drag, a stand-in of it that costs no query (RenderSession::workingMeanField:
/// the fine macrocells' per-cell means at the time shown). The mapper switches it on around those
/// frames only, after the coarse slices of the time are built from the network, so the coarse
/// session's bounds and its time-change frames always come from the network.
class InrStandInSwitch final : public inr::FieldEvaluator
{
public:
  explicit InrStandInSwitch(std::shared_ptr<const inr::FieldEvaluator> network)
    : network(std::move(network))
  {
  }
  void evaluate(const inr::QueryPoint* points, std::size_t n, float* out) const override
  {
    (this->field ? *this->field : *this->network).evaluate(points, n, out);
  }
  std::string name() const override { return this->network->name(); }
  // Shading (the volume property's Shade) needs gradients: the stand-in's own, or the network's.
  bool providesGradient() const override { return this->network->providesGradient(); }
  void evaluateWithGradient(
    const inr::QueryPoint* points, std::size_t n, float* values, float* gradients) const override
  {
    (this->field ? *this->field : *this->network).evaluateWithGradient(points, n, values, gradients);
  }
  const inr::FieldEvaluator& Network() const { return *this->network; }

  std::shared_ptr<const inr::FieldEvaluator> network;
  std::shared_ptr<const inr::GridField> field;  // the stand-in while switched on, else null
};

/// The mapper's two engine sessions on one model: the fine one (the still image) and the coarse
/// one of reduced interactive frames, built from one request (InrSessionOptions), the long
/// macrocell builds and refinement steps optionally on one worker thread (`worker`), query
/// reduction pushed into whichever session draws. No VTK:
/// messages and progress go through the callbacks below.
class InrEngines
{
public:
  InrEngines() = default;
  ~InrEngines();
  InrEngines(const InrEngines&) = delete;
  InrEngines& operator=(const InrEngines&) = delete;

  /// Where messages go (the mapper: vtkErrorMacro / vtkWarningMacro) and a progress handler for
  /// macrocell builds, given the text that prefixes the engine's phase.
  std::function<void(const std::string&)> error, warning;
  std::function<inr::MacrocellProgress(const std::string& prefix)> progress;

  /// The model, loaded from its bytes when their hash changed (both sessions are dropped then);
  /// false (reported once per content) when it cannot be loaded.
  bool SetModel(const unsigned char* bytes, std::size_t n);
  bool HasModel() const { return this->modelOk; }
  const inr::InrModel& Model() const { return this->model; }

  /// The fine session for `request`: rebuilt when a build option differs (the coarse one is
  /// dropped with it: it runs its evaluator), tracking options synchronised otherwise. False when
  /// it cannot be created (reported). Rebuilt() tells whether this call built it. While a job of
  /// the worker on the fine session runs, the session is kept as it is (rebuilt by a later call).
  bool UpdateFine(const InrEngineRequest& request);
  bool Rebuilt() const { return this->rebuilt; }
  /// The coarse session at `resolution` cells per axis, built on first use from the fine
  /// session's request as built; false (render with the fine one) when off (0), not coarser
  /// than the fine grid, or it cannot be created (reported once). Stops a build ahead of its
  /// slices on the worker first (within one slice): the caller is about to draw with it.
  bool UpdateCoarse(int resolution);
  /// Builds every coarse slice not built yet, with progress; the milliseconds it took.
  double BuildCoarseAhead(int resolution, bool report);

  /// Keeps the fine session's stand-in of the network (RenderSession::workingMeanField) for
  /// `time`, the time of the fine session's scene, unless one is kept for it already: the mapper
  /// calls it whenever it holds the fine session (not on the worker) after a frame, so that a
  /// camera drag finds it even while the worker refines the fine session.
  void KeepStandIn(double time);
  /// Whether a camera drag at `time` can draw the coarse session on the stand-in of the network
  /// (InrStandInSwitch): the coarse session runs on the CPU and a stand-in for `time` is kept.
  /// UseStandIn switches the coarse session's evaluator to it and back.
  bool StandInReady(double time) const
  {
    return this->standIn && this->coarse.session && this->standInField && this->standInTime == time;
  }
  void UseStandIn(bool on)
  {
    if (this->standIn)
    {
      this->standIn->field = on ? this->standInField : nullptr;
    }
  }
  /// The coarse session's evaluator where it is the switch (CPU backend), else null.
  const InrStandInSwitch* StandIn() const { return this->standIn.get(); }

  /// Hands the query reduction to `slot`'s session when it changed (a refused set is reported
  /// once and the session keeps what it had).
  void PushQueryReduction(InrEngineSlot& slot, const inr::QueryReductionSettings& asked);

  InrEngineSlot fine, coarse;
  /// The long builds and refinement steps on a worker thread (InrBackgroundWorker.h); declared
  /// after the sessions it works on.
  InrBackgroundWorker worker{ *this };
  int engineBuilds = 0;
  bool muteProgress = false;  // read by the progress handlers the mapper hands out
  std::string queryReductionInUse;

private:
  std::shared_ptr<InrStandInSwitch> standIn;  // the coarse session's evaluator on the CPU
  std::shared_ptr<const inr::GridField> standInField;  // KeepStandIn's, for standInTime
  double standInTime = 0.0;
  std::uint64_t hash = 0;
  bool modelOk = false;
  std::uint64_t reportedBadHash = 0;
  inr::InrModel model;
  bool rebuilt = false;
  bool warnedCuda = false;
  bool coarseFailed = false;  // creation failed once for coarse.asked: reported, not retried
  bool haveRefusedQueryReduction = false;  // the last set the engine refused (reported once,
  inr::QueryReductionSettings refusedQueryReduction;  // not again by a rebuilt session)
};

#endif
