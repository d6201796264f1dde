#include "Evaluator/Cuda/CudaInrEvaluator.h"

#include <cublas_v2.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "Common/Activation.h"
#include "Common/Cuda/CudaCheck.h"
#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Common/DeviceMemory.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/Cuda/FusedLaunchAutotuner.h"
#include "Evaluator/Cuda/FusedMlpDevice.cuh"
#include "Evaluator/Cuda/FusedMlpKernelHopper.cuh"
#include "Evaluator/Cuda/FusedMlpKernels.h"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/Cuda/GeneratedKernels.h"
#include "Evaluator/Encodings.h"
#include "Evaluator/MlpProgram.h"

namespace inr {
namespace {

void cublasCheck(cublasStatus_t s, const char* what) {
  if (s == CUBLAS_STATUS_ALLOC_FAILED) throw deviceOutOfMemoryIn(std::string("cuBLAS's ") + what);
  if (s != CUBLAS_STATUS_SUCCESS)
    throw std::runtime_error(std::string("cuBLAS error in ") + what + ": status " + std::to_string(int(s)));
}

// ---- generic fp32 path: one kernel (or cuBLAS call) per instruction over a chunk of queries.
// Activations: column per query, `ld` floats per column; activation functions from
// Common/Activation.h (exact forms; --use_fast_math maps sinf/expf to intrinsics).

__global__ void genericCoords(cuda::FusedParams P, const float4* points, int n, float* coords) {
  const int q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  cuda::networkInputs(P, points[q], coords + q * 4);
}

__global__ void genericEpilogue(MlpInstr in, const float* bias, float* y, const float* other, int ld, int n) {
  const int q = blockIdx.y * blockDim.y + threadIdx.y;
  const int o = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n || o >= in.nPad) return;
  float v = 0.f;
  if (o < in.outWidth) {
    v = activate(in.act, y[q * ld + o] + bias[o]);
    if (other) v = in.combineScale * (v + other[q * ld + o]);
  }
  y[q * ld + o] = v;
}

__global__ void genericElementwise(MlpInstr in, const float* coords, float* dst, const float* a, const float* other,
                                   int ld, int n, int inputDim) {
  const int q = blockIdx.y * blockDim.y + threadIdx.y;
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n || c >= in.nPad) return;
  float v = 0.f;
  if (in.op == MlpOp::LoadInput) {
    v = c < inputDim ? coords[q * 4 + c] : 0.f;
  } else if (in.op == MlpOp::Activation) {
    v = c < in.outWidth ? activate(in.act, in.actScale * dst[q * ld + c]) : dst[q * ld + c];
  } else {  // Combine
    v = in.combineScale * (a[q * ld + c] + (other ? other[q * ld + c] : 0.f));
  }
  dst[q * ld + c] = v;
}

// Every encoding (Evaluator/Encodings.h), one thread per output element.
__global__ void genericEncoding(MlpInstr in, const float* weights, const float* src, int srcLd, float* dst, int ld, int n) {
  const int q = blockIdx.y * blockDim.y + threadIdx.y;
  const int c = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n || c >= in.nPad) return;
  const float* x = src + q * srcLd;
  dst[q * ld + c] = c < in.outWidth ? encodingElement(in, weights, [x](int k) { return x[k]; }, c) : 0.f;
}

__global__ void genericOutput(MlpInstr in, const float* W, const float* bias, const float* src, int srcLd,
                              cuda::OutputMap map, const float4* points, int n, int offset, float* out,
                              const int* scatter) {
  const int q = blockIdx.x * blockDim.x + threadIdx.x;
  if (q >= n) return;
  float net;
  if (W) {
    float acc = 0.f;
    for (int k = 0; k < in.inWidth; ++k) acc += W[k] * src[q * srcLd + k];
    net = activate(in.act, acc + bias[0]);
  } else {
    net = src[q * srcLd];
  }
  cuda::writeOutput(map, points[q].w, net, offset + q, out, scatter);
}

using cuda::FusedConfig;
using cuda::FusedKernel;
using cuda::FusedLaunchAutotuner;
using cuda::configName;

#if !defined(INR_HAVE_HOPPER_KERNEL)
}  // namespace
namespace cuda {
FusedKernel hopperKernel(int, int, bool, bool) { return nullptr; }  // not built: no Hopper architecture
}  // namespace cuda
namespace {
#endif

// Why the wgmma kernel cannot run here ("" when it can): it is built for sm_90a, so it loads
// only on a compute capability 9.0 device.
std::string whyNoWgmmaKernel(const CudaDeviceInfo& device, const CudaEvaluatorOptions& options) {
  if (options.mma == FusedMma::MmaSync) return "not requested";
  if (!cuda::hopperKernel(64, 2)) return "not built (no CUDA architecture 90)";
  if (device.major != 9 || device.minor != 0) return "needs compute capability 9.0";
  cudaFuncAttributes attr{};
  const cudaError_t e = cudaFuncGetAttributes(&attr, cuda::hopperKernel(64, 2));
  if (e != cudaSuccess) {
    cudaGetLastError();
    return std::string("sm_90a code does not load: ") + cudaGetErrorString(e);
  }
  return "";
}

std::vector<__half> asHalves(const std::vector<std::uint16_t>& bits) {
  std::vector<__half> h(bits.size());
  for (std::size_t i = 0; i < h.size(); ++i) h[i] = __ushort_as_half(bits[i]);
  return h;
}

}  // namespace

GeneratedKernelUse generatedKernelUseFromEnvironment() {
  const char* v = std::getenv("INR_GENERATED_KERNELS");
  if (!v || !*v) return GeneratedKernelUse::Auto;
  const std::string s(v);
  if (s == "auto" || s == "1") return GeneratedKernelUse::Auto;
  if (s == "only") return GeneratedKernelUse::Only;
  if (s == "off" || s == "0") return GeneratedKernelUse::Off;
  std::fprintf(stderr, "INR_GENERATED_KERNELS=%s: taken as auto, the default (it takes off, auto or only)\n", v);
  return GeneratedKernelUse::Auto;
}

