#include "RenderJob.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "Args.h"

namespace inr::cli {

namespace {

const char* kRenderUsageHead =
    "usage: inr render MODEL -o OUT.png|.pfm [options]\n"
    "scene:\n"
    "  --time T                 world time (default: start of the model's time range)\n"
    "  --size WxH               image size (default 512x512)\n"
    "  --camera PX,PY,PZ,FX,FY,FZ,UX,UY,UZ,ANGLE\n"
    "                           VTK camera: position, focal point, view-up, vertical view angle\n"
    "                           in degrees (default: ParaView's reset-camera view of the box)\n"
    "  --parallel-scale S       parallel projection showing 2*S world units vertically\n"
    "  --tf FILE                ParaView colour-map JSON (RGBPoints, Points); default: cool-to-warm\n"
    "                           with a linear opacity ramp over the model's value range\n"
    "  --tf-range LO,HI         rescale the transfer function to this scalar range\n"
    "  --opacity-unit-distance U  scalar opacity unit distance (default: box diagonal / 64)\n"
    "  --gradient-opacity G,A[,G,A...]  gradient opacity, as vtkVolumeProperty's: the scalar\n"
    "                           opacity times a piecewise-linear function of the gradient magnitude\n"
    "                           |grad f| (scalar units per model-space unit), nodes (G, A) with\n"
    "                           increasing G and A in [0, 1]; flat regions fade. The samples it\n"
    "                           can change then ask the network for their gradient too\n"
    "  --tf2d FILE              2D transfer function JSON: colour and opacity over (value, |grad f|),\n"
    "                           as ParaView's Use Transfer2D; replaces --tf's colour and opacity and\n"
    "                           --gradient-opacity (keys: Docs/transfer-functions.md). Every sample\n"
    "                           asks the network for its gradient too\n"
    "  --background R,G,B       background colour (default 0,0,0)\n"
    "  --shadows                ray-traced shadows from a directional light\n"
    "  --light X,Y,Z            direction towards the light (default: above-left of the camera)\n"
    "  --ambient A              share of the colour every sample keeps, unlit and unshadowed: with\n"
    "                           --shadows and with --shade (ParaView's one Ambient; default 0.2)\n"
    "  --shade                  gradient shading from the network's own gradient, as ParaView's\n"
    "                           Shade: ambient + diffuse |N.L| + specular (R.V)^power; the light is\n"
    "                           --light, else with --shadows their default light, else a headlight\n"
    "  --light-kit              with --shade: light as ParaView's render view does by default, its\n"
    "                           light kit (key, fill, back and head lights, VTK's light-list\n"
    "                           lighting); not with --light or --shadows\n"
    "  --diffuse D              with --shade: diffuse coefficient (default 0.8)\n"
    "  --specular S             with --shade: specular coefficient (default 0.2)\n"
    "  --specular-power P       with --shade: specular power in [0, 128] (default 10)\n"
    "  --shadow-estimator delta|ratio  shadow transmittance estimator (default delta)\n"
    "rendering:\n"
    "  --method delta|raymarch|naive  wavefront delta tracking (default), fixed-step ray marching,\n"
    "                           or the naive per-ray delta tracker (one query per network call)\n"
    "  --frames N               frames accumulated (default 64; ray marching: 1 unless jittered);\n"
    "                           with --converge: the most frames\n"
    "  --converge DB            stop once the estimated PSNR of the image over the pixels the\n"
    "                           volume covers reaches DB (e.g. 40; from each pixel's sample\n"
    "                           variance, as the ParaView plugin's Convergence Target), after at\n"
    "                           least 8 frames; prints the frames and time it took\n"
    "  --seed S                 random seed (default 1)\n"
    "  --no-jitter              sample pixel centres (no antialiasing)\n"
    "  --macrocells N|NX,NY,NZ  macrocell grid resolution (default 32)\n"
    "  --time-slices T          temporal macrocell slices over the time range (default 16)\n"
    "  --eager-slices           build every temporal slice at start-up (default: only those needed)\n"
    "  --bounds-padding F       widen macrocell bounds by F x value range (default 0)\n"
    "  --skip-block B           empty-space skipping: rays jump over empty blocks of B^3 macrocells\n"
    "                           (power of two, default 4; 0 = off); the image does not change\n"
    "  --ghost-passes G         ghost passes after building the working grid (default 0)\n"
    "  --no-refine              do not refine under-estimated macrocells from samples\n"
    "  --step S                 ray-march step in world units (default: box diagonal / 512)\n"
    "  --shadow-step S          ray-march shadow step (default: 2 x step)\n"
    "  --threads N              CPU threads (default: all)\n"
    "  --backend B              auto (default: CUDA when a usable GPU is present, else CPU), cpu or cuda;\n"
    "                           --method raymarch runs on it too (on CUDA: the GPU marcher, shadows\n"
    "                           and --shade included)\n"
    "  --traversal T            GPU macrocell traversal: auto (default: OptiX on GPUs with RT cores, else\n"
    "                           the DDA; the choice and its reason are printed), dda or optix (a GAS over\n"
    "                           the non-empty macrocells; needs a build with OptiX). The CPU runs the DDA\n"
    "  --gas-min-majorant M     OptiX: leave macrocells with majorant <= M out of the GAS (default 0:\n"
    "                           exact; > 0 ignores nearly transparent cells, biased)\n"
    "  --brick I/N              sub-domain rendering (delta tracking): split the box into N bricks on\n"
    "                           macrocell boundaries and render brick I only (primary rays clipped to it,\n"
    "                           shadow rays through the whole box, seed varied per brick); -o must be\n"
    "                           .npy: premultiplied RGBA float32, shape (height, width, 4), row 0 at the\n"
    "                           top; OUT.brick.json beside it gives the brick's box and the camera, for\n"
    "                           Benchmarks/composite_bricks.py (front-to-back over in visibility order)\n"
    "  --pixel-share I/N        sub-domain rendering, image-space split (what the ParaView plugin does under\n"
    "                           MPI): trace only the pixels (x + y) mod N = I at full depth, same seed as the\n"
    "                           whole image; output as for --brick (split \"pixels\" in the .brick.json;\n"
    "                           composite_bricks.py adds the shares)\n"
    "  --sample-share I/N       sample-space split: render every pixel, but only this share's frames: local\n"
    "                           frame f is frame f*N+I of one renderer, so N shares of F frames each average\n"
    "                           to one render of N*F frames; output as for --brick (split \"samples\";\n"
    "                           composite_bricks.py averages the shares, weighted by their frames). With\n"
    "                           --converge the estimate is this share's own: the average of N shares is\n"
    "                           about 10*log10(N) dB cleaner\n";

// The query-reduction part of the help prints the defaults of QueryReductionSettings, the one
// place they are defined (the plugin's XML defaults are checked against the same struct).
std::string queryReductionUsage() {
  const QueryReductionSettings d;
  char text[4096];
  std::snprintf(
      text, sizeof text,
      "query reduction (paper sec. 4.2; delta tracking only; each trades accuracy per frame for speed):\n"
      "  --budget S               ray budgeting: none, histogram, stbn or weighted-stbn (default %s);\n"
      "                           fewer rays per frame, the skipped pixels keep their previous estimate\n"
      "  --budget-fraction RHO    rho: fraction of pixels traced per frame, in (0, 1] (default %g; the\n"
      "                           histogram scheme thresholds at 1 - rho); lower = cheaper frames, more of them\n"
      "  --budget-max-skip K      K: histogram scheme's longest skip in frames, S_max = min(K, n/4), 0..1024\n"
      "                           (default %d); higher = fewer rays on converged pixels, staler ones\n"
      "  --budget-alpha A         alpha: how strongly weighted-stbn steers rays to high-residual pixels,\n"
      "                           in [0, 1] (default %g; 0 = plain stbn)\n"
      "  --reproject              keep the accumulation across camera moves by reprojecting it (default %s);\n"
      "  --no-reproject           restart it instead; a still camera is unaffected either way\n"
      "  --prune-epsilon E        epsilon: macrocells whose value range is below E x the field's range are\n"
      "                           answered without a network query, in [0, 1] (default %g; 0 = off);\n"
      "                           higher = fewer queries, a biased image in near-uniform regions\n"
      "  --prune-falloff D        delta: band above epsilon pruned with falling probability, in [0, 1]\n"
      "                           (default %g); softens the epsilon edge. --budget none --prune-epsilon 0\n"
      "                           --prune-falloff 0 --no-reproject renders every pixel exactly, every frame\n",
      budgetSchemeName(d.budget), d.budgetFraction, d.budgetMaxSkip, d.budgetAlpha, d.reproject ? "on" : "off",
      d.pruneEpsilon, d.pruneFalloff);
  return text;
}

// The blend modes' part of the help prints SurfaceOptions' defaults (the engine's one definition).
std::string blendUsage() {
  const SurfaceOptions d;
  char text[4096];
  std::snprintf(
      text, sizeof text,
      "blend modes (ParaView's Volume Blend Mode; isosurface and slice are exact in one frame):\n"
      "  --blend B                composite (default: the volume, --method above), isosurface or slice\n"
      "  --iso V[,V...]           --blend isosurface: the isovalues (ParaView's Isosurface Values), each\n"
      "                           surface coloured by the colour map and made as opaque as the scalar\n"
      "                           opacity at its value, lit from the network's gradient (as --shade:\n"
      "                           --diffuse, --specular, --light-kit apply), several along a ray\n"
      "                           composited front to back\n"
      "  --no-shade               --blend isosurface: flat colours, unlit\n"
      "  --iso-step F             march step as a fraction of a macrocell's edge, in (0, 1] (default %g);\n"
      "                           surfaces closer together than the step can be missed\n"
      "  --iso-tolerance F        a hit is refined to within F x step of the surface, in (0, 1]\n"
      "                           (default %g)\n"
      "  --iso-refine-points R    a hit's bracket is cut into R + 1 parts per round, in [1, %d]\n"
      "                           (default: 32 on the GPU, 8 on the CPU; more: fewer rounds, more queries)\n"
      "  --slice-origin X,Y,Z     --blend slice: a point of the plane, world coordinates (default: the\n"
      "                           box's centre)\n"
      "  --slice-normal X,Y,Z     --blend slice: the plane's normal (default 0,0,1)\n"
      "  --slice-opaque           --blend slice: opaque wherever the plane is hit (default: the colour\n"
      "                           map weighted by the scalar opacity, as ParaView's slice)\n"
      "  --crop XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX  keep only this box of the model (model coordinates; ParaView's\n"
      "                           Cropping): rays are clipped to it. With --blend composite (--method\n"
      "                           delta only) the camera rays are clipped as for --brick; shadow rays\n"
      "                           still cross the whole box\n",
      d.stepFraction, d.toleranceFraction, kMaxSurfaceRefinePoints);
  return text;
}

const char* kRenderUsageTail =
    "output:\n"
    "  -o FILE                  .png (8-bit, composited over the background) or .pfm (linear float);\n"
    "                           .npy with --brick, --pixel-share or --sample-share (premultiplied RGBA,\n"
    "                           see --brick)\n"
    "  --stats-json FILE        statistics: rays, queries, iterations, time per stage, macrocells; per\n"
    "                           frame also budget_skipped (pixels left out) and pruned (queries saved)\n"
    "  --quiet                  only the summary line\n";

// The primary estimator's options (TrackingOptions; Render/RatioTracking.h), checked before the
// model loads; the help prints TrackingOptions' defaults.
TrackingOptions parseEstimatorOptions(const Args& args, TrackingOptions t, const std::string& method) {
  for (const char* option :
       {"estimator", "majorant-scale", "residual-scale", "points-per-iteration", "roulette-threshold", "level-ratio",
        "max-level", "comb-minimum-steps", "comb-floor-depth", "jitter", "jitter-control", "fallback-majorant-scale"}) {
    if (args.has(option) && method != "delta")
      throw UsageError(std::string("--") + option + " applies to --method delta (the wavefront tracker) only");
  }
  try {
    t.estimator = parsePrimaryEstimator(args.get("estimator", primaryEstimatorName(t.estimator)));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--estimator: ") + e.what());
  }
  // An estimator named without a density takes its own (ratio tracking its 8, not the debiased
  // march's 2).
  if (args.has("estimator")) t.majorantScale = TrackingOptions::recommendedFor(t.estimator).majorantScale;
  t.majorantScale = args.getDouble("majorant-scale", t.majorantScale);
  t.residualScale = args.getDouble("residual-scale", t.residualScale);
  t.pointsPerIteration = int(args.getInt("points-per-iteration", t.pointsPerIteration));
  t.rouletteThreshold = args.getDouble("roulette-threshold", t.rouletteThreshold);
  t.levelRatio = args.getDouble("level-ratio", t.levelRatio);
  t.maxLevel = int(args.getInt("max-level", t.maxLevel));
  t.combMinimumSteps = args.getDouble("comb-minimum-steps", t.combMinimumSteps);
  t.combFloorDepth = args.getDouble("comb-floor-depth", t.combFloorDepth);
  t.fallbackMajorantScale = args.getDouble("fallback-majorant-scale", t.fallbackMajorantScale);
  if (args.has("jitter")) {
    const std::string j = args.get("jitter");
    if (j != "random" && j != "stratified") throw UsageError("--jitter must be random or stratified, got '" + j + "'");
    t.stratifiedJitter = j == "stratified";
  }
  t.jitterControlFrames = int(args.getInt("jitter-control", t.jitterControlFrames));
  try {
    t.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--estimator / --majorant-scale / --residual-scale / --points-per-iteration / "
                                 "--roulette-threshold / --level-ratio / --max-level / --comb-minimum-steps / --comb-floor-depth / "
                                 "--jitter-control / --fallback-majorant-scale: ") +
                     e.what());
  }
  return t;
}

