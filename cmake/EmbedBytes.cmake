# Writes a C++ source holding a binary file's bytes as an array, so the engine carries its data
# compiled in (no file to find at run time): the shipped blue-noise texels, the OptiX programs'
# OptiX-IR. Run at build time (cmake -P), only when the input changes; #embed would do this, but
# GCC 12 and nvcc's host compilers lack it.
#   cmake -DINPUT=file -DOUTPUT=file.cpp [-DNAMESPACE=ns] -DNAME=symbol -P cmake/EmbedBytes.cmake
# Defines ns::NAME (const unsigned char[]) and ns::NAMESize (std::size_t); without NAMESPACE, at
# global scope.
foreach(var INPUT OUTPUT NAME)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "EmbedBytes.cmake: -D${var}=... is required")
  endif()
endforeach()
file(READ "${INPUT}" hex HEX)
string(LENGTH "${hex}" hexLength)
math(EXPR size "${hexLength} / 2")
# 16 bytes a line, then every byte as 0xNN.
string(REGEX REPLACE "([0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f][0-9a-f])"
       "\\1\n" hex "${hex}")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," body "${hex}")
get_filename_component(inputName "${INPUT}" NAME)
set(open "")
set(close "")
if(NAMESPACE)
  set(open "namespace ${NAMESPACE} {\n")
  set(close "}  // namespace ${NAMESPACE}\n")
endif()
file(WRITE "${OUTPUT}.tmp"
  "// Generated from ${inputName} by cmake/EmbedBytes.cmake at build time; do not edit.\n"
  "#include <cstddef>\n"
  "${open}"
  "extern const unsigned char ${NAME}[];\n"
  "extern const std::size_t ${NAME}Size;\n"
  "const unsigned char ${NAME}[] = {\n${body}};\n"
  "const std::size_t ${NAME}Size = ${size};\n"
  "${close}")
# Replace only on change, so an unchanged input does not recompile the array.
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
