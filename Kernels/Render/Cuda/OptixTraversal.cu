// The OptiX traversal's host side: context, module (the embedded OptiX-IR of OptixPrograms.cu),
// pipeline and shader binding table, created once; the GAS over the macrocells whose majorant
// exceeds TraversalOptions::gasMinMajorant (one custom AABB primitive per cell, with the
// primitive -> cell map), rebuilt into reused buffers whenever the majorants change; and the
// launch. Built only with INR_WITH_OPTIX (OptiX 9.0 headers; the driver supplies the library).
#include <optix.h>
#include <optix_function_table_definition.h>  // the one translation unit that defines the table
#include <optix_stubs.h>
#include <optix_stack_size.h>  // after optix_stubs.h, whose functions it calls

#include <cub/device/device_select.cuh>
#include <thrust/iterator/counting_iterator.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Common/DeviceMemory.h"
#include "Render/Cuda/OptixLaunchParams.h"

// OptixProgramsIr.cpp, generated at build time from OptixPrograms.cu (cmake/EmbedBytes.cmake).
extern const unsigned char kInrOptixProgramsIr[];
extern const std::size_t kInrOptixProgramsIrSize;

namespace inr {
namespace {

void optixCheck(OptixResult r, const char* call) {
  if (r != OPTIX_SUCCESS)
    throw std::runtime_error(std::string("OptiX: ") + call + " failed: " + optixGetErrorName(r) + " (" +
                             optixGetErrorString(r) + ")");
}
#define INR_OPTIX_CHECK(call) optixCheck((call), #call)

// Shader binding table records: headers only (the programs read everything from the launch
// parameters).
struct alignas(OPTIX_SBT_RECORD_ALIGNMENT) SbtRecord {
  char header[OPTIX_SBT_RECORD_HEADER_SIZE];
};

struct MajorantAbove {
  const float* majorant;
  float threshold;
  __device__ bool operator()(int cell) const { return majorant[cell] > threshold; }  // NaN: out
};

// AABB of each selected cell, from the same face planes the DDA and the intersection program use.
__global__ void cellAabbKernel(MajorantGridView g, const int* cells, const unsigned* count, OptixAabb* aabbs) {
  const unsigned k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= *count) return;
  const int cell = cells[k];
  const int x = cell % g.dims.x, yz = cell / g.dims.x, y = yz % g.dims.y, z = yz / g.dims.y;
  OptixAabb a;
  a.minX = g.box.lo.x + float(x) * g.cellSize.x;
  a.minY = g.box.lo.y + float(y) * g.cellSize.y;
  a.minZ = g.box.lo.z + float(z) * g.cellSize.z;
  a.maxX = g.box.lo.x + float(x + 1) * g.cellSize.x;
  a.maxY = g.box.lo.y + float(y + 1) * g.cellSize.y;
  a.maxZ = g.box.lo.z + float(z + 1) * g.cellSize.z;
  aabbs[k] = a;
}

// Records which cells are selected now and flags any difference from the last update's selection.
__global__ void selectionChangeKernel(MajorantAbove above, int cells, unsigned char* selected, unsigned* changed) {
  const int cell = blockIdx.x * blockDim.x + threadIdx.x;
  if (cell >= cells) return;
  const unsigned char now = above(cell) ? 1 : 0;
  if (now != selected[cell]) {
    selected[cell] = now;
    *changed = 1u;  // every writer writes the same value
  }
}

// Errors always; everything the context reports (its level is 4 then) under INR_OPTIX_DEBUG.
void logCallback(unsigned level, const char* tag, const char* message, void*) {
  std::fprintf(stderr, "OptiX [%u][%s]: %s\n", level, tag, message);
}

class OptixTraversal final : public DeviceTraversal {
public:
  explicit OptixTraversal(const TraversalOptions& options) : options_(options), dda_(makeDdaTraversal()) {
    options_.validate();
    INR_CUDA_CHECK(cudaFree(nullptr));  // make sure the primary context exists
    INR_OPTIX_CHECK(optixInit());
    const char* debug = std::getenv("INR_OPTIX_DEBUG");
    debug_ = debug && *debug && std::string(debug) != "0";
    OptixDeviceContextOptions co = {};
    co.logCallbackFunction = &logCallback;
    co.logCallbackLevel = debug_ ? 4 : 2;
    if (debug_) co.validationMode = OPTIX_DEVICE_CONTEXT_VALIDATION_MODE_ALL;
    INR_OPTIX_CHECK(optixDeviceContextCreate(nullptr, &co, &context_));
    unsigned rt = 0;
    INR_OPTIX_CHECK(optixDeviceContextGetProperty(context_, OPTIX_DEVICE_PROPERTY_RTCORE_VERSION, &rt, sizeof(rt)));
    rtCores_ = rt != 0;
    createPipeline();
    // OptiX work runs on a stream of its own, ordered after and before the caller's stream by
    // events, so it never depends on how OptiX treats the legacy default stream (0), which the
    // renderer's stream may be.
    INR_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
    INR_CUDA_CHECK(cudaEventCreateWithFlags(&callerReady_, cudaEventDisableTiming));
    INR_CUDA_CHECK(cudaEventCreateWithFlags(&optixDone_, cudaEventDisableTiming));
    params_.resize(1);
    count_.resize(1);
    compactedSize_.resize(1);
    changed_.resize(1);
    if (debug_) {
      debugCounts_.resize(kDbgCounts);
      INR_CUDA_CHECK(cudaMemset(debugCounts_.get(), 0, kDbgCounts * sizeof(unsigned long long)));
    }
  }
  ~OptixTraversal() override {
    if (debug_) {
      unsigned long long c[kDbgCounts] = {};
      if (cudaDeviceSynchronize() == cudaSuccess &&
          cudaMemcpy(c, debugCounts_.get(), sizeof(c), cudaMemcpyDeviceToHost) == cudaSuccess)
        std::fprintf(stderr,
                     "OptiX debug: raygen %llu, traces %llu, intersection calls %llu (interval %llu, reported %llu), "
                     "closest hits %llu, hits %llu; %zu builds, %zu primitives\n",
                     c[kDbgRaygen], c[kDbgTrace], c[kDbgIntersect], c[kDbgInterval], c[kDbgReport], c[kDbgClosestHit],
                     c[kDbgHit], info_.builds, info_.primitives);
    }
    if (stream_) cudaStreamSynchronize(stream_);
    if (callerReady_) cudaEventDestroy(callerReady_);
    if (optixDone_) cudaEventDestroy(optixDone_);
    if (stream_) cudaStreamDestroy(stream_);
    if (pipeline_) optixPipelineDestroy(pipeline_);
    for (OptixProgramGroup g : groups_)
      if (g) optixProgramGroupDestroy(g);
    if (module_) optixModuleDestroy(module_);
    if (context_) optixDeviceContextDestroy(context_);
  }