struct CudaInrEvaluator::Impl {
  CudaDeviceInfo device;
  // The kernels generated for this model (null: not built), and what became of them.
  std::unique_ptr<cuda::GeneratedKernels> generated;
  std::string generatedReport = "off";
  // GeneratedKernelUse::Auto: the generated twins of the fastest mma.sync configurations,
  // compiling in the background; when they are ready the next launch loads them, times them
  // against the configurations running (adoptGenerated) and keeps the faster. The generated
  // kernels compute the interpreter's bits, so a frame does not change where they take over.
  std::unique_ptr<cuda::GeneratedKernels::Pending> pendingGenerated;
  std::atomic<bool> generatedPending{false};
  mutable std::mutex adoptMutex;
  std::string adoptionReport;  // what the adoption timed and kept
  std::string choiceReport, persistenceReport;  // the constructor's autotuning; the L2 window
  MlpProgram program;
  CudaEvaluatorPath path = CudaEvaluatorPath::Fused;
  FusedConfig config;       // launches of kSmallBatchThreshold queries or more
  FusedConfig smallConfig;  // smaller launches
  static constexpr int kSmallBatchThreshold = FusedLaunchAutotuner::kSmallBatchThreshold;
  cuda::FusedParams params;
  cuda::FusedParams paramsStored;  // the unfused program (FusedConfig::storedEncoding)
  // The same for the wgmma kernel with the encoding split for its GEMM (FusedConfig::splitEncoding;
  // hopperSplitGemm -1: the program has no such encoding)
  cuda::FusedParams paramsSplit;
  cuda::DeviceBuffer<MlpInstr> storedInstrs;
  cuda::DeviceBuffer<MlpInstr> instrs;
  MlpProgram hopperProgram;  // program.withGemmsInPlace(kHopperKSegment)
  cuda::DeviceBuffer<MlpInstr> hopperInstrs;
  cuda::DeviceBuffer<MlpInstr> hopperStoredInstrs;  // the same with any Fourier encoding stored
  cuda::DeviceBuffer<MlpInstr> hopperSplitInstrs;   // and with one split (FusedParams::hopperSplitGemm)
  cuda::DeviceBuffer<__half> stagedW[2];  // GEMM weights in the stage layout, weight chunks of 64 / 32
  cuda::DeviceBuffer<__half> hopperW[2];  // the same in the wgmma chunks' core-matrix layout, chunks of 64 / 128 columns
  std::string whyNoWgmma;                 // empty when the wgmma kernel can run here
  cuda::DeviceBuffer<float> floatW;
  cuda::DeviceBuffer<__half> hashTables;  // MlpProgram::halfWeights, for a program with a hash grid
  // CudaEvaluatorOptions::hashTablesPersistInL2: the fused launches' access-policy window over
  // the tables (num_bytes 0: none).
  cudaAccessPolicyWindow tablesWindow{};
  cuda::DeviceBuffer<float> outputTable;
  // host-interface staging
  mutable cuda::DeviceBuffer<float4> stagePoints;
  mutable cuda::DeviceBuffer<float> stageOut;
  // generic path
  cublasHandle_t cublas = nullptr;
  mutable cuda::DeviceBuffer<float> genericBuffers, genericCoords;
  static constexpr int kGenericChunk = 1 << 16;
  // Gradient shading's value + gradient queries: the fused kernel's tangent rows (tangentConfig
  // for launches of kSmallBatchThreshold queries or more, smallTangentConfig below) where
  // fusedTangents, else fp32 forward mode, one thread per query (gradientNetwork, built only
  // then; why not fused: whyNoFusedTangents).
  std::unique_ptr<CudaPerThreadMlp> gradientNetwork;
  bool fusedTangents = false;
  std::string whyNoFusedTangents;
  OutputMapping output;
  // Chosen at the first value + gradient call (most evaluators never see one): the tangent
  // scale (a CPU emulation of a sample) and the configurations (timed like the value path's).
  mutable std::once_flag tangentsTuned;
  mutable float tangentScale = 1.f;  // MlpProgram::tangentScale
  int tangentInput[3] = {-1, -1, -1};
  mutable FusedConfig tangentConfig, smallTangentConfig;
  mutable std::string tangentReport;
  std::optional<FusedLaunchAutotuner> tuner;
  std::vector<FusedConfig> tangentCandidates;
  int tangentAutotuneBatch = 0;  // CudaEvaluatorOptions::tangentAutotuneBatch
  mutable bool tangentsTimed = false;  // tuneTangents has run
  Domain domain;

  void prepareParams(const InrModel& model);
  // Sets tablesWindow (and the device's persisting L2 limit) over the hash tables; what it did.
  std::string persistTablesInL2();
  // Runs one fused configuration on n points (at most, with a device-side count).
  void launchFused(const FusedConfig& c, const float4* points, int n, const unsigned* deviceCount, float* out,
                   const int* scatter, cudaStream_t stream) const;
  // The same for value + gradient (a configuration with tangent rows) at world time `time`.
  void launchTangents(const FusedConfig& c, const float4* points, int n, const unsigned* deviceCount, float time,
                      float4* out, cudaStream_t stream) const;
  // Whether the tangent rows can run (their candidates among the value path's), or why not.
  void prepareTangents(const InrModel& model, const CudaEvaluatorOptions& options, const FusedLaunchAutotuner& tuner,
                       const std::vector<FusedConfig>& candidates);
  // The tangent scale and configurations, once (tangentsTuned).
  void tuneTangents() const;
  // The fastest of `race` (configurations with tangent rows) on the tangent batches.
  FusedLaunchAutotuner::Choice chooseTangents(const std::vector<FusedConfig>& race) const;
  // The background compilation's kernels, when ready (or, with wait, once ready): loaded, timed
  // against the configurations running, the faster kept. A no-op after the first time.
  void adoptGenerated(bool wait);
  // The configuration a launch of n queries runs (values or tangent rows), read under
  // adoptMutex: another thread may be adopting the generated kernels.
  FusedConfig launchConfig(int n, bool tangents) {
    std::lock_guard<std::mutex> lock(adoptMutex);
    return n < kSmallBatchThreshold ? (tangents ? smallTangentConfig : smallConfig) : (tangents ? tangentConfig : config);
  }
};

