// Run time against error for query reduction (issue 11 item 5; paper §"Query Reduction
// Tradeoffs"). Per model, through RenderSession on the CPU or CUDA backend:
//   reference   --reference-frames unbudgeted, unpruned frames (seed 977); its premultiplied alpha
//               is the coverage mask ("the volume's pixels": alpha > 0).
//   configs     each a fresh session (fresh accumulation, fresh macrocell refinement; seed 1):
//               frames until --seconds of summed FrameStats::totalMs (render time only: image
//               downloads and PSNRs are outside it) and at least --min-frames, or --max-frames.
//               PSNR over the volume's pixels and over the whole image against the reference,
//               time to 35 / 40 dB, PSNR at frame 400 and at the end, frames/s.
//   heatmaps    rays per pixel per frame, over frames 2..--heatmap-frames+1 (see rayHeatmap).
//   raymarch    fixed-step ray marching, one frame at pixel centres, steps diagonal / D for D in
//               --march-steps: the one-frame method a user would pick instead (PSNR at its time).
//   orbit       --orbit-steps camera steps of --orbit-degrees about the focal point, --orbit-frames
//               frames each, with the compiled defaults with and without reprojection; PSNR per
//               frame against a --orbit-reference-frames render at that step's camera.
// CSV (curves, summary, raymarch, orbit) and PNGs (reference, images at --snapshot-seconds,
// heatmaps, ray-marched frames) under --out; plots: plot_query_reduction.py.
//   query_reduction_benchmark [--backend cpu|cuda|auto] [--size N] [--seconds S] [--configs LIST]
//       [--reference-frames N] [--out DIR] [--help for the rest] [MODEL.inr ...]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "Backends/Refinement.h"
#include "Backends/RenderSession.h"
#include "BenchmarkSupport.h"
#include "Common/ImageIO.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Render/ModelBox.h"
#include "Render/QueryReduction.h"
#include "Render/RayMarcher.h"
#include "ShippedScene.h"
#include "TestSupport/GradientNorms.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestScene.h"

#ifdef INR_HAVE_CUDA
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Render/Cuda/CudaRayMarcher.h"
#endif

using namespace inr;
using namespace inr::bench;
namespace fs = std::filesystem;

namespace {

const char* kUsage =
    "usage: query_reduction_benchmark [options] [MODEL.inr ...]\n"
    "  default models: Testing/Data/real/*.inr, the *_small ones on the CPU, the others on the GPU\n"
    "  --backend B             auto (default), cpu or cuda (no fallback)\n"
    "  --size N                image N x N (default 1024 GPU, 256 CPU)\n"
    "  --seconds S             render time per configuration (default 3 GPU, 20 CPU)\n"
    "  --min-frames N          at least N frames per configuration (default 400 GPU, 0 CPU)\n"
    "  --max-frames N          at most N frames per configuration (default 100000)\n"
    "  --reference-frames N    frames of the unbudgeted reference (default 400)\n"
    "  --configs LIST          ';'-separated: none | defaults | histogram:RHO[:K] | stbn:RHO |\n"
    "                          weighted:RHO[:ALPHA] | prune:EPSILON[:DELTA] | delta | ratio[:K[:P[:R]]] |\n"
    "                          march[:K[:KR[:P[:R]]]] | preint[:K[:KR[:P[:R[:S]]]]] |\n"
    "                          debiased[:K[:Q[:L[:P[:S[:J[:D[:C]]]]]]]] (ratio tracking with\n"
    "                          majorant scale K; unbiased ray marching, with the pre-integrated control\n"
    "                          for preint, comb density K and residual scale KR; points per iteration\n"
    "                          P, roulette threshold R, preint's comb at least every diagonal / S;\n"
    "                          the debiased march with comb density K, level ratio Q, max level L,\n"
    "                          stratified jitter J (0/1), the floor only to majorant / D (D > 0), the\n"
    "                          jitter's control variate in the first C frames; join\n"
    "                          with '+', e.g. ratio:4+prune:0.02; default:\n"
    "                          the paper's set)\n"
    "  --psnr-schedule S       all (every frame; default CPU) or geometric (frames 1,2,3,4,5,6,8,10,..\n"
    "                          growing by 2^(1/4), plus 400 and the last; default GPU)\n"
    "  --heatmap-frames N      frames counted for the rays-per-pixel heatmaps (default 64; 0 = none)\n"
    "  --snapshot-seconds S    write each configuration's image once S seconds are reached (default 1.2)\n"
    "  --march-steps LIST      ray-march steps as diagonal divisors (default 64,128,256,512; '' = none)\n"
    "  --orbit-steps N         camera-orbit steps (default 60 GPU, 12 CPU; 0 = none)\n"
    "  --orbit-degrees D       degrees per step (default 1)\n"
    "  --orbit-frames F        frames per step (default 4)\n"
    "  --orbit-warmup F        frames at the first camera before the orbit starts (default 32)\n"
    "  --orbit-reference-frames N  frames of each step's reference (default 128 GPU, 64 CPU)\n"
    "  --macrocells M          M^3 macrocells (default 64)\n"
    "  --slices T              temporal macrocell slices (default 16; 1 for static models)\n"
    "  --time T                world time (default: middle of the model's time range)\n"
    "  --warm-time T           each configuration's session first renders one frame at world time T,\n"
    "                          then moves to --time: its first measured frame is a time change in a\n"
    "                          warm session (what ParaView's first render after a time change is),\n"
    "                          not a session's first frame (default: off)\n"
    "  --gradient-opacity-median G,A[,G,A...]  gradient opacity on every render (reference, configs,\n"
    "                          marcher): factor A at |grad f| = G x the model's median |grad f| over its\n"
    "                          box at the scene's time (the CPU evaluator's gradient), so one list fits\n"
    "                          models of any gradient scale; default none\n"
    "  --config-jitter 0|1     sub-pixel jitter of the configurations' frames (default 1; 0: pixel\n"
    "                          centres, to measure the jitter's share of their error; the reference\n"
    "                          stays jittered)\n"
    "  --out DIR               results folder (default query-reduction-results)\n"
    "  --append                add to the CSVs already in DIR (e.g. one model per call)\n";

struct Options {
  std::string backend = "auto";
  int size = 0;
  double seconds = 0;
  int minFrames = -1, maxFrames = 100000, referenceFrames = 400;
  std::string configs;
  std::string psnrSchedule;
  int heatmapFrames = 64;
  double snapshotSeconds = 1.2;
  std::string marchSteps = "64,128,256,512";
  int orbitSteps = -1, orbitFrames = 4, orbitWarmup = 32, orbitReferenceFrames = -1;
  double orbitDegrees = 1.0;
  int macrocells = 64, slices = 16;
  double time = NAN, warmTime = NAN;
  std::vector<double> gradientOpacityMedian;  // G, A pairs, G in multiples of the median |grad f|
  std::string out = "query-reduction-results";
  bool append = false;
  bool configJitter = true;
  std::vector<std::string> models;
};

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string t; std::getline(ss, t, sep);)
    if (!t.empty()) out.push_back(t);
  return out;
}

