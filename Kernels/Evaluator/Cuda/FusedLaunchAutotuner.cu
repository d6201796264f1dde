#include "Evaluator/Cuda/FusedLaunchAutotuner.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/Cuda/FusedMlpKernelHopper.cuh"
#include "Evaluator/Cuda/FusedMlpKernels.h"

namespace inr::cuda {

std::string configName(const FusedConfig& c) {
  const std::string hash = c.hashGridPairs < 0 ? "" : c.hashGridPairs ? ", hash lane pairs" : ", hash lane per row";
  if (!c.wgmma)
    return std::string(c.generated ? "generated " : "") + "tile " + std::to_string(c.tile) + " x K " + std::to_string(c.kc) + (c.storedEncoding ? ", stored encoding" : "") +
           (c.tangents ? ", tangent rows" : "") + hash;
  return "wgmma " + std::to_string(c.consumers) + "x" + std::to_string(kHopperRows) + " x N " +
         std::to_string(c.kc) + ", " + std::to_string(c.stages) + " slots" + (c.pingPong ? ", ping-pong" : "") +
         (c.splitColumns ? ", one tile, columns split" : "") +
         (c.splitEncoding ? ", stored encoding split" : c.storedEncoding ? ", stored encoding" : "") + hash;
}

bool sameConfig(const FusedConfig& a, const FusedConfig& b) {
  return a.wgmma == b.wgmma && a.tile == b.tile && a.kc == b.kc && a.stages == b.stages && a.pingPong == b.pingPong &&
         a.storedEncoding == b.storedEncoding && a.splitEncoding == b.splitEncoding && a.hashGridPairs == b.hashGridPairs &&
         a.tangents == b.tangents && a.consumers == b.consumers && a.splitColumns == b.splitColumns &&
         a.generated == b.generated;
}

FusedLaunchAutotuner::FusedLaunchAutotuner(const CudaDeviceInfo& device, const CudaEvaluatorOptions& options)
    : device_(device), options_(options) {}

namespace {

// Dynamic shared memory `kernel` may have beside its static shared memory on `device`.
std::size_t sharedLimit(const CudaDeviceInfo& device, FusedKernel kernel) {
  cudaFuncAttributes attr{};
  INR_CUDA_CHECK(cudaFuncGetAttributes(&attr, kernel));
  return device.sharedMemPerBlockOptin - std::min(device.sharedMemPerBlockOptin, std::size_t(attr.sharedSizeBytes));
}

}  // namespace

std::vector<FusedConfig> FusedLaunchAutotuner::candidates(const FusedParams& P, const FusedParams& stored,
                                                          const FusedParams& split, bool wgmmaRuns,
                                                          const GeneratedKernels* generated) const {
  const CudaEvaluatorOptions& options = options_;
  std::vector<FusedConfig> candidates;
  const bool onlyGenerated = options.generatedKernels == GeneratedKernelUse::Only;
  // mma.sync candidates first: without autotuning the first that fits runs, and that stays
  // the kernel (and arithmetic) of earlier versions; the wgmma kernel wins only by timing.
  if (options.mma != FusedMma::Wgmma)
    for (int t : {128, 64, 32})
      for (int kc : {64, 32}) {
        if ((options.tileQueries && options.tileQueries != t) || (options.weightChunk && options.weightChunk != kc)) continue;
        const FusedKernel kernel = mmaSyncKernel(t, kc);
        // the fused and the stored encoding (where the program has one), each if it fits (one
        // kernel, two shared-memory sizes: its limit allows either at launch)
        const std::size_t limit = sharedLimit(device_, kernel);
        INR_CUDA_CHECK(cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, int(limit)));
        for (const bool storedEncoding : {true, false}) {  // stored first: the kernel of earlier versions
          if (storedEncoding && !P.fusedFourier) continue;
          if (P.fusedFourier && options.storedEncoding >= 0 && options.storedEncoding != int(storedEncoding)) continue;
          const std::size_t b = fusedSharedBytes(t, kc, storedEncoding ? stored : P);
          if (b > limit) continue;
          int perSm = 0;
          INR_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&perSm, kernel, t * 4, b));
          if (perSm < 1) continue;
          if (onlyGenerated) continue;
          candidates.push_back({false, t, kc, 0, false, storedEncoding, false, b, perSm * device_.multiprocessors, 0.0});
        }
      }
  // The same configurations on the kernels generated for the model (the same shared memory; no
  // static shared memory for the program, so a larger limit; their own register counts).
  if (generated && generated->available() && options.mma != FusedMma::Wgmma)
    for (int t : {128, 64, 32})
      for (int kc : {64, 32}) {
        if ((options.tileQueries && options.tileQueries != t) || (options.weightChunk && options.weightChunk != kc)) continue;
        for (const bool storedEncoding : {true, false}) {
          if (storedEncoding && !P.fusedFourier) continue;
          if (P.fusedFourier && options.storedEncoding >= 0 && options.storedEncoding != int(storedEncoding)) continue;
          const FusedKernel kernel = generated->kernel(t, kc, storedEncoding, false);
          if (!kernel) continue;
          const std::size_t limit = sharedLimit(device_, kernel);
          INR_CUDA_CHECK(cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, int(limit)));
          const std::size_t b = fusedSharedBytes(t, kc, storedEncoding ? stored : P);
          if (b > limit) continue;
          int perSm = 0;
          INR_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&perSm, kernel, t * 4, b));
          if (perSm < 1) continue;
          FusedConfig c{false, t, kc, 0, false, storedEncoding, false, b, perSm * device_.multiprocessors, 0.0};
          c.generated = true;
          candidates.push_back(c);
        }
      }
  // wgmma (consumers x 64 queries per round): two consumers, then one; per chunk width (widest
  // first), as many ring slots as fit (2 at least); two consumers with and without turns, and on
  // one tile with its columns split (64 queries per round, hopperConsumer's COLUMNS); a
  // program with a fused Fourier encoding also with it stored, and stored split where its GEMM
  // has K 257..512 (after the fused form, so the configuration without autotuning stays the one
  // of earlier versions). The paper FFN's stored encoding (64 x 512 fp16 per tile beside its
  // 256-wide activations) fits one tile's region with 64-column chunks only (one consumer, or two
  // with the columns split)
  // (hopperSharedBytes: two consumers' buffers alone take most of the shared memory, and a ring
  // slot of 128 columns x K 256 is 64 KB); split (32 KB of operand per consumer, the rest over
  // the activations) also two consumers with 64-column chunks and one with 128. Bounded: at most
  // 8 wgmma candidates per form (6 split), twice that with a hash grid's two gathers, the stored
  // forms only where they fit. A
  // kernel's dynamic shared-memory limit is set to all it may have, as for mma.sync (the fused
  // and the stored form share a kernel with different sizes, and another evaluator's launches
  // may need more than this one's; the split form has its own, hopperKernel(nc, consumers, true)).
  if (wgmmaRuns && !onlyGenerated)
    for (const int consumers : {2, 1}) {
      if (options.wgmmaConsumers && options.wgmmaConsumers != consumers) continue;
      for (const int nc : {128, 64}) {
        if (options.wgmmaChunkColumns && options.wgmmaChunkColumns != nc) continue;
        for (const int form : {0, 1, 2}) {  // fused, stored, stored split (CudaEvaluatorOptions::storedEncoding)
          const bool storedEncoding = form > 0, splitEncoding = form == 2;
          const FusedParams& params = splitEncoding ? split : storedEncoding ? stored : P;
          // (the evaluator gives each stored form its own wgmma instructions where it has one: the
          // split form may have them where the plain stored one does not fit its buffers)
          if (storedEncoding && (!P.fusedFourier || params.hopperInstrs == P.hopperInstrs)) continue;
          if (splitEncoding && split.hopperSplitGemm < 0) continue;
          if (P.fusedFourier && options.storedEncoding >= 0 && options.storedEncoding != form) continue;
          // Two consumers also on one tile, splitting its column chunks (not with the split
          // encoding, whose operand region is per consumer; no turns): one tile's region.
          for (const bool splitColumns : {false, true}) {
            if (splitColumns && (consumers == 1 || splitEncoding)) continue;
            if (options.wgmmaColumnSplit >= 0 && options.wgmmaColumnSplit != int(splitColumns)) continue;
            const FusedKernel kernel = hopperKernel(nc, consumers, splitEncoding, splitColumns);
            if (!kernel) continue;
            const int regions = hopperTileRegions(consumers, splitColumns);
            const std::size_t limit = sharedLimit(device_, kernel);
            int stages = 0;
            for (int s = kHopperMaxStages; s >= 2 && !stages; --s)
              if (hopperSharedBytes(nc, s, regions, params) <= limit) stages = s;
            if (!stages) continue;
            const std::size_t bytes = hopperSharedBytes(nc, stages, regions, params);
            INR_CUDA_CHECK(cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, int(limit)));
            int perSm = 0;
            INR_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&perSm, kernel, hopperThreads(consumers), bytes));
            if (perSm < 1) continue;
            for (const bool pingPong : {true, false}) {
              if (pingPong && (consumers == 1 || splitColumns)) continue;  // turns need two consumers on two tiles
              if (options.wgmmaPingPong >= 0 && options.wgmmaPingPong != int(pingPong)) continue;
              FusedConfig c{true, kHopperRows * regions, nc, stages, pingPong, storedEncoding, splitEncoding, bytes,
                            perSm * device_.multiprocessors, 0.0};
              c.consumers = consumers;
              c.splitColumns = splitColumns;
              candidates.push_back(c);
            }
          }
        }
      }
    }
  if (!P.hashTables) return candidates;
  // A hash grid's gather both ways (FusedParams::hashGridPairs): lane pairs first.
  std::vector<FusedConfig> both;
  for (const FusedConfig& c : candidates)
    for (const int pairs : {1, 0}) {
      if (options.hashGridPairs >= 0 && options.hashGridPairs != pairs) continue;
      both.push_back(c);
      both.back().hashGridPairs = pairs;
    }
  return both;
}

