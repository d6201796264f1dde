#include "Evaluator/Cuda/GeneratedKernels.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <mutex>
#include <thread>

#include "Evaluator/Cuda/NvrtcCompiler.h"
#include "Evaluator/MlpKernelSource.h"

namespace inr::cuda {
namespace {

// FNV-1a, 64 bits: a cache file name, not a security hash (a collision would need two kernels
// whose sources and options hash alike; the file holds one kernel of one name, checked on load).
std::uint64_t fnv1a(const std::string& text, std::uint64_t h = 1469598103934665603ull) {
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

// The part of the key every kernel of this binary shares: the embedded headers (a rebuilt binary
// with other device code must not load an older cubin), NVRTC's version.
std::uint64_t headersKey() {
  static const std::uint64_t key = [] {
    std::uint64_t h = fnv1a(nvrtcVersionString());
    for (const RtcHeader& header : embeddedDeviceHeaders()) h = fnv1a(std::string(header.name) + "\n" + header.text, h);
    return h;
  }();
  return key;
}

std::string hex(std::uint64_t v) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(v));
  return text;
}

bool readFile(const std::filesystem::path& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream s;
  s << in.rdbuf();
  out = s.str();
  return !out.empty();
}

// Written under a temporary name and renamed, so a concurrent reader sees the whole file or none.
void writeFile(const std::filesystem::path& path, const std::string& data) {
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  const std::filesystem::path tmp = path.string() + ".tmp" + std::to_string(std::hash<std::thread::id>{}(std::this_thread::get_id()));
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) return;  // an unwritable cache only costs the next load a compilation
    out.write(data.data(), std::streamsize(data.size()));
    if (!out) return;
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) std::filesystem::remove(tmp, ec);
}

}  // namespace

std::string defaultKernelCacheDir() {
  if (const char* dir = std::getenv("INR_KERNEL_CACHE_DIR"); dir && *dir) return dir;
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return std::string(xdg) + "/inr-volume/kernels";
  if (const char* home = std::getenv("HOME"); home && *home) return std::string(home) + "/.cache/inr-volume/kernels";
  return "";
}

struct GeneratedKernels::Loaded {
  GeneratedKernelSpec spec;
  cudaLibrary_t library = nullptr;
  FusedKernel kernel = nullptr;
  Loaded() = default;
  Loaded(const Loaded&) = delete;
  Loaded& operator=(const Loaded&) = delete;
  ~Loaded() {
    if (library) cudaLibraryUnload(library);
  }
};

GeneratedKernels::GeneratedKernels(const MlpProgram& program, int major, int minor, const std::string& cacheDirOption,
                                   const std::vector<int>& tiles, const std::vector<int>& chunks) {
  const auto start = std::chrono::steady_clock::now();
  const std::string arch = "sm_" + std::to_string(major) + std::to_string(minor);
  ModelKernelSource all;
  try {
    all = generateModelKernels(program, tiles, chunks);
  } catch (const std::invalid_argument& e) {
    report_ = std::string("not generated: ") + e.what();
    return;
  }
  const std::string cacheDir = cacheDirOption.empty() ? defaultKernelCacheDir() : cacheDirOption == "none" ? "" : cacheDirOption;
  // One NVRTC program per kernel (its source: the program forms and that kernel), so they
  // compile in parallel and each is cached alone.
  struct Job {
    GeneratedKernelSpec spec;
    std::string source, name, image, error;
    std::filesystem::path cached;
    bool fromCache = false;
  };
  std::vector<Job> jobs;
  for (const GeneratedKernelSpec& k : all.kernels) {
    Job j;
    j.spec = k;
    j.name = generatedKernelName(k);
    j.source = generateFusedKernelSource(all.forms, {k});
    std::string options;
    for (const std::string& o : generatedKernelOptions(arch)) options += o + "\n";
    const std::uint64_t key = fnv1a(j.source + "\n" + options, headersKey());
    if (!cacheDir.empty()) {
      j.cached = std::filesystem::path(cacheDir) / (j.name + "-" + arch + "-" + hex(key) + ".cubin");
      j.fromCache = readFile(j.cached, j.image);
    }
    jobs.push_back(std::move(j));
  }
  std::vector<Job*> toCompile;
  for (Job& j : jobs)
    if (!j.fromCache) toCompile.push_back(&j);
  if (!toCompile.empty()) {
    const unsigned threads = std::max(1u, std::min(unsigned(toCompile.size()), std::thread::hardware_concurrency()));
    std::vector<std::thread> pool;
    std::size_t next = 0;
    std::mutex m;
    for (unsigned t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        for (;;) {
          Job* j;
          {
            std::lock_guard<std::mutex> lock(m);
            if (next >= toCompile.size()) return;
            j = toCompile[next++];
          }
          const NvrtcOutput out = compileWithNvrtc(j->source, j->name + ".cu", arch);
          if (!out.ok) {
            j->error = out.error;
            continue;
          }
          j->image = out.image;
          if (!j->cached.empty()) writeFile(j->cached, j->image);
        }
      });
    for (std::thread& t : pool) t.join();
  }
  int cached = 0;
  for (Job& j : jobs) {
    if (!j.error.empty()) {
      report_ = "not used: " + j.error;
      loaded_.clear();
      return;
    }
    auto l = std::make_unique<Loaded>();
    l->spec = j.spec;
    cudaError_t e = cudaLibraryLoadData(&l->library, j.image.data(), nullptr, nullptr, 0, nullptr, nullptr, 0);
    cudaKernel_t k = nullptr;
    if (e == cudaSuccess) e = cudaLibraryGetKernel(&k, l->library, j.name.c_str());
    if (e != cudaSuccess) {
      cudaGetLastError();
      if (j.fromCache) {  // a damaged cache file: removed, compiled anew at the next load
        std::error_code ec;
        std::filesystem::remove(j.cached, ec);
      }
      report_ = "not used: loading " + j.name + " (" + arch + ") failed: " + cudaGetErrorString(e);
      loaded_.clear();
      return;
    }
    // A cudaKernel_t stands for the kernel's address in the runtime's launch and attribute
    // calls (cudaLaunchKernelEx, cudaFuncGetAttributes, cudaFuncSetAttribute, occupancy).
    l->kernel = reinterpret_cast<FusedKernel>(reinterpret_cast<void*>(k));
    cached += j.fromCache ? 1 : 0;
    loaded_.push_back(std::move(l));
  }
  available_ = true;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  char line[256];
  std::snprintf(line, sizeof line, "%zu kernels for %s, NVRTC %s, %.2f s (%d from the cache%s%s)", loaded_.size(), arch.c_str(),
                nvrtcVersionString().c_str(), seconds, cached, cacheDir.empty() ? ", no disk cache" : " in ",
                cacheDir.c_str());
  report_ = line;
}

GeneratedKernels::~GeneratedKernels() = default;  // each Loaded unloads its library

FusedKernel GeneratedKernels::kernel(int tile, int kc, bool storedEncoding, bool tangents) const {
  for (const auto& l : loaded_) {
    const GeneratedKernelSpec& s = l->spec;
    if (s.tile == tile && s.kc == kc && s.tangents == tangents && s.form == (storedEncoding ? 1 : 0)) return l->kernel;
  }
  return nullptr;
}

}  // namespace inr::cuda
