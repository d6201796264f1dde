// The mapper's render decision (InrRenderDecision) and the panel's texts (InrMapperReport), without
// VTK: what a render does (reduced or still, which session, on the worker or here, the frames'
// budget) from plain inputs, and the lines the panel shows.
#include <gtest/gtest.h>

#include <limits>

#include "InrMapperReport.h"
#include "InrRenderDecision.h"

namespace
{
using D = InrRenderDecision;
using Lod = InrLevelOfDetail;

// The mapper's state as the decision asks it: counts the calls, plans like a cost model that
// reduces every interactive frame to half size (or keeps the full size: `fullFits`).
struct FakeState
{
  bool coarseExists = true;
  bool standInReady = false;
  bool fullFits = false;
  int coarseCalls = 0;
  bool plannedStandIn = false;
  D::Queries Queries(int width, int height)
  {
    D::Queries q;
    q.coarseSession = [this]()
    {
      ++this->coarseCalls;
      return this->coarseExists;
    };
    q.standInReady = [this]() { return this->standInReady; };
    q.plan = [this, width, height](const Lod::Decision& d, bool standIn)
    {
      this->plannedStandIn = standIn;
      Lod::Frame f;
      f.interactive = d.interactive && !this->fullFits;
      f.width = f.interactive ? width / 2 : width;
      f.height = f.interactive ? height / 2 : height;
      f.frames = f.interactive && d.timeChange ? 3 : 1;
      return f;
    };
    return q;
  }
};

D::Inputs guiStill()
{
  D::Inputs in;  // ParaView's GUI: a still render, background refinement allowed
  in.width = 400;
  in.height = 300;
  in.backgroundAllowed = true;
  return in;
}

Lod::Decision drag() { return Lod::Decision{ true, false, 100.0 }; }
Lod::Decision timeChange() { return Lod::Decision{ true, true, 100.0 }; }

TEST(InrRenderDecision, StillRenderOfTheGuiRefinesOnTheWorkerWithTheWholeBudget)
{
  FakeState state;
  const D::Inputs in = guiStill();
  const D d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_FALSE(d.frame.interactive);
  EXPECT_EQ(d.frame.width, 400);
  EXPECT_TRUE(d.background);
  EXPECT_FALSE(d.useCoarse);
  EXPECT_EQ(state.coarseCalls, 0) << "a still render never creates the coarse session";
  EXPECT_EQ(d.budget, D::Budget::Whole);
  const inr::RefinementOptions o = d.Refinement(in, 7.0);
  EXPECT_DOUBLE_EQ(o.timeBudgetMs, in.timeBudgetMs) << "not what is left: the worker's step";
  EXPECT_EQ(o.framesPerRender, 1);
  // Without background refinement (scripts, a plain VTK window): here, with what is left.
  D::Inputs here = in;
  here.backgroundAllowed = false;
  const D h = D::Decide(here, state.Queries(in.width, in.height));
  EXPECT_FALSE(h.background);
  EXPECT_EQ(h.budget, D::Budget::Remaining);
  EXPECT_DOUBLE_EQ(h.Refinement(here, 7.0).timeBudgetMs, 7.0);
}

TEST(InrRenderDecision, ScriptsAndProgressiveOffCountFramesOnly)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.backgroundAllowed = false;
  in.framesPerRender = 16;
  D d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_EQ(d.budget, D::Budget::None);
  EXPECT_EQ(d.Refinement(in, 7.0).framesPerRender, 16);
  EXPECT_DOUBLE_EQ(d.Refinement(in, 7.0).timeBudgetMs, 0.0);
  in.progressive = false;
  d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_EQ(d.budget, D::Budget::None);
  EXPECT_EQ(d.Refinement(in, 7.0).framesPerRender, 1) << "one frame per render, whatever asked";
}

TEST(InrRenderDecision, TimeChangeDrawsAFreshReducedImageOnTheCoarseSessionWhereItExists)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.lod = timeChange();
  D d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_TRUE(d.frame.interactive);
  EXPECT_EQ(d.frame.width, 200);
  EXPECT_TRUE(d.useCoarse);
  EXPECT_FALSE(d.background);
  EXPECT_FALSE(d.cameraInteraction);
  EXPECT_EQ(d.budget, D::Budget::None);
  EXPECT_EQ(d.Refinement(in, 7.0).framesPerRender, 3) << "the fresh image's frames";
  state.coarseExists = false;
  d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_TRUE(d.frame.interactive);
  EXPECT_FALSE(d.useCoarse) << "no coarse session: the fine one draws the reduced frame";
}

TEST(InrRenderDecision, WhileTheFineSlicesBuildOnTheWorkerAStillRenderIsAReducedCoarseFrame)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.fineOnWorker = true;
  in.fineBusy = true;
  D d = D::Decide(in, state.Queries(in.width, in.height));
  EXPECT_TRUE(d.lod.timeChange);
  EXPECT_TRUE(d.frame.interactive);
  EXPECT_TRUE(d.useCoarse);
  EXPECT_FALSE(d.joinFine) << "drawn on the coarse session: the worker keeps the fine one";
  // Not for a capture (the saved picture is the still image), nor for a tile.
  for (int k = 0; k < 2; ++k)
  {
    D::Inputs capture = in;
    capture.lodSettings.capturing = k == 0;
    capture.tile = k == 1;
    d = D::Decide(capture, state.Queries(in.width, in.height));
    EXPECT_FALSE(d.frame.interactive) << "case " << k;
    EXPECT_TRUE(d.joinFine) << "case " << k << ": the fine session is needed: wait for it";
  }
}