// The program's parameters for the fused kernels (params, and paramsStored with any Fourier
// encoding stored), with the weights packed and uploaded for each kernel and chunk width.
void CudaInrEvaluator::Impl::prepareParams(const InrModel& model) {
  const MlpProgram& prog = program;
  // Input mapping in network input order; output mapping as a (t, a, b) table.
  auto& P = params;
  P.inputDim = model.architecture.inputDim;
  for (int i = 0; i < P.inputDim; ++i) {
    const int w = model.domain.inputOrder[i];
    P.inputCoord[i] = w;
    P.inScale[i] = float(model.domain.toNetwork[w].scale);
    P.inOffset[i] = float(model.domain.toNetwork[w].offset);
  }
  std::vector<float> table;
  if (model.output.perTime) {
    for (double t : model.output.perTime->times) {
      float a, b;
      model.output.affineAt(t, a, b);
      table.insert(table.end(), {float(t), a, b});
    }
    outputTable.upload(table, nullptr);
    P.output.count = int(model.output.perTime->times.size());
    P.output.table = outputTable.get();
  } else {
    P.output.a = model.output.scale;
    P.output.b = model.output.offset;
  }

  instrs.upload(prog.instrs, nullptr);
  for (int kc : {64, 32}) {
    stagedW[cuda::kcIndex(kc)].upload(asHalves(cuda::packStagedWeights(prog, kc, P.stagedOffset[cuda::kcIndex(kc)])), nullptr);
    P.stagedWeights[cuda::kcIndex(kc)] = stagedW[cuda::kcIndex(kc)].get();
  }
  // Each warp of the wgmma kernel holds a layer's A (K <= 256) in registers before its
  // epilogues write the rows: in place up to that K.
  hopperProgram = prog.withGemmsInPlace(cuda::kHopperKSegment);
  if (whyNoWgmma.empty()) {
    for (const int nc : cuda::kHopperChunkWidths) {
      const int w = cuda::chunkIndex(nc);
      hopperW[w].upload(asHalves(cuda::packHopperWeights(prog, nc, P.hopperOffset[w], cuda::kMaxFusedInstrs)), nullptr);
      P.hopperWeights[w] = hopperW[w].get();
      P.hopperStageHalves[w] = cuda::hopperStageHalves(prog, nc);
    }
    hopperInstrs.upload(hopperProgram.instrs, nullptr);
    P.hopperInstrs = hopperInstrs.get();
  }
  P.hopperBiasFloats = cuda::hopperBiasLayout(prog, P.hopperBiasStart, cuda::kMaxFusedInstrs);
  P.hopperNumBuffers = std::max(1, hopperProgram.numBuffers);
  for (int b = 0; b < P.hopperNumBuffers && b < cuda::kMaxBuffers; ++b)
    P.hopperBufferLd[b] = hopperProgram.bufferWidthPad[b] + 8;
  for (const MlpInstr& in : prog.instrs) P.fusedFourier |= in.fourierInput >= 0 ? 1 : 0;
  const MlpProgram storedProgram = prog.withEncodingsStored();
  if (P.fusedFourier) storedInstrs.upload(storedProgram.instrs, nullptr);
  // The wgmma kernel's form of the stored program: the Fourier instruction writes the encoding
  // once per tile into its buffer (a row instruction), the first GEMM loads A from there by
  // ldmatrix, one K segment of 256 at a time, like any wider layer (K > 256: not in place, so its
  // output goes to a second buffer). The GEMMs, their weights, biases and ring slots are the
  // fused program's (the same instruction indices): only the buffers differ.
  MlpProgram hopperStoredProgram, hopperSplitProgram;
  int splitGemm = -1;
  std::vector<int> splitLd;
  if (P.fusedFourier && whyNoWgmma.empty()) {
    hopperStoredProgram = storedProgram.withGemmsInPlace(cuda::kHopperKSegment);
    if (hopperStoredProgram.numBuffers <= cuda::kMaxBuffers) hopperStoredInstrs.upload(hopperStoredProgram.instrs, nullptr);
    // The split form (FusedParams::hopperSplitGemm) for the first GEMM reading a fused encoding
    // with K 257..512 (two K segments: the first from the operand region, the second from the
    // registers): that GEMM in place over the encoding's buffer, which then holds the encoding's
    // columns from 256 on and the values stored there later.
    for (std::size_t i = 1; i < prog.instrs.size() && i < std::size_t(cuda::kMaxFusedInstrs) && splitGemm < 0; ++i) {
      const MlpInstr& g = prog.instrs[i];
      if (g.fourierInput == int(i) - 1 && g.kPad > cuda::kHopperKSegment && g.kPad <= 2 * cuda::kHopperKSegment)
        splitGemm = int(i);
    }
    if (splitGemm >= 0) {
      hopperSplitProgram = storedProgram.withGemmsInPlace(cuda::kHopperKSegment, splitGemm);
      const MlpInstr& f = hopperSplitProgram.instrs[std::size_t(splitGemm) - 1];
      const MlpInstr& g = hopperSplitProgram.instrs[std::size_t(splitGemm)];
      if (hopperSplitProgram.numBuffers > cuda::kMaxBuffers || g.src < 0 || g.dst != g.src || f.dst != g.src) {
        splitGemm = -1;  // not in place: no split form
      } else {
        splitLd.assign(std::size_t(hopperSplitProgram.numBuffers), 16);
        for (const MlpInstr& in : hopperSplitProgram.instrs)
          if (in.dst >= 0) {
            const int w = &in == &f ? in.nPad - cuda::kHopperKSegment : in.nPad;
            splitLd[std::size_t(in.dst)] = std::max(splitLd[std::size_t(in.dst)], w);
          }
        hopperSplitInstrs.upload(hopperSplitProgram.instrs, nullptr);
      }
    }
  }
  floatW.upload(prog.floatWeights, nullptr);
  for (const MlpInstr& in : prog.instrs)
    if (in.op == MlpOp::HashGrid && !hashTables.get()) hashTables.upload(asHalves(prog.halfWeights), nullptr);
  P.hashTables = hashTables.get();
  INR_CUDA_CHECK(cudaDeviceSynchronize());  // the uploads are asynchronous; launches may use other streams
  P.instrs = instrs.get();
  P.numInstrs = int(prog.instrs.size());
  P.floatWeights = floatW.get();
  P.numBuffers = std::max(1, prog.numBuffers);
  for (int b = 0; b < P.numBuffers && b < cuda::kMaxBuffers; ++b) P.bufferLd[b] = prog.bufferWidthPad[b] + 8;
  P.maxGemmOutPad = std::max(16, prog.maxGemmOutPad);
  // The same program with any Fourier encoding stored in its buffer (not fused into the GEMM).
  paramsStored = P;
  if (P.fusedFourier) {
    paramsStored.instrs = storedInstrs.get();
    paramsStored.fusedFourier = 0;
    for (int b = 0; b < P.numBuffers && b < cuda::kMaxBuffers; ++b)
      paramsStored.bufferLd[b] = storedProgram.bufferWidthPad[std::size_t(b)] + 8;
    if (hopperStoredInstrs.get()) {
      paramsStored.hopperInstrs = hopperStoredInstrs.get();
      paramsStored.hopperNumBuffers = std::max(1, hopperStoredProgram.numBuffers);
      for (int b = 0; b < cuda::kMaxBuffers; ++b)
        paramsStored.hopperBufferLd[b] = b < paramsStored.hopperNumBuffers ? hopperStoredProgram.bufferWidthPad[b] + 8 : 0;
    }
  }
  paramsSplit = paramsStored;
  paramsSplit.hopperSplitGemm = -1;
  if (splitGemm >= 0) {
    paramsSplit.hopperInstrs = hopperSplitInstrs.get();
    paramsSplit.hopperSplitGemm = splitGemm;
    paramsSplit.hopperNumBuffers = std::max(1, hopperSplitProgram.numBuffers);
    for (int b = 0; b < cuda::kMaxBuffers; ++b)
      paramsSplit.hopperBufferLd[b] = b < int(splitLd.size()) ? splitLd[std::size_t(b)] + 8 : 0;
  }
}

