/**
 * @class vtkInrVolumeMapper
 * @brief Volume mapper that renders an INR Volume model straight from its weights with the
 * engine's delta-tracking renderer, composited into the render window.
 *
 * The input is the output of vtkInrVolumeReader (a vtkImageData whose field data carries the model
 * bytes "InrModel", the value range "InrValueRange" and the time "InrTime"); the preview samples
 * are ignored. Each Render():
 *  - rebuilds the engine only when the model bytes (hash), the macrocell resolution, the temporal
 *    slices or the backend change;
 *  - translates the VTK scene (InrSceneTranslator): the camera, the volume property's colour
 *    function (sampled, so every VTK colour space is honoured), its scalar-opacity function (nodes
 *    with midpoint/sharpness) and ScalarOpacityUnitDistance, the time, and a per-pixel depth limit
 *    from the depth buffer (world distance to the opaque geometry drawn before); adds the light;
 *  - hands the scene to the engine, whose setScene decides what to redo (inr::SceneChange: time:
 *    working grid + majorants; TF: majorants; camera/light/depth: restart accumulation; nothing:
 *    keep accumulating);
 *  - accumulates frames with the engine's inr::RefinementDriver (at least one new frame while not
 *    converged, and up to FramesPerRender in total, never beyond MaximumFrames or past the
 *    convergence target);
 *  - during interactive renders renders one frame of a reduced image instead (level of detail,
 *    InteractiveLevelOfDetail below), drawn upscaled with linear filtering;
 *  - draws the accumulated premultiplied image over the framebuffer (InrFramebufferCompositor:
 *    blend ONE, ONE_MINUS_SRC_ALPHA; the texture is loaded only when the image changed).
 * Progressive refinement is driven from outside: call Render() again while !GetConverged()
 * (ParaView's GUI does this through the plugin's pqInrRefinementBehavior).
 *
 * Macrocell builds (the slices a new time needs, every build after the engine was rebuilt) take
 * long on the CPU: the mapper reports them as VTK progress (ProgressEvent, UpdateProgress, a
 * ProgressText naming the build) from inside Render(); vtkInrVolumeRepresentation forwards them
 * to ParaView's progress bar.
 */
#ifndef vtkInrVolumeMapper_h
#define vtkInrVolumeMapper_h

#include "InrVolumeRepresentationsModule.h"
#include "vtkVolumeMapper.h"

#include <string>  // for FormatConvergenceEstimate

class vtkRenderer;
class vtkVolume;
class vtkWindow;

class INRVOLUMEREPRESENTATIONS_EXPORT vtkInrVolumeMapper : public vtkVolumeMapper
{
public:
  static vtkInrVolumeMapper* New();
  vtkTypeMacro(vtkInrVolumeMapper, vtkVolumeMapper);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  enum
  {
    BACKEND_AUTO = 0,
    BACKEND_CPU = 1,
    BACKEND_CUDA = 2
  };

  ///@{
  /// Backend: AUTO (CUDA when usable, else CPU), CPU, or CUDA (falls back to CPU with a warning
  /// when this build or machine has no usable CUDA renderer).
  vtkSetClampMacro(Backend, int, 0, 2);
  vtkGetMacro(Backend, int);
  ///@}

  enum
  {
    TRAVERSAL_AUTO = 0,
    TRAVERSAL_DDA = 1,
    TRAVERSAL_OPTIX = 2
  };

  ///@{
  /// GPU traversal of the macrocells: AUTO (the OptiX GAS on GPUs with RT cores, else the DDA),
  /// DDA, or OPTIX (the GAS; falls back to AUTO with a warning where this build or driver has no
  /// OptiX). The CPU backend always runs the DDA. GetBackendInUse() says which runs and why.
  vtkSetClampMacro(Traversal, int, 0, 2);
  vtkGetMacro(Traversal, int);
  ///@}

