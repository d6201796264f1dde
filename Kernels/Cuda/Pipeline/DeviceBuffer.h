#pragma once
// Moved: cuda::DeviceBuffer, PinnedHost and Stream to Cuda/DeviceBuffer.h, DeviceTransferFunction
// to Cuda/Pipeline/DeviceTransferFunction.h. Kept for the pipeline files that include this path.
#include "Cuda/DeviceBuffer.h"
#include "Cuda/Pipeline/DeviceTransferFunction.h"