std::string CudaInrEvaluator::Impl::persistTablesInL2() {
  if (!hashTables.get()) return "";
  // The span of halfWeights the tables occupy (they follow the GEMM weights of earlier layers).
  std::size_t begin = program.halfWeights.size(), end = 0;
  for (const MlpInstr& in : program.instrs) {
    if (in.op != MlpOp::HashGrid) continue;
    const HashGridView g{program.floatWeights.data() + in.floatOffset};
    const int last = g.levels() - 1;
    begin = std::min(begin, std::size_t(in.halfOffset));
    end = std::max(end, std::size_t(in.halfOffset) + (std::size_t(g.firstEntry(last)) + g.entries(last)) * g.features());
  }
  int maxPersist = 0, maxWindow = 0;
  INR_CUDA_CHECK(cudaDeviceGetAttribute(&maxPersist, cudaDevAttrMaxPersistingL2CacheSize, device.device));
  INR_CUDA_CHECK(cudaDeviceGetAttribute(&maxWindow, cudaDevAttrMaxAccessPolicyWindowSize, device.device));
  if (maxPersist <= 0 || maxWindow <= 0) return " [L2 persistence: not supported here]";
  const std::size_t bytes = std::min((end - begin) * sizeof(__half), std::size_t(maxWindow));
  const std::size_t persist = std::min(bytes, std::size_t(maxPersist));
  INR_CUDA_CHECK(cudaDeviceSetLimit(cudaLimitPersistingL2CacheSize, persist));
  tablesWindow.base_ptr = hashTables.get() + begin;
  tablesWindow.num_bytes = bytes;
  // A window larger than the persisting set: only that fraction of its lines persist.
  tablesWindow.hitRatio = float(double(persist) / double(bytes));
  tablesWindow.hitProp = cudaAccessPropertyPersisting;
  tablesWindow.missProp = cudaAccessPropertyStreaming;
  return " [L2 persistence: " + std::to_string(persist >> 20) + " of " + std::to_string(bytes >> 20) + " MB of tables]";
}

void CudaInrEvaluator::Impl::launchFused(const FusedConfig& c, const float4* points, int n, const unsigned* deviceCount,
                                         float* out, const int* scatter, cudaStream_t stream) const {
  // With a device-side count, the grid follows the bound (the kernel's tile loop is
  // grid-strided, so extra blocks just exit).
  const int tiles = (n + c.tile - 1) / c.tile;
  const int grid = std::min(tiles, c.gridBlocks);
  const FusedKernel kernel = c.wgmma       ? cuda::hopperKernel(c.kc, c.consumers, c.splitEncoding, c.splitColumns)
                            : c.generated ? generated->kernel(c.tile, c.kc, c.storedEncoding, false)
                                          : cuda::mmaSyncKernel(c.tile, c.kc);
  cuda::FusedParams P = c.splitEncoding ? paramsSplit : c.storedEncoding ? paramsStored : params;
  if (c.wgmma) {
    P.hopperStages = c.stages;
    P.hopperPingPong = c.pingPong ? 1 : 0;
  }
  P.hashGridPairs = c.hashGridPairs != 0 ? 1 : 0;
  cudaLaunchConfig_t launch{};
  launch.gridDim = dim3(unsigned(grid));
  launch.blockDim = dim3(unsigned(c.wgmma ? cuda::hopperThreads(c.consumers) : c.tile * 4));
  launch.dynamicSmemBytes = c.sharedBytes;
  launch.stream = stream;
  cudaLaunchAttribute window{};
  if (tablesWindow.num_bytes) {
    window.id = cudaLaunchAttributeAccessPolicyWindow;
    window.val.accessPolicyWindow = tablesWindow;
    launch.attrs = &window;
    launch.numAttrs = 1;
  }
  INR_CUDA_CHECK(cudaLaunchKernelEx(&launch, kernel, P, points, n, deviceCount, out, scatter));
  INR_CUDA_CHECK_LAUNCH("fusedMlpKernel");
}

