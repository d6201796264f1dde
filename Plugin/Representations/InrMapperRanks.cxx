#include "InrMapperRanks.h"

#include "vtkActor2D.h"
#include "vtkCamera.h"
#include "vtkMath.h"
#include "vtkMatrix4x4.h"
#include "vtkPropCollection.h"
#include "vtkRenderer.h"
#include "vtkVolume.h"

#include "InrFramebufferCompositor.h"
#include "InrMapperReport.h"

#include "Backends/RenderSession.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <sstream>

namespace
{
// Whether the renderer draws anything that can write depth before its volumes: a visible prop
// with data (ParaView keeps empty actors visible, e.g. the selection's) that is neither a volume
// nor a 2D overlay (those are drawn after the volumes).
bool geometryDrawnBeforeVolumes(vtkRenderer* ren)
{
  vtkPropCollection* props = ren->GetViewProps();
  vtkCollectionSimpleIterator it;
  props->InitTraversal(it);
  while (vtkProp* prop = props->GetNextProp(it))
  {
    if (!prop->GetVisibility() || vtkVolume::SafeDownCast(prop) || vtkActor2D::SafeDownCast(prop))
    {
      continue;
    }
    const double* bounds = prop->GetBounds();
    if (!bounds || vtkMath::AreBoundsInitialized(bounds))
    {
      return true;  // no bounds (e.g. a widget): assume it draws
    }
  }
  return false;
}

// The pixels of a width x height tile that the volume's box can cover (its corners projected,
// two pixels wider for rounding); the whole tile when a corner lies at or behind the eye (its
// projection says nothing), nothing when the volume has no bounds (no data on this rank).
InrParallelRendering::PixelRect volumeRect(vtkRenderer* ren, vtkVolume* vol, int width, int height)
{
  const double* b = vol->GetBounds();
  if (width <= 0 || height <= 0 || !b || !vtkMath::AreBoundsInitialized(b))
  {
    return {};
  }
  vtkMatrix4x4* m = ren->GetActiveCamera()->GetCompositeProjectionTransformMatrix(
    double(width) / double(height), -1, 1);
  double lo[2] = { std::numeric_limits<double>::max(), std::numeric_limits<double>::max() };
  double hi[2] = { std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest() };
  for (int k = 0; k < 8; ++k)
  {
    const double p[4] = { b[k & 1], b[2 + ((k >> 1) & 1)], b[4 + ((k >> 2) & 1)], 1.0 };
    double q[4];
    m->MultiplyPoint(p, q);
    if (!(q[3] > 1e-9))
    {
      return { 0, 0, width, height };
    }
    const double x = (q[0] / q[3] + 1.0) * 0.5 * width, y = (q[1] / q[3] + 1.0) * 0.5 * height;
    lo[0] = std::min(lo[0], x);
    hi[0] = std::max(hi[0], x);
    lo[1] = std::min(lo[1], y);
    hi[1] = std::max(hi[1], y);
  }
  const auto clampTo = [](double v, int n) { return int(std::max(0.0, std::min(double(n), v))); };
  return { clampTo(std::floor(lo[0]) - 2, width), clampTo(std::floor(lo[1]) - 2, height),
    clampTo(std::ceil(hi[0]) + 2, width), clampTo(std::ceil(hi[1]) + 2, height) };
}
}

void InrMapperRanks::LookUpLocalRank()
{
  if (!this->haveLocalRank)
  {
    this->localRank = InrParallelRendering::NodeLocalRank(&this->localRankSource);
    this->haveLocalRank = true;
  }
}

int InrMapperRanks::CudaDevice()
{
  if (!this->haveLocalRank)
  {
    this->localRank = InrParallelRendering::LocalRank(&this->localRankSource);
  }
  if (this->cudaDevices < 0)
  {
    this->cudaDevices = inr::cudaDeviceCount();
  }
  return InrParallelRendering::DeviceForLocalRank(this->localRank, this->cudaDevices);
}

