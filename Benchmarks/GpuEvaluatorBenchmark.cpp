// GPU evaluator throughput (queries/s): the fused tensor-core kernel and the generic fp32 path
// on the paper-size architectures (and a hash-grid network) and on model files, timed with CUDA events (median of R
// launches over one batch of N random world points already on the device).
//   gpu_evaluator_benchmark [--batch N] [--reps R] [--csv FILE] [--write-models DIR]
//                           [--only NAME] [--mma wgmma|mma.sync] [--tile T] [--weight-chunk KC] [--ping-pong 0|1]
//                           [--wgmma-columns 64|128] [--wgmma-consumers 1|2] [--column-split 0|1]
//                           [--stored-encoding 0|1|2]
//                           [--batches N1,N2,...] [--points random|rays]
//                           [--hash-pairs 0|1] [--l2-persist]
//                           [--no-autotune] [--checksum] [--gradient] [--gradient-batch N]
//                           [--tangent-autotune-batch N] [--generated off|auto|only]
//                           [--kernel-cache DIR|none] [MODEL.inr ...]
// --only keeps the models whose name contains NAME; --mma, --tile and --weight-chunk (mma.sync),
// --ping-pong and --wgmma-columns (wgmma: the consumers take turns; output columns per weight
// chunk) and --no-autotune fix
// the fused kernel's configuration (CudaEvaluatorOptions) so a profiler (ncu) sees one kernel;
// --wgmma-consumers fixes the wgmma kernel's consumer warpgroups per block (2: 128 queries per
// round; 1: 64, twice the blocks on a small batch), --column-split whether two consumers share
// one tile, splitting its columns (1) or each run their own (0) (CudaEvaluatorOptions::
// wgmmaColumnSplit). --stored-encoding fixes how a fused Fourier
// encoding (the FFNs) runs: computed in the first GEMM's operand load (0), stored once per tile in
// a buffer (1), or on the wgmma kernel stored split (2: first 256 columns in shared memory in the
// MMAs' operand layout, the rest in registers) (CudaEvaluatorOptions::storedEncoding).
// --batches measures each model's autotuned fused evaluator (one construction) at every batch
// size of the list, on the first N of the same points, and prints each rate's share of the
// largest batch's (issue 30: the few-thousand-query launches of a frame's late iterations), for
// a launch alone and for launches queued back to back (kLaunchesInRow; the wavefront queues its
// evaluator launches behind the traversal's, so the host's launch latency is not in its frames).
// --points rays draws the points in the order of a frame's wavefront iterations (rays of an
// image, neighbouring pixels at nearby depths: test::rayOrderedQueryPoints, at the middle of the
// time range) instead of uniformly at random; a hash grid's table reads feel the difference.
// --hash-pairs fixes a hash grid's gather (lane pairs 1, a lane per row 0), and --l2-persist
// keeps its fp16 tables in L2 with a persisting access-policy window (hashTablesPersistInL2).
// --checksum prints a hash of each row's output bits (the last launch over the batch, seed 1):
// with a fixed configuration, the same on two builds when a change keeps the arithmetic.
// --gradient adds, per model, value + gradient rows (gradient shading's queries, issue 33) on
// --gradient-batch points (default 2^16, a shaded 1024² frame's order): "grad-per-thread" (the
// per-thread fp32 forward mode, at most 5 reps: it is slow) and "grad-fused" (the fused kernel's
// tangent rows; the per-thread path again where the model cannot run them, its note says why),
// each with the time its first call took to choose the tangent scale and configurations;
// --tangent-autotune-batch N times those on N queries (CudaEvaluatorOptions::tangentAutotuneBatch).
// --generated selects the kernels generated for each model (issue 50, compiled by NVRTC:
// CudaEvaluatorOptions::generatedKernels; the default INR_GENERATED_KERNELS): off (the built-in
// kernels only), auto (the generated twins of the chosen mma.sync configurations compile in the
// background and are timed against the built-in kernels when ready; every row here waits for that
// first, waitForGeneratedKernels), only (every generated mma.sync configuration, compiled at
// construction, alone); run it twice, off and only, for the interpreter and the generated kernel
// side by side. The launch report ends with what the compilation did ([generated kernels: N
// kernels for sm_90, NVRTC ..., seconds, how many from the cache]). --kernel-cache sets their
// cache folder. --cold-start DIR measures a model's load instead (measureColdStart): the
// constructor's seconds with the generated kernels off and on, the seconds until they are ready
// and timed, with a cold cache (a fresh folder under DIR) and then a warm one.
// --write-models saves the synthetic paper architectures as .inr files so the PyTorch baseline
// (Benchmarks/pytorch_baseline.py) runs the very same networks.
#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "GpuBenchmarkSupport.h"
#include "TestSupport/DevicePoints.h"
#include "TestSupport/HashGridModels.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

