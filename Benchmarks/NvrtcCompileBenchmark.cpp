// NVRTC's time for the kernels generated per network (issue 50: "cold compile at load <= 2 s per
// model"): each kernel the evaluator generates at model load (Evaluator/MlpKernelSource.h,
// generateModelKernels; one NVRTC program per kernel, as Cuda/GeneratedKernels.cu compiles them)
// through Cuda/NvrtcCompiler.h, one kernel at a time or on a pool of threads as the evaluator
// does. Needs no GPU: a cubin for a real architecture (sm_XY) is NVVM and ptxas, PTX for a
// virtual one (compute_XY) is NVVM alone.
//   nvrtc_compile_benchmark [--arch sm_90|compute_90|...] [--kernels all|T:KC:values|tangents,...]
//                           [--threads N] [--csv FILE] [MODEL ...]
// MODEL: siren, ffn, coordnet (the paper-size architectures, Kernels/TestSupport/
// PaperArchitectures.h), siren-depth-N (the paper SIREN with N hidden layers: how the time grows
// with depth) or an .inr file; default the three paper networks. --kernels all (the
// default) is the evaluator's whole set: tiles 128, 64, 32 x weight chunks 64, 32 x values and
// tangent rows, of the program and, where it fuses a Fourier encoding, of its stored form too;
// a list such as 32:32:values,32:32:tangents picks kernels (of every form). --threads 1 (the
// default) gives each kernel's time alone; --threads N the wall time of a load on N cores.
// Prints a row per kernel (seconds, image size, NVRTC's verdict) and per model (sum, slowest,
// wall), and writes them to --csv.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "Evaluator/Cuda/NvrtcCompiler.h"
#include "Evaluator/MlpKernelSource.h"
#include "Evaluator/MlpProgram.h"
#include "TestSupport/PaperArchitectures.h"

namespace {

using namespace inr;

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr,
               "nvrtc_compile_benchmark: %s\nusage: nvrtc_compile_benchmark [--arch sm_90|compute_90|...] "
               "[--kernels all|T:KC:values|tangents,...] [--threads N] [--csv FILE] [siren|ffn|coordnet|siren-depth-N|MODEL.inr ...]\n",
               why.c_str());
  std::exit(2);
}

// "32:32:tangents" -> {tile 32, chunk 32, tangent rows} (form set per model).
GeneratedKernelSpec parseKernel(const std::string& text) {
  GeneratedKernelSpec k;
  char kind[16] = {0};
  if (std::sscanf(text.c_str(), "%d:%d:%15s", &k.tile, &k.kc, kind) != 3 ||
      (std::string(kind) != "values" && std::string(kind) != "tangents"))
    usage("--kernels takes all or TILE:CHUNK:values|tangents entries, not '" + text + "'");
  if (k.tile != 128 && k.tile != 64 && k.tile != 32) usage("a kernel's tile is 128, 64 or 32, not " + std::to_string(k.tile));
  if (k.kc != 64 && k.kc != 32) usage("a kernel's weight chunk is 64 or 32, not " + std::to_string(k.kc));
  k.tangents = std::string(kind) == "tangents";
  return k;
}

struct Row {
  std::string model, kernel;
  double seconds = 0.0;
  std::size_t bytes = 0;
  bool ok = false;
  std::string error;
};

}  // namespace

