# Writes OUTPUT, a C++ file defining inr::cuda::embeddedDeviceHeaders(): the text of each header
# in HEADERS (paths relative to ROOT, the Kernels folder), under the name the device code includes
# it by, for NVRTC (NvrtcCompiler.cpp: a generated kernel compiles against exactly the headers
# this binary was built from, wherever the sources are). Run by a custom command (CMakeLists.txt
# here) whenever a header changes.
string(REPLACE "|" ";" HEADERS "${HEADERS}")  # (joined with | on the command line)
set(_body "")
foreach(header IN LISTS HEADERS)
  file(READ "${ROOT}/${header}" _text)
  string(FIND "${_text}" ")inr_rtc\"" _clash)
  if(NOT _clash EQUAL -1)
    message(FATAL_ERROR "${header} contains the raw-string delimiter )inr_rtc\"")
  endif()
  string(APPEND _body "    {\"${header}\", R\"inr_rtc(${_text})inr_rtc\"},\n")
endforeach()
file(WRITE "${OUTPUT}.tmp" "// Generated from Kernels/Evaluator/Cuda/EmbedDeviceHeaders.cmake; do not edit.
#include \"Evaluator/Cuda/NvrtcCompiler.h\"

namespace inr::cuda {

const std::vector<RtcHeader>& embeddedDeviceHeaders() {
  static const std::vector<RtcHeader> headers = {
${_body}  };
  return headers;
}

}  // namespace inr::cuda
")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
