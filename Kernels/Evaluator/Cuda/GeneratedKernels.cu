#include "Evaluator/Cuda/GeneratedKernels.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
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

int backgroundCompileThreads() {
  if (const char* v = std::getenv("INR_COMPILE_THREADS"); v && *v) {
    const int n = std::atoi(v);
    if (n >= 1 && n <= 64) return n;
    std::fprintf(stderr, "INR_COMPILE_THREADS=%s ignored: it takes a thread count from 1 to 64\n", v);
  }
  return int(std::clamp(std::thread::hardware_concurrency() / 2u, 1u, 8u));
}

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

struct GeneratedKernels::Job {
  GeneratedKernelSpec spec;
  std::string source, name, image, error;
  std::filesystem::path cached;
  bool fromCache = false;
};

namespace {

std::string resolvedCacheDir(const std::string& option) {
  return option.empty() ? defaultKernelCacheDir() : option == "none" ? "" : option;
}

// One NVRTC program per kernel (its source: the program forms and that kernel), so they compile
// in parallel and each is cached alone; a cached image is read here.
std::vector<GeneratedKernels::Job> makeJobs(const ModelKernelSource& all, const std::string& arch, const std::string& cacheDir) {
  std::string options;
  for (const std::string& o : generatedKernelOptions(arch)) options += o + "\n";
  std::vector<GeneratedKernels::Job> jobs;
  for (const GeneratedKernelSpec& k : all.kernels) {
    GeneratedKernels::Job j;
    j.spec = k;
    j.name = generatedKernelName(k);
    j.source = generateFusedKernelSource(all.forms, {k});
    const std::uint64_t key = fnv1a(j.source + "\n" + options, headersKey());
    if (!cacheDir.empty()) {
      j.cached = std::filesystem::path(cacheDir) / (j.name + "-" + arch + "-" + hex(key) + ".cubin");
      j.fromCache = readFile(j.cached, j.image);
    }
    jobs.push_back(std::move(j));
  }
  return jobs;
}

void compileJob(GeneratedKernels::Job& j, const std::string& arch) {
  const NvrtcOutput out = compileWithNvrtc(j.source, j.name + ".cu", arch);
  if (!out.ok) {
    j.error = out.error;
    return;
  }
  j.image = out.image;
  if (!j.cached.empty()) writeFile(j.cached, j.image);
}

}  // namespace

struct GeneratedKernels::Batch {
  std::vector<Job> jobs;
  std::string arch, cacheDir;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::atomic<bool> cancelled{false};
  std::mutex m;
  std::condition_variable finished;
  int remaining = 0;  // jobs queued or compiling (under m)
};

namespace {

// The process's background compile threads: a queue of (batch, job) taken in order by
// backgroundCompileThreads() workers, started on first use. A cancelled batch's queued jobs are
// skipped. At exit the workers finish the kernel each is compiling and stop.
class CompileThreads {
public:
  static CompileThreads& instance() {
    static CompileThreads threads;
    return threads;
  }
  void submit(const std::shared_ptr<GeneratedKernels::Batch>& batch, const std::vector<std::size_t>& jobs) {
    std::lock_guard<std::mutex> lock(m_);
    for (const std::size_t j : jobs) queue_.emplace_back(batch, j);
    const std::size_t want = std::size_t(backgroundCompileThreads());
    while (workers_.size() < want) workers_.emplace_back([this] { work(); });
    wake_.notify_all();
  }
  ~CompileThreads() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stopping_ = true;
      // Jobs never begun end as failures, so nothing waits for them.
      for (auto& [batch, job] : queue_) finish(*batch, job, "the process is exiting");
      queue_.clear();
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
  }

private:
  void work() {
    for (;;) {
      std::pair<std::shared_ptr<GeneratedKernels::Batch>, std::size_t> item;
      {
        std::unique_lock<std::mutex> lock(m_);
        wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
        if (stopping_) return;
        item = std::move(queue_.front());
        queue_.pop_front();
      }
      GeneratedKernels::Batch& b = *item.first;
      if (b.cancelled.load())
        finish(b, item.second, "cancelled");
      else {
        compileJob(b.jobs[item.second], b.arch);
        finish(b, item.second, nullptr);
      }
    }
  }
  static void finish(GeneratedKernels::Batch& b, std::size_t job, const char* error) {
    std::lock_guard<std::mutex> lock(b.m);
    if (error) b.jobs[job].error = error;
    if (--b.remaining == 0) b.finished.notify_all();
  }
  std::mutex m_;
  std::condition_variable wake_;
  std::deque<std::pair<std::shared_ptr<GeneratedKernels::Batch>, std::size_t>> queue_;
  std::vector<std::thread> workers_;
  bool stopping_ = false;
};

}  // namespace

