// Where homogeneity pruning acts (issue 11 item 5; paper figure fig:homog_cull): per model and
// per epsilon, a picture of the shipped scene (Benchmarks/ShippedScene.h) with every pixel tinted
// by the pruning class of the first visible macrocell along its centre ray, i.e. the first cell
// the ray enters (box entry onwards, DDA order) whose majorant for the transfer function is
// positive:
//   red     always pruned      Delta_c = max_c - min_c < epsilon
//   orange  stochastic band    epsilon <= Delta_c < epsilon + delta (pruned with falling probability)
//   none    never pruned       (or the ray meets no visible cell)
// The tint is blended 50% over a converged CPU delta-tracking render with pruning off.
//
// Epsilon and delta are fractions of the working grid's value range, converted to scalar units
// as WavefrontRenderer::pruneThresholds does; the classes use Kernels/Render/Pruning.h's
// pruneProbability on the working bounds of a fresh grid at the scene's time (what a pruned
// render starts from; refinement never widens an always-pruned cell, since no candidate in it is
// evaluated). Printed per epsilon: the fraction of non-empty cells (positive majorant) always
// pruned / in the band, and the fraction of covered pixels (centre ray meets a non-empty cell)
// whose first visible cell is always pruned / in the band; the same fractions for the bounds
// after the render's refinement are printed for comparison.
//   pruned_cells_picture [--eps LIST] [--delta D] [--macrocells N] [--slices T] [--size N]
//       [--frames F] [--time T] [--out DIR] MODEL.inr ...
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "BenchmarkSupport.h"
#include "Common/ImageIO.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Render/CameraView.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/MacrocellGrid.h"
#include "Render/MajorantGrid.h"
#include "Render/ModelBox.h"
#include "Render/Pruning.h"
#include "Render/QueryReduction.h"
#include "Render/RenderMath.h"
#include "ShippedScene.h"

using namespace inr;
using namespace inr::bench;
namespace fs = std::filesystem;