std::string estimatorUsage() {
  const TrackingOptions d = TrackingOptions::recommended();
  char text[6144];
  std::snprintf(
      text, sizeof text,
      "estimator (--method delta, the wavefront tracker; shadow rays keep --shadow-estimator):\n"
      "  --estimator E            delta: the paper's delta tracking, one collision event per ray; ratio:\n"
      "                           ratio-tracking emission weights at every tentative collision; march:\n"
      "                           unbiased ray marching (a jittered comb per macrocell, transmittance\n"
      "                           corrected by residual ratio tracking); preintegrated: unbiased ray\n"
      "                           marching whose control takes the network as linear between comb points\n"
      "                           and integrates the transfer function exactly over that (ratio tracking\n"
      "                           with shadows, shading or gradient opacity); debiased: a ray march made\n"
      "                           unbiased by refining each comb interval a random number of times (ratio\n"
      "                           tracking with shadows or shading). All converge to the same image; ratio\n"
      "                           and the marches spend cheap queries for far less noise (default %s)\n"
      "  --majorant-scale K       ratio: tentative collisions at K x the macrocell majorant; marches: comb\n"
      "                           points per unit of majorant optical depth; in [1, 1024] (default %g;\n"
      "                           with --estimator ratio or march %g); higher = more queries per frame,\n"
      "                           less noise\n"
      "  --residual-scale KR      marches: residual points at KR x the majorant, in [0, 1024] (default %g;\n"
      "                           0 = no correction: a plain jittered marcher, biased)\n"
      "  --points-per-iteration P ratio: points a ray hands the evaluator per wavefront iteration, 1..%d\n"
      "                           (default %d); the image does not depend on it, only the frame time\n"
      "  --roulette-threshold R   ratio: Russian roulette below this transmittance, in (0, 1] (default %g)\n"
      "  --level-ratio Q          debiased: probability of each further halving of a comb interval's step,\n"
      "                           in (0, 1) (default %g; about (1 - Q) / (1 - 2Q) points per interval)\n"
      "  --max-level L            debiased: at most L halvings, 0..%d (default %d; 0 = the plain march, biased)\n"
      "  --comb-minimum-steps S   debiased, preintegrated: comb points at least every box diagonal / S in\n"
      "                           non-empty macrocells (default %g; 0 = the majorant's density alone)\n"
      "  --comb-floor-depth D     debiased, preintegrated: the floor only up to the cell's majorant / D, so\n"
      "                           faint cells keep about D of majorant optical depth per comb interval,\n"
      "                           in [0, 16] (default %g; 0 = the floor in every non-empty cell)\n"
      "  --jitter random|stratified  sub-pixel jitter over frames: independent, or a low-discrepancy\n"
      "                           sequence per pixel (unbiased per frame, less antialiasing noise over\n"
      "                           frames) (default %s)\n"
      "  --jitter-control N       in the first N frames, subtract the image's slope (a plane through the 8\n"
      "                           neighbours' estimates of the same frame) times each sample's offset from its pixel\n"
      "                           centre: unbiased, less antialiasing noise in those frames, 0..%d\n"
      "                           (default %d; 0 = off)\n"
      "  --fallback-majorant-scale K  preintegrated, debiased: ratio tracking's majorant scale where they\n"
      "                           render as ratio tracking (shadows, shading), 0 or in [1, 1024] (default\n"
      "                           %g; 0 = --majorant-scale)\n",
      primaryEstimatorName(d.estimator), d.majorantScale,
      TrackingOptions::recommendedFor(PrimaryEstimator::Ratio).majorantScale, d.residualScale, TrackingOptions::kMaxPointsPerIteration,
      d.pointsPerIteration, d.rouletteThreshold, d.levelRatio, TrackingOptions::kMaxDebiasedLevel, d.maxLevel,
      d.combMinimumSteps, d.combFloorDepth, d.stratifiedJitter ? "stratified" : "random", TrackingOptions::kMaxJitterControlFrames,
      d.jitterControlFrames, d.fallbackMajorantScale);
  return text;
}

