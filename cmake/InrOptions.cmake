# Feature switches. Each of CUDA / OptiX / ParaView is AUTO (default), ON (required: configure
# fails if unavailable) or OFF; the decision and its reason are printed at the end of configure.
set(INR_ENABLE_CUDA AUTO CACHE STRING "CUDA backend: AUTO, ON or OFF")
set(INR_ENABLE_OPTIX AUTO CACHE STRING "OptiX traversal (needs CUDA and OptiX 9.0 headers): AUTO, ON or OFF")
set(INR_ENABLE_PARAVIEW AUTO CACHE STRING "ParaView plugin: AUTO, ON or OFF")
set(OptiX_INSTALL_DIR "" CACHE PATH "Folder holding OptiX 9.0 'include/optix.h' (NVIDIA/optix-dev)")
option(INR_BUILD_TESTS "Build the test suite" ON)
# The benchmark programs (Benchmarks/); the sanitizer build leaves them out (no test runs them).
option(INR_BUILD_BENCHMARKS "Build the benchmark programs" ON)
# Checking builds (Tools/run-sanitizers.sh, Tools/run-fuzz.sh; Docs/testing.md, "Fuzzing and sanitizers").
set(INR_SANITIZE "" CACHE STRING "Sanitizers for the engine, the CLI and the tests, e.g. address,undefined")
option(INR_FUZZ "Build only the model loader and its libFuzzer target (Testing/Fuzz; needs clang)" OFF)
# Tools/run-tests.sh without a usable GPU (the GPU tests skip there): the CUDA code is compiled to
# PTX for sm_90 with NVVM's optimiser off, a compile check (Docs/testing.md). Not cached into
# CMAKE_CUDA_ARCHITECTURES / CMAKE_CUDA_FLAGS, so turning it off restores the normal build.
option(INR_CUDA_ALL_ARCHITECTURES "Build CUDA code for sm_75, 80, 86, 89 and 90 even where a GPU is present (default: the present GPU's architecture only)" OFF)
option(INR_CUDA_COMPILE_CHECK "Compile-check the CUDA code only (PTX, device optimiser off); no kernel of such a build is for running" OFF)
foreach(opt INR_ENABLE_CUDA INR_ENABLE_OPTIX INR_ENABLE_PARAVIEW)
  set_property(CACHE ${opt} PROPERTY STRINGS AUTO ON OFF)
  string(TOUPPER "${${opt}}" _v)
  if(NOT _v MATCHES "^(AUTO|ON|OFF)$")
    message(FATAL_ERROR "${opt}=${${opt}} is not one of AUTO, ON, OFF")
  endif()
  set(${opt} ${_v})
endforeach()

# --- CUDA
set(INR_WITH_CUDA OFF)
if(INR_ENABLE_CUDA STREQUAL "OFF")
  set(INR_CUDA_REASON "disabled by INR_ENABLE_CUDA=OFF")
