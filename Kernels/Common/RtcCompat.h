#pragma once
// The device headers the fused evaluator kernels are written in are also compiled at run time by
// NVRTC (Evaluator/Cuda/GeneratedKernels.h: a kernel generated for one network), where no C++
// standard library exists. Under NVRTC (__CUDACC_RTC__) this header declares the few standard
// names those headers use; elsewhere it includes the standard headers that declare them.
#if defined(__CUDACC_RTC__)
namespace std {
using int8_t = signed char;
using uint8_t = unsigned char;
using int16_t = short;
using uint16_t = unsigned short;
using int32_t = int;
using uint32_t = unsigned int;
using int64_t = long long;
using uint64_t = unsigned long long;
using size_t = decltype(sizeof(0));
template <class T, T v>
struct integral_constant {
  static constexpr T value = v;
  using value_type = T;
  using type = integral_constant;
  __host__ __device__ constexpr operator value_type() const noexcept { return value; }
  __host__ __device__ constexpr value_type operator()() const noexcept { return value; }
};
template <bool B>
using bool_constant = integral_constant<bool, B>;
using true_type = bool_constant<true>;
using false_type = bool_constant<false>;
}  // namespace std
#ifndef NAN
#define NAN (__int_as_float(0x7fc00000))
#endif
#ifndef INFINITY
#define INFINITY (__int_as_float(0x7f800000))
#endif
#else
#include <cmath>  // NAN, INFINITY
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#endif