// Reads the query-reduction options onto the struct's defaults. Each option is checked as it is
// applied (the defaults are valid), so an error names the option the user typed.
QueryReductionSettings parseQueryReduction(const Args& args) {
  QueryReductionSettings q;
  auto apply = [&](const char* option, auto&& set) {
    if (!args.has(option)) return;
    set();
    try {
      q.validate();
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--") + option + ": " + e.what());
    }
  };
  apply("budget", [&] {
    try {
      q.budget = parseBudgetScheme(args.get("budget"));
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--budget: ") + e.what());
    }
  });
  apply("budget-fraction", [&] { q.budgetFraction = args.getDouble("budget-fraction", q.budgetFraction); });
  apply("budget-max-skip", [&] {
    const long k = args.getInt("budget-max-skip", q.budgetMaxSkip);
    // Beyond int: said here (converting first would show validate() a different number).
    if (k < 0 || k > (1L << 20))
      throw UsageError("--budget-max-skip: " + std::to_string(k) + " is out of range (0..1024 frames)");
    q.budgetMaxSkip = int(k);
  });
  apply("budget-alpha", [&] { q.budgetAlpha = args.getDouble("budget-alpha", q.budgetAlpha); });
  apply("reproject", [&] { q.reproject = true; });
  apply("no-reproject", [&] { q.reproject = false; });
  if (args.has("reproject") && args.has("no-reproject")) throw UsageError("--reproject and --no-reproject contradict");
  apply("prune-epsilon", [&] { q.pruneEpsilon = args.getDouble("prune-epsilon", q.pruneEpsilon); });
  apply("prune-falloff", [&] { q.pruneFalloff = args.getDouble("prune-falloff", q.pruneFalloff); });
  return q;
}

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::array<double, 3> list3(const Args& args, const std::string& name) {
  const auto v = args.getList(name, 3);
  return {v[0], v[1], v[2]};
}

