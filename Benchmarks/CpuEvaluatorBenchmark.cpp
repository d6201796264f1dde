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
#include <random>
#include <string>
#include <vector>

#include "Evaluator/CpuInrEvaluator.h"
#include "PaperArchitectures.h"

using namespace inr;

namespace {

struct Row {
  std::string name;
  std::size_t params;
  double median, lo, hi;
};

Row measure(const InrModel& model, const std::string& name, int batch, int reps, int threads) {
  CpuEvaluatorOptions opts;
  opts.threads = threads;
  const CpuInrEvaluator eval(model, opts);
  std::mt19937 rng(42);
  const auto& b = model.domain.bounds;
  std::vector<QueryPoint> pts(batch);
  for (auto& p : pts) {
    auto u = [&](double lo, double hi) { return float(std::uniform_real_distribution<double>(lo, hi)(rng)); };
    p = {u(b[0], b[1]), u(b[2], b[3]), u(b[4], b[5]), u(model.domain.timeBegin, model.domain.timeEnd)};
  }
  std::vector<float> out(batch);
  eval.evaluate(pts.data(), std::min<std::size_t>(pts.size(), 4096), out.data());  // warm-up
  std::vector<double> rates;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    eval.evaluate(pts.data(), pts.size(), out.data());
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rates.push_back(batch / s);
  }
  std::sort(rates.begin(), rates.end());
  return {name, model.architecture.parameterCount(), rates[rates.size() / 2], rates.front(), rates.back()};
}

}  // namespace

int main(int argc, char** argv) {
  int batch = 1 << 16, reps = 5, threads = 0;
  std::string csv;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--batch") batch = std::max(1, std::stoi(next()));
    else if (a == "--reps") reps = std::max(1, std::stoi(next()));
    else if (a == "--threads") threads = std::stoi(next());
    else if (a == "--csv") csv = next();
    else if (a == "--help") {
      std::puts("usage: cpu_evaluator_benchmark [--batch N] [--reps R] [--threads T] [--csv FILE] [MODEL.inr ...]");
      return 0;
    } else files.push_back(a);
  }
  if (files.empty()) {
    const std::filesystem::path dir = std::filesystem::path(INR_SOURCE_DIR) / "Testing/Data/models";
    if (std::filesystem::exists(dir))
      for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.path().extension() == ".inr") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
  }
  const int nthreads = threads > 0 ? threads : omp_get_max_threads();
  std::printf("CPU evaluator (Eigen fp32), batch %d, %d reps, %d threads\n", batch, reps, nthreads);
  std::printf("%-34s %10s %14s %14s %14s\n", "model", "params", "median q/s", "min q/s", "max q/s");
  std::vector<Row> rows;
  auto report = [&](const Row& r) {
    std::printf("%-34s %10zu %14.4g %14.4g %14.4g\n", r.name.c_str(), r.params, r.median, r.lo, r.hi);
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
      o << '"' << r.name << "\"," << r.params << ',' << nthreads << ',' << batch << ',' << r.median << ',' << r.lo
        << ',' << r.hi << '\n';
    std::printf("wrote %s\n", csv.c_str());
  }
  return 0;
}
