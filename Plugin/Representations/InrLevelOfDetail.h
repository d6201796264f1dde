// The mapper's level-of-detail policy, without VTK: which renders are interactive, at what
// resolution and with how many frames they render, which engine session draws them, when the
// coarse session's slices are built ahead and when the fine slices may build in the background,
// and the cost model behind the resolution (the engine's measured time per pixel, the window's
// fixed cost). vtkInrVolumeMapper feeds it what VTK says (the window's desired update rate, the
// input's time, measured times) and does what it decides; its tests (InrLevelOfDetail_test.cxx)
// run without VTK. The reasons for each rule are in vtkInrVolumeMapper.h (InteractiveLevelOfDetail
// and the options after it).
#ifndef InrLevelOfDetail_h
#define InrLevelOfDetail_h

class InrLevelOfDetail
{
public:
  enum Mode
  {
    Off = 0,
    Interaction = 1,         // renders whose window asks for >= InteractiveUpdateRate fps
    InteractionAndTime = 2,  // and renders whose time changed while FramesPerRender is 1
  };

  /// The reduced image's linear scale is a multiple of 1/kScaleSteps (small cost fluctuations do
  /// not change the resolution, which would restart the accumulation and lose the reprojected
  /// history during a drag), never below kMinScale (bounded blur).
  static constexpr int kScaleSteps = 16;
  static constexpr double kMinScale = 1.0 / kScaleSteps;

  /// The mapper's options that the policy reads.
  struct Settings
  {
    int mode = InteractionAndTime;
    double frameTimeMs = 100.0;   // InteractiveFrameTime
    double updateRate = 1.0;      // InteractiveUpdateRate
    int freshFrames = 4;          // InteractiveFreshFrames
    int framesPerRender = 1;
    bool progressiveRefinement = true;
    bool capturing = false;       // a screenshot or animation capture
    bool coarseAhead = true;      // InteractiveMacrocellsAhead
    int ranks = 1;                // MPI ranks rendering this view
  };

  /// What kind of render this is.
  struct Decision
  {
    bool interactive = false;
    bool timeChange = false;  // interactive because the time changed (a fresh image)
    double budgetMs = 0.0;    // the frame-time budget of an interactive render
  };
  /// `desiredUpdateRate`: the render window's; `time`: the input's time for this render.
  Decision Classify(const Settings& s, double desiredUpdateRate, double time) const;
  /// A still render forced to a reduced coarse frame while the fine slices build on a worker
  /// thread (background builds): treated as a time change with the full budget.
  static Decision WhileFineBuilds(const Settings& s);

  /// The image of a render: its size, frames to render and whether it is still interactive
  /// (false when the full resolution fits the budget: an ordinary still render).
  struct Frame
  {
    int width = 0, height = 0;
    int frames = 1;  // interactive renders: frames of a fresh time-change image
    bool interactive = false;
  };
  /// Chooses the scale of an interactive render of a `width` x `height` view (see ChooseScale);
  /// a time-change frame renders up to Settings::freshFrames frames at a lower scale, no more
  /// than the measured time per frame of earlier fresh images lets fit in the budget.
  Frame Plan(const Settings& s, const Decision& d, int width, int height);

  /// Which session draws an interactive frame: the coarse one for a time change (its fine slices
  /// may not be built) and for a camera drag with Reproject on (the fine session keeps its
  /// full-resolution image for the still render to reproject), when a coarse session exists.
  static bool RendersCoarse(const Decision& d, bool reproject, bool coarseAvailable)
  {
    return d.interactive && (d.timeChange || reproject) && coarseAvailable;
  }
  /// Whether a still render should build the coarse session's slices ahead: time-change frames
  /// may follow it (mode InteractionAndTime, FramesPerRender 1, not a capture).
  static bool BuildsCoarseAhead(const Settings& s)
  {
    return s.coarseAhead && s.mode == InteractionAndTime && s.framesPerRender == 1 && !s.capturing;
  }
  /// Whether the fine slices of a new time may build on a worker thread while reduced coarse
  /// frames are drawn (the GUI: CPU backend, one rank, GUI-like refinement, not a capture).
  static bool BuildsFineInBackground(const Settings& s, bool cpuBackend)
  {
    return !s.capturing && s.framesPerRender == 1 && s.progressiveRefinement &&
      s.mode == InteractionAndTime && s.ranks == 1 && cpuBackend;
  }

  /// The linear scale of an interactive image for a `budgetMs` frame (see the .cxx).
  double ChooseScale(double budgetMs, int width, int height);
  /// The scale and frame count of a fresh (time-change) image for the scale `scale` chosen for
  /// one frame: up to `fresh` frames, pixels x frames at most one frame at `scale`.
  static double FreshFrameScale(double scale, int fresh);
  static int FreshFrameCount(double scale, int fresh);

  /// Updates the cost model from a render that rendered `framesRendered` frames of
  /// `width` x `height`: `renderMs` the mapper's whole render, `refineMs` its engine part of which
  /// `updateMs` were macrocell / majorant updates (left out: they depend on the time change,
  /// not on the resolution).
  void MeasureFrame(double renderMs, double refineMs, double updateMs, int framesRendered,
    int width, int height, bool interactive);
  /// The window's whole render took `windowMs`, of which the mapper's render `mapperMs` and coarse
  /// slices built ahead `aheadMs` (not a cost of the window's frames): the rest is the window's
  /// fixed cost (other props, clear, swap, the view's passes).
  void WindowRendered(double windowMs, double mapperMs, double aheadMs);
  /// A render was asked at `time` (later renders compare their time with it).
  void SawTime(double time)
  {
    this->haveLastTime = true;
    this->lastTime = time;
  }
  /// A render drew an image, interactive or not.
  void Drew(bool interactive) { this->lastInteractive = interactive; }
  /// Another interaction may have made the view cheaper or dearer: a scale found too slow may be
  /// tried again (also after frames measured while a worker shared the CPU).
  void ForgetCeiling() { this->lodCeiling = 2.0; }

  bool LastInteractive() const { return this->lastInteractive; }
  double Scale() const { return this->lodScale; }

private:
  double lodScale = 1.0;
  double msPerPixelFrame = 0.0;  // engine time per pixel per frame, without macrocell updates
  double overheadMs = 0.0;       // the rest of a mapper render: depth read, scene, upload, blend
  double interactiveMs = 0.0;    // engine time of interactive frames at lodScale
  double lodCeiling = 2.0;       // smallest scale found too slow in this interaction
  int framesAtScale = 0;         // interactive frames measured at lodScale
  double freshFrameMs = 0.0;     // engine time per frame of fresh (several-frame) images
  double outsideMs = 0.0;        // the window's render outside this mapper
  bool lastInteractive = false;
  bool haveLastTime = false;
  double lastTime = 0.0;
};

#endif
