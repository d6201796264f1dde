// Sub-domain rendering under MPI (pvbatch / pvserver with several ranks): the ranks split the
// picture (image space: rank r traces the pixels (x + y) mod N = r at full depth,
// inr::RenderSettings::pixelShare), each takes the GPU of its local rank, and the refinement state
// is reduced over all ranks. IceT composites the ranks' premultiplied images in the order of
// boxes each rank reports (RankBrick: bricks that tile the model's box, as ParaView's ordered
// compositing requires); disjoint pixels blend alike in any order. A plain C++ helper of the
// mapper and the representation; with one process (the GUI's builtin server, pvpython)
// everything here is the identity.
#ifndef InrParallelRendering_h
#define InrParallelRendering_h

#include <string>
#include <vector>

#include "Render/BrickDecomposition.h"

namespace InrParallelRendering
{
/// This process's rank and the number of ranks of ParaView's global controller (1 without MPI).
struct Ranks
{
  int rank = 0;
  int count = 1;
};
Ranks GlobalRanks();

/// The rank's index among the ranks of its node, from the launcher's environment
/// (OMPI_COMM_WORLD_LOCAL_RANK for Open MPI, MPI_LOCALRANKID for MPICH / Intel MPI, SLURM_LOCALID
/// under srun), or -1 when none is set. `source` names the variable it came from.
int LocalRank(std::string* source = nullptr);

/// The rank's index among the ranks of its node: with several ranks and MPI initialised, its rank
/// in MPI_Comm_split_type(MPI_COMM_TYPE_SHARED) of the global controller's communicator (any
/// launcher: mpirun of Open MPI or MPICH, srun); otherwise LocalRank(). -1 when unknown. `source`
/// names where it came from. Collective over the controller's ranks when it asks MPI: call it
/// where every rank passes (the mapper: at the start of its first Render).
int NodeLocalRank(std::string* source = nullptr);

/// The GPU of a node-local rank: the ranks of a node take its `devices` GPUs round-robin; -1
/// (the engine's default device) when the local rank is unknown or there is no GPU.
inline int DeviceForLocalRank(int localRank, int devices)
{
  return localRank >= 0 && devices > 0 ? localRank % devices : -1;
}

/// The box rank `rank` reports to ParaView's ordered compositing: the brick of rank `rank` of `count` for a model box (xmin, xmax, ymin, ymax, zmin, zmax) and
/// a macrocell grid of `resolution`^3 cells (refined to at least `count` cells per axis, so any
/// rank count splits); the same on every rank (the decomposition is deterministic).
inr::Brick RankBrick(const double bounds[6], int resolution, int rank, int count);

/// The refinement state of all ranks: converged only when every rank has converged, the fewest
/// accumulated frames and the lowest convergence estimate. Collective: every rank must call it
/// once per render. Without MPI it returns its arguments.
struct Refinement
{
  int converged = 0;
  int frames = 0;
  double estimate = 0.0;
};
Refinement ReduceRefinement(const Refinement& local);

/// Sample shares' refinement state: converged only when every rank has converged, the frames of
/// all ranks together, and the estimated PSNR of their combined image (each rank's error falls
/// with its frames squared over all frames squared: MSE = sum of f_r^2 MSE_r / (sum of f_r)^2;
/// a rank without frames adds nothing). Collective like ReduceRefinement.
Refinement ReduceSampleShares(const Refinement& local);

/// A rectangle of pixels [x0, x1) x [y0, y1) of a render tile; empty when x1 <= x0 or y1 <= y0.
struct PixelRect
{
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool Empty() const { return x1 <= x0 || y1 <= y0; }
};

/// Sample shares (every rank renders the whole view for its own frames): replaces `image` (this
/// rank's premultiplied RGBA, width x height, row 0 at the top, the mean of its `frames` frames)
/// by the mean over every rank's frames, sum of f_r x image_r / sum of f_r, and returns that sum.
/// Only the union of the ranks' `rect`s travels (the pixels the volume can cover; transparent
/// outside). Ranks without frames, or whose size differs from the one the ranks with frames
/// agree on, add nothing; 0 (image untouched) when no rank brings frames or their sizes differ.
/// Collective: every rank calls it once per render, whatever it draws.
int CombineSampleShares(int width, int height, const PixelRect& rect, int frames, std::vector<float>& image);

/// What all ranks agree on before the depth composite: whether any rank drew geometry before its
/// volumes (then every rank takes part in MinOverRanks, also one without geometry of its own),
/// whether every rank's tile has the same size (a composite needs that), and the union of the
/// ranks' volume rectangles (pixels outside every volume's box never need a depth limit).
/// Collective: every rank calls it once per render, whatever it draws. Without MPI it returns
/// its arguments.
struct DepthPlan
{
  bool anyGeometry = false;
  bool sameSize = true;
  PixelRect rect;
};
DepthPlan PlanDepthComposite(bool localGeometry, int width, int height, const PixelRect& localRect);

/// The per-element minimum of `values` over the ranks, in place (the composite of the ranks'
/// depth buffers: the nearest geometry of any rank). Collective; every rank passes as many
/// values. Without MPI it leaves them.
void MinOverRanks(std::vector<float>& values);

/// Every rank's `local` text, in rank order. Collective like ReduceRefinement.
std::vector<std::string> GatherText(const std::string& local);
}

#endif
