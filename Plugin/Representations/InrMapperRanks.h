// The mapper across MPI ranks (pvbatch / pvserver with several ranks; with one process everything
// here is the identity): which GPU this rank takes, which frames or pixels it traces, the depth
// that clips its rays (composited over every rank's geometry), the ranks' images combined (sample
// shares) and the refinement state reduced over the ranks after each render. The collectives
// live here; InrParallelRendering.h holds the MPI calls themselves. Every rank must reach
// CompositeDepth, CombineImage (or FinishRender) and Reduce once per render, in that order,
// whatever it draws: vtkInrVolumeMapper::Render calls them first thing and on every way out.
#ifndef InrMapperRanks_h
#define InrMapperRanks_h

#include <cstddef>
#include <string>
#include <vector>

#include "InrParallelRendering.h"
#include "Backends/Refinement.h"
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

  /// How several ranks share the view (vtkInrVolumeMapper::RankSplit).
  /// - Samples: every rank renders every pixel for its own frames (RenderSettings::sampleShare:
  ///   N ranks of F frames draw the numbers one renderer draws over N x F frames); after each
  ///   render the ranks' images are averaged weighted by their frames (CombineImage), and each
  ///   rank draws the pixels (x + y) mod N = r of that average, so IceT's blend of disjoint pixels
  ///   shows it whole. Why: a frame is a chain of latency-bound iterations over the whole image,
  ///   so fewer frames of every pixel scale where fewer pixels of every frame do not.
  /// - Pixels: rank r traces only the pixels (x + y) mod N = r at full depth
  ///   (RenderSettings::pixelShare) with the seed one rank would use, so the ranks' premultiplied
  ///   images add up to the single-rank image.
  enum class Split
  {
    Samples = 0,
    Pixels = 1
  };
  void SetSplit(Split split) { this->split = split; }
  /// Sample shares in use: several ranks and Split::Samples.
  bool SplitsSamples() const { return this->ranks.count > 1 && this->split == Split::Samples; }

  /// This rank's share in the render settings. Unchanged with one rank.
  void Share(inr::RenderSettings& settings) const;
  /// Sample shares: the stop rule of one rank for a whole: at most maximumFrames / N frames of its
  /// own (rounded up), and the target lowered by 10 log10 N dB (N ranks' frames average to an
  /// image with 1/N of one rank's squared error). Unchanged otherwise.
  void ShareRefinement(inr::RefinementOptions& options) const;

  /// Marks the start of a render (CombineImage not yet reached).
  void BeginRender() { this->imageCombined = false; }
  /// Sample shares: replaces `image` (this rank's premultiplied RGBA, the mean of its `frames`
  /// frames; empty where it has none to give) by the mean over all ranks' frames, keeping only
  /// this rank's pixels (the others transparent); returns all ranks' frames (0: nothing to draw,
  /// image untouched). Collective: once per render on every rank (FinishRender calls it on the
  /// ways out that draw nothing).
  int CombineImage(int width, int height, int frames, std::vector<float>& image);
  /// On every way out of a render: the CombineImage this rank did not reach (it brings no
  /// frames), then nothing else.
  void FinishRender();

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
  Split split = Split::Samples;
  bool imageCombined = false;
  // The pixels the volume can cover in a tile of imageRectWidth x imageRectHeight (CompositeDepth;
  // engine rows), what CombineImage sends.
  InrParallelRendering::PixelRect imageRect;
  int imageRectWidth = -1, imageRectHeight = -1;
  int localRank = -1;  // this rank's index on its node (-1: unknown), and where it came from
  std::string localRankSource;
  bool haveLocalRank = false;
  int cudaDevices = -1;  // CUDA devices this process sees (-1: not counted yet)
  std::string note, noteKey;  // Note's text and the local rank and source it was written for
  bool warnedDepthSize = false;
};

#endif