// "G,A[,G,A...]": an even count of finite numbers, G ascending and A in [0, 1].
std::vector<double> gradientOpacityPairs(const std::string& list) {
  std::vector<double> v;
  bool ok = true;
  for (const std::string& t : split(list, ',')) {
    char* end = nullptr;
    v.push_back(std::strtod(t.c_str(), &end));
    ok = ok && end && *end == '\0';
  }
  ok = ok && !v.empty() && v.size() % 2 == 0;
  for (std::size_t k = 0; ok && k < v.size(); k += 2)
    ok = std::isfinite(v[k]) && v[k] >= 0 && v[k + 1] >= 0 && v[k + 1] <= 1 && (k == 0 || v[k] > v[k - 2]);
  if (!ok)
    throw std::invalid_argument("--gradient-opacity-median '" + list +
                                "': give G,A pairs (G >= 0 ascending, in multiples of the median |grad f|; A in [0, 1])");
  return v;
}

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// ---------------------------------------------------------------- configurations

struct Config {
  std::string label;   // canonical spec, e.g. "stbn:0.75" (also the file-name stem)
  std::string family;  // none, defaults, histogram, stbn, weighted-stbn, prune, delta, ratio
  QueryReductionSettings q;
  TrackingOptions tracking;  // the primary estimator (delta unless a ratio part says otherwise)
};

// Everything off: the estimator the reference uses. Spelled out rather than taken from the
// defaults, which the benchmark is meant to choose and which may turn something on.
QueryReductionSettings allOff() {
  QueryReductionSettings q;
  q.budget = BudgetScheme::None;
  q.reproject = false;
  q.pruneEpsilon = 0.0;
  q.pruneFalloff = 0.0;
  return q;
}

Config parseSingleConfig(const std::string& spec) {
  const std::vector<std::string> t = split(spec, ':');
  if (t.empty()) throw std::invalid_argument("empty configuration");
  auto num = [&](std::size_t i, double fallback) {
    if (i >= t.size()) return fallback;
    std::size_t used = 0;
    const double v = std::stod(t[i], &used);
    if (used != t[i].size()) throw std::invalid_argument("'" + spec + "': '" + t[i] + "' is not a number");
    return v;
  };
  auto arity = [&](std::size_t lo, std::size_t hi) {
    if (t.size() < lo || t.size() > hi) throw std::invalid_argument("'" + spec + "': wrong number of parameters");
  };
  Config c;
  c.q = allOff();
  const std::string& f = t[0];
  if (f == "none") {
    arity(1, 1);
    c.family = "none";
    c.label = "none";
  } else if (f == "defaults") {
    arity(1, 1);
    c.family = "defaults";
    c.label = "defaults";
    c.q = QueryReductionSettings{};
  } else if (f == "histogram") {
    arity(2, 3);
    c.family = "histogram";
    c.q.budget = BudgetScheme::Histogram;
    c.q.budgetFraction = num(1, 0);
    c.q.budgetMaxSkip = int(num(2, 8));
    c.label = "histogram:" + fmt(c.q.budgetFraction) + ":" + std::to_string(c.q.budgetMaxSkip);
  } else if (f == "stbn") {
    arity(2, 2);
    c.family = "stbn";
    c.q.budget = BudgetScheme::Stbn;
    c.q.budgetFraction = num(1, 0);
    c.label = "stbn:" + fmt(c.q.budgetFraction);
  } else if (f == "weighted" || f == "weighted-stbn") {
    arity(2, 3);
    c.family = "weighted-stbn";
    c.q.budget = BudgetScheme::WeightedStbn;
    c.q.budgetFraction = num(1, 0);
    c.q.budgetAlpha = num(2, 0.5);
    c.label = "weighted:" + fmt(c.q.budgetFraction) + ":" + fmt(c.q.budgetAlpha);
  } else if (f == "delta") {
    arity(1, 1);
    c.family = "delta";
    c.label = "delta";
  } else if (f == "ratio") {
    arity(1, 5);
    c.family = "ratio";
    c.tracking.estimator = PrimaryEstimator::Ratio;
    c.tracking.majorantScale = num(1, c.tracking.majorantScale);
    c.tracking.pointsPerIteration = int(num(2, c.tracking.pointsPerIteration));
    c.tracking.rouletteThreshold = num(3, c.tracking.rouletteThreshold);
    c.tracking.stratifiedJitter = num(4, 0) != 0;
    c.tracking.validate();
    c.label = std::string(c.tracking.stratifiedJitter ? "s" : "") + "ratio:" + fmt(c.tracking.majorantScale) + ":" + std::to_string(c.tracking.pointsPerIteration) + ":" +
              fmt(c.tracking.rouletteThreshold);
  } else if (f == "march" || f == "preint") {
    arity(1, f == "preint" ? 6 : 5);
    c.family = f;
    c.tracking.estimator = f == "march" ? PrimaryEstimator::March : PrimaryEstimator::Preintegrated;
    c.tracking.majorantScale = num(1, c.tracking.majorantScale);
    c.tracking.residualScale = num(2, c.tracking.residualScale);
    c.tracking.pointsPerIteration = int(num(3, c.tracking.pointsPerIteration));
    c.tracking.rouletteThreshold = num(4, c.tracking.rouletteThreshold);
    if (f == "preint") c.tracking.combMinimumSteps = num(5, c.tracking.combMinimumSteps);
    c.tracking.validate();
    c.label = f + ":" + fmt(c.tracking.majorantScale) + ":" + fmt(c.tracking.residualScale) + ":" +
              std::to_string(c.tracking.pointsPerIteration) + ":" + fmt(c.tracking.rouletteThreshold);
    if (c.tracking.combMinimumSteps > 0) c.label += ":" + fmt(c.tracking.combMinimumSteps);
  } else if (f == "debiased") {
    arity(1, 9);
    c.family = f;
    c.tracking.estimator = PrimaryEstimator::Debiased;
    c.tracking.majorantScale = num(1, c.tracking.majorantScale);
    c.tracking.levelRatio = num(2, c.tracking.levelRatio);
    c.tracking.maxLevel = int(num(3, c.tracking.maxLevel));
    c.tracking.pointsPerIteration = int(num(4, 32));
    c.tracking.combMinimumSteps = num(5, c.tracking.combMinimumSteps);
    c.tracking.stratifiedJitter = num(6, 0) != 0;
    c.tracking.combFloorDepth = num(7, 0);
    c.tracking.jitterControlFrames = int(num(8, 0));
    c.tracking.validate();
    c.label = std::string(c.tracking.stratifiedJitter ? "s" : "") + f + ":" + fmt(c.tracking.majorantScale) + ":" +
              fmt(c.tracking.levelRatio) + ":" +
              std::to_string(c.tracking.maxLevel) + ":" + std::to_string(c.tracking.pointsPerIteration);
    if (c.tracking.combMinimumSteps > 0) c.label += ":" + fmt(c.tracking.combMinimumSteps);
    if (c.tracking.combFloorDepth > 0) c.label += ":d" + fmt(c.tracking.combFloorDepth);
    if (c.tracking.jitterControlFrames > 0) c.label += ":cv" + std::to_string(c.tracking.jitterControlFrames);
  } else if (f == "prune") {
    arity(2, 3);
    c.family = "prune";
    c.q.pruneEpsilon = num(1, 0);
    c.q.pruneFalloff = num(2, 0.006);
    c.label = "prune:" + fmt(c.q.pruneEpsilon) + ":" + fmt(c.q.pruneFalloff);
  } else {
    throw std::invalid_argument("unknown configuration '" + spec +
                                "' (none, defaults, histogram:RHO[:K], stbn:RHO, weighted:RHO[:ALPHA], "
                                "prune:EPSILON[:DELTA], delta, ratio[:K[:P[:R]]], march[:K[:KR[:P[:R]]]], "
                                "preint[:K[:KR[:P[:R[:S]]]]], debiased[:K[:Q[:L[:P[:S[:J[:D[:C]]]]]]]])");
  }
  c.q.validate();
  return c;
}

