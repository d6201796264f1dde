// GPU traversal benchmark (issue 14): the DDA against the OptiX GAS traversal, per model and
// macrocell resolution, in one run on one GPU:
//   - frame: traverse and shadow-traverse milliseconds per frame (CUDA events), frame time and
//     queries per frame at SIZE² (the render benchmark's scene: TestSupport/TestScene.h, preset
//     transfer function, delta-tracked shadows), after warm-up frames;
//   - structure: GAS primitives (macrocells with a positive majorant), compacted bytes, build
//     milliseconds (selection + build + compaction, host wall incl. synchronisation), the device
//     memory reserved for it, and the builds and build time per frame that refinement caused
//     (a build only when the set of selected cells changes);
//   - time step: a scene time change (working-grid interpolation + majorants + GAS rebuild; all
//     slices prebuilt), host wall, median of 21 changes, with the GAS built at every change
//     (TraversalOptions::rebuildEveryUpdate: the worst case, and the build time measured).
// OptiX traverses in software on GPUs without RT cores (H100, H200): the table shows it as it is.
//   gpu_traversal_benchmark [--size N] [--frames F] [--warmup W] [--macrocells M[,M...]] [--slices T]
//                           [--csv FILE] MODEL.inr ...
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "BenchmarkSupport.h"
#include "Common/Cuda/CudaDevice.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/Cuda/DeviceTraversal.h"
#include "Render/ModelBox.h"
#include "TestSupport/TestScene.h"

using namespace inr;
using namespace inr::bench;

