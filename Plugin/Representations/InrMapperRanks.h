// The mapper across MPI ranks (pvbatch / pvserver with several ranks; with one process everything
// here is the identity): which GPU this rank takes, which pixels it traces, the depth that clips
// its rays (composited over every rank's geometry) and the refinement state reduced over the
// ranks after each render. The collectives live here; InrParallelRendering.h holds the MPI calls
// themselves. Every rank must reach CompositeDepth and Reduce once per render, whatever it draws:
// vtkInrVolumeMapper::Render calls them first thing and on every way out.
#ifndef InrMapperRanks_h
#define InrMapperRanks_h

#include <cstddef>
#include <string>
#include <vector>

#include "InrParallelRendering.h"
#include "Render/SceneInputs.h"

struct InrMapperReport;
class vtkRenderer;
class vtkVolume;

class InrMapperRanks
{
public:
  /// This process's rank and the number of ranks rendering the view.
  const InrParallelRendering::Ranks& Ranks() const { return this->ranks; }
  bool Several() const { return this->ranks.count > 1; }

  /// Asks MPI for this rank's index on its node, once per mapper (neither changes): collective,
  /// so Render calls it first thing, where every rank passes.
  void LookUpLocalRank();
  /// The CUDA device of this rank (one GPU per rank: its index on its node picks it), -1 for the
  /// engine's default. Before LookUpLocalRank (a PrepareRender before the first Render, which not
  /// every rank may reach) the local rank comes from the launcher's environment, without MPI.
  int CudaDevice();
  /// "; rank r of N (local rank l from SOURCE), CUDA device d of D", appended to the backend
  /// description; "" with one rank and no known local rank. Written again when the session was
  /// `rebuilt` or the local rank's source changed (the first Render's MPI look-up after a
  /// PrepareRender built the session from the environment).
  const std::string& Note(bool rebuilt, bool cuda, int cudaDevice);

  /// The image-space split: rank r of N traces the pixels (x + y) mod N = r of the picture at full
  /// depth (RenderSettings::pixelShare) with the seed one rank would use, so the ranks'
  /// premultiplied images add up to the single-rank image (IceT blends them; disjoint pixels blend
  /// the same in any order). Unchanged with one rank.
  void Share(inr::RenderSettings& settings) const;

  /// The depth that clips the rays over the render tile (GL rows), in `depth`; false when there is
  /// no limit. One process: the window's depth buffer where geometry was drawn before the volume
  /// (without any the buffer holds only the clear value, and the read, tens of ms per render on a
  /// software OpenGL, is skipped). Several ranks: each rank's buffer holds only its own geometry,
  /// which IceT composites after the volumes, so the limit is the per-pixel minimum over all
  /// ranks' buffers (over the union of the volumes' rectangles: no ray outside it meets the box).
  /// Collective: every rank calls it once per render.
  bool CompositeDepth(vtkRenderer* ren, vtkVolume* vol, std::vector<float>& depth);

  /// What this rank did in the last render, for the panel's line per rank and the reduction.
  struct Local
  {
    bool rendered = false;  // false: no model on its piece, a failed engine, nothing drawn
    std::size_t queries = 0;  // primary + shadow + shading queries of its last render
    int shownFrames = 0;   // the frames of the image on screen
    int frames = 0;        // the frames of the session drawn (reduced over the ranks)
    bool converged = false;
    double estimate = 0.0;
    std::string backend;
  };
  /// Writes report.ranksInUse (one line per rank) and, with several ranks, report.reduced: every
  /// rank converged, the fewest frames, the lowest estimate; a rank that drew nothing neither
  /// holds back nor speeds up the others. Collective: once per render, on every way out.
  void Reduce(const Local& local, InrMapperReport& report) const;

private:
  InrParallelRendering::Ranks ranks = InrParallelRendering::GlobalRanks();
  int localRank = -1;  // this rank's index on its node (-1: unknown), and where it came from
  std::string localRankSource;
  bool haveLocalRank = false;
  int cudaDevices = -1;  // CUDA devices this process sees (-1: not counted yet)
  std::string note, noteKey;  // Note's text and the local rank and source it was written for
  bool warnedDepthSize = false;
};

#endif