// A configuration, or several joined with '+' (e.g. "stbn:0.75+prune:0.02"): the budgeting of the
// budgeting parts and the pruning of the prune part combined.
Config parseConfig(const std::string& spec) {
  const std::vector<std::string> parts = split(spec, '+');
  if (parts.size() <= 1) return parseSingleConfig(spec);
  Config c = parseSingleConfig(parts[0]);
  for (std::size_t k = 1; k < parts.size(); ++k) {
    const Config p = parseSingleConfig(parts[k]);
    if (p.family == "ratio" || p.family == "march" || p.family == "preint" || p.family == "debiased" ||
        p.family == "delta") {
      c.tracking = p.tracking;
    } else if (p.family == "prune") {
      c.q.pruneEpsilon = p.q.pruneEpsilon;
      c.q.pruneFalloff = p.q.pruneFalloff;
    } else {
      const double eps = c.q.pruneEpsilon, delta = c.q.pruneFalloff;
      c.q = p.q;
      c.q.pruneEpsilon = eps;
      c.q.pruneFalloff = delta;
    }
    c.label += "+" + p.label;
  }
  c.family = "combined";
  c.q.validate();
  return c;
}

// The paper's budgeting figure (3-6 settings per scheme), its pruning figure (epsilon sweep at
// delta 0.006) and the compiled defaults.
const char* kDefaultConfigs =
    "none;histogram:0.25:8;histogram:0.5:8;histogram:0.75:8;stbn:0.25;stbn:0.5;stbn:0.75;"
    "weighted:0.5:0.5;weighted:0.75:0.5;prune:0.01:0.006;prune:0.02:0.006;prune:0.05:0.006;prune:0.1:0.006;"
    "stbn:0.75+prune:0.02:0.006;weighted:0.75:0.5+prune:0.02:0.006;defaults";

std::string describe(const QueryReductionSettings& q) {
  std::ostringstream s;
  s << "budget " << budgetSchemeName(q.budget) << " rho " << q.budgetFraction << " K " << q.budgetMaxSkip
    << " alpha " << q.budgetAlpha << " reproject " << (q.reproject ? "on" : "off") << " (history "
    << q.reprojectHistory << ") epsilon " << q.pruneEpsilon << " delta " << q.pruneFalloff;
  return s.str();
}

std::string fileStem(const std::string& label) {
  std::string s = label;
  for (char& ch : s)
    if (ch == ':') ch = '_';
  return s;
}

// ---------------------------------------------------------------- quality

struct Reference {
  ImageRGBA image;     // composited over the background (what is compared)
  ImageRGBA coverage;  // premultiplied: alpha > 0 marks the volume's pixels
  double coveredFraction = 0;
  // Its own convergence estimate: an image measured against it shows its own error plus the
  // reference's (as mean squared errors), so estimate_honesty.py takes the reference's off.
  double estimatedPsnr = NAN;
};

struct Quality {
  double volume = NAN, image = NAN;  // PSNR (RGB, peak 1) over the volume's pixels / the whole image
  double madVolume = NAN;            // mean absolute RGB difference over the volume's pixels
};

