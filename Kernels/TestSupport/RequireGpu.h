#pragma once
// REQUIRE_GPU(): skips the current GoogleTest (reported as skipped, with the reason) when no
// usable CUDA device is present.
#include <gtest/gtest.h>

#include "Common/Cuda/CudaDevice.h"

#define REQUIRE_GPU()                                                            \
  do {                                                                           \
    const ::inr::CudaDeviceInfo dev_ = ::inr::queryCudaDevice();                 \
    if (!dev_.usable) GTEST_SKIP() << "no GPU: " << dev_.reason;                 \
  } while (0)