using namespace inr;
using namespace inr::bench;

namespace {

struct Row {
  std::string model, path, launch;
  std::size_t params;
  Spread qps;  // queries per second over the launches
  std::uint64_t outputHash;  // FNV-1a over the output floats' bits
  int batch;
  Spread streamQps{};  // --batches: the same with kLaunchesInRow launches queued back to back per timing
};

// --batches times each size twice: a launch alone (the host's launch latency included) and
// this many launches queued back to back, as a frame's wavefront queues them (launchRates).
constexpr int kLaunchesInRow = 10;

std::uint64_t hashBits(const float* v, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t bits;
    std::memcpy(&bits, v + i, sizeof bits);
    h = (h ^ bits) * 1099511628211ull;
  }
  return h;
}

// The benchmark's query points: uniform in the model's box and time range (seed 1), or
// (rayOrdered) in a frame's order at the middle of the time range.
std::vector<QueryPoint> benchmarkPoints(const InrModel& model, int n, bool rayOrdered) {
  if (rayOrdered)
    return test::rayOrderedQueryPoints(model, std::size_t(n), 1, float(0.5 * (model.domain.timeBegin + model.domain.timeEnd)));
  return test::randomQueryPoints(model, std::size_t(n), 1);
}

// mma: FusedMma::MmaSync gives the row "fused-mma.sync" (the pre-Hopper kernel, for comparison
// where the autotuned "fused-fp16" runs the wgmma kernel).
Row measure(const InrModel& model, const std::string& name, CudaEvaluatorPath path, int batch, int reps,
            CudaEvaluatorOptions o, bool rayOrdered) {
  o.path = path;
  const FusedMma mma = o.mma;
  const CudaInrEvaluator eval(model, o);
  eval.waitForGeneratedKernels();  // the steady state: generated kernels adopted where faster
  const cuda::DeviceBuffer<float4> dPts = test::devicePoints(benchmarkPoints(model, batch, rayOrdered));
  cuda::DeviceBuffer<float> dOut(batch);
  Row r{name, path == CudaEvaluatorPath::Generic ? "generic-fp32" : mma == FusedMma::MmaSync ? "fused-mma.sync" : "fused-fp16",
        eval.launchReport(), model.architecture.parameterCount(),
        spreadOf(evaluatorRates(eval, dPts.get(), batch, dOut.get(), reps)), 0, batch};
  const std::vector<float> out = dOut.download(nullptr);
  r.outputHash = hashBits(out.data(), out.size());
  return r;
}

