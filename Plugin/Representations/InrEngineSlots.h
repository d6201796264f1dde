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

#include <memory>
#include <string>

#include "Backends/Refinement.h"
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
/// estimator=ratio majorant_scale=1 residual_scale=1 points_per_iteration=4 budget=stbn rho=0.5
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

#endif
