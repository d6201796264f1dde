// The state the INR Volume panel shows about the mapper (its information properties, read through
// vtkInrVolumeMapper's getters), in one struct without VTK. The mapper's Render writes the
// per-render part as it goes (what it drew, the engine's work, what runs, the ranks' reduced
// state); the refinement figures and the engine's counters are refreshed from the engine when a
// getter reads them (vtkInrVolumeMapper::Internals::Report), because a reset, a property change
// or a job the worker finished between two renders must show at once. The texts for people
// (the estimate, the refinement state) are built by the functions below, tested without VTK.
#ifndef InrMapperReport_h
#define InrMapperReport_h

#include <string>

#include "Backends/Refinement.h"
#include "InrParallelRendering.h"

struct InrMapperReport
{
  ///@{
  /// What the last Render drew: the image's size (the view's unless reduced), whether it was a
  /// reduced interactive frame, on the coarse session, on the stand-in of the network, its wall
  /// time, and what the engine did for it (summed over its frames: queries, rays, pixels left out
  /// by ray budgeting, collisions answered by pruning, macrocell update time).
  int imageWidth = 0, imageHeight = 0;
  bool interactive = false;
  bool shownCoarse = false;
  bool shownStandIn = false;
  double renderMs = 0.0;
  inr::RefinementDriver::Step step;
  ///@}

  ///@{
  /// What runs, written whenever the engine is updated: the backend (with the image transfer and
  /// this rank's place), the macrocell and tracking options, the query reduction, the number of
  /// engine (re)builds; and after each render one line per rank (RanksInUse).
  std::string backendInUse = "none (no model rendered yet)";
  std::string macrocellsInUse;
  std::string queryReductionInUse;
  int engineBuilds = 0;
  std::string ranksInUse;
  ///@}

  ///@{
  /// This rank's refinement (refreshed when read): whether the fine session exists, its frames,
  /// whether it is converged (0 while a reduced image is shown or the worker refines it), and the
  /// estimated PSNR. With several ranks the panel shows `reduced` instead (ReduceOverRanks at the
  /// end of each render: converged only when every rank is, the fewest frames, the lowest
  /// estimate).
  bool haveEngine = false;  // the fine session exists
  int frames = 0;
  bool localConverged = false;
  double estimate = 0.0;
  int ranks = 1;
  InrParallelRendering::Refinement reduced;
  int Frames() const { return this->ranks > 1 ? this->reduced.frames : this->frames; }
  bool Converged() const
  {
    return this->ranks > 1 ? this->reduced.converged != 0 : this->localConverged;
  }
  double Estimate() const { return this->ranks > 1 ? this->reduced.estimate : this->estimate; }
  ///@}

  ///@{
  /// The engine's counters, read from the sessions when asked (after the worker's job on them is
  /// joined): macrocell slices built by the fine and the coarse session, what each runs (one line
  /// each, "" before it exists) and whether they run one evaluator.
  int slicesBuilt = 0;
  int interactiveSlicesBuilt = 0;
  std::string engineOptions;
  std::string interactiveEngineOptions;
  bool sharesEvaluator = false;
  ///@}

  ///@{
  /// The texts handed out as `const char*` (kept here until the next call).
  std::string estimateText;
  std::string refinementState;
  ///@}
};

/// The estimate for people: "31.2 dB", "\u2014" (not known yet: -inf or NaN), "no noise left"
/// (+inf: no covered pixel or no variance).
std::string InrFormatConvergenceEstimate(double db);

/// The refinement options the state line names.
struct InrRefinementLimits
{
  bool progressive = true;         // ProgressiveRefinement
  double convergenceTarget = 0.0;  // dB, 0 = off
  int maximumFrames = 0;
};

/// One line saying whether the image is still refining, e.g. "refining: 37 frames, 31.2 dB of
/// 41 dB", "converged: 206 frames, 41.3 dB", "stopped at 2048 frames (Maximum Frames 2048)",
/// "interacting: reduced 320x192 image", "one frame per render (Progressive Refinement off)".
std::string InrDescribeRefinement(const InrMapperReport& report, const InrRefinementLimits& limits);

#endif
