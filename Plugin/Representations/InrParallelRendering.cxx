#include "InrParallelRendering.h"

#include "vtkCommunicator.h"
#include "vtkMultiProcessController.h"
#ifdef INR_HAVE_VTK_MPI
#include "vtkMPI.h"
#include "vtkMPICommunicator.h"
#endif

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace InrParallelRendering
{
Ranks GlobalRanks()
{
  Ranks r;
  if (vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController())
  {
    r.rank = c->GetLocalProcessId();
    r.count = c->GetNumberOfProcesses();
  }
  if (r.count < 1 || r.rank < 0 || r.rank >= r.count)
  {
    r = Ranks{};
  }
  return r;
}

int LocalRank(std::string* source)
{
  for (const char* name : { "OMPI_COMM_WORLD_LOCAL_RANK", "MPI_LOCALRANKID", "SLURM_LOCALID" })
  {
    const char* v = std::getenv(name);
    if (!v || !*v)
    {
      continue;
    }
    char* end = nullptr;
    const long n = std::strtol(v, &end, 10);
    if (*end == '\0' && n >= 0 && n < 65536)
    {
      if (source)
      {
        *source = name;
      }
      return static_cast<int>(n);
    }
  }
  return -1;
}

int NodeLocalRank(std::string* source)
{
#ifdef INR_HAVE_VTK_MPI
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  auto* comm = vtkMPICommunicator::SafeDownCast(c ? c->GetCommunicator() : nullptr);
  int initialized = 0, finalized = 0;
  MPI_Initialized(&initialized);
  MPI_Finalized(&finalized);
  if (comm && comm->GetMPIComm() && comm->GetMPIComm()->GetHandle() && initialized &&
    !finalized && c->GetNumberOfProcesses() > 1)
  {
    // The ranks that share this node's memory, in the order of their ranks in the communicator:
    // the same numbering as the launchers' local ranks, from MPI itself.
    MPI_Comm node = MPI_COMM_NULL;
    if (MPI_Comm_split_type(*comm->GetMPIComm()->GetHandle(), MPI_COMM_TYPE_SHARED,
          c->GetLocalProcessId(), MPI_INFO_NULL, &node) == MPI_SUCCESS &&
      node != MPI_COMM_NULL)
    {
      int local = -1;
      MPI_Comm_rank(node, &local);
      MPI_Comm_free(&node);
      if (local >= 0)
      {
        if (source)
        {
          *source = "MPI_Comm_split_type";
        }
        return local;
      }
    }
  }
#endif
  return LocalRank(source);
}

inr::Brick RankBrick(const double bounds[6], int resolution, int rank, int count)
{
  const inr::Box3f box{ { float(bounds[0]), float(bounds[2]), float(bounds[4]) },
    { float(bounds[1]), float(bounds[3]), float(bounds[5]) } };
  // Only a tiling for IceT's ordering (each rank draws pixels, not this box): a grid with at
  // least as many cells along each axis as ranks splits for any rank count.
  const int cells = std::max(resolution, count);
  return inr::brickDecomposition(box, inr::Int3{ cells, cells, cells }, count)
    [static_cast<std::size_t>(rank)];
}

Refinement ReduceRefinement(const Refinement& local)
{
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  if (!c || c->GetNumberOfProcesses() < 2)
  {
    return local;
  }
  const int ints[2] = { local.converged, local.frames };
  int intsMin[2] = { 0, 0 };
  c->AllReduce(ints, intsMin, 2, vtkCommunicator::MIN_OP);
  double estimateMin = local.estimate;
  c->AllReduce(&local.estimate, &estimateMin, 1, vtkCommunicator::MIN_OP);
  return Refinement{ intsMin[0], intsMin[1], estimateMin };
}

Refinement ReduceSampleShares(const Refinement& local)
{
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  if (!c || c->GetNumberOfProcesses() < 2)
  {
    return local;
  }
  int converged = local.converged;
  int convergedMin = converged;
  c->AllReduce(&converged, &convergedMin, 1, vtkCommunicator::MIN_OP);
  // The estimate as a mean squared error (+inf dB: 0; -inf dB, a pixel with one sample: +inf).
  const double f = local.frames > 0 ? double(local.frames) : 0.0;
  const double mse = std::pow(10.0, -local.estimate / 10.0);
  const double sums[2] = { f, f > 0.0 ? f * f * mse : 0.0 };
  double all[2] = { 0.0, 0.0 };
  c->AllReduce(sums, all, 2, vtkCommunicator::SUM_OP);
  Refinement r;
  r.converged = convergedMin;
  r.frames = int(all[0] + 0.5);
  r.estimate = all[0] > 0.0 ? -10.0 * std::log10(all[1] / (all[0] * all[0])) : 0.0;
  return r;
}

int CombineSampleShares(int width, int height, const PixelRect& rect, int frames, std::vector<float>& image)
{
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  const std::size_t values = std::size_t(std::max(width, 0)) * std::size_t(std::max(height, 0)) * 4;
  const bool brings = frames > 0 && image.size() == values && values > 0;
  if (!c || c->GetNumberOfProcesses() < 2)
  {
    return brings ? frames : 0;
  }
  // The size of the ranks with frames, as PlanDepthComposite agrees on one (a maximum and a
  // negated minimum agree only when every such rank has that size), and the union of their
  // rectangles (clipped to the image): what travels.
  const int lowest = std::numeric_limits<int>::min() / 2;
  const PixelRect r{ std::max(rect.x0, 0), std::max(rect.y0, 0), std::min(rect.x1, width),
    std::min(rect.y1, height) };
  const bool sends = brings && !r.Empty();
  const int local[8] = { brings ? width : lowest, brings ? -width : lowest, brings ? height : lowest,
    brings ? -height : lowest, sends ? -r.x0 : lowest, sends ? -r.y0 : lowest, sends ? r.x1 : lowest,
    sends ? r.y1 : lowest };
  int all[8];
  c->AllReduce(local, all, 8, vtkCommunicator::MAX_OP);
  if (all[0] == lowest || all[0] != -all[1] || all[2] != -all[3])
  {
    return 0;
  }
  const int w = all[0], h = all[2];
  const PixelRect u = all[4] == lowest ? PixelRect{} : PixelRect{ -all[4], -all[5], all[6], all[7] };
  const int rw = std::max(0, u.x1 - u.x0), rh = std::max(0, u.y1 - u.y0);
  const std::size_t n = std::size_t(rw) * std::size_t(rh) * 4;
  // The frame-weighted sum over the rectangle and the frames, in one reduction (float holds frame
  // counts exactly).
  std::vector<float> mine(n + 1, 0.0f), sum(n + 1, 0.0f);
  if (brings)
  {
    const float f = float(frames);
    for (int y = 0; y < rh; ++y)
    {
      const float* row = image.data() + (std::size_t(u.y0 + y) * std::size_t(w) + std::size_t(u.x0)) * 4;
      float* out = mine.data() + std::size_t(y) * std::size_t(rw) * 4;
      for (std::size_t k = 0; k < std::size_t(rw) * 4; ++k)
      {
        out[k] = f * row[k];
      }
    }
    mine[n] = f;
  }
  c->AllReduce(mine.data(), sum.data(), static_cast<vtkIdType>(n + 1), vtkCommunicator::SUM_OP);
  const float total = sum[n];
  if (!(total > 0.0f))
  {
    return 0;
  }
  image.assign(std::size_t(w) * std::size_t(h) * 4, 0.0f);  // nothing outside the rectangle
  for (int y = 0; y < rh; ++y)
  {
    const float* in = sum.data() + std::size_t(y) * std::size_t(rw) * 4;
    float* row = image.data() + (std::size_t(u.y0 + y) * std::size_t(w) + std::size_t(u.x0)) * 4;
    for (std::size_t k = 0; k < std::size_t(rw) * 4; ++k)
    {
      row[k] = in[k] / total;
    }
  }
  return int(total + 0.5f);
}

DepthPlan PlanDepthComposite(bool localGeometry, int width, int height, const PixelRect& localRect)
{
  DepthPlan plan{ localGeometry, true, localRect };
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  if (!c || c->GetNumberOfProcesses() < 2)
  {
    return plan;
  }
  // One MAX reduction answers everything: a size's maximum and its negated minimum agree only
  // when every rank has that size; the union's corners are the extreme corners of the non-empty
  // rectangles (an empty one takes no part).
  const int lowest = std::numeric_limits<int>::min() / 2;
  const bool empty = localRect.Empty();
  const int local[9] = { localGeometry ? 1 : 0, width, -width, height, -height,
    empty ? lowest : -localRect.x0, empty ? lowest : -localRect.y0,
    empty ? lowest : localRect.x1, empty ? lowest : localRect.y1 };
  int all[9];
  c->AllReduce(local, all, 9, vtkCommunicator::MAX_OP);
  plan.anyGeometry = all[0] != 0;
  plan.sameSize = all[1] == -all[2] && all[3] == -all[4];
  plan.rect = all[5] == lowest ? PixelRect{} : PixelRect{ -all[5], -all[6], all[7], all[8] };
  return plan;
}

void MinOverRanks(std::vector<float>& values)
{
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  if (!c || c->GetNumberOfProcesses() < 2 || values.empty())
  {
    return;
  }
  std::vector<float> all(values.size());
  c->AllReduce(values.data(), all.data(), static_cast<vtkIdType>(values.size()),
    vtkCommunicator::MIN_OP);
  values.swap(all);
}

std::vector<std::string> GatherText(const std::string& local)
{
  vtkMultiProcessController* c = vtkMultiProcessController::GetGlobalController();
  if (!c || c->GetNumberOfProcesses() < 2)
  {
    return { local };
  }
  const int n = c->GetNumberOfProcesses();
  const vtkIdType length = static_cast<vtkIdType>(local.size());
  std::vector<vtkIdType> lengths(static_cast<std::size_t>(n)), offsets(static_cast<std::size_t>(n));
  c->AllGather(&length, lengths.data(), 1);
  vtkIdType total = 0;
  for (int r = 0; r < n; ++r)
  {
    offsets[static_cast<std::size_t>(r)] = total;
    total += lengths[static_cast<std::size_t>(r)];
  }
  std::vector<char> all(static_cast<std::size_t>(std::max<vtkIdType>(total, 1)));
  c->AllGatherV(local.data(), all.data(), length, lengths.data(), offsets.data());
  std::vector<std::string> texts;
  for (int r = 0; r < n; ++r)
  {
    texts.emplace_back(all.data() + offsets[static_cast<std::size_t>(r)],
      static_cast<std::size_t>(lengths[static_cast<std::size_t>(r)]));
  }
  return texts;
}
}
