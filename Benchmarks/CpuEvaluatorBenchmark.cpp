// CPU evaluator throughput (queries/s) on the paper-size architectures and on model files.
//   cpu_evaluator_benchmark [--batch N] [--reps R] [--threads T] [--csv FILE] [MODEL.inr ...]
// With no model files it also runs every *.inr in Testing/Data/models. Prints a table; the CSV
// has one row per model with the median and the min/max over repetitions.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <omp.h>
#include <string>
#include <vector>

#include "BenchmarkSupport.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "TestSupport/PaperArchitectures.h"
#include "TestSupport/ShippedModels.h"

using namespace inr;
using namespace inr::bench;

namespace {

struct Row {
  std::string name;
  std::size_t params;
  Spread qps;  // queries per second over the repetitions
};

Row measure(const InrModel& model, const std::string& name, int batch, int reps, int threads) {
  CpuEvaluatorOptions opts;
  opts.threads = threads;
  const CpuInrEvaluator eval(model, opts);
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, batch, 42);
  std::vector<float> out(batch);
  eval.evaluate(pts.data(), std::min<std::size_t>(pts.size(), 4096), out.data());  // warm-up
  std::vector<double> rates;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    eval.evaluate(pts.data(), pts.size(), out.data());
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rates.push_back(batch / s);
  }
  return {name, model.architecture.parameterCount(), spreadOf(rates)};
}

}  // namespace

int main(int argc, char** argv) {
  int batch = 1 << 16, reps = 5, threads = 0;
  std::string csv;
  std::vector<std::string> files;
  for (CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--batch") batch = std::max(1, std::stoi(cl.value()));
    else if (a == "--reps") reps = std::max(1, std::stoi(cl.value()));
    else if (a == "--threads") threads = std::stoi(cl.value());
    else if (a == "--csv") csv = cl.value();
    else if (a == "--help") {
      std::puts("usage: cpu_evaluator_benchmark [--batch N] [--reps R] [--threads T] [--csv FILE] [MODEL.inr ...]");
      return 0;
    } else files.push_back(a);
  }
  if (files.empty()) files = test::shippedModels();
  const int nthreads = threads > 0 ? threads : omp_get_max_threads();
  std::printf("CPU evaluator (Eigen fp32), batch %d, %d reps, %d threads\n", batch, reps, nthreads);
  std::printf("%-34s %10s %14s %14s %14s\n", "model", "params", "median q/s", "min q/s", "max q/s");
  std::vector<Row> rows;
  auto report = [&](const Row& r) {
    std::printf("%-34s %10zu %14.4g %14.4g %14.4g\n", r.name.c_str(), r.params, r.qps.median, r.qps.lo, r.qps.hi);
    std::fflush(stdout);
    rows.push_back(r);
  };
  report(measure(bench::sirenPaper(), "SIREN 4->256x5->1 (synthetic)", batch, reps, threads));
  report(measure(bench::ffnPaper(), "FFN 256ff 5x256 SiLU (synthetic)", batch, reps, threads));
  report(measure(bench::coordNetPaper(), "CoordNet init48 6res (synthetic)", batch, reps, threads));
  for (const auto& f : files) {
    try {
      report(measure(InrModel::loadFile(f), std::filesystem::path(f).filename().string(), batch, reps, threads));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", f.c_str(), e.what());
    }
  }
  if (!csv.empty()) {
    std::ofstream o(csv);
    o << "model,parameters,threads,batch,median_qps,min_qps,max_qps\n";
    for (const auto& r : rows)
      o << '"' << r.name << "\"," << r.params << ',' << nthreads << ',' << batch << ',' << r.qps.median << ','
        << r.qps.lo << ',' << r.qps.hi << '\n';
    std::printf("wrote %s\n", csv.c_str());
  }
  return 0;
}