// Output file and sub-domain split (--brick / --pixel-share).
void parseOutputAndSplit(const Args& args, RenderJob& job) {
  if (args.positional().size() != 1) throw UsageError("expects exactly one MODEL file (see --help)");
  job.model = args.positional()[0];
  if (!args.has("output")) throw UsageError("-o OUT.png|.pfm is required");
  job.output = args.get("output");
  std::string given;
  for (const auto& [option, kind] : {std::pair{"brick", SplitKind::Brick}, std::pair{"pixel-share", SplitKind::PixelShare},
                                     std::pair{"sample-share", SplitKind::SampleShare}}) {
    if (!args.has(option)) continue;
    if (job.split != SplitKind::None)
      throw UsageError("--brick, --pixel-share and --sample-share are three splits: give one, got " + given + " and --" +
                       option);
    job.split = kind;
    given = std::string("--") + option;
  }
  if (job.split != SplitKind::None) {
    try {
      job.splitIndex = parseBrickIndex(args.get(given.substr(2)));
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(job.splitOption()) + ": " + e.what());
    }
    if (!endsWith(job.output, ".npy"))
      throw UsageError(std::string("-o: with ") + job.splitOption() + " the output must end in .npy, got '" +
                       job.output + "'");
  } else if (!endsWith(job.output, ".png") && !endsWith(job.output, ".pfm")) {
    throw UsageError("-o: output must end in .png or .pfm, got '" + job.output + "'");
  }
}

