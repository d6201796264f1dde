#include "Evaluator/Cuda/NvrtcCompiler.h"

#include <nvrtc.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>

namespace inr::cuda {

std::string nvrtcVersionString() {
  int major = 0, minor = 0;
  if (::nvrtcVersion(&major, &minor) != NVRTC_SUCCESS) return "unknown";
  return std::to_string(major) + "." + std::to_string(minor);
}

std::string cudaToolkitIncludeDir() {
  auto holdsHeaders = [](const std::string& dir) {
    std::error_code ec;
    return !dir.empty() && std::filesystem::exists(std::filesystem::path(dir) / "cuda_fp16.h", ec);
  };
  if (const char* env = std::getenv("INR_CUDA_INCLUDE_DIR"); env && holdsHeaders(env)) return env;
#if defined(INR_CUDA_TOOLKIT_INCLUDE_DIR)
  if (holdsHeaders(INR_CUDA_TOOLKIT_INCLUDE_DIR)) return INR_CUDA_TOOLKIT_INCLUDE_DIR;
#endif
  return "";
}

std::vector<std::string> generatedKernelOptions(const std::string& arch) {
  std::vector<std::string> options = {"--gpu-architecture=" + arch, "--std=c++17", "--use_fast_math", "--generate-line-info",
                                      "--device-as-default-execution-space"};
  const std::string include = cudaToolkitIncludeDir();
  if (!include.empty()) options.push_back("--include-path=" + include);
  return options;
}

std::string firstLogLines(const std::string& log, int lines) {
  std::string out;
  std::size_t at = 0;
  for (int taken = 0; taken < lines && at < log.size();) {
    std::size_t end = log.find('\n', at);
    if (end == std::string::npos) end = log.size();
    const std::string line = log.substr(at, end - at);
    at = end + 1;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    out += (out.empty() ? "" : " | ") + line;
    ++taken;
  }
  return out;
}

NvrtcOutput compileWithNvrtc(const std::string& source, const std::string& name, const std::string& arch, bool syntaxOnly) {
  NvrtcOutput result;
  const auto start = std::chrono::steady_clock::now();
  const std::vector<RtcHeader>& headers = embeddedDeviceHeaders();
  std::vector<const char*> headerTexts, headerNames;
  for (const RtcHeader& h : headers) {
    headerNames.push_back(h.name);
    headerTexts.push_back(h.text);
  }
  nvrtcProgram program = nullptr;
  nvrtcResult r = nvrtcCreateProgram(&program, source.c_str(), name.c_str(), int(headers.size()), headerTexts.data(),
                                     headerNames.data());
  if (r != NVRTC_SUCCESS) {
    result.error = std::string("nvrtcCreateProgram: ") + nvrtcGetErrorString(r);
    return result;
  }
  std::vector<std::string> options = generatedKernelOptions(arch);
  if (syntaxOnly) options.push_back("-fdevice-syntax-only");
  std::vector<const char*> optionPointers;
  for (const std::string& o : options) optionPointers.push_back(o.c_str());
  r = nvrtcCompileProgram(program, int(optionPointers.size()), optionPointers.data());
  std::size_t logSize = 0;
  if (nvrtcGetProgramLogSize(program, &logSize) == NVRTC_SUCCESS && logSize > 1) {
    result.log.resize(logSize);
    nvrtcGetProgramLog(program, result.log.data());
    result.log.resize(logSize - 1);  // the terminating NUL
  }
  if (r != NVRTC_SUCCESS) {
    result.error = std::string("NVRTC ") + nvrtcVersionString() + " could not compile " + name + " for " + arch + " (" +
                   nvrtcGetErrorString(r) + "): " + firstLogLines(result.log);
    if (cudaToolkitIncludeDir().empty())
      result.error += " [no folder with cuda_fp16.h found: set INR_CUDA_INCLUDE_DIR to the CUDA toolkit's include folder]";
    nvrtcDestroyProgram(&program);
    return result;
  }
  if (syntaxOnly) {
    nvrtcDestroyProgram(&program);
    result.ok = true;
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }
  const bool cubin = arch.rfind("sm_", 0) == 0;
  std::size_t size = 0;
  r = cubin ? nvrtcGetCUBINSize(program, &size) : nvrtcGetPTXSize(program, &size);
  if (r == NVRTC_SUCCESS) {
    result.image.resize(size);
    r = cubin ? nvrtcGetCUBIN(program, result.image.data()) : nvrtcGetPTX(program, result.image.data());
  }
  nvrtcDestroyProgram(&program);
  if (r != NVRTC_SUCCESS) {
    result.error = std::string("NVRTC: reading the ") + (cubin ? "cubin" : "PTX") + " failed: " + nvrtcGetErrorString(r);
    result.image.clear();
    return result;
  }
  result.ok = true;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace inr::cuda