GeneratedKernels::GeneratedKernels(const MlpProgram& program, int major, int minor, const std::string& cacheDirOption,
                                   const std::vector<int>& tiles, const std::vector<int>& chunks) {
  const auto start = std::chrono::steady_clock::now();
  const std::string arch = "sm_" + std::to_string(major) + std::to_string(minor);
  const std::string cacheDir = resolvedCacheDir(cacheDirOption);
  std::vector<Job> jobs;
  try {
    jobs = makeJobs(generateModelKernels(program, tiles, chunks), arch, cacheDir);
  } catch (const std::invalid_argument& e) {
    report_ = std::string("not generated: ") + e.what();
    return;
  }
  std::vector<Job*> toCompile;
  for (Job& j : jobs)
    if (!j.fromCache) toCompile.push_back(&j);
  if (!toCompile.empty()) {
    const unsigned threads = std::max(1u, std::min(unsigned(toCompile.size()), std::thread::hardware_concurrency()));
    std::vector<std::thread> pool;
    std::atomic<std::size_t> next{0};
    for (unsigned t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        for (std::size_t i; (i = next++) < toCompile.size();) compileJob(*toCompile[i], arch);
      });
    for (std::thread& t : pool) t.join();
  }
  load(jobs, arch, cacheDir, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), "");
}

void GeneratedKernels::load(std::vector<Job>& jobs, const std::string& arch, const std::string& cacheDir, double seconds,
                            const char* how) {
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
  char line[320];
  std::snprintf(line, sizeof line, "%zu kernels for %s, NVRTC %s, %.2f s%s (%d from the cache%s%s)", loaded_.size(),
                arch.c_str(), nvrtcVersionString().c_str(), seconds, how, cached,
                cacheDir.empty() ? ", no disk cache" : " in ", cacheDir.c_str());
  report_ = line;
}

std::unique_ptr<GeneratedKernels::Pending> GeneratedKernels::startInBackground(
    const MlpProgram& program, int major, int minor, const std::string& cacheDirOption,
    const std::vector<GeneratedKernelConfig>& configs, std::string& why) {
  auto batch = std::make_shared<Batch>();
  batch->arch = "sm_" + std::to_string(major) + std::to_string(minor);
  batch->cacheDir = resolvedCacheDir(cacheDirOption);
  try {
    // Sources for the tiles and chunks asked for only (this runs on the caller's thread: the
    // evaluator's constructor), then only their configurations' kernels (forms: 0 the program,
    // 1 its stored form).
    std::vector<int> tiles, chunks;
    for (const GeneratedKernelConfig& c : configs) {
      if (std::find(tiles.begin(), tiles.end(), c.tile) == tiles.end()) tiles.push_back(c.tile);
      if (std::find(chunks.begin(), chunks.end(), c.kc) == chunks.end()) chunks.push_back(c.kc);
    }
    ModelKernelSource all = generateModelKernels(program, tiles, chunks);
    std::vector<GeneratedKernelSpec> wanted;
    for (const GeneratedKernelSpec& k : all.kernels)
      for (const GeneratedKernelConfig& c : configs)
        if (k.tile == c.tile && k.kc == c.kc && k.form == (c.storedEncoding ? 1 : 0)) {
          wanted.push_back(k);
          break;
        }
    all.kernels = wanted;
    batch->jobs = makeJobs(all, batch->arch, batch->cacheDir);
  } catch (const std::invalid_argument& e) {
    why = std::string("not generated: ") + e.what();
    return nullptr;
  }
  if (batch->jobs.empty()) {
    why = "not generated: no kernel of the configurations asked for";
    return nullptr;
  }
  std::vector<std::size_t> toCompile;
  for (std::size_t i = 0; i < batch->jobs.size(); ++i)
    if (!batch->jobs[i].fromCache) toCompile.push_back(i);
  batch->remaining = int(toCompile.size());
  const int threads = backgroundCompileThreads();
  char line[200];
  std::snprintf(line, sizeof line, "%zu kernels for %s: %zu from the cache, %zu compiling in the background on %d thread%s",
                batch->jobs.size(), batch->arch.c_str(), batch->jobs.size() - toCompile.size(), toCompile.size(),
                threads, threads == 1 ? "" : "s");
  if (!toCompile.empty()) CompileThreads::instance().submit(batch, toCompile);
  return std::make_unique<Pending>(batch, line);
}

GeneratedKernels::Pending::Pending(std::shared_ptr<Batch> batch, std::string what)
    : batch_(std::move(batch)), what_(std::move(what)) {}

GeneratedKernels::Pending::~Pending() {
  if (batch_) batch_->cancelled = true;
}

bool GeneratedKernels::Pending::ready() const {
  std::lock_guard<std::mutex> lock(batch_->m);
  return batch_->remaining == 0;
}

void GeneratedKernels::Pending::wait() const {
  std::unique_lock<std::mutex> lock(batch_->m);
  batch_->finished.wait(lock, [&] { return batch_->remaining == 0; });
}

std::unique_ptr<GeneratedKernels> GeneratedKernels::Pending::take() {
  wait();
  std::unique_ptr<GeneratedKernels> kernels(new GeneratedKernels());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - batch_->start).count();
  const bool compiled = std::any_of(batch_->jobs.begin(), batch_->jobs.end(), [](const Job& j) { return !j.fromCache; });
  kernels->load(batch_->jobs, batch_->arch, batch_->cacheDir, seconds, compiled ? " after the start, in the background" : "");
  batch_.reset();
  return kernels;
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