// Image size, seed, jitter, frames and the convergence target.
void parseImageAndFrames(const Args& args, RenderJob& job) {
  RenderSettings& settings = job.settings;
  const std::string size = args.get("size", "512x512");
  const auto x = size.find('x');
  if (x == std::string::npos) throw UsageError("--size must be WxH, e.g. 512x512");
  const long w = parseInt(size.substr(0, x), "--size width"), h = parseInt(size.substr(x + 1), "--size height");
  if (w < 1 || h < 1 || w > 16384 || h > 16384) throw UsageError("--size: each side must be in [1, 16384]");
  settings.width = int(w);
  settings.height = int(h);
  const long seed = args.getInt("seed", 1);
  if (seed < 0 || seed > 0xffffffffL) throw UsageError("--seed must be in [0, 2^32)");
  // Bricks vary the seed (rays of two bricks must not share noise); pixel shares keep it, so the
  // shares add up to the whole image's pixels, and so do sample shares (their frames differ).
  settings.seed = job.splitIntoBricks() ? brickSeed(std::uint32_t(seed), job.splitIndex.index) : std::uint32_t(seed);
  settings.pixelJitter = !args.has("no-jitter");
  if (job.split == SplitKind::PixelShare) settings.pixelShare = PixelShare{job.splitIndex.index, job.splitIndex.count};
  if (job.split == SplitKind::SampleShare) settings.sampleShare = SampleShare{job.splitIndex.index, job.splitIndex.count};
  // One frame is the whole picture for ray marching without jitter and for the isosurface and
  // slice modes (later frames only anti-alias them).
  const bool oneFrame = (job.method == RenderMethod::RayMarch && !settings.pixelJitter) || job.surfaceBlend();
  job.frames = args.getInt("frames", oneFrame ? 1 : 64);
  if (job.frames < 1 || job.frames > 1000000) throw UsageError("--frames must be in [1, 1000000]");
  job.convergeTarget = args.getDouble("converge", 0.0);
  if (args.has("converge") && !(job.convergeTarget > 0.0 && job.convergeTarget <= 200.0)) {
    throw UsageError("--converge must be a PSNR in (0, 200] dB, e.g. 40");
  }
  if (args.has("converge") && job.method == RenderMethod::RayMarch)
    throw UsageError("--converge applies to delta tracking only");
}

