// CPU evaluator throughput (queries/s) on the paper-size architectures and on model files.
//   cpu_evaluator_benchmark [--batch N] [--reps R] [--threads T] [--gradient] [--csv FILE] [MODEL.inr ...]
// With no model files it also runs every *.inr in Testing/Data/models. Prints a table; the CSV
// has one row per model with the median and the min/max over repetitions. --gradient also times
// evaluateWithGradient (value and world-space gradient in one pass) on the same points and
// prints its rate and its cost relative to the value alone (the CSV gains those two columns).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <omp.h>
#include <optional>
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
  std::optional<Spread> gradientQps;  // evaluateWithGradient, with --gradient
};

// Queries per second of `pass` (one call over all points) over the repetitions, after a warm-up.
template <class Pass>
Spread timeQueries(std::size_t batch, int reps, Pass pass) {
  pass(std::min<std::size_t>(batch, 4096));  // warm-up
  std::vector<double> rates;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    pass(batch);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rates.push_back(batch / s);
  }
  return spreadOf(rates);
}

Row measure(const InrModel& model, const std::string& name, int batch, int reps, int threads, bool gradient) {
  CpuEvaluatorOptions opts;
  opts.threads = threads;
  const CpuInrEvaluator eval(model, opts);
  const std::vector<QueryPoint> pts = test::randomQueryPoints(model, batch, 42);
  std::vector<float> out(batch), gradients;
  Row row{name, model.architecture.parameterCount(),
          timeQueries(pts.size(), reps, [&](std::size_t n) { eval.evaluate(pts.data(), n, out.data()); }), {}};
  if (gradient) {
    gradients.resize(3 * pts.size());
    row.gradientQps = timeQueries(pts.size(), reps, [&](std::size_t n) {
      eval.evaluateWithGradient(pts.data(), n, out.data(), gradients.data());
    });
  }
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int batch = 1 << 16, reps = 5, threads = 0;
  bool gradient = false;
  std::string csv;
  std::vector<std::string> files;
  for (CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--batch") batch = std::max(1, std::stoi(cl.value()));
    else if (a == "--reps") reps = std::max(1, std::stoi(cl.value()));
    else if (a == "--threads") threads = std::stoi(cl.value());
    else if (a == "--gradient") gradient = true;
    else if (a == "--csv") csv = cl.value();
    else if (a == "--help") {
      std::puts("usage: cpu_evaluator_benchmark [--batch N] [--reps R] [--threads T] [--gradient] [--csv FILE] "
                "[MODEL.inr ...]");
      return 0;
    } else files.push_back(a);
  }
  if (files.empty()) files = test::shippedModels();
  const int nthreads = threads > 0 ? threads : omp_get_max_threads();
  std::printf("CPU evaluator (Eigen fp32), batch %d, %d reps, %d threads\n", batch, reps, nthreads);
  std::printf("%-34s %10s %14s %14s %14s", "model", "params", "median q/s", "min q/s", "max q/s");
  if (gradient) std::printf(" %14s %10s", "+grad q/s", "grad cost");
  std::printf("\n");
  std::vector<Row> rows;
  auto report = [&](const Row& r) {
    std::printf("%-34s %10zu %14.4g %14.4g %14.4g", r.name.c_str(), r.params, r.qps.median, r.qps.lo, r.qps.hi);
    // grad cost: time of value + gradient over time of value alone (median rates)
    if (r.gradientQps) std::printf(" %14.4g %9.2fx", r.gradientQps->median, r.qps.median / r.gradientQps->median);
    std::printf("\n");
    std::fflush(stdout);
    rows.push_back(r);
  };
  report(measure(bench::sirenPaper(), "SIREN 4->256x5->1 (synthetic)", batch, reps, threads, gradient));
  report(measure(bench::ffnPaper(), "FFN 256ff 5x256 SiLU (synthetic)", batch, reps, threads, gradient));
  report(measure(bench::coordNetPaper(), "CoordNet init48 6res (synthetic)", batch, reps, threads, gradient));
  for (const auto& f : files) {
    try {
      report(measure(InrModel::loadFile(f), std::filesystem::path(f).filename().string(), batch, reps, threads, gradient));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", f.c_str(), e.what());
    }
  }
  if (!csv.empty()) {
    std::ofstream o(csv);
    o << "model,parameters,threads,batch,median_qps,min_qps,max_qps" << (gradient ? ",gradient_median_qps,gradient_cost" : "")
      << '\n';
    for (const auto& r : rows) {
      o << '"' << r.name << "\"," << r.params << ',' << nthreads << ',' << batch << ',' << r.qps.median << ','
        << r.qps.lo << ',' << r.qps.hi;
      if (r.gradientQps) o << ',' << r.gradientQps->median << ',' << r.qps.median / r.gradientQps->median;
      o << '\n';
    }
    std::printf("wrote %s\n", csv.c_str());
  }
  return 0;
}
