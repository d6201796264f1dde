// What one render of the mapper does, decided from plain inputs, without VTK: whether it draws a
// reduced interactive frame (level of detail) or the still image, at what size and with how many
// frames, on which engine session (the fine one, the coarse one of interactive frames, the
// stand-in of the network during a camera drag), whether the still image refines on the worker
// thread (the GUI) or here, whether the render must wait for the worker first, and the
// refinement options its frames run under (frame count, time budget, a tile's full refinement).
// vtkInrVolumeMapper::Render gathers the inputs, calls Decide and does what it says; the rules
// are tested on their own (Testing/Plugin/TestInrRenderDecision.cxx). The reasons for the level-
// of-detail rules are in vtkInrVolumeMapper.h (InteractiveLevelOfDetail and after).
#ifndef InrRenderDecision_h
#define InrRenderDecision_h

#include <functional>

#include "Backends/Refinement.h"
#include "InrLevelOfDetail.h"

struct InrRenderDecision
{
  /// What the render knows before it decides.
  struct Inputs
  {
    /// The level-of-detail policy's classification of this render (InrLevelOfDetail::Classify:
    /// the window's desired update rate, the input's time); not consulted for a tile.
    InrLevelOfDetail::Decision lod;
    InrLevelOfDetail::Settings lodSettings;
    int width = 0, height = 0;  // the render tile (the view, or a tile of a larger picture)
    bool tile = false;          // a tile of a larger picture (a capture): always the still image
    /// The fine slices of this render's time build on the worker (or will once its refinement
    /// step is done): a still render draws a reduced frame of the coarse session meanwhile.
    bool fineOnWorker = false;
    bool fineBusy = false;       // the worker holds the fine session (a build or a refinement step)
    bool fineRefining = false;   // ... for a refinement step
    /// The still image may refine on the worker (the GUI: background builds on, CPU backend,
    /// GUI-like refinement; InrLevelOfDetail::BuildsFineInBackground).
    bool backgroundAllowed = false;
    bool standInOption = false;  // InteractiveStandIn
    bool reproject = false;      // query reduction's Reproject
    /// Refinement properties.
    bool progressive = true;     // ProgressiveRefinement
    int framesPerRender = 1;
    int maximumFrames = 2048;
    double convergenceTarget = 41.0;
    double timeBudgetMs = 50.0;  // RefinementTimeBudget, for the whole view's render
  };

  /// What the decision asks of the mapper's state, in the order the rules need them (each called
  /// only where the answer matters, as each may do work):
  ///  - coarseSession: the coarse session exists, created if needed (false: none; render fine);
  ///  - standInReady: the stand-in of the network is kept for this render's time;
  ///  - plan: the image of a render of kind `lod`, from the level-of-detail cost model (the
  ///    stand-in's own model when `standIn`: InrLevelOfDetail::Plan).
  struct Queries
  {
    std::function<bool()> coarseSession;
    std::function<bool()> standInReady;
    std::function<InrLevelOfDetail::Frame(const InrLevelOfDetail::Decision& lod, bool standIn)> plan;
  };

  /// The render's kind after the rules: a still render turned into a reduced time-change frame
  /// while the fine slices build on the worker; `interactive` as drawn (false where the full
  /// resolution fits the budget); budgetMs for the log.
  InrLevelOfDetail::Decision lod;
  /// The image: its size, frames of a fresh reduced image, whether it is reduced.
  InrLevelOfDetail::Frame frame;
  /// A camera interaction (the window asked for a rate, the time did not change): one frame, no
  /// time budget (that is for a view at rest), never on the worker, even at full resolution.
  bool cameraInteraction = false;
  bool useCoarse = false;       // drawn on the coarse session (reduced frames only)
  bool standIn = false;         // a drag on the stand-in's cost model (its full resolution too)
  bool drawStandIn = false;     // ... drawn on the coarse session with the stand-in switched on
  bool background = false;      // the still image refines on the worker: this render draws its image
  bool joinFine = false;        // wait for the worker's job on the fine session before rendering
  /// How the frames' time budget is set: none (frame count only), the whole RefinementTimeBudget
  /// (a step on the worker does not hold the view) or what is left of it when the frames start
  /// (the mapper measures that: the view's update, the window's passes).
  enum class Budget
  {
    None,
    Whole,
    Remaining
  };
  Budget budget = Budget::None;

  static InrRenderDecision Decide(const Inputs& in, const Queries& ask);

  /// The refinement options of this render's frames; `remainingMs`: what is left of the view's
  /// budget when the frames start (read only for Budget::Remaining).
  inr::RefinementOptions Refinement(const Inputs& in, double remainingMs) const;
};

#endif
