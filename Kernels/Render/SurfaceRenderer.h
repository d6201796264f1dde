#pragma once
// The isosurface and slice blend modes on the CPU (ParaView's Volume Blend Mode Isosurface and
// Slice, and its cropping box): the per-ray code of Render/SurfaceMarch.h run over chunks of
// pixels, every chunk's queries batched for the FieldEvaluator per iteration (march samples or
// refinement points, then the gradients of the hits that need lighting). Exact in one frame;
// later frames with jitter accumulate an anti-aliased mean. The isosurface's candidate cells come
// from a macrocell grid of its own (per-cell min / max at the scene's time, Render/MacrocellGrid.h),
// built on the first isosurface scene of a time.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "Common/ImageIO.h"
#include "Common/Stopwatch.h"
#include "Evaluator/FieldEvaluator.h"
#include "Render/MacrocellGrid.h"
#include "Render/RenderStats.h"
#include "Render/SurfaceMarch.h"
#include "Render/SceneInputs.h"
#include "Render/TransferFunctionTable.h"

namespace inr {

// ParaView's Volume representation's Blend Mode (vtkVolumeMapper's blend modes of that name).
enum class BlendMode { Composite, Isosurface, Slice };
// "composite", "isosurface", "slice" (case-insensitive); throws std::invalid_argument naming the choices.
BlendMode parseBlendMode(const std::string& name);
const char* blendModeName(BlendMode mode);

// What the isosurface and slice modes need beyond RenderScene, with ParaView's property names.
struct BlendScene {
  BlendMode mode = BlendMode::Composite;
  // IsosurfaceValues: every value is drawn (at most kMaxIsovalues).
  std::vector<double> isovalues;
  // The Slice property's plane (a vtkPlane: origin and normal in world coordinates).
  std::array<double, 3> sliceOrigin{0.0, 0.0, 0.0};
  std::array<double, 3> sliceNormal{0.0, 0.0, 1.0};
  // ParaView's slice shows the colour map weighted by the scalar opacity at each point; true makes
  // it opaque wherever the plane is hit (the colour map alone).
  bool sliceOpaque = false;
  // UseCropping with CroppingOrigin / CroppingScale: rays are clipped to this axis-aligned box in
  // model (data) coordinates (paraviewCroppingBox makes it from ParaView's properties).
  bool crop = false;
  Box3f cropBox{{0.f, 0.f, 0.f}, {0.f, 0.f, 0.f}};

  static constexpr int kMaxIsovalues = 64;
  // Throws std::invalid_argument naming the property at fault (no isovalue or a non-finite one in
  // Isosurface mode, a zero or non-finite slice normal, a crop box with lo > hi or not finite).
  void validate() const;
};

// ParaView's cropping box (vtkImageVolumeRepresentation): along each axis a, the planes
// origin[a] + bounds.lo[a] * scale[a] and origin[a] + bounds.hi[a] * scale[a], for the data
// bounds `bounds`; the region between them is kept.
Box3f paraviewCroppingBox(const Box3f& bounds, const std::array<double, 3>& origin, const std::array<double, 3>& scale);

struct SurfaceOptions {
  // March step as a fraction of the smallest macrocell edge (cells are where the march samples:
  // a surface pair closer together than this is missed).
  float stepFraction = 0.25f;
  // A hit's bracket ends at most this fraction of the step long: the hit lies within
  // tolerance = toleranceFraction * step of a crossing, along the ray.
  float toleranceFraction = 1e-3f;
  int samplesPerIteration = 8;  // K: march samples per ray per batch (<= 32)
  // As a frame's rays finish, the march samples per remaining ray and batch grow from K up to this
  // (in [K, 32]), so the batch keeps about its size and the frame's tail takes fewer iterations.
  // The image is the same for any value; K turns it off. 0 = the backend's choice: 32 on the GPU
  // (an iteration costs launches and a host round trip), K on the CPU (an iteration costs little;
  // the samples a ray draws past a crossing are queries spent for nothing).
  int maxMarchSamples = 0;
  // R: a hit's bracket is cut into R + 1 parts per round (fewer in its last round, what reaches
  // the tolerance), in [1, 1024]; each round is one iteration. 0 = the backend's choice: 32 on
  // the GPU (two rounds reach the default tolerance from one step: iterations are what a GPU
  // frame costs), K on the CPU (four rounds, fewer queries).
  int refinePoints = 0;
  int maxRefinements = 24;      // R-section rounds per hit at most
  float opaqueTransmittance = 1e-3f;  // a ray stops once less than this share of light passes
  int chunkPixels = 16384;      // pixels whose rays share the evaluator batches
  // The candidate cells' grid: dims, temporal slices (the time range's), padding of each cell's
  // lattice-sampled [min, max] by this fraction of the field's value range (MacrocellOptions::
  // boundsPadding: lattice samples can miss a cell's extremes, and with them a surface).
  MacrocellOptions macrocells = defaultMacrocells();
  // Skip cells whose [min, max] holds no isovalue (false: sample every cell; for comparisons).
  bool skipCells = true;