Quality measure(const ImageRGBA& img, const Reference& ref) {
  Quality q;
  q.volume = test::psnrOverCoverage(img, ref.image, ref.coverage);
  q.image = psnrRgb(img, ref.image);
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < std::size_t(img.width) * img.height; ++i) {
    if (!(ref.coverage.data[4 * i + 3] > 0.f)) continue;
    for (int c = 0; c < 3; ++c) sum += std::fabs(double(img.data[4 * i + c]) - double(ref.image.data[4 * i + c]));
    ++n;
  }
  q.madVolume = n ? sum / (3.0 * double(n)) : NAN;
  return q;
}

double coveredFraction(const ImageRGBA& premultiplied) {
  std::size_t n = 0;
  const std::size_t total = std::size_t(premultiplied.width) * premultiplied.height;
  for (std::size_t i = 0; i < total; ++i) n += premultiplied.data[4 * i + 3] > 0.f;
  return total ? double(n) / double(total) : 0.0;
}

// ---------------------------------------------------------------- sessions

struct ModelCase {
  std::string name, path;
  InrModel model;
  RenderScene scene;
};

std::unique_ptr<RenderSession> makeSession(const ModelCase& m, const Options& o, const QueryReductionSettings& q,
                                           std::uint32_t seed, bool jitter = true,
                                           const TrackingOptions& tracking = TrackingOptions{},
                                           const RenderScene* firstScene = nullptr) {
  RenderSessionOptions so;
  so.tracking = tracking;
  so.backend = parseRenderBackend(o.backend);
  so.allowFallback = false;  // a CPU number labelled GPU would be worse than no number
  so.macrocells.dims = Int3{o.macrocells, o.macrocells, o.macrocells};
  so.macrocells.temporalSlices = m.model.domain.usesTime() ? o.slices : 1;
  auto s = RenderSession::create(m.model, so);
  s->setQueryReduction(q);
  RenderSettings rs;
  rs.width = rs.height = o.size;
  rs.seed = seed;
  rs.pixelJitter = jitter;
  s->setSettings(rs);
  s->setScene(firstScene ? *firstScene : m.scene);  // (the first scene builds its macrocell slices)
  return s;
}

// ---------------------------------------------------------------- outputs

struct Outputs {
  std::ofstream curves, summary, raymarch, orbit;
  // `append`: add to the CSVs of an earlier run (one model per call under a time limit); headers
  // only go into files that are new or empty.
  Outputs(const std::string& dir, bool append) {
    fs::create_directories(dir);
    auto open = [&](std::ofstream& f, const std::string& name, const char* header) {
      const std::string path = dir + "/" + name;
      const bool fresh = !append || !fs::exists(path) || fs::file_size(path) == 0;
      f.open(path, append ? std::ios::app : std::ios::trunc);
      if (!f) throw std::runtime_error(path + ": cannot write");
      if (fresh) f << header;
    };
    open(curves, "curves.csv", "model,config,family,frame,seconds,psnr_volume,psnr_image,rays,budget_skipped,pruned,"
                               "queries,estimated_psnr_volume\n");
    open(summary, "summary.csv",
         "model,backend,size,config,family,rho,max_skip,alpha,epsilon,delta,frames,seconds,fps,time_to_35,time_to_40,"
         "psnr_400_volume,psnr_end_volume,psnr_end_image,mad_end_volume,rays_per_frame,budget_skipped_per_frame,"
         "pruned_per_frame,queries_per_frame,heatmap_mean,reference_frames,covered_fraction,estimator,majorant_scale,"
         "points_per_iteration,residual_scale,iterations_per_frame,traverse_ms_per_frame,evaluate_ms_per_frame,"
         "reference_estimated_psnr_volume\n");
    open(raymarch, "raymarch.csv", "model,backend,size,step_divisor,step,seconds,psnr_volume,psnr_image,mad_volume,"
                                   "queries\n");
    open(orbit, "orbit.csv", "model,mode,step,degrees,frame_in_step,accumulated_frames,seconds,psnr_volume,"
                             "psnr_image\n");
  }
};