void CudaInrEvaluator::Impl::launchTangents(const FusedConfig& c, const float4* points, int n, const unsigned* deviceCount,
                                            float time, float4* out, cudaStream_t stream) const {
  const int queriesPerTile = c.tile / 4;  // TileRows<true>: a query's value and three tangents
  const int grid = std::min((n + queriesPerTile - 1) / queriesPerTile, c.gridBlocks);
  cuda::FusedParams P = c.storedEncoding ? paramsStored : params;
  P.tangentScale = tangentScale;
  for (int axis = 0; axis < 3; ++axis) P.tangentInput[axis] = tangentInput[axis];
  // One output mapping for the launch, at `time` (as the per-thread path maps it).
  float a = 1.f, b = 0.f;
  output.affineAt(time, a, b);
  P.output = cuda::OutputMap{a, b, 0, nullptr};
  for (int axis = 0; axis < 3; ++axis) {
    const int i = P.tangentInput[axis];
    P.gradientScale[axis] = i >= 0 ? a * P.inScale[i] / P.tangentScale : 0.f;
  }
  const FusedKernel kernel =
      c.generated ? generated->kernel(c.tile, c.kc, c.storedEncoding, true) : cuda::mmaSyncTangentKernel(c.tile, c.kc);
  // Through the runtime's launch call, never kernel<<<...>>>: a generated kernel is a library's
  // handle, not a host stub that the chevrons would call.
  cudaLaunchConfig_t launch{};
  launch.gridDim = dim3(unsigned(grid));
  launch.blockDim = dim3(unsigned(c.tile * 4));
  launch.dynamicSmemBytes = c.sharedBytes;
  launch.stream = stream;
  INR_CUDA_CHECK(cudaLaunchKernelEx(&launch, kernel, P, points, n, deviceCount, reinterpret_cast<float*>(out),
                                    static_cast<const int*>(nullptr)));
  INR_CUDA_CHECK_LAUNCH("fusedMlpKernel (tangent rows)");
}

void CudaInrEvaluator::Impl::prepareTangents(const InrModel& model, const CudaEvaluatorOptions& options,
                                             const FusedLaunchAutotuner& tuner, const std::vector<FusedConfig>& candidates) {
  int tangentInput[3];
  if (options.gradientPath == CudaGradientPath::PerThread) {
    whyNoFusedTangents = "per-thread requested";
  } else if (path != CudaEvaluatorPath::Fused) {
    whyNoFusedTangents = "the model runs on the generic path";
  } else if (!tangentInputsOf(model.domain, model.architecture.inputDim, tangentInput)) {
    whyNoFusedTangents = "a world axis feeds more than one network input";
  }
  if (whyNoFusedTangents.empty()) tangentCandidates = tuner.tangentCandidates(candidates, generated.get());
  if (whyNoFusedTangents.empty() && tangentCandidates.empty())
    whyNoFusedTangents = "no mma.sync configuration among the launch candidates (the kernel with tangent rows)";
  if (!whyNoFusedTangents.empty()) {
    if (options.gradientPath == CudaGradientPath::FusedTangents)
      throw std::runtime_error("fused tangent rows requested but impossible for this model: " + whyNoFusedTangents);
    // The per-thread network (its own compiled program and fp32 weights on the device) only
    // where it is the gradient path.
    gradientNetwork = std::make_unique<CudaPerThreadMlp>(model);
    return;
  }
  for (int axis = 0; axis < 3; ++axis) this->tangentInput[axis] = tangentInput[axis];
  this->tuner.emplace(tuner);
  tangentAutotuneBatch = options.tangentAutotuneBatch;
  domain = model.domain;
  tangentConfig = smallTangentConfig = tangentCandidates.front();
  fusedTangents = true;
}

void CudaInrEvaluator::Impl::tuneTangents() const {
  std::call_once(tangentsTuned, [&] {
    std::lock_guard<std::mutex> lock(adoptMutex);  // tangentCandidates: an adoption may add to them
    // The scale from a CPU emulation of a sample (MlpProgram.h chooseTangentScale).
    tangentScale = chooseTangentScale(program, domain);
    const FusedLaunchAutotuner::Choice choice = chooseTangents(tangentCandidates);
    tangentConfig = choice.large;
    smallTangentConfig = choice.small;
    tangentReport = choice.report;
    tangentsTimed = true;
  });
}

FusedLaunchAutotuner::Choice CudaInrEvaluator::Impl::chooseTangents(const std::vector<FusedConfig>& race) const {
  INR_CUDA_CHECK(cudaDeviceSynchronize());  // the caller's stream may hold work the timing would count
  cuda::DeviceBuffer<float4> results;
  const int batch = tuner->candidatesBatch() > 0 ? tangentAutotuneBatch : 0;
  results.growTo(std::size_t(std::max(batch, FusedLaunchAutotuner::kSmallBatch)));
  const float time = float(domain.timeBegin);
  return tuner->choose(
      race, domain,
      [&](const FusedConfig& c, const float4* points, int n, float*) {
        launchTangents(c, points, n, nullptr, time, results.get(), nullptr);
      },
      batch);
}

void CudaInrEvaluator::Impl::adoptGenerated(bool wait) {
  if (!generatedPending.load(std::memory_order_acquire)) return;
  std::lock_guard<std::mutex> lock(adoptMutex);
  if (!pendingGenerated || (!wait && !pendingGenerated->ready())) return;
  generated = pendingGenerated->take();
  pendingGenerated.reset();
  generatedPending = false;
  generatedReport = generated->report();
  if (!generated->available()) {
    generated.reset();
    return;
  }
  // The values: the configurations running now against the generated ones (twins of the
  // fastest mma.sync configurations; a hash grid's both gather arrangements).
  const std::vector<FusedConfig> all =
      tuner->candidates(params, paramsStored, paramsSplit, whyNoWgmma.empty(), generated.get());
  std::vector<FusedConfig> race{config};
  if (!cuda::sameConfig(smallConfig, config)) race.push_back(smallConfig);
  for (const FusedConfig& c : all)
    if (c.generated) race.push_back(c);
  INR_CUDA_CHECK(cudaDeviceSynchronize());  // the caller's stream may hold work the timing would count
  const FusedLaunchAutotuner::Choice choice =
      tuner->choose(race, domain, [&](const FusedConfig& c, const float4* points, int n, float* out) {
        launchFused(c, points, n, nullptr, out, nullptr, nullptr);
      });
  config = choice.large;
  smallConfig = choice.small;
  adoptionReport = "generated kernels ready: " + choice.report;
  // The tangent rows: before their first use they join the candidates; after it, they are timed
  // against the configurations chosen then.
  if (!fusedTangents) return;
  std::vector<FusedConfig> generatedTangents;
  for (const FusedConfig& c : tuner->tangentCandidates(all, generated.get()))
    if (c.generated) generatedTangents.push_back(c);
  if (generatedTangents.empty()) return;
  if (!tangentsTimed) {
    tangentCandidates.insert(tangentCandidates.end(), generatedTangents.begin(), generatedTangents.end());
    return;
  }
  std::vector<FusedConfig> tangentRace{tangentConfig};
  if (!cuda::sameConfig(smallTangentConfig, tangentConfig)) tangentRace.push_back(smallTangentConfig);
  tangentRace.insert(tangentRace.end(), generatedTangents.begin(), generatedTangents.end());
  const FusedLaunchAutotuner::Choice t = chooseTangents(tangentRace);
  tangentConfig = t.large;
  smallTangentConfig = t.small;
  tangentReport += "; generated kernels ready: " + t.report;
}

