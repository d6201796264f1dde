#include "InrLevelOfDetail.h"

#include <algorithm>
#include <cmath>

namespace
{
// Re-choose the scale only when the measured engine time leaves this band around the budget, and
// grow it by at most this factor at a time.
constexpr double kKeepScaleAbove = 0.5, kKeepScaleBelow = 1.0;
constexpr double kMaxGrowth = 1.25;
// Aim below the budget: per-frame cost varies with the view (coverage, collisions).
constexpr double kBudgetMargin = 0.8;
// The level of detail is judged on the engine's time (the part that scales with the image's
// pixels). The rest of the window's frame (depth read, upload, drawing the image over the whole
// viewport, the view's own passes, swap: on a software OpenGL 40-110 ms at ~1280x768, varying
// with the machine's load, whatever the image's resolution) is measured and left to the engine's
// budget, but at most this share of the budget: counted in full it drove the scale to its minimum
// (a 1/16 mosaic with a 2 ms engine) although no resolution could make it cheaper.
constexpr double kMaxFixedShare = 0.5;
}

InrLevelOfDetail::Decision InrLevelOfDetail::Classify(
  const Settings& s, double desiredUpdateRate, double time) const
{
  Decision d;
  d.budgetMs = s.frameTimeMs;
  // Under MPI with several ranks every frame is a full-resolution one: each rank would choose its
  // own reduced scale from its own timings, and images of different sizes do not composite.
  if (s.mode == Off || s.capturing || s.ranks > 1)
  {
    return d;
  }
  if (desiredUpdateRate >= s.updateRate)
  {
    d.budgetMs = std::min(d.budgetMs, 1000.0 / desiredUpdateRate);
    d.interactive = true;
    return d;
  }
  d.timeChange = s.mode == InteractionAndTime && s.framesPerRender == 1 && this->haveLastTime &&
    time != this->lastTime;
  d.interactive = d.timeChange;
  return d;
}

InrLevelOfDetail::Decision InrLevelOfDetail::WhileFineBuilds(const Settings& s)
{
  Decision d;
  d.interactive = true;
  d.timeChange = true;
  d.budgetMs = s.frameTimeMs;
  return d;
}

InrLevelOfDetail::Frame InrLevelOfDetail::Plan(
  const Settings& s, const Decision& d, int width, int height)
{
  Frame f;
  f.width = width;
  f.height = height;
  if (!d.interactive)
  {
    return f;
  }
  if (!this->lastInteractive)
  {
    this->ForgetCeiling();  // a new interaction: the view may have become cheaper or dearer
  }
  double scale = this->ChooseScale(d.budgetMs, width, height);
  if (d.timeChange && scale < 1.0)
  {
    f.frames = FreshFrameCount(scale, s.freshFrames);
    scale = FreshFrameScale(scale, s.freshFrames);
    // Small images cost more per pixel (each frame has a fixed cost: wavefront iterations,
    // threads): no more frames than the last fresh image's time per frame lets fit.
    if (this->freshFrameMs > 0.0 && f.frames > 1)
    {
      const double fixed = std::min(this->overheadMs + this->outsideMs, kMaxFixedShare * d.budgetMs);
      const double target = kBudgetMargin * (d.budgetMs - fixed);
      f.frames = std::clamp(int(target / this->freshFrameMs), 1, f.frames);
    }
  }
  f.width = std::max(1, int(std::lround(width * scale)));
  f.height = std::max(1, int(std::lround(height * scale)));
  // Full resolution fits the budget: an ordinary (still) render.
  f.interactive = f.width != width || f.height != height;
  if (!f.interactive)
  {
    f.frames = 1;
  }
  return f;
}

