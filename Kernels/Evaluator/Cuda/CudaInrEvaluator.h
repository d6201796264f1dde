#pragma once
// The GPU evaluator: the model compiled to an MlpProgram and run either by the fused
// tensor-core kernel (one kernel through the whole network, fp16 weights and activations, fp32
// accumulation, first layer / encoding and final dot in fp32) or, for graphs it cannot hold
// (wider than 256, too many live buffers), by a generic fp32 layer-by-layer path on cuBLAS.
// The choice is automatic and reported by path().
//
// Host interface: FieldEvaluator (host arrays in and out). Device interface: DeviceFieldEvaluator
// (evaluateDevice(), which reads float4 world points from device memory and writes, optionally
// scattered through an index array, straight into device memory — how the GPU pipeline writes
// into its rays' state).
#include <cuda_runtime.h>

#include <memory>
#include <string>

#include "Evaluator/Cuda/DeviceFieldEvaluator.h"
#include "Evaluator/FieldEvaluator.h"
#include "Model/InrModel.h"

namespace inr {

enum class CudaEvaluatorPath { Auto, Fused, Generic };
// The fused kernel's tensor-core instructions: mma.sync (every GPU from Turing on) or warpgroup
// MMA (wgmma, Hopper only, code built for sm_90a). Auto times both where both run.
enum class FusedMma { Auto, MmaSync, Wgmma };
// Value + gradient (gradient shading): the fused mma.sync kernel's tangent rows (fp16, forward
// mode beside the value in the same GEMMs) wherever the model runs on the fused path (Auto), or
// the per-thread fp32 forward mode (CudaPerThreadMlp) always (PerThread), or the tangent rows
// only (FusedTangents: the constructor throws, saying why, where they cannot run).
enum class CudaGradientPath { Auto, FusedTangents, PerThread };

// Kernels generated for the model (issue 50; Evaluator/MlpKernelSource.h, Cuda/GeneratedKernels.h):
// the fused mma.sync kernel with the network's program as compile-time constants, compiled by
// NVRTC for this GPU and cached on disk. Auto: after the constructor's autotuning,
// the generated twins of the fastest mma.sync configurations compile in the background (the
// process's compile threads, GeneratedKernels.h); the constructor does not wait for them, and
// the first launch after they are ready loads them, times them against the configurations
// running and keeps the faster (the same bits either way; waitForGeneratedKernels() waits for
// that). From the disk cache they are adopted in the constructor. Only: every configuration's
// generated kernels, compiled in the constructor, are the only candidates (a Fused path throws
// where they cannot be built). Off: none. The environment variable INR_GENERATED_KERNELS (off,
// auto or only) sets the default, auto where it is unset.
enum class GeneratedKernelUse { Auto, Off, Only };
GeneratedKernelUse generatedKernelUseFromEnvironment();

struct CudaEvaluatorOptions {
  int device = 0;
  CudaEvaluatorPath path = CudaEvaluatorPath::Auto;
  // Fused kernel launch configuration: queries per block tile (128, 64 or 32) and weight K-chunk
  // (64 or 32 columns staged per step); 0 = any. Of the configurations whose shared memory fits,
  // the fastest on `autotuneBatch` random queries in the model's domain runs large launches and
  // the fastest on 8192 queries runs launches under 32768 queries (the timing takes a few
  // milliseconds at construction); autotuneBatch = 0 takes the first that fits (largest tile,
  // then largest chunk) for all launches.
  int tileQueries = 0;
  int weightChunk = 0;
  int autotuneBatch = 1 << 18;
  // The large batch the value + gradient configurations (the tangent rows) are timed on; 0 takes
  // the first that fits. They are timed on first use, inside the first frame that asks for a
  // gradient (shading, gradient opacity), where each timed query costs four rows: a batch
  // smaller than the values' keeps that frame short. Unused when autotuneBatch is 0.
  int tangentAutotuneBatch = 1 << 16;
  // Auto: the wgmma kernel joins the autotuned candidates on Hopper (after the mma.sync ones, so
  // autotuneBatch = 0 keeps the mma.sync kernel); Wgmma: only it (a Fused path throws where it
  // cannot run); MmaSync: never it. tileQueries and weightChunk select mma.sync configurations
  // only (the wgmma kernel runs wgmmaConsumers x 64 queries per round, or 64 with the columns
  // split, its weights in chunks of wgmmaChunkColumns output columns: 64 or 128, 0 = both
  // autotuned).
  FusedMma mma = FusedMma::Auto;
  // wgmma kernel, blocks of two consumers: the consumer warpgroups take turns issuing each weight
  // chunk's MMAs (1), never (0), or both are autotuned (-1). 1 rules out one-consumer blocks and
  // the columns split (wgmmaColumnSplit).
  int wgmmaPingPong = -1;
  int wgmmaChunkColumns = 0;
  // wgmma kernel: consumer warpgroups per block, 2 (128 queries per round, turns possible, or 64
  // with the columns split) or 1 (64 queries per round: twice the blocks on a small batch); 0 =
  // both autotuned.
  int wgmmaConsumers = 0;
  // wgmma kernel, blocks of two consumers: both run one 64-query tile, splitting each layer's
  // column chunks between them (1: a small batch's block has two warpgroups on its single tile,
  // each one's epilogues overlapping the other's MMAs; no turns), or each runs a tile of its own
  // (0), or both are autotuned (-1).
  int wgmmaColumnSplit = -1;
  // A program whose Fourier encoding is fused into its first GEMM's operand load (the FFN): run
  // it fused (0), with the encoding stored once per tile in a shared-memory buffer instead (1),
  // or, on the wgmma kernel where the GEMM's K is 257..512, stored split (2: the first 256
  // columns in the MMAs' shared-memory operand layout, the rest in the GEMM's registers, its
  // output written over them: 32 KB less per consumer than 1), or all that fit autotuned (-1).
  // The stored forms compute the encoding once per tile, not once per weight chunk; on the wgmma
  // kernel the paper FFN's 512-wide encoding fits 1 only in one-consumer blocks of 64-column
  // chunks, 2 in one-consumer blocks of either chunk width and two-consumer blocks of 64-column
  // chunks. 2 leaves mma.sync no candidate.
  int storedEncoding = -1;
  // Hash-grid networks: keep the fp16 tables in L2 with a persisting access-policy window on the
  // fused launches (cudaLaunchAttributeAccessPolicyWindow; sets the device's persisting L2 limit
  // to the tables' size, at most what the device allows). Off by default: it changes a
  // device-wide limit that other work on the GPU shares, and a table that fits L2 mostly stays
  // there anyway (gpu_evaluator_benchmark --l2-persist measures both).
  bool hashTablesPersistInL2 = false;
  // Hash-grid networks: the gather's lanes (FusedParams::hashGridPairs): a pair per row and level
  // (1), one lane (0), or both autotuned (-1). The same bits either way.
  int hashGridPairs = -1;
  CudaGradientPath gradientPath = CudaGradientPath::Auto;
  GeneratedKernelUse generatedKernels = generatedKernelUseFromEnvironment();
  // Where the generated kernels' cubins are kept: "" = the environment variable
  // INR_KERNEL_CACHE_DIR, else $XDG_CACHE_HOME/inr-volume/kernels, else
  // ~/.cache/inr-volume/kernels; "none" = no disk cache (compiled at every construction).
  std::string kernelCacheDir;
};

class CudaInrEvaluator final : public FieldEvaluator, public DeviceFieldEvaluator {
public:
  // Throws std::runtime_error when no usable device (message says why) or the path is impossible.
  explicit CudaInrEvaluator(const InrModel& model, CudaEvaluatorOptions options = {});
  ~CudaInrEvaluator() override;