// --blend: the mode, and what the isosurface and slice modes refuse (read before the frames'
// default, which depends on it).
void parseBlendMode(const Args& args, RenderJob& job) {
  try {
    job.blend.mode = inr::parseBlendMode(args.get("blend", "composite"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--blend: ") + e.what());
  }
  if (!job.surfaceBlend()) return;
  const std::string mode = std::string("--blend ") + blendModeName(job.blend.mode);
  if (args.has("method")) throw UsageError("--method applies to --blend composite, not " + mode);
  if (job.split != SplitKind::None) throw UsageError(std::string(job.splitOption()) + " applies to --blend composite, not " + mode);
  for (const char* option : {"converge", "shadows", "estimator", "majorant-scale", "residual-scale", "points-per-iteration",
                             "roulette-threshold", "level-ratio", "max-level", "comb-minimum-steps", "comb-floor-depth", "jitter", "jitter-control", "fallback-majorant-scale", "budget", "budget-fraction", "budget-max-skip", "budget-alpha",
                             "reproject", "no-reproject", "prune-epsilon", "prune-falloff", "ghost-passes",
                             "gradient-opacity", "step", "shadow-step", "shadow-estimator"}) {
    if (args.has(option)) throw UsageError(std::string("--") + option + " applies to --blend composite, not " + mode);
  }
}

// The isosurface and slice options and the crop box, checked against the mode.
void parseBlendOptions(const Args& args, RenderJob& job) {
  BlendScene& blend = job.blend;
  const BlendMode mode = blend.mode;
  auto only = [&](const char* option, BlendMode needs) {
    if (args.has(option) && mode != needs)
      throw UsageError(std::string("--") + option + " needs --blend " + blendModeName(needs) + " (got --blend " +
                       blendModeName(mode) + ")");
  };
  for (const char* option : {"iso", "iso-step", "iso-tolerance", "iso-refine-points"}) only(option, BlendMode::Isosurface);
  for (const char* option : {"slice-origin", "slice-normal", "slice-opaque"}) only(option, BlendMode::Slice);
  if (mode == BlendMode::Isosurface) {
    if (!args.has("iso")) throw UsageError("--blend isosurface needs --iso V[,V...] (the isovalues)");
    blend.isovalues = args.getList("iso", 0);
    if (blend.isovalues.empty()) throw UsageError("--iso needs at least one value");
    if (int(blend.isovalues.size()) > BlendScene::kMaxIsovalues)
      throw UsageError("--iso: at most " + std::to_string(BlendScene::kMaxIsovalues) + " isovalues");
    // The candidate macrocells: --macrocells and --skip-block as the session's; --bounds-padding
    // when given (the surface renderer's default pads: SurfaceOptions::defaultMacrocells).
    job.surface.macrocells.dims = job.session.macrocells.dims;
    job.surface.macrocells.skipBlockCells = job.session.macrocells.skipBlockCells;
    if (args.has("bounds-padding")) job.surface.macrocells.boundsPadding = job.session.macrocells.boundsPadding;
    job.surface.stepFraction = float(args.getDouble("iso-step", job.surface.stepFraction));
    if (!(job.surface.stepFraction > 0.f && job.surface.stepFraction <= 1.f))
      throw UsageError("--iso-step must be in (0, 1] (a fraction of a macrocell's edge)");
    job.surface.toleranceFraction = float(args.getDouble("iso-tolerance", job.surface.toleranceFraction));
    if (!(job.surface.toleranceFraction > 0.f && job.surface.toleranceFraction <= 1.f))
      throw UsageError("--iso-tolerance must be in (0, 1] (a fraction of the step)");
    job.surface.refinePoints = int(args.getInt("iso-refine-points", job.surface.refinePoints));
    if (args.has("iso-refine-points") && (job.surface.refinePoints < 1 || job.surface.refinePoints > kMaxSurfaceRefinePoints))
      throw UsageError("--iso-refine-points must be in [1, " + std::to_string(kMaxSurfaceRefinePoints) + "]");
  }
  if (mode == BlendMode::Slice) {
    if (args.has("slice-origin")) {
      blend.sliceOrigin = list3(args, "slice-origin");
      job.sliceOriginGiven = true;
    }
    if (args.has("slice-normal")) {
      blend.sliceNormal = list3(args, "slice-normal");
      const auto& n = blend.sliceNormal;
      if (!(std::hypot(n[0], n[1], n[2]) > 0)) throw UsageError("--slice-normal must be a non-zero direction");
    }
    blend.sliceOpaque = args.has("slice-opaque");
  }
  if (args.has("crop")) {
    const auto c = args.getList("crop", 6);
    for (int a = 0; a < 3; ++a)
      if (!(c[2 * a] < c[2 * a + 1]))
        throw UsageError(std::string("--crop XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX needs min < max on every axis (axis ") +
                         "xyz"[a] + ": " + std::to_string(c[2 * a]) + " >= " + std::to_string(c[2 * a + 1]) + ")");
    blend.crop = true;
    blend.cropBox = Box3f{{float(c[0]), float(c[2]), float(c[4])}, {float(c[1]), float(c[3]), float(c[5])}};
    if (mode == BlendMode::Composite) {
      if (job.method != RenderMethod::Delta)
        throw UsageError("--crop with --blend composite needs --method delta (it clips the camera rays as --brick does)");
      if (job.split != SplitKind::None)
        throw UsageError(std::string("--crop and ") + job.splitOption() + " both clip the picture: give one");
    }
  }
}

// Macrocells, backend, traversal and CPU threads: the session's options.
void parseSessionOptions(const Args& args, RenderJob& job) {
  MacrocellOptions& mopts = job.session.macrocells;
  if (args.has("macrocells")) {
    const auto m = args.getList("macrocells", 0);
    if (m.size() != 1 && m.size() != 3) throw UsageError("--macrocells takes N or NX,NY,NZ");
    for (double v : m)
      if (v < 1 || v > 1024 || v != std::floor(v)) throw UsageError("--macrocells: each must be an integer in [1, 1024]");
    mopts.dims = m.size() == 1 ? Int3{int(m[0]), int(m[0]), int(m[0])} : Int3{int(m[0]), int(m[1]), int(m[2])};
  }
  if (args.has("time-slices")) {
    const long slices = args.getInt("time-slices", mopts.temporalSlices);
    if (slices < 1 || slices > 4096) throw UsageError("--time-slices must be in [1, 4096]");
    job.timeSlices = int(slices);
  }
  mopts.lazySlices = !args.has("eager-slices");
  mopts.boundsPadding = args.getDouble("bounds-padding", mopts.boundsPadding);
  if (mopts.boundsPadding < 0) throw UsageError("--bounds-padding must be >= 0");
  const long skipBlock = args.getInt("skip-block", mopts.skipBlockCells);
  if (skipBlock < 0 || skipBlock > 1024 || (skipBlock & (skipBlock - 1)) != 0) {
    throw UsageError("--skip-block must be 0 (off) or a power of two up to 1024");
  }
  mopts.skipBlockCells = int(skipBlock);
  const long ghost = args.getInt("ghost-passes", TrackingOptions{}.ghostPassesOnUpdate);
  if (ghost < 0 || ghost > TrackingOptions::kMaxGhostPasses) {
    throw UsageError("--ghost-passes must be in [0, " + std::to_string(TrackingOptions::kMaxGhostPasses) + "]");
  }
  job.ghostPasses = int(ghost);

  RenderSessionOptions& sopts = job.session;
  try {
    sopts.backend = parseRenderBackend(args.get("backend", "auto"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--backend: ") + e.what());
  }
  sopts.allowFallback = false;  // an explicit --backend cuda that cannot run is an error
  try {
    sopts.traversal.kind = parseTraversalKind(args.get("traversal", "auto"));
    sopts.traversal.gasMinMajorant = float(args.getDouble("gas-min-majorant", 0.0));
    sopts.traversal.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--traversal / --gas-min-majorant: ") + e.what());
  }
  if (args.has("no-refine")) sopts.tracking.refineMacrocells = false;
  if (args.has("threads")) {
    const long t = args.getInt("threads", 0);
    if (t < 1 || t > 4096) throw UsageError("--threads must be >= 1");
    job.threads = int(t);
  }
  sopts.cpuThreads = job.threads;
}

// Time, camera, transfer function, background, shadows and the ray marcher's steps.
void parseScene(const Args& args, RenderJob& job) {
  if (args.has("time")) job.time = args.getDouble("time", 0.0);
  if (args.has("camera")) {
    const auto c = args.getList("camera", 10);
    Camera camera;
    camera.position = {c[0], c[1], c[2]};
    camera.focalPoint = {c[3], c[4], c[5]};
    camera.viewUp = {c[6], c[7], c[8]};
    camera.viewAngle = c[9];
    job.camera = camera;
  }
  if (args.has("parallel-scale")) job.parallelScale = args.getDouble("parallel-scale", 1.0);
  if (job.camera || job.parallelScale) {
    // Checked on the camera given (or a default one for --parallel-scale alone: the model's
    // framing camera differs only in where it stands).
    Camera check = job.camera.value_or(Camera{});
    if (job.parallelScale) {
      check.parallelProjection = true;
      check.parallelScale = *job.parallelScale;
    }
    try {
      check.view(job.settings.width, job.settings.height);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(job.camera ? "--camera: " : "--parallel-scale: ") + e.what());
    }
  }
  job.transferFunctionFile = args.get("tf");
  if (args.has("tf") && job.transferFunctionFile.empty()) throw UsageError("--tf needs a file name");
  job.transfer2DFile = args.get("tf2d");
  if (args.has("tf2d") && job.transfer2DFile.empty()) throw UsageError("--tf2d needs a file name");
  if (args.has("tf-range")) {
    const auto r = args.getList("tf-range", 2);
    if (!(r[1] > r[0])) throw UsageError("--tf-range LO,HI needs LO < HI");
    job.transferFunctionRange = std::array<double, 2>{r[0], r[1]};
  }
  if (args.has("gradient-opacity")) {
    const auto v = args.getList("gradient-opacity", 0);
    if (v.empty() || v.size() % 2 != 0)
      throw UsageError("--gradient-opacity needs pairs G,A (gradient magnitude, opacity factor), got " +
                       std::to_string(v.size()) + " numbers");
    for (std::size_t k = 0; k < v.size(); k += 2) {
      const double g = v[k], a = v[k + 1];
      if (!(g >= 0.0 && g < INFINITY)) throw UsageError("--gradient-opacity: magnitude " + std::to_string(g) + " must be finite and >= 0");
      if (!(a >= 0.0 && a <= 1.0)) throw UsageError("--gradient-opacity: factor " + std::to_string(a) + " must be in [0, 1]");
      if (k > 0 && !(g > v[k - 2])) throw UsageError("--gradient-opacity: magnitudes must increase");
      job.gradientOpacity.push_back(TransferFunction::OpacityPoint{g, a});
    }
  }
  if (args.has("opacity-unit-distance")) {
    job.opacityUnitDistance = args.getDouble("opacity-unit-distance", 1.0);
    if (!(*job.opacityUnitDistance > 0)) throw UsageError("--opacity-unit-distance must be > 0");
  }
  if (args.has("background")) {
    const auto bg = list3(args, "background");
    job.background = {float(bg[0]), float(bg[1]), float(bg[2])};
  }
  job.shadows = args.has("shadows");
  if (args.has("light")) {
    job.toLight = list3(args, "light");
    const auto& l = *job.toLight;
    if (!(std::hypot(l[0], l[1], l[2]) > 0)) throw UsageError("--light must be a non-zero direction");
  }
  job.ambient = float(args.getDouble("ambient", 0.2));
  if (job.ambient < 0.f || job.ambient > 1.f) throw UsageError("--ambient must be in [0, 1]");
  // The isosurface is lit unless --no-shade (ParaView's Volume with Shade on).
  if (args.has("no-shade") && args.has("shade")) throw UsageError("--shade and --no-shade contradict");
  if (args.has("no-shade") && job.blend.mode != BlendMode::Isosurface)
    throw UsageError("--no-shade applies to --blend isosurface (the other modes are unlit unless --shade)");
  job.shading.enabled = args.has("shade") || (job.blend.mode == BlendMode::Isosurface && !args.has("no-shade"));
  if (args.has("light-kit")) {
    if (!job.shading.enabled) throw UsageError("--light-kit needs --shade");
    if (job.shadows || job.toLight)
      throw UsageError("--light-kit lights with several lights; --light and --shadows take one: use one or the other");
    job.shading.lightList = true;
    job.shading.lights = paraviewLightKit();
  }
  struct Coefficient {
    const char* name;
    float* value;
    float max;  // vtkVolumeProperty's range (the coefficients have none above)
  };
  for (const Coefficient& c : {Coefficient{"diffuse", &job.shading.diffuse, INFINITY},
                               Coefficient{"specular", &job.shading.specular, INFINITY},
                               Coefficient{"specular-power", &job.shading.specularPower, 128.f}}) {
    if (!args.has(c.name)) continue;
    if (!job.shading.enabled) throw UsageError(std::string("--") + c.name + " needs --shade");
    *c.value = float(args.getDouble(c.name, 0.0));
    if (!(*c.value >= 0.f && *c.value <= c.max && *c.value < INFINITY))
      throw UsageError(std::string("--") + c.name +
                       (c.max < INFINITY ? " must be in [0, 128]" : " must be finite and >= 0"));
  }
  const std::string estimator = args.get("shadow-estimator", "delta");
  if (estimator != "delta" && estimator != "ratio") throw UsageError("--shadow-estimator must be delta or ratio");
  job.shadowEstimator = estimator == "ratio" ? ShadowEstimator::Ratio : ShadowEstimator::Delta;

  job.rayMarch.step = float(args.getDouble("step", 0.0));
  job.rayMarch.shadowStep = float(args.getDouble("shadow-step", 0.0));
  if (args.has("step") && !(job.rayMarch.step > 0)) throw UsageError("--step must be > 0");
  if (args.has("shadow-step") && !(job.rayMarch.shadowStep > 0)) throw UsageError("--shadow-step must be > 0");
}

}  // namespace

const char* renderMethodName(RenderMethod method) {
  switch (method) {
    case RenderMethod::Delta: return "delta";
    case RenderMethod::RayMarch: return "raymarch";
    case RenderMethod::Naive: return "naive";
  }
  return "?";
}

const char* splitKindName(SplitKind split) {
  switch (split) {
    case SplitKind::None: return "none";
    case SplitKind::Brick: return "bricks";
    case SplitKind::PixelShare: return "pixels";
    case SplitKind::SampleShare: return "samples";
  }
  return "?";
}

std::string renderUsage() {
  return std::string(kRenderUsageHead) + estimatorUsage() + queryReductionUsage() + blendUsage() +
         kRenderUsageTail;
}

RenderJob parseRenderJob(const std::vector<std::string>& arguments) {
  const Args args(arguments,
                  {"time", "size", "frames", "seed", "camera", "parallel-scale", "tf", "tf2d", "tf-range", "gradient-opacity",
                   "opacity-unit-distance", "background", "light", "ambient", "shadow-estimator", "method", "sample-share",
                   "stats-json", "macrocells", "time-slices", "bounds-padding", "skip-block", "ghost-passes", "step",
                   "shadow-step", "threads", "backend", "traversal", "gas-min-majorant", "output", "converge",
                   "budget", "budget-fraction", "budget-max-skip", "budget-alpha", "prune-epsilon", "prune-falloff",
                   "brick", "pixel-share", "estimator", "majorant-scale", "residual-scale", "points-per-iteration",
                   "roulette-threshold", "level-ratio", "max-level", "comb-minimum-steps", "comb-floor-depth", "jitter", "jitter-control", "fallback-majorant-scale", "diffuse", "specular", "specular-power", "blend", "iso", "iso-step",
                   "iso-tolerance", "iso-refine-points", "slice-origin", "slice-normal", "crop"},
                  {"help", "shadows", "shade", "no-shade", "light-kit", "no-jitter", "eager-slices", "no-refine", "quiet",
                   "reproject", "no-reproject", "slice-opaque"});
  RenderJob job;
  if (args.has("help")) {
    job.help = true;
    return job;
  }
  parseOutputAndSplit(args, job);
  const std::string method = args.get("method", "delta");
  if (method == "delta") job.method = RenderMethod::Delta;
  else if (method == "raymarch") job.method = RenderMethod::RayMarch;
  else if (method == "naive") job.method = RenderMethod::Naive;
  else throw UsageError("--method must be delta, raymarch or naive, got '" + method + "'");
  if (job.split != SplitKind::None && job.method != RenderMethod::Delta)
    throw UsageError(std::string(job.splitOption()) + " applies to --method delta only");
  parseBlendMode(args, job);
  job.quiet = args.has("quiet");
  job.statsJson = args.get("stats-json");
  if (args.has("stats-json") && job.statsJson.empty()) throw UsageError("--stats-json needs a file name");

  parseImageAndFrames(args, job);
  job.queryReduction = parseQueryReduction(args);
  job.session.tracking = parseEstimatorOptions(args, TrackingOptions::recommended(), method);
  for (const char* option : {"budget", "budget-fraction", "budget-max-skip", "budget-alpha", "reproject",
                             "no-reproject", "prune-epsilon", "prune-falloff"}) {
    if (args.has(option) && job.method == RenderMethod::RayMarch)
      throw UsageError(std::string("--") + option + " applies to delta tracking only, not --method raymarch");
  }
  parseSessionOptions(args, job);
  parseScene(args, job);
  parseBlendOptions(args, job);
  return job;
}

}  // namespace inr::cli