CudaInrEvaluator::CudaInrEvaluator(const InrModel& model, CudaEvaluatorOptions options)
    : impl_(std::make_unique<Impl>()) {
  if (options.tangentAutotuneBatch < 0)
    throw std::invalid_argument("CudaEvaluatorOptions::tangentAutotuneBatch must be 0 (no timing) or more, not " +
                                std::to_string(options.tangentAutotuneBatch));
  if (options.wgmmaConsumers < 0 || options.wgmmaConsumers > 2)
    throw std::invalid_argument("CudaEvaluatorOptions::wgmmaConsumers must be 0 (both autotuned), 1 or 2, not " +
                                std::to_string(options.wgmmaConsumers));
  if (options.storedEncoding < -1 || options.storedEncoding > 2)
    throw std::invalid_argument("CudaEvaluatorOptions::storedEncoding must be -1 (all autotuned), 0, 1 or 2, not " +
                                std::to_string(options.storedEncoding));
  if (options.wgmmaConsumers == 1 && options.wgmmaPingPong == 1)
    throw std::invalid_argument("CudaEvaluatorOptions: wgmmaPingPong = 1 (turns) needs two consumers; set "
                                "wgmmaConsumers to 2 or 0, or wgmmaPingPong to 0 or -1");
  if (options.wgmmaColumnSplit < -1 || options.wgmmaColumnSplit > 1)
    throw std::invalid_argument("CudaEvaluatorOptions::wgmmaColumnSplit must be -1 (both autotuned), 0 or 1, not " +
                                std::to_string(options.wgmmaColumnSplit));
  if (options.wgmmaColumnSplit == 1 && (options.wgmmaConsumers == 1 || options.wgmmaPingPong == 1))
    throw std::invalid_argument("CudaEvaluatorOptions: wgmmaColumnSplit = 1 (two consumers on one tile) needs two "
                                "consumers without turns; set wgmmaConsumers to 2 or 0 and wgmmaPingPong to 0 or -1, "
                                "or wgmmaColumnSplit to 0 or -1");
  if (options.wgmmaColumnSplit == 1 && options.storedEncoding == 2)
    throw std::invalid_argument("CudaEvaluatorOptions: wgmmaColumnSplit = 1 (two consumers on one tile) does not run "
                                "the split encoding (storedEncoding = 2); set one of them to -1 or 0");
  Impl& I = *impl_;
  I.device = queryCudaDevice(options.device);
  if (!I.device.usable) throw std::runtime_error("CUDA backend unavailable: " + I.device.reason);
  INR_CUDA_CHECK(cudaSetDevice(options.device));
  I.program = MlpProgram::compile(model.architecture);
  I.whyNoWgmma = whyNoWgmmaKernel(I.device, options);
  {
    const DeviceAllocationPurpose purpose(
        "the network's weights (" + std::to_string(model.architecture.parameterCount()) + " parameters, packed per kernel)",
        "free GPU memory (close other views or models on this GPU) or render this model on the CPU");
    I.prepareParams(model);
  }
  I.persistenceReport = options.hashTablesPersistInL2 ? I.persistTablesInL2() : "";
  I.output = model.output;

  // The path: fused where the program and a configuration fit, else generic.
  const MlpProgram& prog = I.program;
  bool fused = prog.fusable && options.path != CudaEvaluatorPath::Generic;
  std::string why = prog.whyNotFused;
  if (fused && int(prog.instrs.size()) > cuda::kMaxFusedInstrs) {
    fused = false;
    why = "the program has " + std::to_string(prog.instrs.size()) + " instructions (fused kernel: up to " +
          std::to_string(cuda::kMaxFusedInstrs) + ")";
  }
  if (fused && options.mma == FusedMma::Wgmma && !I.whyNoWgmma.empty()) {
    fused = false;
    why = "the wgmma kernel was requested but is unavailable: " + I.whyNoWgmma;
  }
  // The kernels generated for this model (the mma.sync design: not with the wgmma kernel forced).
  // Only: all of them, compiled here; Auto: after the autotuning, in the background (below).
  if (fused && options.generatedKernels == GeneratedKernelUse::Only && options.mma != FusedMma::Wgmma) {
    // (the configurations the options allow only: each kernel is a compilation)
    const std::vector<int> tiles = options.tileQueries ? std::vector<int>{options.tileQueries} : std::vector<int>{128, 64, 32};
    const std::vector<int> chunks = options.weightChunk ? std::vector<int>{options.weightChunk} : std::vector<int>{64, 32};
    I.generated = std::make_unique<cuda::GeneratedKernels>(prog, I.device.major, I.device.minor, options.kernelCacheDir,
                                                           tiles, chunks);
    I.generatedReport = I.generated->report();
    if (!I.generated->available()) I.generated.reset();
  } else if (options.generatedKernels == GeneratedKernelUse::Off) {
    I.generatedReport = "off (CudaEvaluatorOptions::generatedKernels / INR_GENERATED_KERNELS)";
  } else if (fused && options.mma == FusedMma::Wgmma) {
    I.generatedReport = "off (the wgmma kernel requested)";
  }
  const FusedLaunchAutotuner tuner(I.device, options);
  std::vector<FusedConfig> candidates;
  if (fused) {
    candidates = tuner.candidates(I.params, I.paramsStored, I.paramsSplit, I.whyNoWgmma.empty(), I.generated.get());
    if (candidates.empty() && options.generatedKernels == GeneratedKernelUse::Only) {
      fused = false;
      why = "only generated kernels requested (CudaEvaluatorOptions::generatedKernels / INR_GENERATED_KERNELS), and "
            "there are none that fit: " + I.generatedReport;
    } else if (candidates.empty()) {
      fused = false;
      if (options.storedEncoding == 2 && I.params.fusedFourier && I.paramsSplit.hopperSplitGemm < 0)
        why = "CudaEvaluatorOptions::storedEncoding 2 (the split encoding) needs the wgmma kernel " +
              std::string(I.whyNoWgmma.empty() ? "and a first layer reading the Fourier encoding with K 257..512; this "
                                                 "model's is not one: set storedEncoding to -1, 0 or 1"
                                               : "(unavailable: " + I.whyNoWgmma + "); set storedEncoding to -1, 0 or 1");
      else if (options.storedEncoding == 2 && I.params.fusedFourier && options.mma == FusedMma::MmaSync)
        why = "CudaEvaluatorOptions::storedEncoding 2 (the split encoding) runs on the wgmma kernel only, and mma is "
              "MmaSync: set mma to Auto or Wgmma, or storedEncoding to -1, 0 or 1";
      else
        why = "the fused kernel needs more shared memory than " + I.device.name + " offers per block" +
              (options.storedEncoding == 2 && I.params.fusedFourier ? " in the split encoding's form (storedEncoding 2)" : "");
    }
  }
  if (options.path == CudaEvaluatorPath::Fused && !fused)
    throw std::runtime_error("fused CUDA evaluator requested but impossible for this model: " + why);
  I.path = fused ? CudaEvaluatorPath::Fused : CudaEvaluatorPath::Generic;
  if (!fused) {
    cublasCheck(cublasCreate(&I.cublas), "cublasCreate");
    I.prepareTangents(model, options, tuner, candidates);  // says why not
    return;
  }
  const FusedLaunchAutotuner::Choice choice =
      tuner.choose(candidates, model.domain, [&](const FusedConfig& c, const float4* points, int n, float* out) {
        I.launchFused(c, points, n, nullptr, out, nullptr, nullptr);
      });
  I.config = choice.large;
  I.smallConfig = choice.small;
  I.choiceReport = choice.report;
  I.tuner.emplace(tuner);
  I.domain = model.domain;
  I.prepareTangents(model, options, tuner, candidates);
  if (options.generatedKernels == GeneratedKernelUse::Auto && options.mma != FusedMma::Wgmma) {
    if (!choice.hasMmaSync) {
      I.generatedReport = "not built: no mma.sync configuration fits";
    } else if (options.autotuneBatch <= 0) {
      I.generatedReport = "not built: autotuning is off (autotuneBatch 0), so they would never be chosen";
    } else {
      // The twins of the fastest interpreter configurations, large and small batches.
      std::vector<cuda::GeneratedKernelConfig> wanted;
      for (const FusedConfig& c : {choice.mmaSyncLarge, choice.mmaSyncSmall})
        wanted.push_back({c.tile, c.kc, c.storedEncoding});
      std::string why;
      I.pendingGenerated = cuda::GeneratedKernels::startInBackground(prog, I.device.major, I.device.minor,
                                                                     options.kernelCacheDir, wanted, why);
      I.generatedReport = I.pendingGenerated ? I.pendingGenerated->what() : why;
      I.generatedPending = bool(I.pendingGenerated);
      I.adoptGenerated(false);  // all from the disk cache: adopted now
    }
  }
}