  bool rtCores() const { return rtCores_; }
  const char* name() const override { return "optix"; }
  TraversalBuildInfo buildInfo() const override { return info_; }

  void majorantsChanged(const MajorantGridView& grid, cudaStream_t caller) override {
    const auto t0 = std::chrono::steady_clock::now();
    try {
      update(grid, caller);
    } catch (...) {
      // Whatever failed (the selection record may already be the new one while the GAS is
      // not), the next update reserves and builds afresh, and traverse() runs the DDA until then.
      shape_ = Int3{0, 0, 0};
      gas_ = 0;
      builtFor_ = nullptr;
      throw;
    }
    info_.lastBuildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }

  void traverse(const TraversalLaunch& launch, cudaStream_t caller) const override {
    // Majorants the GAS was not built from (ghost passes' own), or no GAS yet, or nothing in it
    // (every cell empty: the DDA is as fast and exact): the DDA.
    if (launch.medium.grid.majorant != builtFor_ || !gas_) {
      dda_->traverse(launch, caller);
      return;
    }
    const cudaStream_t stream = stream_;
    INR_CUDA_CHECK(cudaEventRecord(callerReady_, caller));
    INR_CUDA_CHECK(cudaStreamWaitEvent(stream, callerReady_, 0));
    OptixTraversalParams p;
    p.launch = launch;
    p.gas = gas_;
    p.cellOfPrimitive = cellOfPrimitive_.get();
    if (debug_) {
      p.debugCounts = debugCounts_.get();
      if (!launch.list && launch.fc.camera.width > 0)
        p.debugRay = launch.fc.camera.height / 2 * launch.fc.camera.width + launch.fc.camera.width / 2;
    }
    // Stream-ordered: a launch still reading the previous parameters finishes before the copy.
    INR_CUDA_CHECK(cudaMemcpyAsync(params_.get(), &p, sizeof(p), cudaMemcpyHostToDevice, stream));
    const CameraView& cam = launch.fc.camera;
    const bool image = !launch.list && cam.width > 0 && cam.height > 0 &&
                       (long long)cam.width * cam.height == (long long)launch.n;
    const unsigned width = image ? unsigned(cam.width) : unsigned(std::max(1, launch.n));
    const unsigned height = image ? unsigned(cam.height) : 1u;
    INR_OPTIX_CHECK(optixLaunch(pipeline_, stream, reinterpret_cast<CUdeviceptr>(params_.get()),
                                sizeof(OptixTraversalParams), &sbt_, width, height, 1));
    INR_CUDA_CHECK(cudaEventRecord(optixDone_, stream));
    INR_CUDA_CHECK(cudaStreamWaitEvent(caller, optixDone_, 0));  // the caller's next work waits
  }

private:
  void update(const MajorantGridView& grid, cudaStream_t caller) {
    // After the caller's majorant computation; everything below runs on the OptiX stream.
    INR_CUDA_CHECK(cudaEventRecord(callerReady_, caller));
    INR_CUDA_CHECK(cudaStreamWaitEvent(stream_, callerReady_, 0));
    const cudaStream_t stream = stream_;
    const int cells = grid.dims.x * grid.dims.y * grid.dims.z;
    // A new grid shape reserves anew; a new box (same shape) moves every cell's AABB: both build.
    const bool newShape = !(grid.dims.x == shape_.x && grid.dims.y == shape_.y && grid.dims.z == shape_.z);
    const bool newBox = !sameBox(grid.box, box_);
    if (newShape) reserveFor(grid);
    box_ = grid.box;

    // The GAS holds the cells' boxes only (the intersection program reads each cell's majorant
    // from the grid), so it needs a build only when the set of selected cells changes: a time
    // step or a TF edit may change it, refinements (which only widen majorants) rarely do.
    INR_CUDA_CHECK(cudaMemsetAsync(changed_.get(), 0, sizeof(unsigned), stream));
    const MajorantAbove above{grid.majorant, options_.gasMinMajorant};
    selectionChangeKernel<<<(cells + 255) / 256, 256, 0, stream>>>(above, cells, selected_.get(), changed_.get());
    INR_CUDA_CHECK_LAUNCH("selectionChangeKernel");
    unsigned changed = 0;
    INR_CUDA_CHECK(cudaMemcpyAsync(&changed, changed_.get(), sizeof(unsigned), cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaStreamSynchronize(stream));
    if (!changed && !newShape && !newBox && !options_.rebuildEveryUpdate) {
      builtFor_ = grid.majorant;
      ++info_.reuses;
      info_.lastRebuilt = false;
      return;
    }
    build(grid, stream);
    builtFor_ = grid.majorant;
    ++info_.builds;
    info_.lastRebuilt = true;
  }

  static bool sameBox(const Box3f& a, const Box3f& b) {
    return a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x && a.hi.y == b.hi.y &&
           a.hi.z == b.hi.z;
  }

  // Device memory for the GAS of a grid of this shape, sized once for the worst case (every cell
  // a primitive), so that rebuilds never allocate and the memory held does not creep up with the
  // scene (it is reported as reservedBytes): the selection and its boxes, cub's temporary, the
  // build's temporary and output and the compacted GAS (never larger than the build's output).
  void reserveFor(const MajorantGridView& grid) {
    const std::size_t cells = std::size_t(grid.dims.x) * grid.dims.y * grid.dims.z;
    shape_ = Int3{0, 0, 0};  // until every buffer below is in place
    gas_ = 0;
    INR_CUDA_CHECK(cudaStreamSynchronize(stream_));  // nothing of the OptiX stream reads the old buffers
    // A lack of memory leaves shape_ empty: the next build reserves again.
    const DeviceAllocationPurpose purpose(
        "the OptiX traversal's acceleration structure over " + std::to_string(cells) + " macrocells",
        "lower the macrocell resolution or set GPU Traversal to DDA (inr render --traversal dda)");
    cellOfPrimitive_.resize(cells);
    aabbs_.resize(cells);
    selected_.resize(cells);
    INR_CUDA_CHECK(cudaMemsetAsync(selected_.get(), 0, cells, stream_));
    std::size_t tempBytes = 0;
    selectCells(grid, nullptr, tempBytes, stream_);  // cub's temporary for this many cells
    selectTemp_.resize(tempBytes);
    const OptixAccelBufferSizes sizes = buildSizes(unsigned(cells));
    buildTemp_.resize(sizes.tempSizeInBytes);
    uncompacted_.resize(sizes.outputSizeInBytes);
    gasBuffer_.resize(sizes.outputSizeInBytes);
    info_.reservedBytes = cells * (sizeof(int) + sizeof(OptixAabb) + 1) + tempBytes + sizes.tempSizeInBytes +
                          2 * sizes.outputSizeInBytes;
    shape_ = grid.dims;
    ++info_.reservations;
  }

  // The cells above the GAS threshold, in increasing index order, into cellOfPrimitive_ and their
  // number into count_ (cub's select; with temp == nullptr only the temporary's size).
  void selectCells(const MajorantGridView& grid, void* temp, std::size_t& tempBytes, cudaStream_t stream) {
    const int cells = grid.dims.x * grid.dims.y * grid.dims.z;
    const thrust::counting_iterator<int> first(0);
    const MajorantAbove above{grid.majorant, options_.gasMinMajorant};
    INR_CUDA_CHECK(cub::DeviceSelect::If(temp, tempBytes, first, cellOfPrimitive_.get(), count_.get(), cells, above,
                                         stream));
  }

  OptixBuildInput buildInput(unsigned primitives, const CUdeviceptr* aabbPtr) const {
    static const unsigned geometryFlags = OPTIX_GEOMETRY_FLAG_DISABLE_ANYHIT;
    OptixBuildInput input = {};
    input.type = OPTIX_BUILD_INPUT_TYPE_CUSTOM_PRIMITIVES;
    input.customPrimitiveArray.aabbBuffers = aabbPtr;
    input.customPrimitiveArray.numPrimitives = primitives;
    input.customPrimitiveArray.flags = &geometryFlags;
    input.customPrimitiveArray.numSbtRecords = 1;
    return input;
  }
  static OptixAccelBuildOptions buildOptions() {
    OptixAccelBuildOptions build = {};
    build.buildFlags = OPTIX_BUILD_FLAG_PREFER_FAST_TRACE | OPTIX_BUILD_FLAG_ALLOW_COMPACTION;
    build.operation = OPTIX_BUILD_OPERATION_BUILD;
    return build;
  }
  OptixAccelBufferSizes buildSizes(unsigned primitives) const {
    const CUdeviceptr aabbPtr = reinterpret_cast<CUdeviceptr>(aabbs_.get());
    const OptixBuildInput input = buildInput(primitives, &aabbPtr);
    const OptixAccelBuildOptions options = buildOptions();
    OptixAccelBufferSizes sizes = {};
    INR_OPTIX_CHECK(optixAccelComputeMemoryUsage(context_, &options, &input, 1, &sizes));
    return sizes;
  }

  // The selected cells (increasing index order: the same majorants give the same primitives,
  // whichever session built them), their boxes, the build and the compaction, into the reserved
  // buffers.
  void build(const MajorantGridView& grid, cudaStream_t stream) {
    const int cells = grid.dims.x * grid.dims.y * grid.dims.z;
    std::size_t tempBytes = selectTemp_.size();
    selectCells(grid, selectTemp_.get(), tempBytes, stream);
    cellAabbKernel<<<(cells + 255) / 256, 256, 0, stream>>>(grid, cellOfPrimitive_.get(), count_.get(), aabbs_.get());
    INR_CUDA_CHECK_LAUNCH("cellAabbKernel");
    unsigned primitives = 0;
    INR_CUDA_CHECK(cudaMemcpyAsync(&primitives, count_.get(), sizeof(unsigned), cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaStreamSynchronize(stream));
    if (debug_ && primitives > 0) {
      OptixAabb a;
      int c0 = 0;
      INR_CUDA_CHECK(cudaMemcpy(&a, aabbs_.get(), sizeof(a), cudaMemcpyDeviceToHost));
      INR_CUDA_CHECK(cudaMemcpy(&c0, cellOfPrimitive_.get(), sizeof(c0), cudaMemcpyDeviceToHost));
      std::fprintf(stderr, "OptiX debug: %u of %d cells; primitive 0 = cell %d [%g %g %g]-[%g %g %g]\n", primitives,
                   cells, c0, a.minX, a.minY, a.minZ, a.maxX, a.maxY, a.maxZ);
    }
    gas_ = 0;
    info_.primitives = primitives;
    info_.bytes = 0;
    if (primitives == 0) return;  // every cell empty: traverse() runs the DDA, as fast and exact
    const OptixAccelBufferSizes sizes = buildSizes(primitives);
    // Within the worst-case reservation (sizes grow with the primitive count); checked, not assumed.
    if (sizes.tempSizeInBytes > buildTemp_.size() || sizes.outputSizeInBytes > uncompacted_.size())
      throw std::logic_error("OptiX GAS: build needs more than the reservation for all cells");
    OptixAccelEmitDesc emit = {};
    emit.type = OPTIX_PROPERTY_TYPE_COMPACTED_SIZE;
    emit.result = reinterpret_cast<CUdeviceptr>(compactedSize_.get());
    const CUdeviceptr aabbPtr = reinterpret_cast<CUdeviceptr>(aabbs_.get());
    const OptixBuildInput input = buildInput(primitives, &aabbPtr);
    const OptixAccelBuildOptions options = buildOptions();
    OptixTraversableHandle handle = 0;
    INR_OPTIX_CHECK(optixAccelBuild(context_, stream, &options, &input, 1,
                                    reinterpret_cast<CUdeviceptr>(buildTemp_.get()), sizes.tempSizeInBytes,
                                    reinterpret_cast<CUdeviceptr>(uncompacted_.get()), sizes.outputSizeInBytes,
                                    &handle, &emit, 1));
    std::size_t compacted = 0;
    INR_CUDA_CHECK(cudaMemcpyAsync(&compacted, compactedSize_.get(), sizeof(compacted), cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaStreamSynchronize(stream));
    if (compacted < sizes.outputSizeInBytes) {
      INR_OPTIX_CHECK(optixAccelCompact(context_, stream, handle, reinterpret_cast<CUdeviceptr>(gasBuffer_.get()),
                                        compacted, &handle));
      INR_CUDA_CHECK(cudaStreamSynchronize(stream));
      info_.bytes = compacted;
    } else {
      // Compaction saved nothing: trace the build's own output (kept until the next build).
      info_.bytes = sizes.outputSizeInBytes;
    }
    gas_ = handle;
  }

  void createPipeline() {
    OptixModuleCompileOptions mco = {};
    mco.maxRegisterCount = OPTIX_COMPILE_DEFAULT_MAX_REGISTER_COUNT;
    mco.optLevel = OPTIX_COMPILE_OPTIMIZATION_DEFAULT;
    mco.debugLevel = OPTIX_COMPILE_DEBUG_LEVEL_NONE;
    OptixPipelineCompileOptions pco = {};
    pco.usesMotionBlur = 0;
    pco.traversableGraphFlags = OPTIX_TRAVERSABLE_GRAPH_FLAG_ALLOW_SINGLE_GAS;
    pco.numPayloadValues = int(kOptixPayloadValues);
    pco.numAttributeValues = int(kOptixAttributeValues);
    pco.exceptionFlags = OPTIX_EXCEPTION_FLAG_NONE;
    pco.pipelineLaunchParamsVariableName = "params";
    pco.usesPrimitiveTypeFlags = OPTIX_PRIMITIVE_TYPE_FLAGS_CUSTOM;
    char log[4096];
    size_t logSize = sizeof(log);
    const OptixResult r = optixModuleCreate(context_, &mco, &pco, reinterpret_cast<const char*>(kInrOptixProgramsIr),
                                            kInrOptixProgramsIrSize, log, &logSize, &module_);
    if (r != OPTIX_SUCCESS)
      throw std::runtime_error(std::string("OptiX: optixModuleCreate failed: ") + optixGetErrorName(r) + ": " + log);

    OptixProgramGroupOptions pgo = {};
    OptixProgramGroupDesc desc[3] = {};
    desc[0].kind = OPTIX_PROGRAM_GROUP_KIND_RAYGEN;
    desc[0].raygen.module = module_;
    desc[0].raygen.entryFunctionName = "__raygen__traverse";
    desc[1].kind = OPTIX_PROGRAM_GROUP_KIND_MISS;
    desc[1].miss.module = module_;
    desc[1].miss.entryFunctionName = "__miss__none";
    desc[2].kind = OPTIX_PROGRAM_GROUP_KIND_HITGROUP;
    desc[2].hitgroup.moduleIS = module_;
    desc[2].hitgroup.entryFunctionNameIS = "__intersection__macrocell";
    desc[2].hitgroup.moduleCH = module_;
    desc[2].hitgroup.entryFunctionNameCH = "__closesthit__macrocell";
    logSize = sizeof(log);
    INR_OPTIX_CHECK(optixProgramGroupCreate(context_, desc, 3, &pgo, log, &logSize, groups_));

    OptixPipelineLinkOptions plo = {};
    plo.maxTraceDepth = 1;
    logSize = sizeof(log);
    INR_OPTIX_CHECK(optixPipelineCreate(context_, &pco, &plo, groups_, 3, log, &logSize, &pipeline_));
    OptixStackSizes ss = {};
    for (OptixProgramGroup g : groups_) INR_OPTIX_CHECK(optixUtilAccumulateStackSizes(g, &ss, pipeline_));
    unsigned dcTraversal = 0, dcState = 0, continuation = 0;
    INR_OPTIX_CHECK(optixUtilComputeStackSizes(&ss, 1, 0, 0, &dcTraversal, &dcState, &continuation));
    INR_OPTIX_CHECK(optixPipelineSetStackSize(pipeline_, dcTraversal, dcState, continuation, 1));

    SbtRecord records[3];
    for (int k = 0; k < 3; ++k) INR_OPTIX_CHECK(optixSbtRecordPackHeader(groups_[k], &records[k]));
    sbtRecords_.resize(3);
    INR_CUDA_CHECK(cudaMemcpy(sbtRecords_.get(), records, sizeof(records), cudaMemcpyHostToDevice));
    const CUdeviceptr base = reinterpret_cast<CUdeviceptr>(sbtRecords_.get());
    sbt_.raygenRecord = base;
    sbt_.missRecordBase = base + sizeof(SbtRecord);
    sbt_.missRecordStrideInBytes = sizeof(SbtRecord);
    sbt_.missRecordCount = 1;
    sbt_.hitgroupRecordBase = base + 2 * sizeof(SbtRecord);
    sbt_.hitgroupRecordStrideInBytes = sizeof(SbtRecord);
    sbt_.hitgroupRecordCount = 1;
  }

  TraversalOptions options_;
  std::unique_ptr<DeviceTraversal> dda_;
  OptixDeviceContext context_ = nullptr;
  OptixModule module_ = nullptr;
  OptixProgramGroup groups_[3] = {nullptr, nullptr, nullptr};
  OptixPipeline pipeline_ = nullptr;
  OptixShaderBindingTable sbt_ = {};
  bool rtCores_ = false;
  bool debug_ = false;
  cudaStream_t stream_ = nullptr;
  cudaEvent_t callerReady_ = nullptr, optixDone_ = nullptr;  // INR_OPTIX_DEBUG: validation mode, counters, one ray printed
  cuda::DeviceBuffer<unsigned long long> debugCounts_;
  cuda::DeviceBuffer<SbtRecord> sbtRecords_;
  cuda::DeviceBuffer<OptixTraversalParams> params_;
  // The GAS and its inputs, reserved per grid shape (reserveFor) and reused from build to build.
  cuda::DeviceBuffer<int> cellOfPrimitive_;
  cuda::DeviceBuffer<unsigned> count_;
  cuda::DeviceBuffer<unsigned char> selectTemp_, buildTemp_, uncompacted_, gasBuffer_;
  cuda::DeviceBuffer<OptixAabb> aabbs_;
  cuda::DeviceBuffer<std::size_t> compactedSize_;
  cuda::DeviceBuffer<unsigned char> selected_;  // per cell: in the GAS (majorant above the threshold)
  cuda::DeviceBuffer<unsigned> changed_;        // set when a cell's selection differs from selected_
  Int3 shape_{0, 0, 0};                         // the grid shape the buffers are reserved for
  Box3f box_{};                                 // the box of the last build's cells
  OptixTraversableHandle gas_ = 0;
  const float* builtFor_ = nullptr;
  TraversalBuildInfo info_;
};

}  // namespace

std::unique_ptr<DeviceTraversal> makeOptixTraversal(const TraversalOptions& options, bool* rtCores) {
  auto t = std::make_unique<OptixTraversal>(options);
  if (rtCores) *rtCores = t->rtCores();
  return t;
}

}  // namespace inr