const std::string& InrMapperRanks::Note(bool rebuilt, bool cuda, int cudaDevice)
{
  const std::string key = std::to_string(this->localRank) + this->localRankSource;
  if (rebuilt || key != this->noteKey)
  {
    this->noteKey = key;
    this->note.clear();
    if (this->ranks.count > 1 || this->localRank >= 0)
    {
      std::ostringstream s;
      s << "; rank " << this->ranks.rank << " of " << this->ranks.count;
      if (this->localRank >= 0)
      {
        s << " (local rank " << this->localRank << " from " << this->localRankSource << ")";
      }
      if (cuda)
      {
        s << ", CUDA device " << cudaDevice << " of " << this->cudaDevices;
      }
      this->note = s.str();
    }
  }
  return this->note;
}

void InrMapperRanks::Share(inr::RenderSettings& settings) const
{
  if (this->SplitsSamples())
  {
    settings.sampleShare = inr::SampleShare{ this->ranks.rank, this->ranks.count };
  }
  else if (this->ranks.count > 1)
  {
    settings.pixelShare = inr::PixelShare{ this->ranks.rank, this->ranks.count };
  }
}

void InrMapperRanks::ShareRefinement(inr::RefinementOptions& options) const
{
  if (!this->SplitsSamples())
  {
    return;
  }
  const int n = this->ranks.count;
  options.maximumFrames = std::max(1, (options.maximumFrames + n - 1) / n);
  options.minimumFrames = std::max(2, (options.minimumFrames + n - 1) / n);
  options.framesPerRender = std::max(1, (options.framesPerRender + n - 1) / n);
  if (options.convergenceTarget > 0.0)
  {
    options.convergenceTarget = std::max(1e-3, options.convergenceTarget - 10.0 * std::log10(double(n)));
  }
}

int InrMapperRanks::CombineImage(int width, int height, int frames, std::vector<float>& image)
{
  if (!this->SplitsSamples() || this->imageCombined)
  {
    return 0;
  }
  this->imageCombined = true;
  // A reduced interactive image has another size than the tile: all of it travels.
  const bool tileSized = width == this->imageRectWidth && height == this->imageRectHeight;
  const InrParallelRendering::PixelRect rect =
    tileSized ? this->imageRect : InrParallelRendering::PixelRect{ 0, 0, width, height };
  int total = InrParallelRendering::CombineSampleShares(width, height, rect, frames, image);
  if (std::getenv("INR_VOLUME_DEBUG"))
  {
    std::cerr << "INR Volume: rank " << this->ranks.rank << " sample shares: " << frames
              << " own frames, " << total << " in all, over " << std::max(0, rect.x1 - rect.x0) << "x"
              << std::max(0, rect.y1 - rect.y0) << " of " << width << "x" << height << " pixels\n";
  }
  if (total == 0 && frames > 0 && image.size() == std::size_t(width) * std::size_t(height) * 4)
  {
    total = frames;  // the ranks' sizes differ: this rank's own frames, an unbiased image still
  }
  if (total > 0)
  {
    // This rank's pixels of the whole: IceT blends the ranks' disjoint pixels in any order.
    const int n = this->ranks.count, r = this->ranks.rank;
    const std::size_t w = std::size_t(width);
    for (std::size_t y = 0; y < std::size_t(height); ++y)
    {
      for (std::size_t x = 0; x < w; ++x)
      {
        if (int((x + y) % std::size_t(n)) != r)
        {
          std::fill_n(image.begin() + std::ptrdiff_t(4 * (y * w + x)), 4, 0.0f);
        }
      }
    }
  }
  return total;
}

void InrMapperRanks::FinishRender()
{
  std::vector<float> none;
  this->CombineImage(0, 0, 0, none);
}