// Value + gradient queries (CudaInrEvaluator::evaluateWithGradientDevice) at the middle of the
// time range, through the gradient path `gp`.
Row measureGradient(const InrModel& model, const std::string& name, CudaGradientPath gp, int batch, int reps,
                    CudaEvaluatorOptions o) {
  o.gradientPath = gp;
  const CudaInrEvaluator eval(model, o);
  eval.waitForGeneratedKernels();
  const float time = float(0.5 * (model.domain.timeBegin + model.domain.timeEnd));
  const cuda::DeviceBuffer<float4> dPts = test::devicePoints(test::randomQueryPoints(model, batch, 1, time));
  cuda::DeviceBuffer<float4> dOut(batch);
  // The first gradient call chooses the tangent scale and times the configurations: the wait a
  // frame that first asks for gradients (shading, gradient opacity) sees on top of its work.
  const auto t0 = std::chrono::steady_clock::now();
  std::string path = eval.gradientPath();
  if (eval.usesFusedTangents()) {
    char chosen[96];
    std::snprintf(chosen, sizeof chosen, "; chosen at the first call in %.1f ms",
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    path += chosen;
  }
  Row r{name, gp == CudaGradientPath::PerThread ? "grad-per-thread" : "grad-fused", path,
        model.architecture.parameterCount(), spreadOf(gradientRates(eval, dPts.get(), batch, time, dOut.get(), reps)), 0,
        batch};
  const std::vector<float4> out = dOut.download(nullptr);
  r.outputHash = hashBits(reinterpret_cast<const float*>(out.data()), 4 * out.size());
  return r;
}

// The autotuned fused evaluator at each batch size in `batches` (ascending), one construction,
// on the first n of the same points: a row per size (path "fused-fp16", or "generic-fp32" for a
// model the fused kernels cannot hold).
std::vector<Row> measureBatches(const InrModel& model, const std::string& name, const std::vector<int>& batches, int reps,
                                CudaEvaluatorOptions o, bool rayOrdered) {
  o.path = CudaEvaluatorPath::Auto;
  const CudaInrEvaluator eval(model, o);
  eval.waitForGeneratedKernels();
  const int largest = batches.back();
  const cuda::DeviceBuffer<float4> dPts = test::devicePoints(benchmarkPoints(model, largest, rayOrdered));
  cuda::DeviceBuffer<float> dOut(largest);
  std::vector<Row> rows;
  const char* path = eval.path() == CudaEvaluatorPath::Fused ? "fused-fp16" : "generic-fp32";
  for (const int n : batches)
    rows.push_back({name, path, eval.launchReport(), model.architecture.parameterCount(),
                    spreadOf(evaluatorRates(eval, dPts.get(), n, dOut.get(), reps)), 0, n,
                    spreadOf(evaluatorRates(eval, dPts.get(), n, dOut.get(), reps, kLaunchesInRow))});
  return rows;
}

// --cold-start: what loading a model costs with the generated kernels compiled in the background
// (GeneratedKernelUse::Auto) against none, on a cold and a warm disk cache (a fresh folder under `cacheRoot`):
// the constructor's seconds (what the first frame waits), the seconds until the generated kernels
// are compiled and timed (waitForGeneratedKernels after the constructor), which kernel runs
// then, and the large-batch rate before and after.
struct ColdStartRow {
  std::string model, cache;
  double offSeconds = 0, constructSeconds = 0, readySeconds = 0, qpsBefore = 0, qpsAfter = 0;
  bool generatedKept = false;
  std::string report;
};

ColdStartRow measureColdStart(const InrModel& model, const std::string& name, int batch, int reps,
                              CudaEvaluatorOptions o, const std::string& cacheDir, bool warm) {
  using clock = std::chrono::steady_clock;
  const auto seconds = [](clock::time_point a) { return std::chrono::duration<double>(clock::now() - a).count(); };
  const cuda::DeviceBuffer<float4> dPts = test::devicePoints(benchmarkPoints(model, batch, false));
  cuda::DeviceBuffer<float> dOut(batch);
  ColdStartRow r{name, warm ? "warm" : "cold"};
  o.kernelCacheDir = cacheDir;
  {
    CudaEvaluatorOptions off = o;
    off.generatedKernels = GeneratedKernelUse::Off;
    const auto t0 = clock::now();
    const CudaInrEvaluator eval(model, off);
    r.offSeconds = seconds(t0);
  }
  o.generatedKernels = GeneratedKernelUse::Auto;
  const auto t0 = clock::now();
  const CudaInrEvaluator eval(model, o);
  r.constructSeconds = seconds(t0);
  // Timed while compiling (the built-in kernel; with a warm cache the generated one may already run).
  r.qpsBefore = spreadOf(evaluatorRates(eval, dPts.get(), batch, dOut.get(), reps)).median;
  eval.waitForGeneratedKernels();
  r.readySeconds = seconds(t0);
  r.qpsAfter = spreadOf(evaluatorRates(eval, dPts.get(), batch, dOut.get(), reps)).median;
  r.generatedKept = eval.usesGeneratedKernel();
  r.report = eval.generatedKernelReport();
  return r;
}

void printRow(const Row& r, bool checksum) {
  std::printf("%-28s %-16s %9zu %12.4f %12.4f %12.4f\n", r.model.c_str(), r.path.c_str(), r.params, r.qps.median / 1e9,
              r.qps.lo / 1e9, r.qps.hi / 1e9);
  if (!r.launch.empty()) std::printf("    %s: %s\n", r.path.rfind("grad", 0) == 0 ? "value + gradient" : "fused launch autotuning",
                                     r.launch.c_str());
  if (checksum) std::printf("    output checksum: %016llx\n", (unsigned long long)r.outputHash);
  std::fflush(stdout);
}

void writeCsv(const std::string& path, const std::vector<Row>& rows, const std::string& device) {
  std::ofstream o(path);
  o << "model,path,parameters,batch,median_qps,min_qps,max_qps,device,stream_median_qps\n";
  for (const auto& r : rows) {
    o << r.model << ',' << r.path << ',' << r.params << ',' << r.batch << ',' << r.qps.median << ',' << r.qps.lo << ',' << r.qps.hi
      << ",\"" << device << "\",";
    if (r.streamQps.median > 0) o << r.streamQps.median;  // --batches only
    o << '\n';
  }
}

}  // namespace

