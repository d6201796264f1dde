// The reader's preview grid (what ParaView's own filters see of the network, issue 48 item 3): the
// time to evaluate an r^3 grid over each model's box through PreviewEvaluator, chunk by chunk as
// the reader does, on the backends asked for. Prints a table and writes CSV (--csv).
//
//   preview_grid_benchmark [--resolutions 64,128,256] [--backends auto,cpu] [--reps 3] [--csv OUT]
//                          MODEL.inr ...
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "Backends/PreviewEvaluator.h"
#include "BenchmarkSupport.h"

namespace {

const char* kUsage =
    "preview_grid_benchmark [--resolutions 64,128,256] [--backends auto,cpu] [--reps 3] [--csv OUT] MODEL.inr ...\n"
    "  Evaluates each model on an r^3 grid over its box, in the reader's chunks, per backend; median of --reps.\n";

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace inr;
  std::vector<int> resolutions = {64, 128, 256};
  std::vector<std::string> backends = {"auto", "cpu"}, paths;
  int reps = 3;
  std::string csvPath;
  for (bench::CommandLine cl(argc, argv); !cl.done();) {
    const std::string a = cl.next();
    if (a == "--resolutions") {
      resolutions.clear();
      for (const auto& r : split(cl.value())) resolutions.push_back(std::stoi(r));
    } else if (a == "--backends") {
      backends = split(cl.value());
    } else if (a == "--reps") {
      reps = std::max(1, std::stoi(cl.value()));
    } else if (a == "--csv") {
      csvPath = cl.value();
    } else if (const int status = cl.other(a, kUsage, paths); status >= 0) {
      return status;
    }
  }
  if (paths.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  std::ofstream csv;
  if (!csvPath.empty()) {
    csv.open(csvPath);
    csv << "model,backend_asked,backend_in_use,resolution,points,chunks,first_ms,median_ms,min_ms,max_ms,mpoints_per_s\n";
  }
  std::printf("%-34s %-6s %-44s %5s %10s %10s %10s %10s\n", "model", "asked", "in use", "r", "points", "first ms",
              "median ms", "M pts/s");
  for (const auto& [name, model] : bench::loadModelFiles(paths)) {
    for (const std::string& b : backends) {
      PreviewEvaluatorOptions o;
      o.backend = parseRenderBackend(b);
      PreviewEvaluator preview(model, o);
      for (const int r : resolutions) {
        const std::size_t n = std::size_t(r) * r * r;
        const auto& d = model.domain.bounds;
        const float t = float(0.5 * (model.domain.timeBegin + model.domain.timeEnd));
        // The reader's points: node-centred over the box (vtkImageData's origin and spacing).
        std::vector<QueryPoint> p(n);
        std::size_t k = 0;
        for (int z = 0; z < r; ++z)
          for (int y = 0; y < r; ++y)
            for (int x = 0; x < r; ++x, ++k)
              p[k] = QueryPoint{float(d[0] + x * ((d[1] - d[0]) / (r - 1))), float(d[2] + y * ((d[3] - d[2]) / (r - 1))),
                                float(d[4] + z * ((d[5] - d[4]) / (r - 1))), t};
        std::vector<float> values(n);
        std::vector<double> ms;
        std::size_t chunks = 0;
        for (int rep = 0; rep <= reps; ++rep) {  // rep 0: the first grid (chunk set-up, caches)
          const auto t0 = std::chrono::steady_clock::now();
          const std::size_t chunk = preview.chunkPoints(n);
          chunks = 0;
          for (std::size_t first = 0; first < n; first += chunk, ++chunks)
            preview.evaluate(p.data() + first, std::min(chunk, n - first), values.data() + first);
          ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
        const double first = ms.front();
        ms.erase(ms.begin());
        const bench::Spread s = bench::spreadOf(ms);
        std::printf("%-34s %-6s %-44.44s %5d %10zu %10.1f %10.1f %10.1f\n", name.c_str(), b.c_str(),
                    preview.description().c_str(), r, n, first, s.median, n / s.median / 1e3);
        std::fflush(stdout);
        if (csv)
          csv << name << "," << b << ",\"" << preview.description() << "\"," << r << "," << n << "," << chunks << ","
              << first << "," << s.median << "," << s.lo << "," << s.hi << "," << n / s.median / 1e3 << "\n";
      }
    }
  }
  return 0;
}