  ///@{
  /// Macrocells per axis (default 32) and temporal slices (default 16) of the majorant grid.
  vtkSetClampMacro(MacrocellResolution, int, 2, 256);
  vtkGetMacro(MacrocellResolution, int);
  vtkSetClampMacro(TemporalSlices, int, 1, 4096);
  vtkGetMacro(TemporalSlices, int);
  ///@}

  ///@{
  /// More macrocell options (inr::MacrocellOptions and inr::TrackingOptions, whose defaults these
  /// start from: the one place defaults are defined). Stored as asked and checked the way the
  /// `inr render` CLI checks them when the engine is next updated: an invalid value is reported
  /// once (vtkErrorMacro naming the property and its range) and the last valid one is kept.
  ///  - SkipBlock (--skip-block; 0 = off, else a power of two up to 1024): empty-space skipping,
  ///    rays jump over empty blocks of SkipBlock^3 macrocells; images are unchanged. Rebuilds the
  ///    macrocells.
  ///  - BoundsPadding (--bounds-padding; >= 0): widen each macrocell's [min, max] by this fraction
  ///    of the value range. Rebuilds the macrocells.
  ///  - GhostPasses (--ghost-passes; 0..1000): ghost passes after each time or transfer-function
  ///    change (refine under-estimated macrocells before they are seen). Applies from the next
  ///    change; the engine is kept.
  ///  - RefineMacrocells (off = --no-refine): widen under-estimated macrocells from evaluated
  ///    samples. Applies from the next frame; the engine is kept.
  void SetSkipBlock(int cells);
  int GetSkipBlock();
  void SetBoundsPadding(double fraction);
  double GetBoundsPadding();
  void SetGhostPasses(int count);
  int GetGhostPasses();
  void SetRefineMacrocells(int on);
  int GetRefineMacrocells();
  ///  - Estimator (--estimator; 0 delta, 1 ratio, 2 march, 3 preintegrated, 4 debiased),
  ///    MajorantScale (--majorant-scale, [1, 1024]; 0 = the estimator's own,
  ///    inr::TrackingOptions::recommendedFor), ResidualScale (--residual-scale, [0, 1024]),
  ///    PointsPerIteration (--points-per-iteration, 1..64): how primary rays turn tentative
  ///    collisions into an image (Docs/cli.md, "Estimators"); defaults
  ///    inr::TrackingOptions::recommended(). Apply from the next frame and keep the accumulation:
  ///    every estimator converges to the same image.
  void SetEstimator(int estimator);
  int GetEstimator();
  void SetMajorantScale(double scale);
  double GetMajorantScale();
  void SetResidualScale(double scale);
  double GetResidualScale();
  void SetPointsPerIteration(int points);
  int GetPointsPerIteration();
  ///  - StratifiedJitter (--jitter stratified / random): sub-pixel jitter from a low-discrepancy
  ///    sequence per pixel (1) or independent draws (0); default from recommended().
  void SetStratifiedJitter(int on);
  int GetStratifiedJitter();
  ///  - JitterControlFrames (--jitter-control N): the sub-pixel jitter's control variate in an
  ///    accumulation's first N frames (0 = off); default from recommended().
  void SetJitterControlFrames(int frames);
  int GetJitterControlFrames();
  /// The macrocell options the engine holds (read back from it after the last Render), e.g.
  /// "dims=32x32x32 slices=16 skip_block=4 bounds_padding=0 ghost_passes=0 refine=1"; "" before.
  const char* GetMacrocellsInUse();
  ///@}

  ///@{
  /// Shadows from one directional light. LightDirection points towards the light (world space);
  /// (0,0,0) = automatic: above-left-behind the camera, following it. Ambient in [0,1].
  /// ShadowEstimator: 0 delta (binary visibility), 1 ratio tracking (less noise, more queries).
  vtkSetMacro(Shadows, int);
  vtkGetMacro(Shadows, int);
  vtkSetVector3Macro(LightDirection, double);
  vtkGetVector3Macro(LightDirection, double);
  vtkSetClampMacro(Ambient, double, 0.0, 1.0);
  vtkGetMacro(Ambient, double);
  vtkSetClampMacro(ShadowEstimator, int, 0, 1);
  vtkGetMacro(ShadowEstimator, int);
  ///@}

