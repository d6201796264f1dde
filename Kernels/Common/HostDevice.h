#pragma once
// Per-ray and per-query logic is written once and compiled for the CPU (plain C++) and the GPU
// (nvcc). INR_HD marks such functions; it expands to nothing in a host-only build.
#if defined(__CUDACC__)
#define INR_HD __host__ __device__ __forceinline__
#define INR_DEVICE_CODE 1
#else
#define INR_HD inline
#endif