// A CSV number; empty for "not measured" so plotting tools see a gap, not a zero.
std::string csvNum(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// Rays per pixel per frame as an 8-bit PNG: an inferno-like ramp from 0 (black) to 1 (every
// frame, pale yellow); pixels outside the volume (or never measured) grey.
void writeHeatmapPng(const std::string& path, const std::vector<float>& rate, const Reference& ref) {
  static const float stops[5][3] = {{0, 0, 0.02f}, {0.34f, 0.06f, 0.43f}, {0.73f, 0.21f, 0.33f},
                                    {0.98f, 0.55f, 0.04f}, {0.99f, 1.f, 0.64f}};
  const int w = ref.image.width, h = ref.image.height;
  std::vector<std::uint8_t> px(std::size_t(3) * w * h);
  for (std::size_t i = 0; i < std::size_t(w) * h; ++i) {
    float rgb[3] = {0.35f, 0.35f, 0.35f};
    if (ref.coverage.data[4 * i + 3] > 0.f && !std::isnan(rate[i])) {
      const float x = std::clamp(rate[i], 0.f, 1.f) * 4.f;
      const int k = std::min(3, int(x));
      const float f = x - float(k);
      for (int c = 0; c < 3; ++c) rgb[c] = stops[k][c] + (stops[k + 1][c] - stops[k][c]) * f;
    }
    for (int c = 0; c < 3; ++c) px[3 * i + c] = std::uint8_t(std::lround(std::clamp(rgb[c], 0.f, 1.f) * 255.f));
  }
  writePng8(path, w, h, 3, px.data());
}

// ---------------------------------------------------------------- runs

// Frames at which the GPU run measures PSNR: 1..6, then growing by 2^(1/4) (at most 19% late
// for a time-to-X).
bool geometricFrame(int frame) {
  int k = 1;
  while (k < frame) k = std::max(k + 1, int(std::lround(k * 1.189207115)));
  return k == frame;
}

// Rays per pixel, derived through the session's public accessors (the renderer keeps its
// per-pixel sample counts to itself): a pixel whose accumulation (premultiplied RGBA) or residual
// changed in a frame was traced in it. That test is only sound once the pixel has accumulated some
// alpha: before, a traced ray that misses leaves colour 0 and residual 0 as they were, which looks
// like a skip. So each pixel's rate is (frames it changed) / (frames that began with alpha > 0),
// over frames 2..N+1; pixels never eligible are shown as outside the volume. A traced pixel whose
// sample equals its running mean exactly is still missed (a lower bound, rarely off).
class RayHeatmap {
public:
  explicit RayHeatmap(int frames) : frames_(frames) {}
  bool active(int frame) const { return frames_ > 0 && frame <= frames_ + 1; }
  void observe(const RenderSession& s, int frame) {
    ImageRGBA img = s.premultipliedImage();
    std::vector<float> res = s.residual();
    if (frame >= 2) {
      if (count_.empty()) count_.assign(res.size(), 0u), eligible_.assign(res.size(), 0u);
      for (std::size_t i = 0; i < res.size(); ++i) {
        if (!(prevImage_.data[4 * i + 3] > 0.f)) continue;
        bool changed = res[i] != prevResidual_[i];
        for (int c = 0; c < 4 && !changed; ++c) changed = img.data[4 * i + c] != prevImage_.data[4 * i + c];
        count_[i] += changed;
        ++eligible_[i];
      }
      observed_ = true;
    }
    prevImage_ = std::move(img);
    prevResidual_ = std::move(res);
  }
  bool empty() const { return !observed_; }
  // Rays per frame per pixel; NaN where no frame was eligible.
  std::vector<float> rate() const {
    std::vector<float> r(count_.size());
    for (std::size_t i = 0; i < r.size(); ++i) r[i] = eligible_[i] ? float(count_[i]) / float(eligible_[i]) : NAN;
    return r;
  }

private:
  int frames_;
  bool observed_ = false;
  std::vector<std::uint32_t> count_, eligible_;
  ImageRGBA prevImage_;
  std::vector<float> prevResidual_;
};

struct RunSummary {
  Config config;
  int frames = 0;
  double seconds = 0, time35 = NAN, time40 = NAN, heatmapMean = NAN;
  Quality at400, end, first;
  FrameStats total, firstFrame;  // firstFrame: frame 1 alone (it carries the update and buffer setup)
};

RunSummary runConfig(const ModelCase& m, const Options& o, const Config& c, const Reference& ref,
                     Outputs& out, const std::string& imageDir) {
  RunSummary r;
  r.config = c;
  // With --warm-time the session starts at another time and renders a frame there, so frame 1 is
  // a time change: its update builds the macrocell slices of the scene's time (unless the warm
  // time shares them) and interpolates the working grid, as ParaView's first visit to a time does.
  RenderScene warm = m.scene;
  if (!std::isnan(o.warmTime)) warm.time = o.warmTime;
  auto s = makeSession(m, o, c.q, 1u, o.configJitter, c.tracking, &warm);
  if (!std::isnan(o.warmTime)) {
    s->renderFrame();
    s->setScene(m.scene);
  }
  const bool everyFrame = o.psnrSchedule == "all";
  RayHeatmap heat(o.heatmapFrames);
  bool snapshotWritten = false;
  for (int frame = 1;; ++frame) {
    const FrameStats st = s->renderFrame();
    r.total += st;
    if (frame == 1) r.firstFrame = st;
    r.seconds += st.totalMs * 1e-3;
    r.frames = frame;
    const bool last = (r.seconds >= o.seconds && frame >= o.minFrames) || frame >= o.maxFrames;
    const bool snapshot = !snapshotWritten && r.seconds >= o.snapshotSeconds;
    if (heat.active(frame)) heat.observe(*s, frame);
    Quality q;
    if (everyFrame || geometricFrame(frame) || frame == 400 || last || snapshot) {
      const ImageRGBA img = s->image();
      q = measure(img, ref);
      if (std::isnan(r.time35) && q.volume >= 35.0) r.time35 = r.seconds;
      if (std::isnan(r.time40) && q.volume >= 40.0) r.time40 = r.seconds;
      if (frame == 400) r.at400 = q;
      if (frame == 1) r.first = q;
      if (last) r.end = q;
      if (snapshot) {
        writePng(imageDir + "/" + fileStem(c.label) + "_at_" + fmt(o.snapshotSeconds) + "s.png", img);
        snapshotWritten = true;
      }
    }
    out.curves << m.name << ',' << c.label << ',' << c.family << ',' << frame << ',' << csvNum(r.seconds) << ','
               << csvNum(q.volume) << ',' << csvNum(q.image) << ',' << st.rays << ',' << st.budgetSkipped << ','
               << st.pruned << ',' << st.queries << ',' << csvNum(convergenceEstimate(st)) << '\n';
    if (last) break;
  }
  if (!heat.empty()) {
    const std::vector<float> rate = heat.rate();
    writeHeatmapPng(imageDir + "/" + fileStem(c.label) + "_rays_per_pixel.png", rate, ref);
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < rate.size(); ++i)
      if (ref.coverage.data[4 * i + 3] > 0.f && !std::isnan(rate[i])) sum += rate[i], ++n;
    r.heatmapMean = n ? sum / double(n) : NAN;
  }
  out.curves.flush();
  return r;
}

Reference renderReference(RenderSession& s, int frames, double* seconds) {
  double ms = 0;
  FrameStats last;
  for (int k = 0; k < frames; ++k) ms += (last = s.renderFrame()).totalMs;
  if (seconds) *seconds = ms * 1e-3;
  Reference ref;
  ref.estimatedPsnr = convergenceEstimate(last);
  ref.image = s.image();
  ref.coverage = s.premultipliedImage();
  ref.coveredFraction = coveredFraction(ref.coverage);
  return ref;
}