  void evaluate(const QueryPoint* points, std::size_t n, float* out) const override;
  std::string name() const override;

  // DeviceFieldEvaluator: evaluateDevice(points, n, out, scatter, stream), and the same for
  // *deviceCount points (device memory, written by an earlier kernel on `stream`), at most maxN:
  // no host round trip on the fused path (the generic path reads the count).
  using DeviceFieldEvaluator::evaluateDevice;
  void evaluateDevice(const float4* points, const unsigned* deviceCount, int maxN, float* out, const int* scatter,
                      cudaStream_t stream) const override;

  // Gradient shading (Render/Shade.h): values and gradients in one forward-mode pass. On the
  // fused path, the mma.sync kernel's tangent rows (fp16 like the values: the gradient's error
  // is fp16's, MlpProgram.h emulateFusedTangents); elsewhere (the generic path's models: wider
  // than 256 outputs, more than 4 live buffers or 64 instructions; a world axis feeding two
  // network inputs; wgmma forced) the per-thread fp32 forward mode. gradientPath() says which.
  bool providesGradient() const override { return true; }
  void evaluateWithGradient(const QueryPoint* points, std::size_t n, float* values, float* gradients) const override;
  bool providesDeviceGradient() const override { return true; }
  void evaluateWithGradientDevice(const float4* points, const unsigned* deviceCount, int maxN, float time, float4* out,
                                  cudaStream_t stream) const override;

  CudaEvaluatorPath path() const;
  // "fused tangent rows (tile ...)" or "per-thread fp32 (why)".
  std::string gradientPath() const;
  bool usesFusedTangents() const;
  float tangentScale() const;  // the program's MlpProgram::tangentScale (1 without tangent rows)
  // Fused path: the chosen configuration and, when autotuned, each candidate's measured rate,
  // e.g. "... tile 128 x K 64: L / S Gq/s; ... -> tile 128 x K 64, below 32768 queries
  // tile 32 x K 64" (L / S: large / small batch rates; empty for the generic path).
  std::string launchReport() const;
  // Whether the fused launches (either batch size) use the wgmma kernel.
  bool usesWgmma() const;
  // Whether the fused launches (either batch size) use a kernel generated for this model, and
  // what became of the generated kernels ("N kernels for sm_90, ..." or why there are none).
  bool usesGeneratedKernel() const;
  std::string generatedKernelReport() const;
  // GeneratedKernelUse::Auto: whether the generated kernels are still compiling (not yet timed
  // against the built-in ones); waitForGeneratedKernels() waits for them and adopts them where
  // they are faster (benchmarks and tests that need the steady state call it).
  bool generatedKernelsPending() const;
  void waitForGeneratedKernels() const;
  std::string describeProgram() const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace inr
