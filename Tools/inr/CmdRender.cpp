// `inr render`: volume rendering of a model (delta tracking on the CPU or CUDA backend, or the
// ray-marching / naive baselines), accumulated over frames, written as PNG or linear PFM.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "Args.h"
#include "Commands.h"
#include "Common/ImageIO.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Backends/Refinement.h"
#include "Backends/RenderSession.h"
#include "Render/BrickDecomposition.h"
#include "Render/DeltaTrackingRenderer.h"
#include "Render/ModelBox.h"
#include "Render/QueryReduction.h"
#include "Render/RayMarcher.h"

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
    "  --background R,G,B       background colour (default 0,0,0)\n"
    "  --shadows                ray-traced shadows from a directional light\n"
    "  --light X,Y,Z            direction towards the light (default: above-left of the camera)\n"
    "  --ambient A              unshadowed fraction of the emission with --shadows (default 0.2)\n"
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
    "                           the ray marcher evaluates through the chosen backend's evaluator\n"
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
    "                           composite_bricks.py adds the shares)\n";

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

const char* kRenderUsageTail =
    "output:\n"
    "  -o FILE                  .png (8-bit, composited over the background) or .pfm (linear float);\n"
    "                           .npy with --brick (premultiplied RGBA, see --brick)\n"
    "  --stats-json FILE        statistics: rays, queries, iterations, time per stage, macrocells; per\n"
    "                           frame also budget_skipped (pixels left out) and pruned (queries saved)\n"
    "  --quiet                  only the summary line\n";

// The primary estimator's options (TrackingOptions; Render/RatioTracking.h), checked before the
// model loads; the help prints TrackingOptions' defaults.
TrackingOptions parseEstimatorOptions(const Args& args, TrackingOptions t, const std::string& method) {
  for (const char* option :
       {"estimator", "majorant-scale", "residual-scale", "points-per-iteration", "roulette-threshold"}) {
    if (args.has(option) && method != "delta")
      throw UsageError(std::string("--") + option + " applies to --method delta (the wavefront tracker) only");
  }
  try {
    t.estimator = parsePrimaryEstimator(args.get("estimator", primaryEstimatorName(t.estimator)));
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--estimator: ") + e.what());
  }
  t.majorantScale = args.getDouble("majorant-scale", t.majorantScale);
  t.residualScale = args.getDouble("residual-scale", t.residualScale);
  t.pointsPerIteration = int(args.getInt("points-per-iteration", t.pointsPerIteration));
  t.rouletteThreshold = args.getDouble("roulette-threshold", t.rouletteThreshold);
  try {
    t.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--estimator / --majorant-scale / --residual-scale / --points-per-iteration / "
                                 "--roulette-threshold: ") +
                     e.what());
  }
  return t;
}

std::string estimatorUsage() {
  const TrackingOptions d = TrackingOptions::recommended();
  char text[2048];
  std::snprintf(
      text, sizeof text,
      "estimator (--method delta, the wavefront tracker; shadow rays keep --shadow-estimator):\n"
      "  --estimator E            delta: the paper's delta tracking, one collision event per ray; ratio:\n"
      "                           ratio-tracking emission weights at every tentative collision; march:\n"
      "                           unbiased ray marching (a jittered comb per macrocell, transmittance\n"
      "                           corrected by residual ratio tracking). All three converge to the same\n"
      "                           image; ratio and march spend cheap queries for far less noise (default %s)\n"
      "  --majorant-scale K       ratio: tentative collisions at K x the macrocell majorant; march: comb\n"
      "                           points per unit of majorant optical depth; in [1, 1024] (default %g);\n"
      "                           higher = more queries per frame, less noise\n"
      "  --residual-scale KR      march: residual points at KR x the majorant, in [0, 1024] (default %g;\n"
      "                           0 = no correction: a plain jittered marcher, biased)\n"
      "  --points-per-iteration P ratio: points a ray hands the evaluator per wavefront iteration, 1..%d\n"
      "                           (default %d); the image does not depend on it, only the frame time\n"
      "  --roulette-threshold R   ratio: Russian roulette below this transmittance, in (0, 1] (default %g)\n",
      primaryEstimatorName(d.estimator), d.majorantScale, d.residualScale, TrackingOptions::kMaxPointsPerIteration,
      d.pointsPerIteration, d.rouletteThreshold);
  return text;
}