// One frame of fixed-step ray marching at pixel centres, on the session's backend. The CUDA
// marcher gets a warm-up frame first (its first frame allocates the batch buffers).
void runRayMarch(const ModelCase& m, const Options& o, RenderSession& session, const Reference& ref, Outputs& out,
                 const std::string& imageDir, const std::string& backend) {
  const Box3f box = modelWorldBox(m.model);
  const double diagonal = length(box.hi - box.lo);
  RenderSettings rs;
  rs.width = rs.height = o.size;
  rs.pixelJitter = false;
  for (const std::string& d : split(o.marchSteps, ',')) {
    const double divisor = std::stod(d);
    RayMarchOptions ro;
    ro.step = float(diagonal / divisor);
    FrameStats st;
    ImageRGBA img;
#ifdef INR_HAVE_CUDA
    if (session.backend() == RenderBackend::Cuda) {
      const auto& eval = dynamic_cast<const CudaInrEvaluator&>(session.evaluator());
      CudaRayMarcher march(eval, box, ro);
      march.setSettings(rs);
      march.setScene(m.scene);
      march.renderFrame();
      march.resetAccumulation();
      st = march.renderFrame();
      img = march.image();
    } else
#endif
    {
      RayMarchRenderer march(session.evaluator(), box, ro);
      march.setSettings(rs);
      march.setScene(m.scene);
      st = march.renderFrame();
      img = march.image();
    }
    const Quality q = measure(img, ref);
    writePng(imageDir + "/raymarch_d" + d + ".png", img);
    out.raymarch << m.name << ',' << backend << ',' << o.size << ',' << d << ',' << csvNum(ro.step) << ','
                 << csvNum(st.totalMs * 1e-3) << ',' << csvNum(q.volume) << ',' << csvNum(q.image) << ','
                 << csvNum(q.madVolume) << ',' << st.queries << '\n';
    std::printf("   raymarch step diag/%-5s %9.4f s  %6.2f dB volume  %6.2f dB image  %12zu queries\n", d.c_str(),
                st.totalMs * 1e-3, q.volume, q.image, st.queries);
    std::fflush(stdout);
  }
  out.raymarch.flush();
}

// Camera orbit with the compiled defaults, without and with reprojection. Each step's reference
// is rendered by its own session (all off, another seed) at that step's camera.
void runOrbit(const ModelCase& m, const Options& o, Outputs& out) {
  struct Mode {
    std::string name;
    std::unique_ptr<RenderSession> s;
    double sumFirst = 0, sumLast = 0;
  };
  std::vector<Mode> modes;
  for (bool reproject : {false, true}) {
    QueryReductionSettings q;
    q.reproject = reproject;
    Mode md;
    md.name = reproject ? "reproject" : "no-reproject";
    md.s = makeSession(m, o, q, 1u);
    for (int k = 0; k < o.orbitWarmup; ++k) md.s->renderFrame();
    modes.push_back(std::move(md));
  }
  auto refSession = makeSession(m, o, allOff(), 978u);
  RenderScene scene = m.scene;
  for (int step = 1; step <= o.orbitSteps; ++step) {
    const double degrees = step * o.orbitDegrees;
    scene.camera = orbitCamera(m.scene.camera, degrees);
    refSession->setScene(scene);  // a camera move without reprojection restarts it
    const Reference ref = renderReference(*refSession, o.orbitReferenceFrames, nullptr);
    for (Mode& md : modes) {
      md.s->setScene(scene);
      for (int f = 1; f <= o.orbitFrames; ++f) {
        const FrameStats st = md.s->renderFrame();
        const Quality q = measure(md.s->image(), ref);
        if (f == 1) md.sumFirst += q.volume;
        if (f == o.orbitFrames) md.sumLast += q.volume;
        out.orbit << m.name << ',' << md.name << ',' << step << ',' << csvNum(degrees) << ',' << f << ','
                  << md.s->accumulatedFrames() << ',' << csvNum(st.totalMs * 1e-3) << ',' << csvNum(q.volume) << ','
                  << csvNum(q.image) << '\n';
      }
    }
  }
  out.orbit.flush();
  for (const Mode& md : modes)
    std::printf("   orbit %-13s mean PSNR over the volume after the 1st frame of a step %6.2f dB, after frame %d "
                "%6.2f dB (%d steps of %g deg)\n",
                md.name.c_str(), md.sumFirst / o.orbitSteps, o.orbitFrames, md.sumLast / o.orbitSteps, o.orbitSteps,
                o.orbitDegrees);
  std::fflush(stdout);
}

std::string dbOrDash(double v) {
  if (std::isnan(v)) return "—";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f", v);
  return b;
}