CudaInrEvaluator::~CudaInrEvaluator() {
  if (impl_ && impl_->cublas) cublasDestroy(impl_->cublas);
}

CudaEvaluatorPath CudaInrEvaluator::path() const { return impl_->path; }

std::string CudaInrEvaluator::name() const {
  std::lock_guard<std::mutex> lock(impl_->adoptMutex);
  const Impl& I = *impl_;
  return I.path == CudaEvaluatorPath::Fused
             ? "cuda-fused-fp16 (" + configName(I.config) + ", " +
                   std::to_string(I.config.sharedBytes / 1024) + " KB smem, " +
                   std::to_string(I.config.gridBlocks / std::max(1, I.device.multiprocessors)) + " blocks/SM; under " +
                   std::to_string(Impl::kSmallBatchThreshold) + " queries " + configName(I.smallConfig) +
                   "; generated kernels: " + I.generatedReport + ") on " + I.device.name
             : "cuda-generic-fp32 (" + (I.program.fusable ? std::string("forced") : I.program.whyNotFused) + ") on " +
                   I.device.name;
}

std::string CudaInrEvaluator::launchReport() const {
  const Impl& I = *impl_;
  if (I.path != CudaEvaluatorPath::Fused) return "";
  std::lock_guard<std::mutex> lock(impl_->adoptMutex);
  std::string r = I.choiceReport;
  if (!I.whyNoWgmma.empty()) r += " [wgmma: " + I.whyNoWgmma + "]";
  r += " [generated kernels: " + I.generatedReport + "]";
  if (!I.adoptionReport.empty()) r += " [" + I.adoptionReport + "]";
  return r + I.persistenceReport;
}

bool CudaInrEvaluator::generatedKernelsPending() const { return impl_->generatedPending.load(); }

void CudaInrEvaluator::waitForGeneratedKernels() const { impl_->adoptGenerated(true); }

bool CudaInrEvaluator::usesWgmma() const {
  return impl_->path == CudaEvaluatorPath::Fused && (impl_->config.wgmma || impl_->smallConfig.wgmma);
}

bool CudaInrEvaluator::usesGeneratedKernel() const {
  return impl_->path == CudaEvaluatorPath::Fused && (impl_->config.generated || impl_->smallConfig.generated);
}

std::string CudaInrEvaluator::generatedKernelReport() const {
  std::lock_guard<std::mutex> lock(impl_->adoptMutex);
  return impl_->generatedReport;
}

std::string CudaInrEvaluator::describeProgram() const { return impl_->program.describe(); }