  ///@{
  /// Refinement control. MaximumFrames (default 2048): accumulation stops there.
  /// ConvergenceTarget (dB, default 41, 0 = off): accumulation stops when the estimated PSNR of
  /// the displayed image over the pixels the volume covers reaches it (from each pixel's sample
  /// variance; inr::RefinementDriver). FramesPerRender (default 1): one Render() call accumulates until the image holds at
  /// least this many frames (scripts set it to N to get an N-frame image from one render).
  vtkSetClampMacro(MaximumFrames, int, 1, 1 << 20);
  vtkGetMacro(MaximumFrames, int);
  vtkSetClampMacro(ConvergenceTarget, double, 0.0, 200.0);
  vtkGetMacro(ConvergenceTarget, double);
  vtkSetClampMacro(FramesPerRender, int, 1, 1 << 20);
  vtkGetMacro(FramesPerRender, int);
  /// RefinementTimeBudget (ms, default 50; 0 = off): while FramesPerRender is 1 (the GUI's
  /// refinement, which renders again by itself), one still render of the view takes about this
  /// long: the frames get what is left of it after the work the render does around them (the
  /// view's update at a new time, reported by MarkViewUpdate: the reader, data delivery; the
  /// window's own passes before this mapper and, as measured in earlier renders, after it), the
  /// first frame always (inr::RefinementOptions::timeBudgetMs). A fast backend cleans the image
  /// in a few renders instead of one render per frame, and the view still repaints about 20
  /// times a second, animations included. Frame count only when FramesPerRender > 1 (scripts
  /// asking for an N-frame image get exactly that), for interactive (reduced) frames, tiles of a
  /// capture and with ProgressiveRefinement off.
  vtkSetClampMacro(RefinementTimeBudget, double, 0.0, 10000.0);
  vtkGetMacro(RefinementTimeBudget, double);
  /// ProgressiveRefinement (default on). Off: each Render() adds exactly one frame (whatever
  /// FramesPerRender says) and GetConverged() reports 1, so nothing renders again by itself
  /// (ParaView's GUI then shows one frame per render and stays idle).
  vtkSetMacro(ProgressiveRefinement, int);
  vtkGetMacro(ProgressiveRefinement, int);
  ///@}

  ///@{
  /// Seed of the random streams (fixed seed + same inputs = same image).
  vtkSetMacro(Seed, int);
  vtkGetMacro(Seed, int);
  ///@}

  ///@{
  /// How several MPI ranks (mpirun pvbatch / pvserver) share the view: RANK_SPLIT_SAMPLES (every
  /// rank renders every pixel for its own frames; the ranks' images are averaged after each
  /// render, weighted by their frames) or RANK_SPLIT_PIXELS (each rank traces an interleaved
  /// share of the pixels). Nothing changes with one process. InrMapperRanks::Split says why
  /// samples are the default.
  enum
  {
    RANK_SPLIT_SAMPLES = 0,
    RANK_SPLIT_PIXELS = 1
  };
  vtkSetClampMacro(RankSplit, int, RANK_SPLIT_SAMPLES, RANK_SPLIT_PIXELS);
  vtkGetMacro(RankSplit, int);
  ///@}