int main(int argc, char** argv) {
  std::string arch = "sm_90", csvPath;
  std::vector<GeneratedKernelSpec> picked;  // empty: all
  unsigned threads = 1;
  std::vector<std::string> models;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--arch") {
      arch = value();
      if (arch.rfind("sm_", 0) != 0 && arch.rfind("compute_", 0) != 0) usage("--arch takes sm_XY or compute_XY, not '" + arch + "'");
    } else if (a == "--kernels") {
      const std::string list = value();
      if (list != "all") {
        std::stringstream s(list);
        for (std::string item; std::getline(s, item, ',');) picked.push_back(parseKernel(item));
      }
    } else if (a == "--threads") {
      const int n = std::atoi(value().c_str());
      if (n < 1) usage("--threads takes a positive count");
      threads = unsigned(n);
    } else if (a == "--csv") {
      csvPath = value();
    } else if (a.rfind("--", 0) == 0) {
      usage("unknown option " + a);
    } else {
      models.push_back(a);
    }
  }
  if (models.empty()) models = {"siren", "ffn", "coordnet"};
  std::printf("NVRTC %s, %s, %u thread%s; kernels: %s\n", cuda::nvrtcVersionString().c_str(), arch.c_str(), threads,
              threads == 1 ? "" : "s", picked.empty() ? "the evaluator's whole set" : "as listed");
  std::vector<Row> rows;
  std::vector<std::string> summaries;
  for (const std::string& name : models) {
    InrModel model;
    try {
      int depth = 0;
      if (std::sscanf(name.c_str(), "siren-depth-%d", &depth) == 1) {
        if (depth < 1 || depth > 60) usage("siren-depth-N takes 1 to 60 hidden layers, not " + std::to_string(depth));
        model = bench::sirenOfDepth(depth);
      } else
      model = name == "siren" ? bench::sirenPaper()
              : name == "ffn" ? bench::ffnPaper()
              : name == "coordnet" ? bench::coordNetPaper()
                                   : InrModel::loadFile(name);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "nvrtc_compile_benchmark: %s: %s\n", name.c_str(), e.what());
      return 1;
    }
    const MlpProgram program = MlpProgram::compile(model.architecture);
    ModelKernelSource all;
    try {
      all = generateModelKernels(program);
    } catch (const std::invalid_argument& e) {
      std::printf("%-12s no generated kernels: %s\n", name.c_str(), e.what());
      continue;
    }
    std::vector<GeneratedKernelSpec> kernels;
    for (const GeneratedKernelSpec& k : all.kernels)
      if (picked.empty() || std::any_of(picked.begin(), picked.end(), [&](const GeneratedKernelSpec& p) {
            return p.tile == k.tile && p.kc == k.kc && p.tangents == k.tangents;
          }))
        kernels.push_back(k);
    std::vector<Row> mine(kernels.size());
    std::size_t next = 0;
    std::mutex m;
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < std::min<std::size_t>(threads, kernels.size()); ++t)
      pool.emplace_back([&] {
        for (;;) {
          std::size_t j;
          {
            std::lock_guard<std::mutex> lock(m);
            if (next >= kernels.size()) return;
            j = next++;
          }
          const GeneratedKernelSpec& k = kernels[j];
          const std::string kernelName = generatedKernelName(k);
          const cuda::NvrtcOutput out =
              cuda::compileWithNvrtc(generateFusedKernelSource(all.forms, {k}), kernelName + ".cu", arch);
          Row& r = mine[j];
          r.model = name;
          r.kernel = kernelName;
          r.seconds = out.seconds;
          r.bytes = out.image.size();
          r.ok = out.ok;
          r.error = out.ok ? "" : cuda::firstLogLines(out.error, 1);
          std::lock_guard<std::mutex> lock(m);
          std::printf("%-12s %-34s %7.2f s  %6zu KB%s%s\n", name.c_str(), kernelName.c_str(), r.seconds, r.bytes / 1024,
                      r.ok ? "" : "  FAILED: ", r.error.c_str());
          std::fflush(stdout);
        }
      });
    for (std::thread& t : pool) t.join();
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    double sum = 0.0, slowest = 0.0;
    for (const Row& r : mine) {
      sum += r.seconds;
      slowest = std::max(slowest, r.seconds);
    }
    char line[256];
    std::snprintf(line, sizeof line, "%-12s %2zu kernels: sum %7.2f s, slowest %6.2f s, wall %7.2f s on %u thread%s", name.c_str(),
                  mine.size(), sum, slowest, wall, threads, threads == 1 ? "" : "s");
    std::printf("%s\n", line);
    summaries.push_back(line);
    rows.insert(rows.end(), mine.begin(), mine.end());
  }
  std::printf("\n");
  for (const std::string& s : summaries) std::printf("%s\n", s.c_str());
  if (!csvPath.empty()) {
    std::ofstream csv(csvPath);
    if (!csv) {
      std::fprintf(stderr, "nvrtc_compile_benchmark: cannot write %s\n", csvPath.c_str());
      return 1;
    }
    csv << "model,kernel,arch,threads,seconds,image_bytes,ok\n";
    for (const Row& r : rows)
      csv << r.model << "," << r.kernel << "," << arch << "," << threads << "," << r.seconds << "," << r.bytes << "," << r.ok << "\n";
  }
  return std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.ok; }) ? 0 : 1;
}