  static MacrocellOptions defaultMacrocells() {
    MacrocellOptions m;
    m.boundsPadding = 0.02;
    return m;
  }
  // Throws std::invalid_argument naming the option out of its range.
  void validate() const;
};

class SurfaceRenderer {
public:
  // The field over `box` (model space) and time range [timeBegin, timeEnd] (the macrocells').
  SurfaceRenderer(const FieldEvaluator& evaluator, const Box3f& box, double timeBegin, double timeEnd,
                  SurfaceOptions options = {});
  ~SurfaceRenderer();
  void setSettings(const RenderSettings& settings);
  // The scene and the blend mode (Isosurface or Slice; Composite is the session's renderer). A
  // change of the time or of the isovalues the TF shows (opacity > 0 at the value: the others are
  // not drawn, and cost nothing) rebuilds the candidate mask (a new time may build macrocell
  // slices); anything else only restarts the accumulation. Throws std::invalid_argument naming the problem
  // (BlendScene::validate, shading without gradients, shadows, a depth limit of the wrong size).
  void setScene(const RenderScene& scene, const BlendScene& blend);
  FrameStats renderFrame();
  // A frame in parts, for a caller that must return within a time budget (the GUI's event loop):
  // renders the current frame's next part until `budgetMs` has passed (at least one step: a chunk
  // of SurfaceOptions::chunkPixels for the slice, one march iteration of a chunk's rays for the
  // isosurface) and returns true once the frame is complete
  // (accumulated; `stats`, if given, then holds the whole frame's figures). Until then the image
  // mixes the finished pixels of this frame with the previous accumulation's. New settings, a new
  // scene or resetAccumulation drop a frame in progress. renderFrame() is one call with no budget.
  bool renderFramePart(double budgetMs, FrameStats* stats);
  double frameProgress() const;  // the share of the frame in progress rendered (0: none started)
  // Whether an isosurface scene at `time` finds the slices of its candidate macrocells built
  // (else setScene builds them: lattice queries, the slow part of a new time or a first
  // isosurface), and that build alone, for a caller that does it off its event loop.
  bool macrocellsBuiltFor(double time) const;
  void buildMacrocellsFor(double time);
  void resetAccumulation();
  const SurfaceOptions& options() const { return options_; }
  int accumulatedFrames() const { return frameIndex_; }
  ImageRGBA image() const;               // over the background
  ImageRGBA premultipliedImage() const;  // the surfaces only
  // Per pixel, the world distance along its ray to the first surface that took colour (the
  // isosurface's depth for the depth buffer) in the last frame, INFINITY where none; the slice's
  // hit distance where it was hit.
  const std::vector<float>& surfaceDepth() const { return depth_; }
  float step() const { return step_; }            // model units
  float tolerance() const { return tolerance_; }  // model units
  // Candidate cells of the current isosurface scene (1: may hold an isovalue), x fastest over
  // the macrocell grid; empty before the first isosurface scene.
  const std::vector<float>& candidateCells() const { return candidates_.cell; }
  const MacrocellGrid* macrocells() const { return grid_.get(); }

  // What a backend's per-ray code reads for the next frame (host pointers: the TF table, the
  // candidate mask, the isovalues, the depth limit; a GPU backend swaps in its device copies).
  const BlendScene& blendScene() const { return blend_; }
  const RenderScene& scene() const { return scene_; }
  const RenderSettings& settings() const { return settings_; }
  const TransferFunctionTable& transferFunctionTable() const { return *tfTable_; }
  const MajorantArrays& candidates() const { return candidates_; }
  const std::vector<float>& isovalues() const { return isovalues_; }  // the visible ones
  SliceConstants sliceConstants() const;
  SurfaceConstants surfaceConstants() const;  // (isosurface scenes only)
  // A backend that renders the frames itself: the update time to report with its next frame, and
  // the frame it rendered (the accumulation index the constants above use).
  double takePendingUpdateMs() {
    const double ms = pendingUpdateMs_;
    pendingUpdateMs_ = 0.0;
    return ms;
  }
  void frameRenderedElsewhere() { ++frameIndex_; }

private:
  // The frame in progress from pixel partNext_ on, chunk by chunk, while less than `budgetMs` has
  // passed since `start`; its figures add up in partStats_.
  void renderSliceChunks(Clock::time_point start, double budgetMs);
  void renderIsosurfaceChunks(Clock::time_point start, double budgetMs);
  void updateCandidates();
  MacrocellGrid& candidateGrid();  // grid_, made on first use
  // Whether a frame in progress has begun (a chunk finished, or an isosurface chunk under way).
  bool framePartStarted() const { return partNext_ > 0 || isoChunkN_ > 0; }

  const FieldEvaluator& evaluator_;
  Box3f box_;
  double timeBegin_, timeEnd_;
  SurfaceOptions options_;
  float step_ = 0.f, tolerance_ = 0.f;
  RenderSettings settings_;
  RenderScene scene_;
  BlendScene blend_;
  bool haveScene_ = false;
  std::unique_ptr<TransferFunctionTable> tfTable_;
  std::unique_ptr<MacrocellGrid> grid_;
  MajorantArrays candidates_;
  std::vector<float> isovalues_;
  bool candidatesValid_ = false;
  double pendingUpdateMs_ = 0.0;
  std::vector<Vec4f> accum_;
  std::vector<float> depth_;
  int frameIndex_ = 0;
  int partNext_ = 0;         // the frame in progress: its first pixel not rendered yet (0: none)
  FrameStats partStats_;     // ... its figures so far
  double partWallMs_ = 0.0;  // ... and its wall time so far
  // The isosurface's chunk in progress (from pixel partNext_ on): its pixels (0: none) and its
  // rays, kept between calls, so that a part may end after any march iteration.
  int isoChunkN_ = 0;
  std::vector<SurfaceRay> isoRays_;
  std::vector<int> isoActive_;
};

}  // namespace inr