void CudaInrEvaluator::evaluateDevice(const float4* points, const unsigned* deviceCount, int maxN, float* out,
                                      const int* scatter, cudaStream_t stream) const {
  impl_->adoptGenerated(false);
  const Impl& I = *impl_;
  int n = maxN;
  if (n <= 0) return;
  if (I.path == CudaEvaluatorPath::Fused) {
    I.launchFused(impl_->launchConfig(n, false), points, n, deviceCount, out, scatter, stream);
    return;
  }
  if (deviceCount) {  // the generic path sizes its cuBLAS calls on the host: read the count
    unsigned k = 0;
    INR_CUDA_CHECK(cudaMemcpyAsync(&k, deviceCount, sizeof k, cudaMemcpyDeviceToHost, stream));
    INR_CUDA_CHECK(cudaStreamSynchronize(stream));
    n = std::min(n, int(k));
    if (n <= 0) return;
  }
  // Generic fp32 path, chunk by chunk.
  const MlpProgram& prog = I.program;
  const int ld = prog.maxWidthPad;
  const int chunk = Impl::kGenericChunk;
  I.genericBuffers.growTo(std::size_t(std::max(1, prog.numBuffers)) * ld * chunk);
  I.genericCoords.growTo(std::size_t(4) * chunk);
  cublasCheck(cublasSetStream(I.cublas, stream), "cublasSetStream");
  const float one = 1.f, zero = 0.f;
  for (int begin = 0; begin < n; begin += chunk) {
    const int m = std::min(chunk, n - begin);
    auto buf = [&](int b) { return I.genericBuffers.get() + std::size_t(b) * ld * chunk; };
    genericCoords<<<(m + 255) / 256, 256, 0, stream>>>(I.params, points + begin, m, I.genericCoords.get());
    INR_CUDA_CHECK_LAUNCH("genericCoords");
    for (const MlpInstr& in : prog.instrs) {
      // coordInput: a first layer whose fused form reads split coordinates; fp32 reads them raw.
      const bool fromCoords = in.src < 0 || in.coordInput;
      const float* src = fromCoords ? I.genericCoords.get() : buf(in.src);
      const int srcLd = fromCoords ? 4 : ld;
      const dim3 block(32, 8), grid2((std::max(in.nPad, 1) + 31) / 32, (m + 7) / 8);
      switch (in.op) {
        case MlpOp::DenseFp32:
        case MlpOp::Gemm:
          if (in.finalOutput) {  // the final width-1 layer: an fp32 dot per query
            genericOutput<<<(m + 255) / 256, 256, 0, stream>>>(in, I.floatW.get() + in.floatOffset,
                                                               I.floatW.get() + in.biasOffset, src, srcLd, I.params.output,
                                                               points + begin, m, begin, out, scatter);
            INR_CUDA_CHECK_LAUNCH("genericOutput");
            break;
          }
          cublasCheck(cublasSgemm(I.cublas, CUBLAS_OP_T, CUBLAS_OP_N, in.outWidth, m, in.inWidth, &one,
                                  I.floatW.get() + in.floatOffset, in.inWidth, src, srcLd, &zero, buf(in.dst), ld),
                      "cublasSgemm");
          genericEpilogue<<<grid2, block, 0, stream>>>(in, I.floatW.get() + in.biasOffset, buf(in.dst),
                                                      in.other >= 0 ? buf(in.other) : nullptr, ld, m);
          INR_CUDA_CHECK_LAUNCH("genericEpilogue");
          break;
        case MlpOp::Fourier:  // every encoding
        case MlpOp::HashGrid:
          genericEncoding<<<grid2, block, 0, stream>>>(in, I.floatW.get(), src, srcLd, buf(in.dst), ld, m);
          INR_CUDA_CHECK_LAUNCH("genericEncoding");
          break;
        case MlpOp::LoadInput:
        case MlpOp::Activation:
        case MlpOp::Combine:
          genericElementwise<<<grid2, block, 0, stream>>>(in, I.genericCoords.get(), buf(in.dst),
                                                         in.src >= 0 ? buf(in.src) : nullptr,
                                                         in.other >= 0 ? buf(in.other) : nullptr, ld, m, prog.inputDim);
          INR_CUDA_CHECK_LAUNCH("genericElementwise");
          break;
        case MlpOp::OutputDot:
        case MlpOp::Output:
          genericOutput<<<(m + 255) / 256, 256, 0, stream>>>(
              in, in.op == MlpOp::OutputDot ? I.floatW.get() + in.floatOffset : nullptr, I.floatW.get() + in.biasOffset, src,
              srcLd, I.params.output, points + begin, m, begin, out, scatter);
          INR_CUDA_CHECK_LAUNCH("genericOutput");
          break;
      }
    }
  }
}

void CudaInrEvaluator::evaluate(const QueryPoint* points, std::size_t n, float* out) const {
  const Impl& I = *impl_;
  if (n == 0) return;
  if (n > std::size_t(1) << 30) throw std::runtime_error("CudaInrEvaluator::evaluate: batch larger than 2^30 queries");
  static_assert(sizeof(QueryPoint) == sizeof(float4), "QueryPoint must match float4");
  {
    const DeviceAllocationPurpose purpose("a batch of " + std::to_string(n) + " host queries and their values",
                                          "evaluate fewer points per call");
    I.stagePoints.growTo(n);
    I.stageOut.growTo(n);
  }
  INR_CUDA_CHECK(cudaMemcpy(I.stagePoints.get(), points, n * sizeof(float4), cudaMemcpyHostToDevice));
  evaluateDevice(I.stagePoints.get(), int(n), I.stageOut.get(), nullptr, nullptr);
  INR_CUDA_CHECK(cudaMemcpy(out, I.stageOut.get(), n * sizeof(float), cudaMemcpyDeviceToHost));
}

void CudaInrEvaluator::evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values,
                                            float* gradients) const {
  gradientsThroughDevice(impl_->output, points, n, values, gradients, [&](const float4* p, int m, float time, float4* out) {
    evaluateWithGradientDevice(p, nullptr, m, time, out, nullptr);
  });
}

void CudaInrEvaluator::evaluateWithGradientDevice(const float4* points, const unsigned* deviceCount, int maxN,
                                                  float time, float4* out, cudaStream_t stream) const {
  impl_->adoptGenerated(false);
  const Impl& I = *impl_;
  if (maxN <= 0) return;
  if (!I.fusedTangents) {
    I.gradientNetwork->evaluateWithGradientDevice(points, deviceCount, maxN, time, out, stream);
    return;
  }
  I.tuneTangents();
  I.launchTangents(impl_->launchConfig(maxN, true), points, maxN, deviceCount, time, out, stream);
}

std::string CudaInrEvaluator::gradientPath() const {
  const Impl& I = *impl_;
  if (!I.fusedTangents) return "per-thread fp32 (" + I.whyNoFusedTangents + ")";
  I.tuneTangents();
  return "fused tangent rows, tangent scale " + std::to_string(I.tangentScale) + " (" + I.tangentReport + ")";
}

bool CudaInrEvaluator::usesFusedTangents() const { return impl_->fusedTangents; }

float CudaInrEvaluator::tangentScale() const {
  if (impl_->fusedTangents) impl_->tuneTangents();
  return impl_->tangentScale;
}

}  // namespace inr