namespace {

const char* kUsage =
    "usage: pruned_cells_picture [options] MODEL.inr ...\n"
    "  --eps LIST        comma-separated epsilons, fractions of the value range (default 0.02,0.05,0.1)\n"
    "  --delta D         falloff band width, fraction of the value range (default 0.006)\n"
    "  --macrocells N    N^3 macrocells (default 64)\n"
    "  --slices T        temporal macrocell slices (default 16; 1 for static models)\n"
    "  --size N          image N x N (default 512)\n"
    "  --frames F        delta-tracking frames of the background render (default 64)\n"
    "  --time T          world time (default: middle of the model's time range)\n"
    "  --out DIR         output folder (default pruned-cells)\n"
    "writes DIR/MODEL_pruned_epsEPS.png per epsilon and DIR/MODEL_render.png (the untinted render)\n";

struct Options {
  std::vector<double> eps{0.02, 0.05, 0.1};
  double delta = 0.006;
  int macrocells = 64, slices = 16, size = 512, frames = 64;
  double time = NAN;
  std::string out = "pruned-cells";
  std::vector<std::string> models;
};

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

std::vector<double> parseList(const std::string& s) {
  std::vector<double> out;
  std::stringstream ss(s);
  for (std::string t; std::getline(ss, t, ',');)
    if (!t.empty()) out.push_back(std::stod(t));
  return out;
}

// Index of the first cell with a positive majorant along the centre ray of pixel (x, y), -1 when
// the ray misses the box or meets none. Same entry and walk as RayInit.h / Traverse.h (without
// the coarse level, which only skips empty cells).
// The DDA at the entry of the centre ray of pixel (x, y) into the grid's box; false when it misses.
struct CentreRayWalk {
  Vec3f o, d;
  float tEnter = 0.f, tExit = 0.f;
  Int3 cell;
  Vec3f tNext;
  bool start(const MajorantGridView& g, const CameraView& cam, int x, int y) {
    cameraRay(cam, x, y, 0.5f, 0.5f, o, d);
    if (!intersectBox(g.box, o, d, tEnter, tExit) || !(tEnter < tExit)) return false;
    ddaStart(g, o, d, tEnter, cell, tNext);
    return true;
  }
};

int firstVisibleCell(const MajorantGridView& g, const CameraView& cam, int x, int y) {
  CentreRayWalk w;
  if (!w.start(g, cam, x, y)) return -1;
  for (;;) {
    if (majorantAt(g, w.cell) > 0.f) return linearCellIndex(g.dims, w.cell);
    if (ddaCellExit(w.tNext) >= w.tExit) return -1;
    if (!ddaStep(g, w.o, w.d, w.cell, w.tNext)) return -1;
  }
}

// Index of the cell where the centre ray of pixel (x, y) most likely has its first real collision,
// -1 when it has none: per cell along the walk, P_c = T_before (1 - exp(-sigma_c len_c)) with
// sigma_c the TF's extinction at the cell's working mean (an estimate of the medium, not a bound),
// and the argmax of P_c. This is the cell that contributes most to the pixel, where the first
// visible cell is often a faint one at the box face.
int dominantCell(const MajorantGridView& g, const TransferFunctionView& tf, const std::vector<float>& mean,
                 const CameraView& cam, int x, int y) {
  CentreRayWalk w;
  if (!w.start(g, cam, x, y)) return -1;
  double transmittance = 1.0, best = 0.0;
  int bestCell = -1;
  float t = w.tEnter;
  for (;;) {
    const float t1 = std::min(ddaCellExit(w.tNext), w.tExit);
    const int c = linearCellIndex(g.dims, w.cell);
    if (majorantAt(g, w.cell) > 0.f && t1 > t) {
      const double tau = double(extinctionAt(tf, mean[c])) * double(t1 - t);
      const double p = transmittance * -std::expm1(-tau);
      if (p > best) {
        best = p;
        bestCell = c;
      }
      transmittance *= std::exp(-tau);
    }
    if (t1 >= w.tExit || !ddaStep(g, w.o, w.d, w.cell, w.tNext)) return bestCell;
    t = t1;
  }
}

enum Class : int { kKept = 0, kBand = 1, kAlways = 2 };

int classify(const PruneView& v, int cell) {
  const float p = pruneProbability(v, cell);
  return p >= 1.f ? kAlways : p > 0.f ? kBand : kKept;
}

struct Fractions {
  std::size_t cells = 0, cellsAlways = 0, cellsBand = 0;
  std::size_t pixels = 0, pixelsAlways = 0, pixelsBand = 0;
};

Fractions count(const PruneView& v, const std::vector<float>& majorants, const std::vector<int>& firstCell) {
  Fractions f;
  for (std::size_t c = 0; c < majorants.size(); ++c) {
    if (!(majorants[c] > 0.f)) continue;
    ++f.cells;
    const int k = classify(v, int(c));
    f.cellsAlways += k == kAlways;
    f.cellsBand += k == kBand;
  }
  for (int c : firstCell) {
    if (c < 0) continue;
    ++f.pixels;
    const int k = classify(v, c);
    f.pixelsAlways += k == kAlways;
    f.pixelsBand += k == kBand;
  }
  return f;
}

double pct(std::size_t a, std::size_t b) { return b ? 100.0 * double(a) / double(b) : 0.0; }

void printFractions(const char* label, double eps, const PruneView& v, const Fractions& f) {
  std::printf("  %-9s eps %-5s (abs %.4g, band to %.4g): cells %6.2f%% always %6.2f%% band of %zu non-empty;"
              "  pixels %6.2f%% always %6.2f%% band of %zu covered\n",
              label, fmt(eps).c_str(), double(v.epsilon), double(v.epsilon + v.falloff), pct(f.cellsAlways, f.cells),
              pct(f.cellsBand, f.cells), f.cells, pct(f.pixelsAlways, f.pixels), pct(f.pixelsBand, f.pixels),
              f.pixels);
}

void runModel(const std::string& path, const Options& o) {
  const std::string name = fs::path(path).stem().string();
  const InrModel model = InrModel::loadFile(path);
  CpuInrEvaluator evaluator(model);
  const RenderScene scene = shippedScene(model, path, evaluator, o.time);

  MacrocellOptions mo;
  mo.dims = Int3{o.macrocells, o.macrocells, o.macrocells};
  mo.temporalSlices = model.domain.usesTime() ? o.slices : 1;
  MacrocellGrid grid(evaluator, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, mo);
  grid.setTime(scene.time);
  const TransferFunctionTable table(scene.transferFunction);
  std::vector<float> majorants;
  grid.computeMajorants(table.view(), majorants);
  const MajorantGridView gv = grid.view(majorants);
  // Copies: the render below refines the grid's bounds.
  const std::vector<float> cellMin = grid.workingMin(), cellMax = grid.workingMax();
  const std::array<float, 2> range = grid.workingValueRange();
  const double span = double(range[1]) - double(range[0]);

  const CameraView cam = scene.camera.view(o.size, o.size);
  std::vector<int> firstCell(std::size_t(o.size) * o.size), mainCell(firstCell.size());
  const std::vector<float> cellMean = grid.workingMean();
  for (int y = 0; y < o.size; ++y)
    for (int x = 0; x < o.size; ++x) {
      firstCell[std::size_t(y) * o.size + x] = firstVisibleCell(gv, cam, x, y);
      mainCell[std::size_t(y) * o.size + x] = dominantCell(gv, table.view(), cellMean, cam, x, y);
    }

  std::printf("\n== %s  %d^2, t = %g, %d^3 macrocells x %d slices, value range [%g, %g], delta %g\n", name.c_str(),
              o.size, scene.time, o.macrocells, grid.temporalSlices(), double(range[0]), double(range[1]), o.delta);
  std::fflush(stdout);

  // Background: converged delta tracking, pruning and budgeting off.
  CpuWavefrontRenderer renderer(evaluator, grid);
  QueryReductionSettings q;
  q.budget = BudgetScheme::None;
  q.reproject = false;
  q.pruneEpsilon = 0.0;
  q.pruneFalloff = 0.0;
  renderer.setQueryReduction(q);
  RenderSettings rs;
  rs.width = rs.height = o.size;
  rs.seed = 977;
  renderer.setSettings(rs);
  renderer.setScene(scene);
  double ms = 0;
  for (int f = 0; f < o.frames; ++f) ms += renderer.renderFrame().totalMs;
  const ImageRGBA render = renderer.image();
  std::printf("  render: %d frames in %.1f s, %zu refinements\n", o.frames, ms / 1000.0, grid.refinementCount());
  fs::create_directories(o.out);
  writePng(o.out + "/" + name + "_render.png", render);

  std::vector<float> refinedMajorants;
  grid.computeMajorants(table.view(), refinedMajorants);
  for (double eps : o.eps) {
    PruneView v;  // thresholds as WavefrontRenderer::pruneThresholds: fractions of the range
    v.epsilon = float(eps * span);
    v.falloff = float(o.delta * span);
    v.cellMin = cellMin.data();
    v.cellMax = cellMax.data();
    PruneView r = v;
    r.cellMin = grid.workingMin().data();
    r.cellMax = grid.workingMax().data();
    printFractions("first", eps, v, count(v, majorants, firstCell));
    printFractions("refined", eps, r, count(r, refinedMajorants, firstCell));
    printFractions("dominant", eps, v, count(v, majorants, mainCell));

    auto overlay = [&](const std::vector<int>& cells, const std::string& file) {
      ImageRGBA img = render;
      for (int y = 0; y < o.size; ++y)
        for (int x = 0; x < o.size; ++x) {
          const int c = cells[std::size_t(y) * o.size + x];
          if (c < 0) continue;
          const int k = classify(v, c);
          if (k == kKept) continue;
          const float tint[3] = {1.f, k == kAlways ? 0.f : 0.55f, 0.f};
          float* p = img.pixel(x, y);
          for (int i = 0; i < 3; ++i) p[i] = 0.5f * std::clamp(p[i], 0.f, 1.f) + 0.5f * tint[i];
        }
      writePng(o.out + "/" + file, img);
    };
    overlay(firstCell, name + "_pruned_eps" + fmt(eps) + ".png");
    overlay(mainCell, name + "_pruned_dominant_eps" + fmt(eps) + ".png");
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    for (CommandLine cl(argc, argv); !cl.done();) {
      const std::string a = cl.next();
      if (a == "--eps") o.eps = parseList(cl.value());
      else if (a == "--delta") o.delta = std::stod(cl.value());
      else if (a == "--macrocells") o.macrocells = std::stoi(cl.value());
      else if (a == "--slices") o.slices = std::stoi(cl.value());
      else if (a == "--size") o.size = std::stoi(cl.value());
      else if (a == "--frames") o.frames = std::max(1, std::stoi(cl.value()));
      else if (a == "--time") o.time = std::stod(cl.value());
      else if (a == "--out") o.out = cl.value();
      else if (const int status = cl.other(a, kUsage, o.models); status >= 0)
        return status;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bad option value: %s\n", e.what());
    return 2;
  }
  if (o.models.empty() || o.size < 1 || o.macrocells < 1 || o.delta < 0) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  try {
    for (const std::string& m : o.models) runModel(m, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
