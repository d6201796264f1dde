#include "InrRenderDecision.h"

InrRenderDecision InrRenderDecision::Decide(const Inputs& in, const Queries& ask)
{
  InrRenderDecision r;
  // Tiles of a larger picture are captures (still renders): always at full resolution.
  InrLevelOfDetail::Decision d;
  if (!in.tile)
  {
    d = in.lod;
    if (in.fineOnWorker && !d.interactive && !in.lodSettings.capturing)
    {
      // The fine slices of this time are still building on the worker (or will, once its
      // refinement step is done): a reduced frame of the coarse session, as right after a time
      // change (a fresh image).
      d = InrLevelOfDetail::WhileFineBuilds(in.lodSettings);
    }
  }
  // A reduced frame of a time change, or of a camera drag with Reproject on, draws on the coarse
  // session (where it exists): during a drag the fine session keeps its full-resolution image,
  // which the still render after the drag reprojects to the new camera instead of restarting.
  const auto rendersCoarse = [&in, &ask](const InrLevelOfDetail::Decision& k)
  { return InrLevelOfDetail::RendersCoarse(k, in.reproject, true) && ask.coarseSession(); };
  // A camera drag drawn on the stand-in of the network has its own cost model, and stays on the
  // stand-in even where its full resolution fits the budget (an on-screen view only).
  r.standIn = in.standInOption && !in.tile && !in.lodSettings.capturing && d.interactive &&
    !d.timeChange && rendersCoarse(d) && ask.standInReady();
  r.frame = ask.plan(d, r.standIn);
  r.frame.interactive = r.frame.interactive || r.standIn;
  // A camera interaction that fits at full resolution renders as a still frame, but one frame:
  // the refinement time budget is for a view at rest (a drag frame would otherwise take it all).
  r.cameraInteraction = d.interactive && !d.timeChange;
  d.interactive = r.frame.interactive;
  r.useCoarse = rendersCoarse(d);
  // A still render of the fine session in the GUI refines it on the worker; a camera drag that
  // fits at full resolution renders its one frame here (it must show the new camera at once).
  r.background = !r.frame.interactive && !r.useCoarse && !r.cameraInteraction && !in.tile &&
    in.backgroundAllowed;
  // A frame of the fine session here needs it back from the worker; a render that lets the
  // worker go on refining draws the image the worker's steps made so far.
  r.joinFine = in.fineBusy && !r.useCoarse && !(r.background && in.fineRefining);
  r.drawStandIn = r.standIn && r.useCoarse;
  r.lod = d;
  // Refinement by time: a still render of the GUI's one-frame-per-render refinement adds the
  // frames that fit in the budget.
  if (!r.frame.interactive && !r.cameraInteraction && in.progressive && in.framesPerRender == 1 &&
    !in.tile)
  {
    r.budget = r.background ? Budget::Whole : Budget::Remaining;
  }
  return r;
}

inr::RefinementOptions InrRenderDecision::Refinement(const Inputs& in, double remainingMs) const
{
  inr::RefinementOptions o;
  o.maximumFrames = in.maximumFrames;
  o.convergenceTarget = in.convergenceTarget;
  o.framesPerRender = this->frame.interactive ? this->frame.frames
    : in.progressive                          ? in.framesPerRender
                                              : 1;
  if (this->budget != Budget::None)
  {
    o.timeBudgetMs = this->budget == Budget::Whole ? in.timeBudgetMs : remainingMs;
  }
  if (in.tile && in.progressive && !this->frame.interactive)
  {
    // A tile is rendered once per capture, from a fresh accumulation: refine it to the still
    // image's quality (convergence target or frame limit) in this one render.
    o.framesPerRender = o.maximumFrames;
  }
  return o;
}