std::vector<FusedConfig> FusedLaunchAutotuner::tangentCandidates(const std::vector<FusedConfig>& candidates,
                                                                 const GeneratedKernels* generated) const {
  std::vector<FusedConfig> out;
  for (FusedConfig c : candidates) {
    if (c.wgmma) continue;
    // A hash grid's value candidates come twice, once per gather lane arrangement; the tangent
    // rows gather query by query (runTangentRowInstr) whatever it is, so each is taken once.
    c.hashGridPairs = -1;
    const auto same = [&](const FusedConfig& o) {
      return o.tile == c.tile && o.kc == c.kc && o.storedEncoding == c.storedEncoding && o.generated == c.generated;
    };
    if (std::any_of(out.begin(), out.end(), same)) continue;
    const FusedKernel kernel = c.generated ? (generated ? generated->kernel(c.tile, c.kc, c.storedEncoding, true) : nullptr)
                                           : mmaSyncTangentKernel(c.tile, c.kc);
    if (!kernel) continue;
    // Its limit, not this candidate's size: the stored and the fused encoding share the kernel
    // with two sizes, and the larger must still launch after the smaller was set.
    const std::size_t limit = sharedLimit(device_, kernel);
    if (c.sharedBytes > limit) continue;
    INR_CUDA_CHECK(cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, int(limit)));
    int perSm = 0;
    INR_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&perSm, kernel, c.tile * 4, c.sharedBytes));
    if (perSm < 1) continue;
    c.tangents = true;
    c.gridBlocks = perSm * device_.multiprocessors;
    out.push_back(c);
  }
  return out;
}

