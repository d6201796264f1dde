#pragma once
// NVRTC (the CUDA toolkit's run-time compiler) for the kernels generated per network
// (Evaluator/MlpKernelSource.h): the device headers they include, embedded in the binary at build
// time (EmbedDeviceHeaders.cmake), the options they are compiled with, and one call that compiles
// a source to PTX (a virtual architecture, compute_XY: no GPU needed, how CI checks the generated
// source) or to a cubin (a real one, sm_XY: what the evaluator loads). Host code only; needs no
// GPU and no CUDA driver.
#include <string>
#include <vector>

namespace inr::cuda {

struct RtcHeader {
  const char* name;  // as the device code includes it, e.g. "Evaluator/Cuda/FusedMlpKernel.cuh"
  const char* text;
};
// The project's device headers a generated kernel includes (generated at build time).
const std::vector<RtcHeader>& embeddedDeviceHeaders();

// NVRTC's version, e.g. "13.0".
std::string nvrtcVersionString();

// The folder holding the CUDA toolkit's own device headers (cuda_fp16.h, cuda_pipeline.h), which
// a generated kernel includes: the environment variable INR_CUDA_INCLUDE_DIR, else the toolkit
// this binary was built with. Empty when neither holds cuda_fp16.h.
std::string cudaToolkitIncludeDir();

// The options a generated kernel is compiled with for `arch` (compute_XY or sm_XY): C++17,
// --use_fast_math and line info as the built-in kernels (Evaluator/Cuda/CMakeLists.txt), the
// toolkit's include folder.
std::vector<std::string> generatedKernelOptions(const std::string& arch);

struct NvrtcOutput {
  bool ok = false;
  std::string error;  // when !ok: what failed, with the first lines of NVRTC's log
  std::string log;    // NVRTC's whole log (warnings too)
  std::string image;  // PTX text (compute_XY) or cubin bytes (sm_XY)
  double seconds = 0.0;
};

// Compiles `source` (named `name` in messages) with generatedKernelOptions(arch) and the
// embedded headers. Never throws for a compilation error: the result says what failed.
// syntaxOnly: NVRTC's front end only (-fdevice-syntax-only: every template instantiated and
// checked, no code generated, no image; about a second where the optimiser takes tens).
NvrtcOutput compileWithNvrtc(const std::string& source, const std::string& name, const std::string& arch,
                             bool syntaxOnly = false);

// The first `lines` lines of a compiler log (for a one-line report), joined with " | ".
std::string firstLogLines(const std::string& log, int lines = 3);

}  // namespace inr::cuda