// The linear scale of an interactive image, judged on the engine's time (which scales with the
// pixel count) against the budget left once the window's fixed cost is taken off (capped at
// kMaxFixedShare of the budget; see there). A stable resolution lets reprojection reuse the
// accumulation during a drag, so the scale is kept while the engine's measured time at it stays
// in a band around that budget; outside it the scale is re-chosen from that measurement, growing
// by at most kMaxGrowth per change because small images cost more per pixel (each wavefront
// iteration has a fixed cost). Before any interactive measurement: from the per-pixel cost of the
// frames rendered so far. Full resolution when the budget allows it.
double InrLevelOfDetail::ChooseScale(double budgetMs, int width, int height)
{
  const double pixels = double(width) * double(height);
  const double fixed = std::min(this->overheadMs + this->outsideMs, kMaxFixedShare * budgetMs);
  const double engineBudget = budgetMs - fixed;
  const double target = kBudgetMargin * engineBudget;
  const double measured = this->interactiveMs;
  double s = this->lodScale;
  if (measured > 0.0)
  {
    if (measured >= kKeepScaleAbove * engineBudget && measured <= kKeepScaleBelow * engineBudget)
    {
      return this->lodScale;
    }
    if (measured < kKeepScaleAbove * engineBudget && this->framesAtScale >= 4 &&
      this->lodCeiling <= 1.0)
    {
      // Four frames at this scale well under the budget: the frame that barred the larger scale
      // may have been an outlier (a loaded machine, a background build). Allow it again only if
      // this scale's time, grown by the pixel ratio, says it fits: otherwise trying it again
      // restarts the accumulation, is too slow again, and the drag flips between two sizes.
      const double ratio = this->lodCeiling / this->lodScale;
      if (measured * ratio * ratio <= kKeepScaleBelow * engineBudget)
      {
        this->lodCeiling = 2.0;
      }
    }
    if (measured > kKeepScaleBelow * engineBudget && measured <= 2.0 * engineBudget &&
      this->framesAtScale < 2)
    {
      // One frame somewhat over the budget may be noise (a loaded machine): a second one decides
      // before the scale drops and is barred for the rest of the interaction.
      return this->lodScale;
    }
    s = std::min(this->lodScale * std::sqrt(target / std::max(measured, 1e-3)),
      this->lodScale * kMaxGrowth);
    if (measured > kKeepScaleBelow * engineBudget)
    {
      this->lodCeiling = std::min(this->lodCeiling, this->lodScale);  // measured too slow
    }
  }
  else if (this->msPerPixelFrame > 0.0)
  {
    s = std::sqrt(target / (this->msPerPixelFrame * pixels));
  }
  else
  {
    s = 0.25;  // nothing measured yet: a cautious first guess
  }
  s = std::clamp(std::floor(s * kScaleSteps) / kScaleSteps, kMinScale, 1.0);
  if (s == this->lodScale && measured > 0.0)
  {
    // Out of the band but rounded back to the same scale: one step in the needed direction.
    s = std::clamp(s + (measured > engineBudget ? -1.0 : 1.0) / kScaleSteps, kMinScale, 1.0);
  }
  if (s >= this->lodCeiling)
  {
    s = this->lodScale;  // never back up to a scale this interaction found too slow: no oscillation
  }
  if (s != this->lodScale)
  {
    this->lodScale = s;
    this->interactiveMs = 0.0;  // not measured at the new scale yet
    this->framesAtScale = 0;
  }
  return s;
}

// A time-change frame starts its image afresh (one frame of a thin medium is sparse speckle):
// up to `fresh` frames at a scale that keeps pixels x frames at most what one frame at `scale`
// costs, so the scale controller's measurement (taken as the render time of one frame at its
// scale) still holds. The scale is a step of 1/kScaleSteps, never below kMinScale.
double InrLevelOfDetail::FreshFrameScale(double scale, int fresh)
{
  if (fresh <= 1)
  {
    return scale;
  }
  const double s = std::max(kMinScale,
    std::floor(scale / std::sqrt(double(fresh)) * kScaleSteps + 1e-9) / kScaleSteps);
  return std::floor(scale * scale / (s * s) + 1e-9) >= 2.0 ? s : scale;
}

int InrLevelOfDetail::FreshFrameCount(double scale, int fresh)
{
  const double s = FreshFrameScale(scale, fresh);
  return s == scale ? 1 : std::clamp(int(std::floor(scale * scale / (s * s) + 1e-9)), 1, fresh);
}

// Exponential moving averages (recent frames dominate: the view changes during a drag): the
// engine's time per pixel per frame, the rest of the render (scene, depth read, upload, blend),
// and the engine time of interactive frames at the current scale.
void InrLevelOfDetail::MeasureFrame(double renderMs, double refineMs, double updateMs,
  int framesRendered, int width, int height, bool interactive)
{
  if (framesRendered <= 0)
  {
    return;
  }
  const double engineMs = std::max(0.0, refineMs - updateMs);
  const double perPixel = engineMs / (double(framesRendered) * double(width) * double(height));
  const double overhead = std::max(0.0, renderMs - refineMs);
  constexpr double kWeight = 0.5;
  auto ema = [](double old, double now) { return old > 0.0 ? (1.0 - kWeight) * old + kWeight * now : now; };
  this->msPerPixelFrame = ema(this->msPerPixelFrame, perPixel);
  this->overheadMs = ema(this->overheadMs, overhead);
  if (interactive)
  {
    this->interactiveMs = ema(this->interactiveMs, engineMs);
    ++this->framesAtScale;
    if (framesRendered > 1)
    {
      this->freshFrameMs = ema(this->freshFrameMs, engineMs / framesRendered);
    }
  }
}

void InrLevelOfDetail::WindowRendered(double windowMs, double mapperMs, double aheadMs)
{
  const double outside = std::max(0.0, windowMs - mapperMs - aheadMs);
  this->outsideMs = this->outsideMs > 0.0 ? 0.5 * (this->outsideMs + outside) : outside;
}