else()
  include(CheckLanguage)
  if(NOT CMAKE_CUDA_COMPILER AND EXISTS /usr/local/cuda/bin/nvcc)
    set(CMAKE_CUDA_COMPILER /usr/local/cuda/bin/nvcc)
  endif()
  check_language(CUDA)
  if(CMAKE_CUDA_COMPILER)
    if(INR_CUDA_COMPILE_CHECK)
      # A normal variable: it shadows (never overwrites) a cached choice.
      set(CMAKE_CUDA_ARCHITECTURES 90-virtual)
    elseif(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
      # With a usable GPU: the present GPUs' architectures only (what CMake's "native" means,
      # spelled out so that the Hopper kernel below sees "90"), one device compile per kernel
      # instead of five. INR_CUDA_ALL_ARCHITECTURES (packagers, or a build machine without the
      # GPU that will run it) builds for RTX workstations (Turing..Ada) plus Hopper; the fastest
      # path is picked at run time.
      set(_inr_present_archs "")
      if(NOT INR_CUDA_ALL_ARCHITECTURES)
        execute_process(COMMAND nvidia-smi --query-gpu=compute_cap --format=csv,noheader
                        RESULT_VARIABLE _inr_smi OUTPUT_VARIABLE _inr_caps ERROR_QUIET)
        if(_inr_smi EQUAL 0)
          string(REGEX MATCHALL "[0-9]+\\.[0-9]+" _inr_caps "${_inr_caps}")
          foreach(cap IN LISTS _inr_caps)
            string(REPLACE "." "" cap "${cap}")
            list(APPEND _inr_present_archs ${cap})
          endforeach()
          list(REMOVE_DUPLICATES _inr_present_archs)
        endif()
      endif()
      if(_inr_present_archs)
        set(CMAKE_CUDA_ARCHITECTURES ${_inr_present_archs})
      else()
        set(CMAKE_CUDA_ARCHITECTURES 75-real 80-real 86-real 89-real 90)
      endif()
    endif()
    enable_language(CUDA)
    find_package(CUDAToolkit REQUIRED)
    set(INR_WITH_CUDA ON)
    set(INR_CUDA_REASON "nvcc ${CMAKE_CUDA_COMPILER_VERSION}, architectures ${CMAKE_CUDA_ARCHITECTURES}")
    if(INR_CUDA_COMPILE_CHECK)
      add_compile_options("$<$<COMPILE_LANGUAGE:CUDA>:SHELL:-Xcicc -O0>")
      string(APPEND INR_CUDA_REASON "; compile check only (INR_CUDA_COMPILE_CHECK): no kernel of this build is for running")
    endif()
  else()
    set(INR_CUDA_REASON "no nvcc found (set CMAKE_CUDA_COMPILER)")
    if(INR_ENABLE_CUDA STREQUAL "ON")
      message(FATAL_ERROR "INR_ENABLE_CUDA=ON but ${INR_CUDA_REASON}")
    endif()
  endif()
endif()

# --- OptiX
set(INR_WITH_OPTIX OFF)
if(INR_ENABLE_OPTIX STREQUAL "OFF")
  set(INR_OPTIX_REASON "disabled by INR_ENABLE_OPTIX=OFF")
elseif(NOT INR_WITH_CUDA)
  set(INR_OPTIX_REASON "needs the CUDA backend")
elseif(OptiX_INSTALL_DIR AND EXISTS "${OptiX_INSTALL_DIR}/include/optix.h")
  set(INR_WITH_OPTIX ON)
  set(INR_OPTIX_REASON "headers in ${OptiX_INSTALL_DIR}/include")
else()
  set(INR_OPTIX_REASON "no OptiX headers (set OptiX_INSTALL_DIR to a folder with include/optix.h)")
endif()
if(INR_ENABLE_OPTIX STREQUAL "ON" AND NOT INR_WITH_OPTIX)
  message(FATAL_ERROR "INR_ENABLE_OPTIX=ON but ${INR_OPTIX_REASON}")
endif()

# --- ParaView
set(INR_WITH_PARAVIEW OFF)
if(INR_ENABLE_PARAVIEW STREQUAL "OFF")
  set(INR_PARAVIEW_REASON "disabled by INR_ENABLE_PARAVIEW=OFF")
else()
  find_package(ParaView 5.11 QUIET)
  if(ParaView_FOUND)
    set(INR_WITH_PARAVIEW ON)
    set(INR_PARAVIEW_REASON "ParaView ${ParaView_VERSION} at ${ParaView_DIR}")
  else()
    set(INR_PARAVIEW_REASON "ParaView SDK not found (apt-get install paraview-dev, or set ParaView_DIR)")
    if(INR_ENABLE_PARAVIEW STREQUAL "ON")
      message(FATAL_ERROR "INR_ENABLE_PARAVIEW=ON but ${INR_PARAVIEW_REASON}")
    endif()
  endif()
endif()

# The environment of every test that renders on the CPU: OpenMP threads that sleep at barriers
# instead of spinning. ctest -j runs tests side by side, and a spinning thread holds a core the
# thread it waits for needs (two CPU renders side by side ran 5x slower under libgomp's default).
# The inr CLI sets this itself (Tools/inr/main.cpp); test programs and ParaView processes get it here.
set(INR_TEST_OPENMP_ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE")

# Adds a GoogleTest executable and registers its tests with ctest.
#   inr_add_gtest(NAME name SOURCES a.cpp ... [LIBS ...] [LABELS ...])
function(inr_add_gtest)
  # SERIAL: its tests run alone under ctest -j (RUN_SERIAL), for tests that measure something
  # the whole machine shares (a GPU's memory in use).
  cmake_parse_arguments(T "SERIAL" "NAME" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE inr_engine GTest::gtest GTest::gtest_main ${T_LIBS})
  target_compile_definitions(${T_NAME} PRIVATE
    INR_TEST_DATA_DIR="${PROJECT_SOURCE_DIR}/Testing/Data")
  # A GTEST_SKIP (e.g. no GPU) is reported by ctest as skipped, not passed.
  set(props SKIP_REGULAR_EXPRESSION "  SKIPPED " ENVIRONMENT "${INR_TEST_OPENMP_ENVIRONMENT}")
  if(T_LABELS)
    list(APPEND props LABELS "${T_LABELS}")
  endif()
  if(T_SERIAL)
    list(APPEND props RUN_SERIAL TRUE)
  endif()
  gtest_discover_tests(${T_NAME} DISCOVERY_TIMEOUT 60 PROPERTIES ${props})
endfunction()

# CPU code (the Eigen evaluator, the CPU backend) is built for the machine that builds it: AVX2/FMA
# roughly double the evaluator's throughput. Turn off for binaries that must run elsewhere.
option(INR_NATIVE_ARCH "Compile CPU code with -march=native" ON)
if(INR_NATIVE_ARCH)
  include(CheckCXXCompilerFlag)
  check_cxx_compiler_flag(-march=native INR_HAS_MARCH_NATIVE)
  if(INR_HAS_MARCH_NATIVE)
    add_compile_options($<$<COMPILE_LANGUAGE:CXX>:-march=native>)
  endif()
endif()

# --- Sanitizers: every C++ target of this project (the engine, the CLI, the tests) is compiled and
# linked with them. Recovery is off, so a report ends the process with a non-zero status.
if(INR_SANITIZE)
  if(NOT INR_SANITIZE MATCHES "^[a-z,_-]+$")
    message(FATAL_ERROR "INR_SANITIZE=${INR_SANITIZE}: expected a list like address,undefined")
  endif()
  if(INR_WITH_CUDA)
    message(FATAL_ERROR "INR_SANITIZE needs -DINR_ENABLE_CUDA=OFF (nvcc takes no -fsanitize)")
  endif()
  set(_san -fsanitize=${INR_SANITIZE} -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_compile_options(${_san})
  add_link_options(${_san})
endif()

# --- Fuzzing: a separate clang build of the loader alone (the top-level CMakeLists stops after it).
if(INR_FUZZ AND NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
  message(FATAL_ERROR "INR_FUZZ=ON needs clang (libFuzzer): configure a separate build folder with "
                      "-DCMAKE_CXX_COMPILER=clang++ -DCMAKE_C_COMPILER=clang, or run Tools/run-fuzz.sh")
endif()