  ///@{
  /// Query reduction (paper sec. 4.2; inr::QueryReductionSettings, whose defaults these start
  /// from: the one place defaults are defined). Pushed into the engine on the next Render(); an
  /// invalid combination is reported once (vtkErrorMacro, naming the parameter and its range) and
  /// the engine keeps its previous settings. A change of PruneEpsilon / PruneFalloff restarts the
  /// accumulation (the engine does it); the budget and reprojection apply from the next frame.
  ///  - RayBudget: 0 none, 1 histogram, 2 stbn, 3 weighted-stbn (BUDGET_* below)
  ///  - BudgetFraction (rho, (0, 1]): fraction of pixels traced per frame by the STBN schemes
  ///  - BudgetMaxSkip (K, 0..1024 frames): longest skip countdown of the histogram scheme
  ///  - BudgetAlpha (alpha, [0, 1]): residual steering of weighted STBN
  ///  - Reproject: camera moves reproject the accumulation instead of restarting it
  ///  - PruneEpsilon (epsilon), PruneFalloff (delta): pruning thresholds, fractions of the
  ///    field's value range (0, 0 = off)
  enum
  {
    BUDGET_NONE = 0,
    BUDGET_HISTOGRAM = 1,
    BUDGET_STBN = 2,
    BUDGET_WEIGHTED_STBN = 3
  };
  void SetRayBudget(int scheme);
  int GetRayBudget();
  void SetBudgetFraction(double rho);
  double GetBudgetFraction();
  void SetBudgetMaxSkip(int k);
  int GetBudgetMaxSkip();
  void SetBudgetAlpha(double alpha);
  double GetBudgetAlpha();
  void SetReproject(int on);
  int GetReproject();
  void SetPruneEpsilon(double epsilon);
  double GetPruneEpsilon();
  void SetPruneFalloff(double delta);
  double GetPruneFalloff();
  /// The settings the engine holds (read back from it after the last Render), e.g.
  /// "budget=stbn rho=0.75 K=8 alpha=0.5 reproject=0 epsilon=0 delta=0"; "" before the first.
  const char* GetQueryReductionInUse();
  ///@}

  ///@{
  /// When on, ignore the volume property and use the engine's default transfer function (cool to
  /// warm colours, linear opacity ramp) over the model's value range. ParaView's representation
  /// turns this on while the representation is not coloured by an array.
  vtkSetMacro(UseDefaultTransferFunction, int);
  vtkGetMacro(UseDefaultTransferFunction, int);
  ///@}