std::string secondsOrDash(double v) {
  if (std::isnan(v)) return "—";
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

void printTable(const std::string& model, const std::vector<RunSummary>& runs) {
  std::printf("\n   %-22s %7s %8s %8s %9s %9s %8s %8s %8s %6s %10s %9s %9s %5s\n", "config", "frames", "seconds", "fps",
              "t35 [s]", "t40 [s]", "dB@400", "dB end", "dB img", "MAD%", "rays/fr", "skip/fr", "pruned/fr",
              "rpp");
  for (const RunSummary& r : runs) {
    const double n = r.frames;
    // "—" is 3 bytes and 1 column: printf pads by bytes, so pad those cells by hand.
    auto cell = [](const std::string& s, int w) {
      const int cols = int(s.size()) - (s.find("—") != std::string::npos ? 2 : 0);
      return std::string(std::max(0, w - cols), ' ') + s;
    };
    std::printf("   %-22s %7d %8.3f %8.1f %s %s %s %8.2f %8.2f %6.2f %10.0f %9.0f %9.0f %5s\n", r.config.label.c_str(),
                r.frames, r.seconds, n / r.seconds, cell(secondsOrDash(r.time35), 9).c_str(),
                cell(secondsOrDash(r.time40), 9).c_str(), cell(dbOrDash(r.at400.volume), 8).c_str(), r.end.volume,
                r.end.image, 100.0 * r.end.madVolume, r.total.rays / n, r.total.budgetSkipped / n, r.total.pruned / n,
                std::isnan(r.heatmapMean) ? "—" : fmt(std::round(r.heatmapMean * 100) / 100).c_str());
  }
  std::printf("   (%s; t35/t40: render time until the PSNR over the volume's pixels first reached 35/40 dB; dB@400: "
              "at frame 400; MAD%%: mean absolute RGB difference over the volume at the end; rpp: rays per covered "
              "pixel per frame from the heatmap)\n",
              model.c_str());
  std::fflush(stdout);
}

void benchModel(const std::string& path, const Options& o, Outputs& out, const std::vector<Config>& configs,
                const std::string& backendName) {
  ModelCase m;
  m.path = path;
  m.name = fs::path(path).stem().string();
  m.model = InrModel::loadFile(path);
  const std::string imageDir = o.out + "/images/" + m.name;
  fs::create_directories(imageDir);

  // The reference session also supplies the evaluator for the default transfer function's range
  // and the ray marcher; its scene is set once the scene is known.
  RenderSessionOptions probe;
  probe.backend = parseRenderBackend(o.backend);
  probe.allowFallback = false;
  probe.macrocells.dims = Int3{o.macrocells, o.macrocells, o.macrocells};
  probe.macrocells.temporalSlices = m.model.domain.usesTime() ? o.slices : 1;
  auto refSession = RenderSession::create(m.model, probe);
  m.scene = shippedScene(m.model, path, refSession->evaluator(), o.time);
  std::string gradientOpacityNote;
  if (!o.gradientOpacityMedian.empty()) {
    const double median = test::medianGradientNorm(CpuInrEvaluator(m.model), m.model, float(m.scene.time));
    if (!(median > 0.0) || !std::isfinite(median))
      throw std::runtime_error(m.name + ": --gradient-opacity-median needs a positive median |grad f|, the model's is " +
                               fmt(median) + " (a constant field?)");
    gradientOpacityNote = ", gradient opacity (median |grad f| " + fmt(median) + "):";
    m.scene.transferFunction.gradientOpacity.clear();  // the ramp replaces any the .tf.json brings
    for (std::size_t k = 0; k + 1 < o.gradientOpacityMedian.size(); k += 2) {
      const double g = o.gradientOpacityMedian[k] * median, a = o.gradientOpacityMedian[k + 1];
      m.scene.transferFunction.gradientOpacity.push_back({g, a});
      gradientOpacityNote += " " + fmt(g) + " -> " + fmt(a);
    }
  }
  refSession->setQueryReduction(allOff());
  RenderSettings rs;
  rs.width = rs.height = o.size;
  rs.seed = 977;
  refSession->setSettings(rs);
  refSession->setScene(m.scene);
  const MacrocellInfo mi = refSession->macrocellInfo();
  std::printf("\n== %s  (%s)  %d^2, t = %g, %d^3 macrocells x %d slices (built %d in %.2f s)%s%s\n", m.name.c_str(),
              refSession->description().c_str(), o.size, m.scene.time, mi.dims.x, mi.temporalSlices, mi.slicesBuilt,
              mi.buildSeconds, suggestedTransferFunctionPath(path).empty() ? ", preset transfer function" : "",
              gradientOpacityNote.c_str());
  std::fflush(stdout);
  double refSeconds = 0;
  const Reference ref = renderReference(*refSession, o.referenceFrames, &refSeconds);
  writePng(imageDir + "/reference.png", ref.image);
  std::printf("   reference: %d frames in %.2f s; the volume covers %.1f%% of the image; its estimated error "
              "%.2f dB\n", o.referenceFrames, refSeconds, 100.0 * ref.coveredFraction, ref.estimatedPsnr);
  std::fflush(stdout);

  std::vector<RunSummary> runs;
  for (const Config& c : configs) {
    RunSummary r = runConfig(m, o, c, ref, out, imageDir);
    const double n = r.frames;
    const QueryReductionSettings& q = c.q;
    out.summary << m.name << ',' << backendName << ',' << o.size << ',' << c.label << ',' << c.family << ','
                << (q.budget == BudgetScheme::None ? "" : csvNum(q.budgetFraction)) << ','
                << (q.budget == BudgetScheme::Histogram ? std::to_string(q.budgetMaxSkip) : "") << ','
                << (q.budget == BudgetScheme::WeightedStbn ? csvNum(q.budgetAlpha) : "") << ','
                << csvNum(q.pruneEpsilon) << ',' << csvNum(q.pruneFalloff) << ',' << r.frames << ','
                << csvNum(r.seconds) << ',' << csvNum(n / r.seconds) << ',' << csvNum(r.time35) << ','
                << csvNum(r.time40) << ',' << csvNum(r.at400.volume) << ',' << csvNum(r.end.volume) << ','
                << csvNum(r.end.image) << ',' << csvNum(r.end.madVolume) << ',' << csvNum(r.total.rays / n) << ','
                << csvNum(r.total.budgetSkipped / n) << ',' << csvNum(r.total.pruned / n) << ','
                << csvNum(r.total.queries / n) << ',' << csvNum(r.heatmapMean) << ',' << o.referenceFrames << ','
                << csvNum(ref.coveredFraction) << ',' << primaryEstimatorName(c.tracking.estimator) << ','
                << csvNum(c.tracking.majorantScale) << ',' << c.tracking.pointsPerIteration << ','
                << csvNum(c.tracking.residualScale) << ','
                << csvNum(r.total.iterations / n) << ',' << csvNum(r.total.traverseMs / n) << ','
                << csvNum(r.total.evaluateMs / n) << ',' << csvNum(ref.estimatedPsnr) << '\n';
    out.summary.flush();
    std::printf("   %-22s %6d frames %7.3f s  t35 %s s  t40 %s s  end %.2f dB  (%.1f iterations, %.0f queries, "
                "%.3f ms per frame: traverse %.3f, evaluate %.3f)\n",
                c.label.c_str(), r.frames, r.seconds, secondsOrDash(r.time35).c_str(), secondsOrDash(r.time40).c_str(),
                r.end.volume, r.total.iterations / n, r.total.queries / n, 1e3 * r.seconds / n, r.total.traverseMs / n,
                r.total.evaluateMs / n);
    // Where a frame's time goes: what budgeting can shrink (per-ray work) and what it cannot
    // (per-iteration and per-pixel passes).
    const double f = double(std::max(1, r.frames));
    std::printf("   %-22s per frame: init %.3f  traverse %.3f  evaluate %.3f  shadow %.3f  finalize %.3f  "
                "total %.3f ms; %.1f iterations, %.0f queries\n", "", r.total.initMs / f, r.total.traverseMs / f,
                r.total.evaluateMs / f, (r.total.shadowTraverseMs + r.total.shadowEvaluateMs) / f,
                r.total.finalizeMs / f, r.total.totalMs / f, double(r.total.iterations) / f,
                double(r.total.queries) / f);
    const FrameStats& f1 = r.firstFrame;
    std::printf("   %-22s first frame: total %.3f ms (update %.3f, setup %.3f, other %.3f)  %.2f dB volume\n", "",
                f1.totalMs, f1.updateMs, f1.setupMs, f1.otherMs, r.first.volume);
    std::fflush(stdout);
    runs.push_back(std::move(r));
  }
  printTable(m.name, runs);
  if (!o.marchSteps.empty()) runRayMarch(m, o, *refSession, ref, out, imageDir, backendName);
  refSession.reset();
  if (o.orbitSteps > 0) runOrbit(m, o, out);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    for (CommandLine cl(argc, argv); !cl.done();) {
      const std::string a = cl.next();
      if (a == "--backend") o.backend = cl.value();
      else if (a == "--size") o.size = std::stoi(cl.value());
      else if (a == "--seconds") o.seconds = std::stod(cl.value());
      else if (a == "--min-frames") o.minFrames = std::stoi(cl.value());
      else if (a == "--max-frames") o.maxFrames = std::max(1, std::stoi(cl.value()));
      else if (a == "--reference-frames") o.referenceFrames = std::max(1, std::stoi(cl.value()));
      else if (a == "--configs") o.configs = cl.value();
      else if (a == "--psnr-schedule") o.psnrSchedule = cl.value();
      else if (a == "--heatmap-frames") o.heatmapFrames = std::max(0, std::stoi(cl.value()));
      else if (a == "--snapshot-seconds") o.snapshotSeconds = std::stod(cl.value());
      else if (a == "--march-steps") o.marchSteps = cl.value();
      else if (a == "--orbit-steps") o.orbitSteps = std::max(0, std::stoi(cl.value()));
      else if (a == "--orbit-degrees") o.orbitDegrees = std::stod(cl.value());
      else if (a == "--orbit-frames") o.orbitFrames = std::max(1, std::stoi(cl.value()));
      else if (a == "--orbit-warmup") o.orbitWarmup = std::max(0, std::stoi(cl.value()));
      else if (a == "--orbit-reference-frames") o.orbitReferenceFrames = std::max(1, std::stoi(cl.value()));
      else if (a == "--macrocells") o.macrocells = std::stoi(cl.value());
      else if (a == "--slices") o.slices = std::stoi(cl.value());
      else if (a == "--time") o.time = std::stod(cl.value());
      else if (a == "--warm-time") o.warmTime = std::stod(cl.value());
      else if (a == "--gradient-opacity-median") o.gradientOpacityMedian = gradientOpacityPairs(cl.value());
      else if (a == "--out") o.out = cl.value();
      else if (a == "--append") o.append = true;
      else if (a == "--config-jitter") o.configJitter = cl.value() != "0";
      else if (const int status = cl.other(a, kUsage, o.models); status >= 0)
        return status;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bad option value: %s\n", e.what());
    return 2;
  }
  std::vector<Config> configs;
  try {
    parseRenderBackend(o.backend);
    for (const std::string& spec : split(o.configs.empty() ? kDefaultConfigs : o.configs, ';'))
      configs.push_back(parseConfig(spec));
    for (const std::string& d : split(o.marchSteps, ','))
      if (!(std::stod(d) > 0)) throw std::invalid_argument("--march-steps: divisors must be > 0");
    if (!o.psnrSchedule.empty() && o.psnrSchedule != "all" && o.psnrSchedule != "geometric")
      throw std::invalid_argument("--psnr-schedule must be all or geometric");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  std::string why;
  const RenderBackend requested = parseRenderBackend(o.backend);
  const bool gpu = requested != RenderBackend::Cpu && cudaBackendAvailable(&why);
  if (requested == RenderBackend::Cuda && !gpu) {
    std::fprintf(stderr, "--backend cuda: %s\n", why.c_str());
    return 1;
  }
  o.backend = gpu ? "cuda" : "cpu";
  // GPU and CPU defaults differ by the cost of a frame (issue 11: 1024^2 on the GPU, 256^2 on the CPU).
  if (o.size <= 0) o.size = gpu ? 1024 : 256;
  if (!(o.seconds > 0)) o.seconds = gpu ? 3.0 : 20.0;
  if (o.minFrames < 0) o.minFrames = gpu ? 400 : 0;
  if (o.psnrSchedule.empty()) o.psnrSchedule = gpu ? "geometric" : "all";
  if (o.orbitSteps < 0) o.orbitSteps = gpu ? 60 : 12;
  if (o.orbitReferenceFrames < 0) o.orbitReferenceFrames = gpu ? 128 : 64;
  if (o.models.empty()) {
    for (const std::string& p : test::shippedModels("real")) {
      const bool small = fs::path(p).stem().string().size() > 6 &&
                         fs::path(p).stem().string().compare(fs::path(p).stem().string().size() - 6, 6, "_small") == 0;
      if (small != gpu) o.models.push_back(p);
    }
  }
  std::printf("query reduction benchmark: backend %s, %d^2, %g s per configuration (>= %d frames), reference %d "
              "frames, PSNR schedule %s\ncompiled defaults: %s\n",
              o.backend.c_str(), o.size, o.seconds, o.minFrames, o.referenceFrames, o.psnrSchedule.c_str(),
              describe(QueryReductionSettings{}).c_str());
  std::printf("command:");
  for (int i = 0; i < argc; ++i) std::printf(" %s", argv[i]);
  std::printf("\n");
  try {
    Outputs out(o.out, o.append);
    for (const std::string& path : o.models) benchModel(path, o, out, configs, o.backend);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