TEST(InrRenderDecision, ARunningRefinementStepIsJoinedOnlyWhenThisRenderDrawsTheFineSessionHere)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.fineBusy = in.fineRefining = true;
  EXPECT_FALSE(D::Decide(in, state.Queries(400, 300)).joinFine) << "the worker goes on refining";
  in.lod = drag();
  state.fullFits = true;  // a drag at full resolution renders its frame here, at once
  const D d = D::Decide(in, state.Queries(400, 300));
  EXPECT_FALSE(d.frame.interactive);
  EXPECT_TRUE(d.cameraInteraction);
  EXPECT_FALSE(d.background);
  EXPECT_TRUE(d.joinFine);
  EXPECT_EQ(d.budget, D::Budget::None) << "the time budget is for a view at rest";
}

TEST(InrRenderDecision, DragsWithReprojectDrawOnTheCoarseSessionAndTheStandInWhereReady)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.lod = drag();
  D d = D::Decide(in, state.Queries(400, 300));
  EXPECT_TRUE(d.frame.interactive);
  EXPECT_FALSE(d.useCoarse) << "without Reproject a drag renders on the fine session";
  in.reproject = true;
  d = D::Decide(in, state.Queries(400, 300));
  EXPECT_TRUE(d.useCoarse);
  EXPECT_FALSE(d.standIn) << "no stand-in asked for";
  in.standInOption = true;
  d = D::Decide(in, state.Queries(400, 300));
  EXPECT_FALSE(d.standIn) << "stand-in not kept for this time yet";
  state.standInReady = true;
  state.fullFits = true;
  d = D::Decide(in, state.Queries(400, 300));
  EXPECT_TRUE(d.standIn && d.drawStandIn);
  EXPECT_TRUE(state.plannedStandIn) << "planned on the stand-in's cost model";
  EXPECT_TRUE(d.frame.interactive) << "stays on the stand-in even where full resolution fits";
  // Never for a tile or a capture.
  in.tile = true;
  d = D::Decide(in, state.Queries(400, 300));
  EXPECT_FALSE(d.standIn || d.frame.interactive || d.useCoarse);
}

TEST(InrRenderDecision, ATileRefinesToTheStillImagesQualityInOneRender)
{
  FakeState state;
  D::Inputs in = guiStill();
  in.tile = true;
  in.lod = drag();  // ignored for a tile
  in.maximumFrames = 300;
  const D d = D::Decide(in, state.Queries(400, 300));
  EXPECT_FALSE(d.frame.interactive);
  EXPECT_FALSE(d.background);
  EXPECT_EQ(d.budget, D::Budget::None);
  EXPECT_EQ(d.Refinement(in, 7.0).framesPerRender, 300);
  EXPECT_EQ(state.coarseCalls, 0);
}

TEST(InrMapperReport, TextsForThePanel)
{
  EXPECT_EQ(InrFormatConvergenceEstimate(31.24), "31.2 dB");
  EXPECT_EQ(InrFormatConvergenceEstimate(std::numeric_limits<double>::infinity()), "no noise left");
  EXPECT_EQ(InrFormatConvergenceEstimate(-std::numeric_limits<double>::infinity()), "\u2014");
  InrMapperReport r;
  const InrRefinementLimits limits{ true, 41.0, 2048 };
  EXPECT_EQ(InrDescribeRefinement(r, limits), "\u2014 (nothing rendered yet)");
  r.haveEngine = true;
  r.frames = 37;
  r.estimate = 31.2;
  EXPECT_EQ(InrDescribeRefinement(r, limits), "refining: 37 frames, 31.2 dB of 41 dB");
  r.localConverged = true;
  r.estimate = 41.3;
  EXPECT_EQ(InrDescribeRefinement(r, limits), "converged: 37 frames, 41.3 dB");
  r.estimate = 30.0;
  EXPECT_EQ(InrDescribeRefinement(r, limits), "stopped at 37 frames (Maximum Frames 2048), 30.0 dB");
  r.interactive = true;
  r.imageWidth = 320;
  r.imageHeight = 192;
  EXPECT_EQ(InrDescribeRefinement(r, limits), "interacting: reduced 320x192 image");
  // Several ranks: the reduced state, not this rank's.
  r = InrMapperReport{};
  r.haveEngine = true;
  r.frames = 50;
  r.localConverged = true;
  r.ranks = 2;
  r.reduced = InrParallelRendering::Refinement{ 0, 12, 25.0 };
  EXPECT_FALSE(r.Converged());
  EXPECT_EQ(InrDescribeRefinement(r, limits), "refining: 12 frames, 25.0 dB of 41 dB");
}
}
