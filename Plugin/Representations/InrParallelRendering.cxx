#include "InrParallelRendering.h"

#include "vtkCommunicator.h"
#include "vtkMultiProcessController.h"

#include <algorithm>
#include <cstdlib>

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