  ///@{
  /// Level of detail while interacting, so the view stays responsive when one frame at full
  /// resolution takes long (the CPU fallback at ~1280x768: about a second). An interactive render
  /// draws one frame at a reduced resolution, upscaled with linear filtering. The resolution is
  /// chosen from the engine's measured time of recent frames (the part that scales with the
  /// pixels) so that it fits InteractiveFrameTime less the window's fixed cost around it (depth
  /// read, drawing the image over the viewport, the window's other work: the mapper observes the
  /// window's StartEvent/EndEvent), that fixed cost counted up to half the budget only (on a
  /// software OpenGL it alone is 40-110 ms at ~1280x768 whatever the resolution: counted in full
  /// it kept drags at the smallest scale); the resolution is kept while the frames stay within
  /// the budget (a stable
  /// resolution lets reprojection keep accumulating during a drag). The next still render is at
  /// full resolution and refines exactly as without LOD (same seed, same frames: the same
  /// image). When the full resolution already fits the budget (small views, the GPU) interactive
  /// renders are at full resolution.
  ///  - InteractiveLevelOfDetail: LOD_OFF (every render at full resolution); LOD_INTERACTION:
  ///    renders whose render window asks for at least InteractiveUpdateRate frames per second
  ///    (ParaView's interactive renders during a camera drag: 5; VTK interactors: 15);
  ///    LOD_INTERACTION_AND_TIME (default): also a render whose time differs from the previous
  ///    render's while FramesPerRender is 1 (ParaView's time-slider drags and animation playback
  ///    are still renders; a script asking for N frames per render always gets full resolution).
  ///  - InteractiveFrameTime (ms, default 100): the budget; the render window's desired frame
  ///    time (1000 / DesiredUpdateRate) when that is smaller. It trades resolution for speed.
  ///    It is also a GUI still render's budget in the isosurface and slice blend modes: a full
  ///    frame that would not fit it is drawn reduced first, then in parts over the next renders.
  ///  - InteractiveUpdateRate (frames per second, default 1, as vtkSmartVolumeMapper's).
  /// Environment INR_VOLUME_LOD_LOG=1 prints one line per render (interactive or still,
  /// resolution, milliseconds).
  enum
  {
    LOD_OFF = 0,
    LOD_INTERACTION = 1,
    LOD_INTERACTION_AND_TIME = 2
  };
  vtkSetClampMacro(InteractiveLevelOfDetail, int, 0, 2);
  vtkGetMacro(InteractiveLevelOfDetail, int);
  vtkSetClampMacro(InteractiveFrameTime, double, 1.0, 60000.0);
  vtkGetMacro(InteractiveFrameTime, double);
  vtkSetClampMacro(InteractiveUpdateRate, double, 1e-6, 1e6);
  vtkGetMacro(InteractiveUpdateRate, double);
  /// InteractiveMacrocellResolution (cells per axis, default 8; 0 = off): a reduced interactive
  /// frame caused by a time change, or by a camera drag while Reproject is on, is rendered by a
  /// second engine session whose majorant grid has this many cells per axis (same temporal
  /// slices). During a drag the fine session thus keeps its full-resolution image, which the
  /// still render after the drag reprojects to the new camera and keeps refining (a reduced
  /// frame on the fine session would restart it: another resolution). A first visit of a time builds coarse
  /// slices (about 1/50 of the work of 32^3 ones: the build samples (2n+1)^3 lattice points)
  /// instead of waiting for the fine ones. Coarser cells bound the field more loosely (more null
  /// collisions per ray) but are still majorants: the image is unbiased. The still render that
  /// follows builds the fine slices as before (with progress). Off, or when not below
  /// MacrocellResolution, time-change frames use the fine grid.
  vtkSetClampMacro(InteractiveMacrocellResolution, int, 0, 256);
  vtkGetMacro(InteractiveMacrocellResolution, int);
  /// InteractiveMacrocellsAhead (default on): every slice of that coarse grid is built ahead,
  /// in the first still render that time-change frames may follow (InteractiveLevelOfDetail
  /// LOD_INTERACTION_AND_TIME, FramesPerRender 1, not a capture), with progress ("INR Volume
  /// (interactive macrocells): building macrocells: ..."): a first visit of a time then finds its
  /// coarse slices built and costs what a visit of a built time costs, instead of waiting for
  /// a coarse build inside its frame (30-64 ms per slice for the shipped paper-size models on a
  /// 2-core CPU: a frame over the budget). It costs that build once per session (16 slices:
  /// 0.5-1 s on that CPU), added to a first still render that waits seconds for its fine slices
  /// anyway. Off: coarse slices are built when a time-change frame first needs them.
  vtkSetMacro(InteractiveMacrocellsAhead, int);
  vtkGetMacro(InteractiveMacrocellsAhead, int);
  /// InteractiveFreshFrames (default 4, 1 = off): a time-change interactive frame starts its
  /// image afresh, and one sample per pixel of a thin medium is sparse speckle; it renders up to
  /// this many frames at a resolution lowered so that pixels x frames stay what one frame at the
  /// chosen resolution costs (the budget holds): a smoother, blurrier reduced image.
  vtkSetClampMacro(InteractiveFreshFrames, int, 1, 64);
  vtkGetMacro(InteractiveFreshFrames, int);
  /// InteractiveStandIn (default on): camera drags on the CPU backend draw a stand-in of the
  /// network, the fine macrocells' per-cell means at the time shown (a coarse grid interpolated
  /// trilinearly, no network query), on the coarse interactive macrocells: a frame costs a small
  /// part of a network frame, so drags run at a higher resolution, with the blur of that grid.
  /// The still image after the drag is the network's. It has its own level-of-detail cost
  /// model (a drag's scale does not carry over to time changes, which draw the network). Used
  /// once the fine session has rendered the time shown (not while its slices build) and with
  /// Reproject on (drags on the coarse session); the GPU draws the network.
  vtkSetMacro(InteractiveStandIn, int);
  vtkGetMacro(InteractiveStandIn, int);
  /// The scale and frame count of such a render, for the scale `scale` chosen for one frame.
  static double InteractiveFreshFrameScale(double scale, int fresh);
  static int InteractiveFreshFrameCount(double scale, int fresh);
  /// Macrocell slices built by that coarse session (0 before it is first used).
  int GetInteractiveSlicesBuilt();
  /// What the fine session (the still image) and the coarse session (InteractiveMacrocell-
  /// Resolution) run, read back from each (backend, traversal, device, macrocell and tracking
  /// options, query reduction; "" before it exists), one line each; they differ in the majorant
  /// grid's dims (and a skip block capped to it) only: the coarse one honours every user setting.
  const char* GetEngineOptionsInUse();
  const char* GetInteractiveEngineOptionsInUse();
  /// 1 when both sessions exist and run one evaluator (weights uploaded, and on CUDA autotuned,
  /// once).
  int GetInteractiveSharesEvaluator();
  /// 1 when the last Render drew a frame of the stand-in (InteractiveStandIn).
  int GetLastRenderStandIn();
  /// 1 when the last Render drew a frame of the coarse session.
  int GetLastRenderCoarse();
  /// Capturing (set by the representation while ParaView captures a screenshot or an animation
  /// frame): never a reduced frame then, whatever the time did, so a saved picture is the still
  /// image at full resolution.
  vtkSetMacro(Capturing, bool);
  vtkGetMacro(Capturing, bool);
  /// 1 when the last Render drew an interactive (level-of-detail) frame; GetConverged() is 0
  /// then, so a refinement loop renders again at full resolution.
  int GetLastRenderInteractive();
  /// Size of the image the engine rendered in the last Render (the view's size unless reduced).
  int GetLastImageWidth();
  int GetLastImageHeight();
  /// Wall time of the last Render (ms), and of its macrocell/majorant update part.
  double GetLastRenderMilliseconds();
  ///@}

