// End-to-end GPU rendering benchmark (issue 6, groups 4b-4d), one run:
//   4b  the CUDA wavefront delta tracker at SIZE² (default 1024²): frames/s with and without
//       shadows and with gradient shading, queries and traverse-evaluate iterations per frame, milliseconds per stage
//       (CUDA events), and frame time / (queries / evaluator throughput measured in this run).
//   4c  the naive per-thread GPU delta tracker and the GPU ray marcher on the same scenes. They
//       are slow: one frame at a lower resolution (--naive-size, --march-size), its time scaled
//       to SIZE² by the pixel ratio (work is per pixel); the table says so.
//   4d  time-step update latency (working grid + majorants; the DDA's traversal structure IS the
//       majorant grid) at 64³ and 128³ macrocells with all temporal slices built.
// Models: the synthetic paper architectures (Kernels/TestSupport/PaperArchitectures.h, world box
// [-1,1]³, time [-1,1]) unless --no-paper, then every model file given.
//   gpu_render_benchmark [--size N] [--frames F] [--warmup W] [--naive-size N] [--march-size N]
//                        [--macrocells M] [--slices T] [--no-paper] [--no-baselines]
//                        [--traversal auto|dda|optix] [--per-thread-gradient] [--wgmma-consumers 1|2]
//                        [--column-split 0|1] [--mma wgmma|mma.sync]
//                        [--csv FILE] [MODEL.inr ...]
// The shaded row's value + gradient queries run on the fused kernel's tangent rows where the
// model runs fused (the header line says which path), or with --per-thread-gradient on the
// per-thread fp32 forward mode (the path before the tangent rows, for comparison).
// --mma keeps the evaluator's candidates to one kernel (CudaEvaluatorOptions::mma; mma.sync: what
// the FFNs ran on before the wgmma kernel stored their encoding), for a before/after in one run.
// --wgmma-consumers keeps the evaluator's wgmma candidates to blocks of that many consumer
// warpgroups (CudaEvaluatorOptions::wgmmaConsumers; 2 = the candidates before one-consumer
// blocks existed), for a before/after in one run; --column-split 0 likewise leaves out two
// consumers on one tile (CudaEvaluatorOptions::wgmmaColumnSplit).
#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/ValueRange.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/Cuda/CudaRayMarcher.h"
#include "Render/Cuda/DeviceTransferFunction.h"
#include "GpuBenchmarkSupport.h"
#include "Render/ModelBox.h"
#include "TestSupport/DevicePoints.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestScene.h"

using namespace inr;
using namespace inr::bench;