FusedLaunchAutotuner::Choice FusedLaunchAutotuner::choose(const std::vector<FusedConfig>& candidates,
                                                          const Domain& domain, const Launch& launch,
                                                          int largeBatch) const {
  Choice choice;
  choice.large = choice.small = candidates.front();
  const auto interpreterMmaSync = [](const FusedConfig& c) { return !c.wgmma && !c.generated; };
  for (const FusedConfig& c : candidates)
    if (interpreterMmaSync(c) && !choice.hasMmaSync) {
      choice.mmaSyncLarge = choice.mmaSyncSmall = c;
      choice.hasMmaSync = true;
    }
  const int batch = largeBatch < 0 ? options_.autotuneBatch : largeBatch;
  if (candidates.size() < 2 || batch <= 0) {
    choice.report = configName(choice.large) +
                    (candidates.size() > 1 ? " (first that fits, not autotuned)" : " (the only configuration)");
    return choice;
  }
  // Every candidate runs on the same random points in the model's domain.
  const int smallBatch = std::min(batch, kSmallBatch);
  std::vector<float4> pts(static_cast<std::size_t>(batch));
  std::uint32_t state = 12345u;
  auto uniform = [&](double lo, double hi) {
    state = state * 1664525u + 1013904223u;
    return float(lo + (hi - lo) * ((state >> 8) * (1.0 / 16777216.0)));
  };
  const auto& b = domain.bounds;
  for (auto& p : pts)
    p = make_float4(uniform(b[0], b[1]), uniform(b[2], b[3]), uniform(b[4], b[5]),
                    uniform(domain.timeBegin, domain.timeEnd));
  DeviceBuffer<float4> points;
  DeviceBuffer<float> values;
  points.growTo(pts.size());
  values.growTo(pts.size());
  INR_CUDA_CHECK(cudaMemcpy(points.get(), pts.data(), pts.size() * sizeof(float4), cudaMemcpyHostToDevice));
  cudaEvent_t e0, e1;
  INR_CUDA_CHECK(cudaEventCreate(&e0));
  INR_CUDA_CHECK(cudaEventCreate(&e1));
  // Queries per second: the best of 3 timings after a warm-up, each over `launches` launches in
  // a row (the small batch's: one short launch times launch jitter about as much as the kernel,
  // and the choice flipped between runs; in a frame such launches queue in a row too).
  auto rate = [&](const FusedConfig& config, int n, int launches) {
    float best = 0.f;
    for (int r = -1; r < 3; ++r) {
      INR_CUDA_CHECK(cudaEventRecord(e0));
      for (int l = 0; l < launches; ++l) launch(config, points.get(), n, values.get());
      INR_CUDA_CHECK(cudaEventRecord(e1));
      INR_CUDA_CHECK(cudaEventSynchronize(e1));
      float ms = 0.f;
      INR_CUDA_CHECK(cudaEventElapsedTime(&ms, e0, e1));
      if (r == 0 || (r > 0 && ms < best)) best = ms;
    }
    return double(n) * launches / (double(best) * 1e-3);
  };
  std::string report;
  double bestLarge = 0.0, bestSmall = 0.0, bestMmaLarge = 0.0, bestMmaSmall = 0.0;
  for (const FusedConfig& c : candidates) {
    const double large = rate(c, batch, 1), small = rate(c, smallBatch, kSmallBatchLaunches);
    if (large > bestLarge) bestLarge = large, choice.large = c;
    if (small > bestSmall) bestSmall = small, choice.small = c;
    if (interpreterMmaSync(c) && large > bestMmaLarge) bestMmaLarge = large, choice.mmaSyncLarge = c;
    if (interpreterMmaSync(c) && small > bestMmaSmall) bestMmaSmall = small, choice.mmaSyncSmall = c;
    char line[128];
    std::snprintf(line, sizeof line, "%s%s: %.3f / %.3f Gq/s", report.empty() ? "" : "; ", configName(c).c_str(),
                  large * 1e-9, small * 1e-9);
    report += line;
  }
  cudaEventDestroy(e0);
  cudaEventDestroy(e1);
  choice.report = "batch " + std::to_string(batch) + " / " + std::to_string(smallBatch) + ": " + report + " -> " +
                  configName(choice.large) + ", below " + std::to_string(kSmallBatchThreshold) + " queries " +
                  configName(choice.small);
  return choice;
}

}  // namespace inr::cuda