  /// Forget the accumulated frames (the next Render starts a new estimate).
  void ResetAccumulation();

  ///@{
  /// State after the last Render(). Under MPI with several ranks (sub-domain rendering: each rank
  /// renders an interleaved share of the pixels, see InrParallelRendering.h) these are reduced
  /// over all ranks at the end of each Render: converged only when every rank is, the fewest
  /// frames, the lowest estimate; GetLocalConverged is this rank's own state.
  int GetAccumulatedFrames();
  int GetConverged();
  int GetLocalConverged();
  double GetConvergenceEstimate();
  /// The estimate for people: "31.2 dB", "\u2014" (not known yet: -inf above), "no noise left"
  /// (+inf: no covered pixel or no variance).
  const char* GetConvergenceEstimateText();
  static std::string FormatConvergenceEstimate(double db);
  /// One line saying whether the image is still refining, e.g. "refining: 37 frames, 31.2 dB of
  /// 41 dB", "converged: 206 frames, 41.3 dB", "stopped at 2048 frames (Maximum Frames 2048)",
  /// "interacting: reduced 320x192 image", "one frame per render (Progressive Refinement off)".
  const char* GetRefinementState();
  /// e.g. "CPU (auto: this build has no CUDA renderer)".
  const char* GetBackendInUse();
  /// One line per rank (under MPI with several ranks; else one line) after the last Render: its
  /// queries, frames, state and backend (device).
  const char* GetRanksInUse();

  /// The model's box (InrDomainBounds of the input) when the input carries it: under MPI the
  /// pieces of ranks > 0 hold the model but no preview grid, and every rank draws its pixel share
  /// of the whole box, so none may cull the volume.
  double* GetBounds() override;
  using Superclass::GetBounds;
  /// Working-grid / majorant update time reported by the engine during the last Render (ms).
  double GetLastUpdateMilliseconds();
  /// Macrocell slices built since the engine was created (time changes build new ones lazily).
  int GetSlicesBuilt();
  /// How many times the engine (evaluator, macrocells, renderer) was (re)built.
  int GetEngineBuilds();
  /// INR queries issued during the last Render (primary + shadow).
  double GetLastQueries();
  /// Primary rays, pixels left out by ray budgeting and collisions answered by pruning during the
  /// last Render (summed over its frames).
  double GetLastRays();
  double GetLastBudgetSkipped();
  double GetLastPruned();
  ///@}