namespace {

struct Options {
  int size = 1024, frames = 20, warmup = 5, naiveSize = 256, marchSize = 256, macrocells = 64, slices = 16;
  bool paper = true, baselines = true, perThreadGradient = false;
  int wgmmaConsumers = 0;
  int wgmmaColumnSplit = -1;
  FusedMma mma = FusedMma::Auto;
  TraversalKind traversal = TraversalKind::Dda;  // --traversal: the wavefront rows' GPU traversal
  std::string csv;
  std::vector<std::string> models;
};

struct Row {
  std::string group, model, variant;
  int size = 0;
  double frameMs = 0, queries = 0, iterations = 0;
  double initMs = 0, traverseMs = 0, evaluateMs = 0, shadowTraverseMs = 0, shadowEvaluateMs = 0, finalizeMs = 0,
         updateMs = 0;
  double evalGqps = 0, ratio = 0;
  std::string note;
};

std::vector<Row> rows;

// The model tests' scene (TestSupport/TestScene.h) with delta-tracked shadows.
RenderScene benchScene(const InrModel& model, const std::array<float, 2>& range, bool shadows) {
  return test::testScene(model, range, shadows, ShadowEstimator::Delta);
}

// Evaluator throughput in this run: median of 10 launches over 2^21 random points of the box.
double evaluatorGqps(const CudaInrEvaluator& eval, const InrModel& model, float time) {
  const int n = 1 << 21;
  const cuda::DeviceBuffer<float4> dPts = test::devicePoints(test::randomQueryPoints(model, n, 7, time));
  cuda::DeviceBuffer<float> dOut(n);
  return medianOf(evaluatorRates(eval, dPts.get(), n, dOut.get(), 10)) * 1e-9;
}

Row fromStats(const std::string& group, const std::string& model, const std::string& variant, int size,
              const FrameStats& total, int frames) {
  Row r;
  r.group = group;
  r.model = model;
  r.variant = variant;
  r.size = size;
  const double f = frames;
  r.frameMs = total.totalMs / f;
  r.queries = double(total.totalQueries()) / f;
  r.iterations = double(total.iterations + total.shadowIterations) / f;
  r.initMs = total.initMs / f;
  r.traverseMs = total.traverseMs / f;
  r.evaluateMs = total.evaluateMs / f;
  r.shadowTraverseMs = total.shadowTraverseMs / f;
  r.shadowEvaluateMs = total.shadowEvaluateMs / f;
  r.finalizeMs = total.finalizeMs / f;
  r.updateMs = total.updateMs / f;
  return r;
}

void benchModel(const std::string& name, const InrModel& model, const Options& o) {
  CudaEvaluatorOptions evalOptions;
  if (o.perThreadGradient) evalOptions.gradientPath = CudaGradientPath::PerThread;
  evalOptions.wgmmaConsumers = o.wgmmaConsumers;
  evalOptions.wgmmaColumnSplit = o.wgmmaColumnSplit;
  evalOptions.mma = o.mma;
  const CudaInrEvaluator eval(model, evalOptions);
  const float time = float(0.5 * (model.domain.timeBegin + model.domain.timeEnd));
  const double gqps = evaluatorGqps(eval, model, time);
  const auto range = valueRangeFor(model, eval);
  const Box3f box = modelWorldBox(model);
  std::printf("\n== %s  (%s)\n   evaluator %.3f G queries/s (2^21 batch, this run); value range [%.3g, %.3g]\n",
              name.c_str(), eval.name().c_str(), gqps, range[0], range[1]);
  std::printf("   value + gradient: %s\n", eval.gradientPath().c_str());
  std::fflush(stdout);
  MacrocellOptions mo;
  mo.dims = Int3{o.macrocells, o.macrocells, o.macrocells};
  mo.temporalSlices = o.slices;
  CudaMacrocellGrid grid(eval, box, model.domain.timeBegin, model.domain.timeEnd, mo);
  CudaWavefrontRenderer renderer(eval, grid);
  TraversalOptions traversal;
  traversal.kind = o.traversal;
  renderer.setTraversal(traversal);
  std::printf("   traversal %s\n", renderer.traversalChoice().c_str());
  RenderSettings settings;
  settings.width = settings.height = o.size;
  renderer.setSettings(settings);
  double oursMs[2] = {0, 0};
  // Gradient shading (a headlight, ParaView's default light) costs one value + gradient query per
  // lit ray; its row's note gives the frame time against the unshaded one.
  struct Variant {
    const char* name;
    bool shadows, shade;
  };
  for (const Variant& v : {Variant{"wavefront", false, false}, Variant{"wavefront+shadows", true, false},
                           Variant{"wavefront+shade", false, true}}) {
    const bool shadows = v.shadows;
    RenderScene scene = benchScene(model, range, shadows);
    scene.shading.enabled = v.shade;
    scene.shading.headlight = true;
    renderer.setScene(scene);
    for (int k = 0; k < o.warmup; ++k) renderer.renderFrame();
    FrameStats total;
    for (int k = 0; k < o.frames; ++k) total += renderer.renderFrame();
    Row r = fromStats("4b", name, v.name, o.size, total, o.frames);
    r.evalGqps = gqps;
    r.ratio = r.frameMs / (r.queries / (gqps * 1e9) * 1e3);
    if (renderer.counters().truncatedFrames) r.note = "iteration cap hit";
    if (v.shade) {
      char note[96];
      std::snprintf(note, sizeof note, "%.2fx the unshaded frame; %.0f shading queries; %.2f ms shading",
                    r.frameMs / oursMs[0], double(total.shadingQueries) / o.frames, total.shadingMs / o.frames);
      r.note = note;
      std::printf("   %-18s %s\n", "", note);
    } else {
      oursMs[shadows] = r.frameMs;
    }
    rows.push_back(r);
    std::printf("   %-18s %6.2f ms/frame (%6.1f fps)  %9.0f queries  %5.1f iterations  ratio %.2f\n",
                r.variant.c_str(), r.frameMs, 1e3 / r.frameMs, r.queries, r.iterations, r.ratio);
    std::fflush(stdout);
  }
  if (!o.baselines) return;
  // 4c: naive per-thread tracker (one frame at naiveSize, scaled to size²).
  const CudaPerThreadMlp net(model);
  const double scaleNaive = double(o.size) * o.size / (double(o.naiveSize) * o.naiveSize);
  {
    CudaMacrocellGrid g2(eval, box, model.domain.timeBegin, model.domain.timeEnd, mo);
    CudaWavefrontRenderer naive(eval, g2);
    RenderSettings s2;
    s2.width = s2.height = o.naiveSize;
    naive.setSettings(s2);
    for (bool shadows : {false, true}) {
      naive.setScene(benchScene(model, range, shadows));
      const FrameStats st = naive.renderFrameNaive(net);
      Row r = fromStats("4c", name, shadows ? "naive+shadows" : "naive", o.naiveSize, st, 1);
      r.frameMs *= scaleNaive;
      r.queries *= scaleNaive;
      r.ratio = r.frameMs / oursMs[shadows];
      r.note = "1 frame at " + std::to_string(o.naiveSize) + "^2, time and queries x" + std::to_string(int(scaleNaive)) +
               " to " + std::to_string(o.size) + "^2";
      rows.push_back(r);
      std::printf("   %-18s %9.1f ms/frame at %d^2 (scaled from %d^2)  %.0f queries  %.0fx slower than wavefront\n",
                  r.variant.c_str(), r.frameMs, o.size, o.naiveSize, r.queries, r.ratio);
      std::fflush(stdout);
    }
  }
  // 4c: GPU ray marcher (no shadows on the GPU), step = box diagonal / 512.
  {
    CudaRayMarcher march(eval, box);
    RenderSettings s3;
    s3.width = s3.height = o.marchSize;
    march.setSettings(s3);
    march.setScene(benchScene(model, range, false));
    const FrameStats st = march.renderFrame();
    const double scale = double(o.size) * o.size / (double(o.marchSize) * o.marchSize);
    Row r = fromStats("4c", name, "raymarch", o.marchSize, st, 1);
    r.frameMs *= scale;
    r.queries *= scale;
    r.ratio = r.frameMs / oursMs[0];
    r.note = "1 frame at " + std::to_string(o.marchSize) + "^2 scaled x" + std::to_string(int(scale)) +
             "; step diagonal/512; no shadows";
    rows.push_back(r);
    std::printf("   %-18s %9.1f ms/frame at %d^2 (scaled from %d^2)  %.0f queries  %.0fx slower than wavefront\n",
                r.variant.c_str(), r.frameMs, o.size, o.marchSize, r.queries, r.ratio);
    std::fflush(stdout);
  }
}

// 4d: setTime (working-grid interpolation) + majorants, all slices prebuilt; median of 21 changes.
void benchTimeStep(const std::string& name, const InrModel& model, int m, int slices) {
  const CudaInrEvaluator eval(model);
  MacrocellOptions mo;
  mo.dims = Int3{m, m, m};
  mo.temporalSlices = slices;
  cuda::Stream stream;
  CudaMacrocellGrid grid(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, mo, stream.get());
  const auto t0 = std::chrono::steady_clock::now();
  grid.buildAllSlices();
  const double buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const auto range = grid.workingValueRange();
  const TransferFunctionTable table(TransferFunction::preset(range[0], range[1], 0.6));
  cuda::DeviceTransferFunction tf;
  tf.upload(table, stream.get());
  cuda::DeviceBuffer<float> maj(grid.cellCount());
  EventTimer timer;
  std::vector<double> gpuMs, wallMs;
  std::mt19937 rng(3);
  for (int k = 0; k < 22; ++k) {
    const double t = std::uniform_real_distribution<double>(model.domain.timeBegin, model.domain.timeEnd)(rng);
    const auto w0 = std::chrono::steady_clock::now();
    timer.start(stream.get());
    grid.setTime(t);
    grid.computeMajorants(tf.view(), maj.get());
    timer.stop(stream.get());
    const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count();
    const float ms = timer.ms();
    if (k == 0) continue;  // first change: warm-up
    gpuMs.push_back(ms);
    wallMs.push_back(wall);
  }
  Row r;
  r.group = "4d";
  r.model = name;
  r.variant = "timestep " + std::to_string(m) + "^3";
  r.size = m;
  r.frameMs = medianOf(gpuMs);
  r.updateMs = medianOf(wallMs);
  r.note = "GPU time (events); update_ms = host wall incl. launches and sync; " + std::to_string(slices) +
           " slices built in " + std::to_string(int(buildMs)) + " ms";
  rows.push_back(r);
  std::printf("   %d^3 macrocells: time-step update %.3f ms GPU, %.3f ms wall (median of 21); "
              "%d slices built in %.0f ms\n",
              m, r.frameMs, r.updateMs, slices, buildMs);
  std::fflush(stdout);
}

void writeCsv(const std::string& path) {
  std::ofstream f(path);
  f << "group,model,variant,size,frame_ms,fps,queries_per_frame,iterations_per_frame,init_ms,traverse_ms,evaluate_ms,"
       "shadow_traverse_ms,shadow_evaluate_ms,finalize_ms,update_ms,evaluator_gqps,ratio,note\n";
  for (const Row& r : rows) {
    f << r.group << ',' << '"' << r.model << '"' << ',' << r.variant << ',' << r.size << ',' << r.frameMs << ','
      << (r.frameMs > 0 ? 1e3 / r.frameMs : 0) << ',' << r.queries << ',' << r.iterations << ',' << r.initMs << ','
      << r.traverseMs << ',' << r.evaluateMs << ',' << r.shadowTraverseMs << ',' << r.shadowEvaluateMs << ','
      << r.finalizeMs << ',' << r.updateMs << ',' << r.evalGqps << ',' << r.ratio << ',' << '"' << r.note << '"'
      << '\n';
  }
}

void printTable() {
  std::printf("\n%-5s %-28s %-18s %6s %10s %8s %11s %6s %7s %7s %7s %7s %7s %7s %6s\n", "group", "model", "variant",
              "size", "ms/frame", "fps", "queries", "iters", "init", "trav", "eval", "s.trav", "s.eval", "final",
              "ratio");
  for (const Row& r : rows) {
    std::printf("%-5s %-28.28s %-18s %6d %10.3f %8.2f %11.0f %6.1f %7.3f %7.3f %7.3f %7.3f %7.3f %7.3f %6.2f\n",
                r.group.c_str(), r.model.c_str(), r.variant.c_str(), r.size, r.frameMs,
                r.frameMs > 0 ? 1e3 / r.frameMs : 0, r.queries, r.iterations, r.initMs, r.traverseMs, r.evaluateMs,
                r.shadowTraverseMs, r.shadowEvaluateMs, r.finalizeMs, r.ratio);
  }
  std::printf("ratio: 4b = frame time / (queries / evaluator throughput) (target <= 1.5); "
              "4c = baseline frame time / wavefront frame time at the same size (targets >= 100 naive, >= 150 "
              "ray marching)\n");
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--size") o.size = std::stoi(cl.value());
    else if (a == "--frames") o.frames = std::max(1, std::stoi(cl.value()));
    else if (a == "--warmup") o.warmup = std::max(0, std::stoi(cl.value()));
    else if (a == "--naive-size") o.naiveSize = std::stoi(cl.value());
    else if (a == "--march-size") o.marchSize = std::stoi(cl.value());
    else if (a == "--macrocells") o.macrocells = std::stoi(cl.value());
    else if (a == "--slices") o.slices = std::stoi(cl.value());
    else if (a == "--no-paper") o.paper = false;
    else if (a == "--no-baselines") o.baselines = false;
    else if (a == "--per-thread-gradient") o.perThreadGradient = true;
    else if (a == "--wgmma-consumers") o.wgmmaConsumers = std::stoi(cl.value());
    else if (a == "--column-split") o.wgmmaColumnSplit = std::stoi(cl.value()) ? 1 : 0;
    else if (a == "--mma") {
      const std::optional<FusedMma> m = bench::parseMmaOption(cl.value(), "gpu_render_benchmark");
      if (!m) return 2;
      o.mma = *m;
    } else if (a == "--csv") o.csv = cl.value();
    else if (a == "--traversal") o.traversal = parseTraversalKind(cl.value());
    else if (a == "-h" || a == "--help") {
      std::printf("usage: gpu_render_benchmark [--size N] [--frames F] [--warmup W] [--naive-size N] "
                  "[--march-size N] [--macrocells M] [--slices T] [--no-paper] [--no-baselines] "
                  "[--traversal auto|dda|optix (default dda)] [--per-thread-gradient] [--wgmma-consumers 1|2] [--column-split 0|1] "
                  "[--mma wgmma|mma.sync] [--csv FILE] "
                  "[MODEL.inr ...]\n");
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    } else
      o.models.push_back(a);
  }
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) {
    std::fprintf(stderr, "no usable GPU: %s\n", dev.reason.c_str());
    return 1;
  }
  std::printf("GPU render benchmark on %s; %d^2, %d frames after %d warm-up, %d^3 macrocells x %d slices\n",
              dev.name.c_str(), o.size, o.frames, o.warmup, o.macrocells, o.slices);
  try {
    std::vector<std::pair<std::string, InrModel>> models;
    if (o.paper) {
      models.emplace_back("SIREN 4-256x5-1 (synthetic)", bench::sirenPaper());
      models.emplace_back("FFN 256ff 5x256 (synthetic)", bench::ffnPaper());
      models.emplace_back("CoordNet init48 (synthetic)", bench::coordNetPaper());
    }
    for (auto& m : loadModelFiles(o.models)) models.push_back(std::move(m));
    for (const auto& [name, model] : models) benchModel(name, model, o);
    std::printf("\n== 4d time-step update latency\n");
    const InrModel m = models.empty() ? bench::sirenPaper() : models.front().second;
    const std::string mName = models.empty() ? "SIREN 4-256x5-1 (synthetic)" : models.front().first;
    for (int cells : {64, 128}) benchTimeStep(mName, m, cells, o.slices);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    printTable();
    if (!o.csv.empty()) writeCsv(o.csv);
    return 1;
  }
  printTable();
  if (!o.csv.empty()) writeCsv(o.csv);
  return 0;
}