std::array<double, 3> list3(const Args& args, const std::string& name) {
  const auto v = args.getList(name, 3);
  return {v[0], v[1], v[2]};
}

nlohmann::json statsJson(const FrameStats& s) {
  return {{"frame", s.frame},
          {"pixels", s.pixels},
          {"rays", s.rays},
          {"queries", s.queries},
          {"iterations", s.iterations},
          {"shadow_rays", s.shadowRays},
          {"shadow_queries", s.shadowQueries},
          {"shadow_iterations", s.shadowIterations},
          {"refinements", s.refinements},
          {"residual_sum", s.residualSum},
          {"capped_rays", s.cappedRays},
          {"budget_skipped", s.budgetSkipped},
          {"pruned", s.pruned},
          {"traversal_primitives", s.traversalPrimitives},
          {"traversal_bytes", s.traversalBytes},
          {"ms",
           {{"update", s.updateMs},
            {"init", s.initMs},
            {"traverse", s.traverseMs},
            {"evaluate", s.evaluateMs},
            {"shadow_traverse", s.shadowTraverseMs},
            {"shadow_evaluate", s.shadowEvaluateMs},
            {"finalize", s.finalizeMs},
            {"traversal_build", s.traversalBuildMs},
            {"total", s.totalMs}}}};
}

nlohmann::json queryReductionJson(const QueryReductionSettings& q) {
  return {{"budget", budgetSchemeName(q.budget)},
          {"budget_fraction", q.budgetFraction},
          {"budget_max_skip", q.budgetMaxSkip},
          {"budget_alpha", q.budgetAlpha},
          {"reproject", q.reproject},
          {"prune_epsilon", q.pruneEpsilon},
          {"prune_falloff", q.pruneFalloff}};
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

// NumPy's .npy format (version 1.0): float32 little-endian, shape (height, width, 4), C order:
// the premultiplied RGBA of a brick, readable with numpy.load.
void writeNpyRgba(const std::string& path, const ImageRGBA& image) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(image.height) + ", " +
                       std::to_string(image.width) + ", 4), }";
  // Magic (6) + version (2) + length (2) + header + newline, padded to a multiple of 64.
  const std::size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot write the brick image");
  const unsigned char magic[8] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0};
  f.write(reinterpret_cast<const char*>(magic), 8);
  const unsigned char len[2] = {static_cast<unsigned char>(header.size() & 0xff),
                                static_cast<unsigned char>(header.size() >> 8)};
  f.write(reinterpret_cast<const char*>(len), 2);
  f.write(header.data(), std::streamsize(header.size()));
  static_assert(sizeof(float) == 4, "float32 output");
  f.write(reinterpret_cast<const char*>(image.data.data()), std::streamsize(image.data.size() * sizeof(float)));
  if (!f) throw std::runtime_error(path + ": write failed");
}

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