  void Render(vtkRenderer* ren, vtkVolume* vol) override;
  /// Called by a view before its GL render of the volume (ParaView's representation does it in
  /// its render request): does the long, GL-free work of the next Render() here (engine rebuild,
  /// the macrocell slices the input's time needs, the coarse slices built ahead), reporting their
  /// progress. Once it has been called, Render() reports no progress itself: a GUI that repaints
  /// its progress bar inside the GL render corrupts VTK's cached GL state. Without it (a plain VTK
  /// window) Render() builds and reports as before.
  void PrepareRender(vtkRenderer* ren, vtkVolume* vol);

  /// Called by a view when it starts updating its data for a render (ParaView's representation
  /// does it in its update request and when an algorithm upstream starts executing): the time
  /// from the earliest call since the last render to this mapper's frames (the reader's execution
  /// at a new time, data delivery) is part of the render, and counts against the
  /// RefinementTimeBudget.
  void MarkViewUpdate();
  /// Process-wide, off by default; ParaView's GUI turns it on (its refinement behaviour renders
  /// again by itself): PrepareRender then builds the fine macrocell slices of a new time on a
  /// worker thread (CPU backend, one rank, FramesPerRender 1, InteractiveLevelOfDetail with time
  /// changes, not capturing), and renders meanwhile draw reduced frames of the coarse interactive
  /// macrocells, so the event loop never waits seconds for a build; the next render after the
  /// build uses the fine macrocells. A capture or any render that needs the fine session waits
  /// for the worker. Scripts (pvpython, pvbatch) keep building in the render's preparation.
  static void SetBackgroundMacrocellBuilds(bool on);
  static bool GetBackgroundMacrocellBuilds();
  /// With background builds on, still renders of the fine session also refine it on that worker
  /// thread, one refinement step at a time: a render joins a finished step, draws its image and
  /// starts the next one (a render that finds the step running draws the image it has). 1 while
  /// the worker runs such a step, or builds the coarse slices ahead, and has not finished: a
  /// render now would draw nothing new (the GUI's refinement loop waits for it instead of
  /// rendering: on a software OpenGL a render costs the worker a large share of the CPU).
  int GetBackgroundWorkRunning();
  void ReleaseGraphicsResources(vtkWindow* win) override;

protected:
  vtkInrVolumeMapper();
  ~vtkInrVolumeMapper() override;
  int FillInputPortInformation(int port, vtkInformation* info) override;

private:
  vtkInrVolumeMapper(const vtkInrVolumeMapper&) = delete;
  void operator=(const vtkInrVolumeMapper&) = delete;

  int Backend = BACKEND_AUTO;
  int Traversal = TRAVERSAL_AUTO;
  int MacrocellResolution = 32;
  int TemporalSlices = 16;
  int Shadows = 0;
  double LightDirection[3] = { 0, 0, 0 };
  double Ambient = 0.2;
  int ShadowEstimator = 0;
  int MaximumFrames = 2048;
  double ConvergenceTarget = 41.0;
  int FramesPerRender = 1;
  double RefinementTimeBudget = 50.0;
  int ProgressiveRefinement = 1;
  int Seed = 1;
  int RankSplit = RANK_SPLIT_SAMPLES;
  int UseDefaultTransferFunction = 0;
  int InteractiveLevelOfDetail = LOD_INTERACTION_AND_TIME;
  double InteractiveFrameTime = 100.0;
  double InteractiveUpdateRate = 1.0;
  int InteractiveMacrocellResolution = 8;
  int InteractiveMacrocellsAhead = 1;
  int InteractiveFreshFrames = 4;
  int InteractiveStandIn = 1;
  bool Capturing = false;

  struct Internals;
  Internals* Internal;
};

#endif