namespace {

const char* kUsage =
    "usage: gpu_traversal_benchmark [--size N] [--frames F] [--warmup W] [--macrocells M[,M...]] [--slices T]\n"
    "                               [--csv FILE] MODEL.inr ...\n"
    "  DDA vs OptiX GAS traversal per model and macrocell resolution (default 64,128): traverse ms per frame\n"
    "  with and without shadows, GAS primitives / bytes / build ms, time-step update incl. the GAS rebuild.\n";

struct Options {
  int size = 1024, frames = 20, warmup = 5, slices = 16;
  std::vector<int> macrocells{64, 128};
  std::string csv;
  std::vector<std::string> models;
};

struct Row {
  std::string model, traversal;
  int macrocells = 0;
  bool shadows = false;
  double frameMs = 0, traverseMs = 0, shadowTraverseMs = 0, queries = 0, rebuildMsPerFrame = 0;
  std::size_t primitives = 0, bytes = 0, reservedBytes = 0;
  double buildMs = 0, timeStepMs = 0, buildsPerFrame = 0;
};
std::vector<Row> rows;

void benchModel(const std::string& name, const InrModel& model, int m, const Options& o) {
  const CudaInrEvaluator eval(model);
  const auto range = valueRangeFor(model, eval);
  MacrocellOptions mo;
  mo.dims = Int3{m, m, m};
  mo.temporalSlices = o.slices;
  CudaMacrocellGrid grid(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, mo);
  grid.buildAllSlices();  // time steps below interpolate, never build
  CudaWavefrontRenderer renderer(eval, grid);
  RenderSettings settings;
  settings.width = settings.height = o.size;
  renderer.setSettings(settings);
  for (TraversalKind kind : {TraversalKind::Dda, TraversalKind::Optix}) {
    TraversalOptions to;
    to.kind = kind;
    to.rebuildEveryUpdate = true;  // time steps: every change builds (timed); frames below: only as needed
    try {
      renderer.setTraversal(to);
    } catch (const std::exception& e) {
      std::printf("   %s: unavailable (%s)\n", traversalKindName(kind), e.what());
      continue;
    }
    std::printf("   %d^3, %s\n", m, renderer.traversalChoice().c_str());
    // Time steps first (the frames' refinements would otherwise differ between traversals).
    RenderScene scene = test::testScene(model, range, false, ShadowEstimator::Delta);
    renderer.setScene(scene);
    std::vector<double> stepMs, buildMs;
    std::mt19937 rng(3);
    for (int k = 0; k < 22; ++k) {
      scene.time = std::uniform_real_distribution<double>(model.domain.timeBegin, model.domain.timeEnd)(rng);
      const auto t0 = std::chrono::steady_clock::now();
      renderer.setScene(scene);  // working grid, majorants, GAS rebuild; synchronised
      const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      if (k == 0) continue;  // warm-up
      stepMs.push_back(wall);
      buildMs.push_back(renderer.traversal().buildInfo().lastBuildMs);
    }
    to.rebuildEveryUpdate = false;
    renderer.setTraversal(to);
    for (bool shadows : {false, true}) {
      scene = test::testScene(model, range, shadows, ShadowEstimator::Delta);
      renderer.setScene(scene);
      for (int k = 0; k < o.warmup; ++k) renderer.renderFrame();
      FrameStats total;
      const std::size_t buildsBefore = renderer.traversal().buildInfo().builds;
      for (int k = 0; k < o.frames; ++k) total += renderer.renderFrame();
      const TraversalBuildInfo info = renderer.traversal().buildInfo();
      Row r;
      r.model = name;
      r.traversal = traversalKindName(kind);
      r.macrocells = m;
      r.shadows = shadows;
      const double f = o.frames;
      r.frameMs = total.totalMs / f;
      r.traverseMs = total.traverseMs / f;
      r.shadowTraverseMs = total.shadowTraverseMs / f;
      r.queries = double(total.totalQueries()) / f;
      r.rebuildMsPerFrame = total.traversalBuildMs / f;
      r.primitives = total.traversalPrimitives;
      r.bytes = total.traversalBytes;
      r.reservedBytes = info.reservedBytes;
      r.buildsPerFrame = double(info.builds - buildsBefore) / f;
      r.buildMs = kind == TraversalKind::Optix ? medianOf(buildMs) : 0.0;
      r.timeStepMs = medianOf(stepMs);
      rows.push_back(r);
      std::printf("     %-8s %8.3f ms/frame  traverse %7.3f  shadow traverse %7.3f  %9.0f queries  "
                  "GAS %zu cells %.2f MB (reserved %.2f MB) build %.3f ms (%.2f builds, %.3f ms per frame)  "
                  "time step %.3f ms\n",
                  shadows ? "shadows" : "primary", r.frameMs, r.traverseMs, r.shadowTraverseMs, r.queries,
                  r.primitives, r.bytes / 1048576.0, r.reservedBytes / 1048576.0, r.buildMs, r.buildsPerFrame,
                  r.rebuildMsPerFrame, r.timeStepMs);
      std::fflush(stdout);
    }
  }
}

void writeCsv(const std::string& path) {
  std::ofstream f(path);
  f << "model,macrocells,traversal,shadows,frame_ms,traverse_ms,shadow_traverse_ms,queries_per_frame,"
       "gas_primitives,gas_bytes,gas_reserved_bytes,gas_build_ms,builds_per_frame,rebuild_ms_per_frame,time_step_ms\n";
  for (const Row& r : rows)
    f << '"' << r.model << "\"," << r.macrocells << ',' << r.traversal << ',' << (r.shadows ? 1 : 0) << ','
      << r.frameMs << ',' << r.traverseMs << ',' << r.shadowTraverseMs << ',' << r.queries << ',' << r.primitives
      << ',' << r.bytes << ',' << r.reservedBytes << ',' << r.buildMs << ',' << r.buildsPerFrame << ','
      << r.rebuildMsPerFrame << ',' << r.timeStepMs << '\n';
}

void printTable() {
  std::printf("\n%-28s %5s %-6s %-7s %9s %9s %9s %10s %9s %9s %9s %9s %9s %9s\n", "model", "cells", "trav",
              "shadows", "ms/frame", "traverse", "s.trav", "queries", "GAS prims", "GAS MB", "rsrv MB", "build ms",
              "builds/fr", "step ms");
  for (const Row& r : rows)
    std::printf("%-28.28s %5d %-6s %-7s %9.3f %9.3f %9.3f %10.0f %9zu %9.2f %9.2f %9.3f %9.2f %9.3f\n",
                r.model.c_str(), r.macrocells, r.traversal.c_str(), r.shadows ? "yes" : "no", r.frameMs,
                r.traverseMs, r.shadowTraverseMs, r.queries, r.primitives, r.bytes / 1048576.0,
                r.reservedBytes / 1048576.0, r.buildMs, r.buildsPerFrame, r.timeStepMs);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--size") o.size = std::stoi(cl.value());
    else if (a == "--frames") o.frames = std::max(1, std::stoi(cl.value()));
    else if (a == "--warmup") o.warmup = std::max(0, std::stoi(cl.value()));
    else if (a == "--slices") o.slices = std::max(1, std::stoi(cl.value()));
    else if (a == "--csv") o.csv = cl.value();
    else if (a == "--macrocells") {
      o.macrocells.clear();
      std::stringstream ss(cl.value());
      for (std::string item; std::getline(ss, item, ',');) o.macrocells.push_back(std::stoi(item));
    } else if (const int rc = cl.other(a, kUsage, o.models); rc >= 0)
      return rc;
  }
  if (o.models.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) {
    std::fprintf(stderr, "no usable GPU: %s\n", dev.reason.c_str());
    return 1;
  }
  std::printf("GPU traversal benchmark on %s; %d^2, %d frames after %d warm-up, %d slices\n", dev.name.c_str(),
              o.size, o.frames, o.warmup, o.slices);
  try {
    for (const auto& [name, model] : loadModelFiles(o.models)) {
      std::printf("\n== %s\n", name.c_str());
      for (int m : o.macrocells) benchModel(name, model, m, o);
    }
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
