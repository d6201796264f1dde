// GPU evaluator throughput (queries/s): the fused tensor-core kernel and the generic fp32 path
// on the paper-size architectures and on model files, timed with CUDA events (median of R
// launches over one batch of N random world points already on the device).
//   gpu_evaluator_benchmark [--batch N] [--reps R] [--csv FILE] [--write-models DIR] [MODEL.inr ...]
// --write-models saves the synthetic paper architectures as .inr files so the PyTorch baseline
// (Benchmarks/pytorch_baseline.py) runs the very same networks.
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "Cuda/CudaCheck.h"
#include "Cuda/CudaDevice.h"
#include "Cuda/CudaInrEvaluator.h"
#include "PaperArchitectures.h"

using namespace inr;

namespace {

struct Row {
  std::string model, path, launch;
  std::size_t params;
  double median, lo, hi;
};

Row measure(const InrModel& model, const std::string& name, CudaEvaluatorPath path, int batch, int reps) {
  CudaEvaluatorOptions o;
  o.path = path;
  const CudaInrEvaluator eval(model, o);
  std::mt19937 rng(1);
  const auto& b = model.domain.bounds;
  std::vector<float4> pts(batch);
  for (auto& p : pts) {
    auto u = [&](double lo, double hi) { return float(std::uniform_real_distribution<double>(lo, hi)(rng)); };
    p = make_float4(u(b[0], b[1]), u(b[2], b[3]), u(b[4], b[5]), u(model.domain.timeBegin, model.domain.timeEnd));
  }
  float4* dPts;
  float* dOut;
  INR_CUDA_CHECK(cudaMalloc(&dPts, sizeof(float4) * batch));
  INR_CUDA_CHECK(cudaMalloc(&dOut, sizeof(float) * batch));
  INR_CUDA_CHECK(cudaMemcpy(dPts, pts.data(), sizeof(float4) * batch, cudaMemcpyHostToDevice));
  cudaEvent_t e0, e1;
  cudaEventCreate(&e0);
  cudaEventCreate(&e1);
  eval.evaluateDevice(dPts, batch, dOut, nullptr, nullptr);  // warm-up
  INR_CUDA_CHECK(cudaDeviceSynchronize());
  std::vector<double> rates;
  for (int r = 0; r < reps; ++r) {
    cudaEventRecord(e0);
    eval.evaluateDevice(dPts, batch, dOut, nullptr, nullptr);
    cudaEventRecord(e1);
    INR_CUDA_CHECK(cudaEventSynchronize(e1));
    float ms = 0;
    cudaEventElapsedTime(&ms, e0, e1);
    rates.push_back(batch / (ms * 1e-3));
  }
  cudaEventDestroy(e0);
  cudaEventDestroy(e1);
  cudaFree(dPts);
  cudaFree(dOut);
  std::sort(rates.begin(), rates.end());
  return {name, path == CudaEvaluatorPath::Generic ? "generic-fp32" : "fused-fp16", eval.launchReport(),
          model.architecture.parameterCount(), rates[rates.size() / 2], rates.front(), rates.back()};
}

}  // namespace

int main(int argc, char** argv) {
  int batch = 1 << 21, reps = 20;
  std::string csv, writeDir;
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
    else if (a == "--csv") csv = next();
    else if (a == "--write-models") writeDir = next();
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
  for (const auto& f : files) models.emplace_back(std::filesystem::path(f).filename().string(), InrModel::loadFile(f));

  std::printf("GPU evaluator on %s, batch %d, %d reps (median of CUDA-event timings)\n", dev.reason.c_str(), batch, reps);
  std::printf("%-28s %-13s %9s %12s %12s %12s\n", "model", "path", "params", "median Gq/s", "min", "max");
  std::vector<Row> rows;
  for (const auto& [name, model] : models)
    for (CudaEvaluatorPath p : {CudaEvaluatorPath::Auto, CudaEvaluatorPath::Generic}) {
      Row r;
      try {
        r = measure(model, name, p, batch, reps);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: %s\n", name.c_str(), e.what());
        continue;
      }
      std::printf("%-28s %-13s %9zu %12.4f %12.4f %12.4f\n", r.model.c_str(), r.path.c_str(), r.params, r.median / 1e9,
                  r.lo / 1e9, r.hi / 1e9);
      if (!r.launch.empty()) std::printf("    fused launch autotuning: %s\n", r.launch.c_str());
      std::fflush(stdout);
      rows.push_back(r);
    }
  if (!csv.empty()) {
    std::ofstream o(csv);
    o << "model,path,parameters,batch,median_qps,min_qps,max_qps,device\n";
    for (const auto& r : rows)
      o << r.model << ',' << r.path << ',' << r.params << ',' << batch << ',' << r.median << ',' << r.lo << ',' << r.hi
        << ",\"" << dev.name << "\"\n";
  }
  return 0;
}