int runRender(int argc, char** argv) {
  Args args(argc, argv,
            {"time", "size", "frames", "seed", "camera", "parallel-scale", "tf", "tf-range",
             "opacity-unit-distance", "background", "light", "ambient", "shadow-estimator", "method",
             "stats-json", "macrocells", "time-slices", "bounds-padding", "skip-block", "ghost-passes",
             "step", "shadow-step", "threads", "backend", "traversal", "gas-min-majorant", "output", "converge", "budget", "budget-fraction",
             "budget-max-skip", "budget-alpha", "prune-epsilon", "prune-falloff", "brick", "pixel-share",
             "estimator", "majorant-scale", "residual-scale", "points-per-iteration", "roulette-threshold"},
            {"help", "shadows", "no-jitter", "eager-slices", "no-refine", "quiet", "reproject", "no-reproject"});
  if (args.has("help")) {
    std::fputs(kRenderUsageHead, stdout);
    std::fputs(estimatorUsage().c_str(), stdout);
    std::fputs(queryReductionUsage().c_str(), stdout);
    std::fputs(kRenderUsageTail, stdout);
    return 0;
  }
  if (args.positional().size() != 1) throw UsageError("expects exactly one MODEL file (see --help)");
  if (!args.has("output")) throw UsageError("-o OUT.png|.pfm is required");
  const std::string out = args.get("output");
  const bool pixelShareMode = args.has("pixel-share");
  if (pixelShareMode && args.has("brick")) throw UsageError("--brick and --pixel-share are two splits: give one");
  const bool brickMode = args.has("brick") || pixelShareMode;  // both write a premultiplied .npy
  const char* splitOption = pixelShareMode ? "--pixel-share" : "--brick";
  BrickIndex brick;
  if (brickMode) {
    try {
      brick = parseBrickIndex(args.get(pixelShareMode ? "pixel-share" : "brick"));
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(splitOption) + ": " + e.what());
    }
    if (!endsWith(out, ".npy"))
      throw UsageError(std::string("-o: with ") + splitOption + " the output must end in .npy, got '" + out + "'");
  } else if (!endsWith(out, ".png") && !endsWith(out, ".pfm")) {
    throw UsageError("-o: output must end in .png or .pfm, got '" + out + "'");
  }
  const std::string method = args.get("method", "delta");
  if (method != "delta" && method != "raymarch" && method != "naive") {
    throw UsageError("--method must be delta, raymarch or naive, got '" + method + "'");
  }
  if (brickMode && method != "delta") throw UsageError(std::string(splitOption) + " applies to --method delta only");
  const bool quiet = args.has("quiet");

  // --- image settings
  RenderSettings settings;
  {
    const std::string size = args.get("size", "512x512");
    const auto x = size.find('x');
    if (x == std::string::npos) throw UsageError("--size must be WxH, e.g. 512x512");
    const long w = parseInt(size.substr(0, x), "--size width"), h = parseInt(size.substr(x + 1), "--size height");
    if (w < 1 || h < 1 || w > 16384 || h > 16384) throw UsageError("--size: each side must be in [1, 16384]");
    settings.width = int(w);
    settings.height = int(h);
  }
  const long seed = args.getInt("seed", 1);
  if (seed < 0 || seed > 0xffffffffL) throw UsageError("--seed must be in [0, 2^32)");
  // Bricks vary the seed (rays of two bricks must not share noise); pixel shares keep it, so the
  // shares add up to the whole image's pixels.
  settings.seed = brickMode && !pixelShareMode ? brickSeed(std::uint32_t(seed), brick.index) : std::uint32_t(seed);
  settings.pixelJitter = !args.has("no-jitter");
  const long frames = args.getInt("frames", method == "raymarch" && !settings.pixelJitter ? 1 : 64);
  if (frames < 1 || frames > 1000000) throw UsageError("--frames must be in [1, 1000000]");
  const double convergeTarget = args.getDouble("converge", 0.0);
  if (args.has("converge") && !(convergeTarget > 0.0 && convergeTarget <= 200.0)) {
    throw UsageError("--converge must be a PSNR in (0, 200] dB, e.g. 40");
  }
  if (args.has("converge") && method == "raymarch") throw UsageError("--converge applies to delta tracking only");
  // Checked before the model loads, so a typo fails at once.
  const QueryReductionSettings queryReduction = parseQueryReduction(args);
  const TrackingOptions estimatorOptions = parseEstimatorOptions(args, TrackingOptions::recommended(), method);
  for (const char* option : {"budget", "budget-fraction", "budget-max-skip", "budget-alpha", "reproject",
                             "no-reproject", "prune-epsilon", "prune-falloff"}) {
    if (args.has(option) && method == "raymarch")
      throw UsageError(std::string("--") + option + " applies to delta tracking only, not --method raymarch");
  }
  if (args.has("threads")) {
    const long t = args.getInt("threads", 0);
    if (t < 1 || t > 4096) throw UsageError("--threads must be >= 1");
    omp_set_num_threads(int(t));
  }

  // --- model and evaluator
  const InrModel model = InrModel::loadFile(args.positional()[0]);
  const Box3f box = modelWorldBox(model);
  const double diagonal = length(box.hi - box.lo);

  // --- macrocells
  MacrocellOptions mopts;
  if (args.has("macrocells")) {
    const auto m = args.getList("macrocells", 0);
    if (m.size() != 1 && m.size() != 3) throw UsageError("--macrocells takes N or NX,NY,NZ");
    for (double v : m)
      if (v < 1 || v > 1024 || v != std::floor(v)) throw UsageError("--macrocells: each must be an integer in [1, 1024]");
    mopts.dims = m.size() == 1 ? Int3{int(m[0]), int(m[0]), int(m[0])} : Int3{int(m[0]), int(m[1]), int(m[2])};
  }
  const long slices = args.getInt("time-slices", model.domain.usesTime() ? mopts.temporalSlices : 1);
  if (slices < 1 || slices > 4096) throw UsageError("--time-slices must be in [1, 4096]");
  mopts.temporalSlices = int(slices);
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


  std::vector<Brick> bricks;
  if (pixelShareMode) {
    Brick whole;
    whole.box = box;
    whole.cellLo = Int3{0, 0, 0};
    whole.cellHi = mopts.dims;
    bricks.assign(std::size_t(brick.count), whole);
    settings.pixelShare = PixelShare{brick.index, brick.count};
  } else if (brickMode) {
    try {
      bricks = brickDecomposition(box, mopts.dims, brick.count);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--brick: ") + e.what());
    }
    settings.clipToBrick = true;
    settings.brick = bricks[std::size_t(brick.index)].box;
  }

  // --- backend session (evaluator, macrocells, renderer)
  RenderSessionOptions sopts;
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
  sopts.macrocells = mopts;
  sopts.tracking = estimatorOptions;
  if (args.has("no-refine")) sopts.tracking.refineMacrocells = false;
  sopts.cpuThreads = int(args.getInt("threads", 0));
  double lastShown = -1.0;
  if (!quiet) {
    sopts.progress = [&](double fraction, const std::string& phase) {
      if (fraction == 0.0 || fraction == 1.0 || fraction - lastShown >= 0.25) {
        std::printf("%s: %3.0f%%\n", phase.c_str(), 100.0 * fraction);
        std::fflush(stdout);
        lastShown = fraction == 1.0 ? -1.0 : fraction;
      }
    };
  }
  const std::unique_ptr<RenderSession> session = RenderSession::create(model, sopts);
  const FieldEvaluator& evaluator = session->evaluator();
  if (!quiet) std::printf("backend: %s\n", session->description().c_str());
  session->setQueryReduction(queryReduction);

  // --- scene
  RenderScene scene;
  scene.time = args.getDouble("time", model.domain.timeBegin);
  if (scene.time < model.domain.timeBegin || scene.time > model.domain.timeEnd) {
    std::fprintf(stderr, "inr render: warning: --time %g is outside the model's time range [%g, %g]\n",
                 scene.time, model.domain.timeBegin, model.domain.timeEnd);
  }
  scene.camera = Camera::framing(box);
  if (args.has("camera")) {
    const auto c = args.getList("camera", 10);
    scene.camera.position = {c[0], c[1], c[2]};
    scene.camera.focalPoint = {c[3], c[4], c[5]};
    scene.camera.viewUp = {c[6], c[7], c[8]};
    scene.camera.viewAngle = c[9];
  }
  if (args.has("parallel-scale")) {
    scene.camera.parallelProjection = true;
    scene.camera.parallelScale = args.getDouble("parallel-scale", 1.0);
  }
  try {
    scene.camera.view(settings.width, settings.height);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--camera: ") + e.what());
  }
  if (args.has("tf")) {
    scene.transferFunction = TransferFunction::fromParaViewJsonFile(args.get("tf"));
    const std::string warning = scene.transferFunction.colorSpaceWarning();
    if (!warning.empty()) std::fprintf(stderr, "inr render: warning: %s\n", warning.c_str());
  } else {
    const auto range = valueRangeFor(model, evaluator);
    scene.transferFunction = TransferFunction::preset(range[0], range[1]);
  }
  if (args.has("tf-range")) {
    const auto r = args.getList("tf-range", 2);
    if (!(r[1] > r[0])) throw UsageError("--tf-range LO,HI needs LO < HI");
    scene.transferFunction.rescale(r[0], r[1]);
  }
  scene.transferFunction.unitDistance = args.getDouble("opacity-unit-distance", diagonal / 64.0);
  if (!(scene.transferFunction.unitDistance > 0)) throw UsageError("--opacity-unit-distance must be > 0");
  if (args.has("background")) {
    const auto bg = list3(args, "background");
    scene.background = {float(bg[0]), float(bg[1]), float(bg[2])};
  }
  scene.shadows = args.has("shadows");
  scene.toLight = args.has("light") ? list3(args, "light") : defaultLightDirection(scene.camera);
  if (!(std::hypot(scene.toLight[0], scene.toLight[1], scene.toLight[2]) > 0)) {
    throw UsageError("--light must be a non-zero direction");
  }
  scene.ambient = float(args.getDouble("ambient", 0.2));
  if (scene.ambient < 0.f || scene.ambient > 1.f) throw UsageError("--ambient must be in [0, 1]");
  const std::string estimator = args.get("shadow-estimator", "delta");
  if (estimator != "delta" && estimator != "ratio") throw UsageError("--shadow-estimator must be delta or ratio");
  scene.shadowEstimator = estimator == "ratio" ? ShadowEstimator::Ratio : ShadowEstimator::Delta;

  RayMarchOptions ropts;
  ropts.step = float(args.getDouble("step", 0.0));
  ropts.shadowStep = float(args.getDouble("shadow-step", 0.0));
  if (args.has("step") && !(ropts.step > 0)) throw UsageError("--step must be > 0");
  if (args.has("shadow-step") && !(ropts.shadowStep > 0)) throw UsageError("--shadow-step must be > 0");

  nlohmann::json report;
  report["model"] = args.positional()[0];
  report["method"] = method;
  if (method == "delta") {
    const TrackingOptions& t = session->trackingOptions();
    report["estimator"] = {{"name", primaryEstimatorName(t.estimator)},
                           {"majorant_scale", t.majorantScale},
                           {"residual_scale", t.residualScale},
                           {"points_per_iteration", t.pointsPerIteration},
                           {"roulette_threshold", t.rouletteThreshold}};
  }
  report["width"] = settings.width;
  report["height"] = settings.height;
  report["time"] = scene.time;
  report["frames_requested"] = frames;
  report["threads"] = omp_get_max_threads();
  report["evaluator"] = evaluator.name();
  report["backend"] = session->description();
  // What the session holds, read back: the settings every frame below ran with.
  if (method != "raymarch") report["query_reduction"] = queryReductionJson(session->queryReduction());

  FrameStats total;
  long renderedFrames = frames;
  std::vector<nlohmann::json> perFrame;
  ImageRGBA image;
  auto progressLine = [&](const FrameStats& st, long k) {
    if (quiet) return;
    std::printf("frame %ld/%ld: %zu rays, %zu queries (+%zu shadow) in %d (+%d) iterations, %.1f ms", k + 1, frames,
                st.rays, st.queries, st.shadowQueries, st.iterations, st.shadowIterations, st.totalMs);
    // Only when query reduction did something, so the usual line stays as it was.
    if (st.budgetSkipped || st.pruned) std::printf("; %zu pixels skipped, %zu pruned", st.budgetSkipped, st.pruned);
    std::printf("\n");
    std::fflush(stdout);
  };

  if (method == "raymarch") {
    RayMarchRenderer renderer(evaluator, box, ropts);
    renderer.setSettings(settings);
    renderer.setScene(scene);
    report["step"] = renderer.step();
    report["shadow_step"] = renderer.shadowStep();
    for (long k = 0; k < frames; ++k) {
      const FrameStats st = renderer.renderFrame();
      progressLine(st, k);
      total += st;
      perFrame.push_back(statsJson(st));
    }
    image = renderer.image();
  } else {
    RenderSession& renderer = *session;
    renderer.setSettings(settings);
    const auto t0 = std::chrono::steady_clock::now();
    renderer.setScene(scene);
    const double setupMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const MacrocellInfo mi = renderer.macrocellInfo();
    if (!quiet) {
      std::printf("macrocells: %dx%dx%d x %d slices; built %d slice(s) in %.3f s (%zu lattice queries)%s\n",
                  mi.dims.x, mi.dims.y, mi.dims.z, mi.temporalSlices, mi.slicesBuilt, mi.buildSeconds,
                  mi.latticeQueries, mopts.lazySlices && mi.temporalSlices > mi.slicesBuilt ? "; lazy build" : "");
      if (mopts.lazySlices && mi.temporalSlices > mi.slicesBuilt) {
        std::printf("macrocells: building all %d slices up front would take about %.2f s more\n", mi.temporalSlices,
                    mi.sliceSeconds() * (mi.temporalSlices - mi.slicesBuilt));
      }
    }
    report["macrocells"] = {{"dims", {mi.dims.x, mi.dims.y, mi.dims.z}},
                            {"temporal_slices", mi.temporalSlices},
                            {"slices_built", mi.slicesBuilt},
                            {"build_seconds", mi.buildSeconds},
                            {"lattice_queries", mi.latticeQueries},
                            {"setup_ms", setupMs},
                            {"lazy", mopts.lazySlices},
                            {"skip_block", mi.skipBlockCells},
                            {"bounds_padding", mi.boundsPadding},
                            {"ghost_passes", ghost},
                            {"refine", renderer.trackingOptions().refineMacrocells}};
    if (ghost > 0) {
      const FrameStats g = renderer.runGhostPasses(int(ghost));
      if (!quiet) {
        std::printf("ghost passes: %ld, %zu queries, %zu cells refined, %.1f ms\n", ghost, g.queries,
                    g.refinements, g.totalMs);
      }
      report["ghost_passes"] = statsJson(g);
    }
    // One frame per request, so each frame is reported; the driver's stop rule is the plugin's.
    RefinementOptions ro;
    ro.maximumFrames = int(frames);
    ro.convergenceTarget = convergeTarget;
    RefinementDriver driver(ro);
    const auto tRender = std::chrono::steady_clock::now();
    while (!driver.converged()) {
      const RefinementDriver::Step step = driver.advance(renderer, method == "naive");
      if (step.framesRendered == 0) break;
      const long k = renderer.accumulatedFrames() - 1;
      progressLine(step.total, k);
      total += step.total;
      nlohmann::json js = statsJson(step.total);
      js["estimated_psnr_db"] = driver.estimate();
      js["covered_pixels"] = step.total.coveredPixels;
      perFrame.push_back(js);
    }
    const double renderSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - tRender).count();
    renderedFrames = renderer.accumulatedFrames();
    report["convergence"] = {{"target", convergeTarget},
                             {"estimate", driver.estimate()},
                             {"frames", renderedFrames},
                             {"converged", convergeTarget > 0.0 && driver.estimate() >= convergeTarget},
                             {"seconds", renderSeconds}};
    if (args.has("converge")) {
      const bool reached = driver.estimate() >= convergeTarget;
      std::printf("convergence: %s after %ld frame(s) in %.3f s (estimated PSNR over the volume %.2f dB, target %g dB)\n",
                  reached ? "reached" : "NOT reached (frame limit)", renderedFrames, renderSeconds,
                  driver.estimate(), convergeTarget);
    }
    report["macrocells"]["refinements"] = renderer.macrocellInfo().refinements;
    image = brickMode ? renderer.premultipliedImage() : renderer.image();
    if (brickMode) {
      // What the compositing script needs to order the bricks, and what the run cost.
      const Brick& b = bricks[std::size_t(brick.index)];
      const Camera& c = scene.camera;
      nlohmann::json meta;
      meta["brick"] = {{"index", brick.index}, {"count", brick.count}};
      meta["split"] = pixelShareMode ? "pixels" : "bricks";
      meta["box"] = {b.box.lo.x, b.box.hi.x, b.box.lo.y, b.box.hi.y, b.box.lo.z, b.box.hi.z};
      meta["cells"] = {b.cellLo.x, b.cellHi.x, b.cellLo.y, b.cellHi.y, b.cellLo.z, b.cellHi.z};
      meta["camera"] = {{"position", c.position}, {"focal_point", c.focalPoint}, {"parallel", c.parallelProjection}};
      meta["seed"] = settings.seed;
      meta["width"] = settings.width;
      meta["height"] = settings.height;
      meta["frames"] = renderer.accumulatedFrames();
      meta["queries"] = total.queries;
      meta["shadow_queries"] = total.shadowQueries;
      meta["render_seconds"] = renderSeconds;
      meta["ms_per_frame"] = total.totalMs / std::max(1, renderer.accumulatedFrames());
      meta["estimated_psnr_db"] = driver.estimate();
      meta["backend"] = session->description();
      const std::string metaPath = out.substr(0, out.size() - 4) + ".brick.json";
      std::ofstream js(metaPath);
      if (!js) throw std::runtime_error(metaPath + ": cannot write the brick description");
      js << meta.dump(2) << "\n";
    }
  }

  if (brickMode) writeNpyRgba(out, image);
  else writeImage(out, image);
  const double n = double(renderedFrames);
  // The wavefront tracker's line names its estimator (ratio, delta, march), not the method.
  const std::string summaryMethod =
      method == "delta" ? primaryEstimatorName(session->trackingOptions().estimator) : method;
  std::printf("%s: %s %dx%d, %ld frame(s), t=%g: %.0f rays, %.0f queries (+%.0f shadow), %.1f iterations per "
              "frame; %.1f ms per frame (traverse %.1f, evaluate %.1f, shadows %.1f, finalize %.1f) -> %s\n",
              args.positional()[0].c_str(), summaryMethod.c_str(), settings.width, settings.height, renderedFrames,
              scene.time,
              total.rays / n, total.queries / n, total.shadowQueries / n, total.iterations / n, total.totalMs / n,
              total.traverseMs / n, total.evaluateMs / n, (total.shadowTraverseMs + total.shadowEvaluateMs) / n,
              total.finalizeMs / n, out.c_str());
  if (args.has("stats-json")) {
    report["total"] = statsJson(total);
    report["frames"] = perFrame;
    std::ofstream js(args.get("stats-json"));
    if (!js) throw std::runtime_error(args.get("stats-json") + ": cannot write statistics");
    js << report.dump(2) << "\n";
  }
  return 0;
}

}  // namespace inr::cli