// Whether to read is decided by all ranks together (PlanDepthComposite) since the reduction is
// collective: a rank without geometry contributes the clear value.
bool InrMapperRanks::CompositeDepth(vtkRenderer* ren, vtkVolume* vol, std::vector<float>& depth)
{
  int width = 0, height = 0, x0 = 0, y0 = 0;
  ren->GetTiledSizeAndOrigin(&width, &height, &x0, &y0);
  const bool localGeometry = geometryDrawnBeforeVolumes(ren);
  if (this->ranks.count < 2)
  {
    if (localGeometry && width > 0 && height > 0)
    {
      InrFramebufferCompositor::ReadDepth(ren->GetRenderWindow(), x0, y0, width, height, depth);
      return true;
    }
    return false;
  }
  const InrParallelRendering::DepthPlan plan = InrParallelRendering::PlanDepthComposite(
    localGeometry, width, height, volumeRect(ren, vol, width, height));
  // What sample shares send of a tile-sized image (CombineImage): the volume's rectangle, in the
  // engine's rows (0 at the top; GL's 0 is the bottom).
  this->imageRect = plan.sameSize
    ? InrParallelRendering::PixelRect{ plan.rect.x0, height - plan.rect.y1, plan.rect.x1, height - plan.rect.y0 }
    : InrParallelRendering::PixelRect{ 0, 0, width, height };
  this->imageRectWidth = width;
  this->imageRectHeight = height;
  if (!plan.anyGeometry || width <= 0 || height <= 0)
  {
    return false;
  }
  if (!plan.sameSize)
  {
    // Not seen with ParaView (every rank renders the same view); each rank keeps its own depth.
    if (!this->warnedDepthSize)
    {
      std::cerr << "INR Volume: the ranks' render sizes differ: each rank clips its rays by its "
                   "own geometry only\n";
      this->warnedDepthSize = true;
    }
    if (localGeometry)
    {
      InrFramebufferCompositor::ReadDepth(ren->GetRenderWindow(), x0, y0, width, height, depth);
      return true;
    }
    return false;
  }
  const InrParallelRendering::PixelRect r = plan.rect;
  const int rw = std::max(0, r.x1 - r.x0), rh = std::max(0, r.y1 - r.y0);
  std::vector<float> part;
  if (localGeometry && rw > 0 && rh > 0)
  {
    InrFramebufferCompositor::ReadDepth(ren->GetRenderWindow(), x0 + r.x0, y0 + r.y0, rw, rh, part);
  }
  else
  {
    part.assign(std::size_t(rw) * std::size_t(rh), 1.0f);  // the clear value: no geometry here
  }
  InrParallelRendering::MinOverRanks(part);
  depth.assign(std::size_t(width) * std::size_t(height), 1.0f);
  for (int j = 0; j < rh; ++j)
  {
    std::copy_n(part.begin() + std::ptrdiff_t(j) * rw, rw,
      depth.begin() + std::ptrdiff_t(r.y0 + j) * width + r.x0);
  }
  if (std::getenv("INR_VOLUME_DEBUG"))
  {
    std::cerr << "INR Volume: rank " << this->ranks.rank << " depth composite over " << rw << "x"
              << rh << " pixels (own geometry " << (localGeometry ? "yes" : "no") << ")\n";
  }
  return true;
}

void InrMapperRanks::Reduce(const Local& local, InrMapperReport& report) const
{
  // What every rank did (GetRanksInUse): how a user checks that all of them render.
  std::ostringstream line;
  line << "rank " << this->ranks.rank << " of " << this->ranks.count << ": ";
  if (local.rendered)
  {
    line << local.queries << " queries in the last render, " << local.shownFrames << " frames, "
         << (local.converged ? "converged" : "refining") << "; " << local.backend;
  }
  else
  {
    line << "nothing drawn in the last render";
  }
  if (this->ranks.count < 2)
  {
    report.ranksInUse = line.str();
    return;
  }
  // A rank that drew nothing reports "converged", the most frames and the highest estimate.
  InrParallelRendering::Refinement mine;
  mine.converged = local.rendered ? int(local.converged) : 1;
  mine.frames = local.rendered ? local.frames : std::numeric_limits<int>::max();
  mine.estimate = local.rendered ? local.estimate : std::numeric_limits<double>::infinity();
  InrParallelRendering::Refinement all = this->SplitsSamples()
    ? InrParallelRendering::ReduceSampleShares(
        InrParallelRendering::Refinement{ mine.converged, local.rendered ? local.frames : 0, mine.estimate })
    : InrParallelRendering::ReduceRefinement(mine);
  if (all.frames == std::numeric_limits<int>::max())
  {
    all = InrParallelRendering::Refinement{ 0, 0, 0.0 };  // no rank drew anything
  }
  report.reduced = all;
  std::string text;
  for (const std::string& l : InrParallelRendering::GatherText(line.str()))
  {
    text += (text.empty() ? "" : "\n") + l;
  }
  report.ranksInUse = text;
}