int main(int argc, char** argv) {
  int batch = 1 << 21, reps = 20, gradientBatch = 1 << 16;
  std::vector<int> batches;
  bool rayOrdered = false;
  std::string csv, writeDir, only;
  bool checksum = false, gradient = false;
  std::string coldStartRoot;
  std::vector<std::string> files;
  CudaEvaluatorOptions fixed;
  for (CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--batch") batch = std::max(1, std::stoi(cl.value()));
    else if (a == "--reps") reps = std::max(1, std::stoi(cl.value()));
    else if (a == "--csv") csv = cl.value();
    else if (a == "--write-models") writeDir = cl.value();
    else if (a == "--only") only = cl.value();
    else if (a == "--weight-chunk") fixed.weightChunk = std::stoi(cl.value());
    else if (a == "--tile") fixed.tileQueries = std::stoi(cl.value());
    else if (a == "--wgmma-columns") fixed.wgmmaChunkColumns = std::stoi(cl.value());
    else if (a == "--ping-pong") fixed.wgmmaPingPong = std::stoi(cl.value()) ? 1 : 0;
    else if (a == "--wgmma-consumers") fixed.wgmmaConsumers = std::stoi(cl.value());
    else if (a == "--column-split") fixed.wgmmaColumnSplit = std::stoi(cl.value()) ? 1 : 0;
    else if (a == "--stored-encoding") fixed.storedEncoding = std::stoi(cl.value());
    else if (a == "--batches") {
      std::stringstream list(cl.value());
      for (std::string item; std::getline(list, item, ',');) batches.push_back(std::max(1, std::stoi(item)));
      std::sort(batches.begin(), batches.end());
    } else if (a == "--points") {
      const std::string m = cl.value();
      if (m != "random" && m != "rays") {
        std::fprintf(stderr, "gpu_evaluator_benchmark: --points takes random or rays, not '%s'\n", m.c_str());
        return 2;
      }
      rayOrdered = m == "rays";
    }
    else if (a == "--no-autotune") fixed.autotuneBatch = 0;
    else if (a == "--hash-pairs") fixed.hashGridPairs = std::stoi(cl.value()) ? 1 : 0;
    else if (a == "--l2-persist") fixed.hashTablesPersistInL2 = true;
    else if (a == "--checksum") checksum = true;
    else if (a == "--gradient") gradient = true;
    else if (a == "--gradient-batch") gradientBatch = std::max(1, std::stoi(cl.value()));
    else if (a == "--tangent-autotune-batch") fixed.tangentAutotuneBatch = std::stoi(cl.value());  // < 0: refused
    else if (a == "--generated") {
      const std::string g = cl.value();
      if (g == "off") fixed.generatedKernels = GeneratedKernelUse::Off;
      else if (g == "auto") fixed.generatedKernels = GeneratedKernelUse::Auto;
      else if (g == "only") fixed.generatedKernels = GeneratedKernelUse::Only;
      else {
        std::fprintf(stderr, "gpu_evaluator_benchmark: --generated takes off, auto or only, not '%s'\n", g.c_str());
        return 2;
      }
    }
    else if (a == "--kernel-cache") fixed.kernelCacheDir = cl.value();
    else if (a == "--cold-start") coldStartRoot = cl.value();
    else if (a == "--mma") {
      const std::optional<FusedMma> m = bench::parseMmaOption(cl.value(), "gpu_evaluator_benchmark");
      if (!m) return 2;
      fixed.mma = *m;
    }
    else files.push_back(a);
  }
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) {
    std::fprintf(stderr, "gpu_evaluator_benchmark: %s\n", dev.reason.c_str());
    return 1;
  }
  std::vector<std::pair<std::string, InrModel>> models;
  std::vector<std::uint8_t> bytes;
  auto synthetic = [&](const std::string& file, InrModel m) {
    if (!writeDir.empty()) {
      std::filesystem::create_directories(writeDir);
      std::ofstream(std::filesystem::path(writeDir) / file, std::ios::binary)
          .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    }
    models.emplace_back(file, std::move(m));
  };
  synthetic("paper_siren.inr", bench::sirenPaper(1, &bytes));
  synthetic("paper_ffn.inr", bench::ffnPaper(2, &bytes));
  synthetic("paper_coordnet.inr", bench::coordNetPaper(3, &bytes));
  {
    // The hash-grid network of issue 34's target: tiny-cuda-nn's HashGrid over x, y, z, t (16
    // levels x 2 features, 2^19 entries, base 16, x1.5 per level) into 2 x 64 ReLU.
    const test::HashGridOptions o = test::hashGridMlp(4, 16, 19, 16, 1.5, 64, 2);
    bytes = test::hashGridModelBytes(o);
    synthetic("paper_hashgrid.inr", test::load(bytes, "paper_hashgrid.inr"));
    // The same over x, y, z only (the form tiny-cuda-nn's published rates are for: 8 corners per
    // level instead of 16).
    const test::HashGridOptions o3 = test::hashGridMlp(3, 16, 19, 16, 1.5, 64, 2);
    bytes = test::hashGridModelBytes(o3);
    synthetic("paper_hashgrid3d.inr", test::load(bytes, "paper_hashgrid3d.inr"));
  }
  for (auto& m : loadModelFiles(files)) models.push_back(std::move(m));

  const char* pointsName = rayOrdered ? "ray-ordered points" : "random points";
  if (!coldStartRoot.empty()) {  // the cold start alone
    std::printf("GPU evaluator on %s: model load with the generated kernels in the background, batch %d, %d reps\n",
                dev.reason.c_str(), batch, reps);
    std::printf("%-24s %5s %10s %12s %12s %12s %12s %10s\n", "model", "cache", "off s", "construct s", "ready s",
                "Gq/s before", "Gq/s after", "runs");
    std::vector<ColdStartRow> rows;
    int index = 0;
    for (const auto& [name, model] : models) {
      if (!only.empty() && name.find(only) == std::string::npos) continue;
      const std::string dir = coldStartRoot + "/model-" + std::to_string(index++);
      std::filesystem::remove_all(dir);
      for (const bool warm : {false, true}) {
        try {
          rows.push_back(measureColdStart(model, name, batch, reps, fixed, dir, warm));
        } catch (const std::exception& e) {
          std::fprintf(stderr, "%s: %s\n", name.c_str(), e.what());
          break;
        }
        const ColdStartRow& r = rows.back();
        std::printf("%-24s %5s %10.3f %12.3f %12.3f %12.4f %12.4f %10s\n    %s\n", r.model.c_str(), r.cache.c_str(),
                    r.offSeconds, r.constructSeconds, r.readySeconds, r.qpsBefore / 1e9, r.qpsAfter / 1e9,
                    r.generatedKept ? "generated" : "built-in", r.report.c_str());
        std::fflush(stdout);
      }
    }
    if (!csv.empty()) {
      std::ofstream out(csv);
      out << "model,cache,off_construct_s,construct_s,ready_s,qps_before,qps_after,runs,device,report\n";
      for (const ColdStartRow& r : rows)
        out << r.model << ',' << r.cache << ',' << r.offSeconds << ',' << r.constructSeconds << ',' << r.readySeconds << ','
            << r.qpsBefore << ',' << r.qpsAfter << ',' << (r.generatedKept ? "generated" : "built-in") << ",\"" << dev.name
            << "\",\"" << r.report << "\"\n";
    }
    return 0;
  }
  if (!batches.empty()) {  // the batch-size sweep alone
    std::printf("GPU evaluator on %s, batch sizes swept, %s, %d reps (median of CUDA-event timings)\n", dev.reason.c_str(),
                pointsName, reps);
    std::printf("(a launch alone, and %d queued back to back as a frame queues them)\n", kLaunchesInRow);
    std::printf("%-28s %9s %12s %12s %12s %16s %14s %16s\n", "model", "batch", "median Gq/s", "min", "max", "of the largest",
                "queued Gq/s", "of the largest");
    std::vector<Row> rows;
    for (const auto& [name, model] : models) {
      if (!only.empty() && name.find(only) == std::string::npos) continue;
      std::vector<Row> sweep;
      try {
        sweep = measureBatches(model, name, batches, reps, fixed, rayOrdered);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", name.c_str(), e.what());
        continue;
      }
      for (const Row& r : sweep)
        std::printf("%-28s %9d %12.4f %12.4f %12.4f %15.0f%% %14.4f %15.0f%%\n", r.model.c_str(), r.batch, r.qps.median / 1e9,
                    r.qps.lo / 1e9, r.qps.hi / 1e9, 100.0 * r.qps.median / sweep.back().qps.median, r.streamQps.median / 1e9,
                    100.0 * r.streamQps.median / sweep.back().streamQps.median);
      std::printf("    fused launch autotuning: %s\n", sweep.front().launch.c_str());
      std::fflush(stdout);
      rows.insert(rows.end(), sweep.begin(), sweep.end());
    }
    if (!csv.empty()) writeCsv(csv, rows, dev.name);
    return 0;
  }
  std::printf("GPU evaluator on %s, batch %d, %s, %d reps (median of CUDA-event timings)\n", dev.reason.c_str(), batch,
              pointsName, reps);
  std::printf("%-28s %-16s %9s %12s %12s %12s\n", "model", "path", "params", "median Gq/s", "min", "max");
  std::vector<Row> rows;
  const bool fixedConfig = fixed.mma != FusedMma::Auto || fixed.tileQueries || fixed.weightChunk || fixed.wgmmaPingPong >= 0 || fixed.wgmmaChunkColumns || fixed.wgmmaConsumers || fixed.wgmmaColumnSplit >= 0 || !fixed.autotuneBatch ||
                          fixed.hashGridPairs >= 0 || fixed.storedEncoding >= 0 ||
                          fixed.generatedKernels == GeneratedKernelUse::Only;
  for (const auto& [name, model] : models)
    for (int variant = 0; variant < 5; ++variant) {
      if (!only.empty() && name.find(only) == std::string::npos) continue;
      if (variant >= 3) {  // value + gradient: per-thread, then fused tangent rows
        if (!gradient) continue;
        const bool perThread = variant == 3;
        try {
          rows.push_back(measureGradient(model, name, perThread ? CudaGradientPath::PerThread : CudaGradientPath::Auto,
                                         gradientBatch, perThread ? std::min(reps, 5) : reps, fixed));
        } catch (const std::exception& e) {
          std::fprintf(stderr, "%s: %s\n", name.c_str(), e.what());
          continue;
        }
        printRow(rows.back(), checksum);
        continue;
      }
      const CudaEvaluatorPath p = variant == 2 ? CudaEvaluatorPath::Generic : CudaEvaluatorPath::Auto;
      CudaEvaluatorOptions o = fixed;
      if (variant == 1) o.mma = FusedMma::MmaSync;
      // The mma.sync row only where the autotuned fused row ran the wgmma kernel; a fixed
      // configuration gives its fused row alone.
      if (variant == 1 && (fixedConfig || rows.empty() || rows.back().model != name ||
                           rows.back().launch.find("-> wgmma") == std::string::npos))
        continue;
      if (variant == 2 && fixedConfig) continue;
      Row r;
      try {
        r = measure(model, name, p, batch, reps, o, rayOrdered);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", name.c_str(), e.what());
        continue;
      }
      printRow(r, checksum);
      rows.push_back(r);
    }
  if (!csv.empty()) writeCsv(csv, rows, dev.name);
  return 0;
}
