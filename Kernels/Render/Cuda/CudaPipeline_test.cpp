// GPU pipeline against the CPU backend (ctest label `cuda`). Without a usable GPU every test here
// is reported as skipped, with the reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <utility>
#include <vector>

#include "Common/Cuda/CudaDevice.h"
#include "Common/Cuda/DeviceBuffer.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/AnalyticDeviceField.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/Cuda/CudaRayMarcher.h"
#include "Render/Cuda/DeviceTransferFunction.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/ModelBox.h"
#include "Render/RayMarcher.h"
#include "TestSupport/RequireGpu.h"
#include "TestSupport/ShippedModels.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

namespace fs = std::filesystem;
using test::nonFinitePixels;
using test::shippedModels;
using test::testMacrocells;
using test::testScene;


int envInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v ? std::max(1, std::atoi(v)) : fallback;
}

TEST(CudaPipeline, MacrocellGridsMatchCpu) {
  REQUIRE_GPU();
  const auto models = shippedModels();
  for (const auto& path : models) {
    const InrModel model = InrModel::loadFile(path);
    const CudaInrEvaluator gpuEval(model);
    const CpuInrEvaluator cpuEval(model);
    const Box3f box = modelWorldBox(model);
    MacrocellOptions o;
    o.dims = Int3{18, 16, 13};
    o.temporalSlices = 5;
    // Slabs of 2 cell layers on the CPU, 3 on the GPU (lattice planes of 37 x 33 points): the
    // planes carried from slab to slab, at other places on each.
    o.maxBatch = 5 * 37 * 33;
    o.gpuMaxBatch = 7 * 37 * 33;
    CudaMacrocellGrid gpu(gpuEval, box, model.domain.timeBegin, model.domain.timeEnd, o);
    MacrocellGrid sameEval(gpuEval, box, model.domain.timeBegin, model.domain.timeEnd, o);
    MacrocellGrid cpuRef(cpuEval, box, model.domain.timeBegin, model.domain.timeEnd, o);
    const double t = model.domain.timeBegin + 0.37 * (model.domain.timeEnd - model.domain.timeBegin);
    gpu.setTime(t);
    sameEval.setTime(t);
    cpuRef.setTime(t);
    int k0, k1;
    float w;
    gpu.interpolationWeights(t, k0, k1, w);
    std::vector<float> mn, mx, mean;
    double range = 0;
    for (float v : cpuRef.slice(k0).max) range = std::max(range, double(v));
    double lo = INFINITY;
    for (float v : cpuRef.slice(k0).min) lo = std::min(lo, double(v));
    range = std::max(1.0, range - lo);
    double maxSame = 0, maxRef = 0;
    for (int k : {k0, k1}) {
      ASSERT_TRUE(gpu.sliceBuilt(k));
      gpu.downloadSlice(k, mn, mx, mean);
      const auto& a = sameEval.slice(k);
      const auto& b = cpuRef.slice(k);
      for (int c = 0; c < gpu.cellCount(); ++c) {
        maxSame = std::max({maxSame, std::abs(double(mn[c]) - a.min[c]), std::abs(double(mx[c]) - a.max[c]),
                            std::abs(double(mean[c]) - a.mean[c])});
        maxRef = std::max({maxRef, std::abs(double(mn[c]) - b.min[c]), std::abs(double(mx[c]) - b.max[c])});
      }
    }
    std::vector<float> wMin, wMax, wMean;
    gpu.downloadWorking(wMin, wMax, wMean);
    double maxWork = 0;
    for (int c = 0; c < gpu.cellCount(); ++c)
      maxWork = std::max({maxWork, std::abs(double(wMin[c]) - sameEval.workingMin()[c]),
                          std::abs(double(wMax[c]) - sameEval.workingMax()[c])});
    // Majorants from the same working bounds and TF.
    const TransferFunctionTable table(TransferFunction::preset(lo, lo + range, 0.8));
    cuda::DeviceTransferFunction dtf;
    dtf.upload(table, nullptr);
    cuda::DeviceBuffer<float> dMaj(gpu.cellCount());
    gpu.computeMajorants(dtf.view(), dMaj.get());
    const std::vector<float> maj = dMaj.download(nullptr);
    std::vector<float> cpuMaj;
    sameEval.computeMajorants(table.view(), cpuMaj);
    double maxMaj = 0;
    for (int c = 0; c < gpu.cellCount(); ++c) maxMaj = std::max(maxMaj, std::abs(double(maj[c]) - cpuMaj[c]));
    std::printf("%-24s slices vs CPU grid (same GPU evaluator) %.3g, vs CPU fp32 evaluator %.3g (range %.3g); "
                "working %.3g; majorants %.3g\n",
                fs::path(path).filename().c_str(), maxSame, maxRef, range, maxWork, maxMaj);
    EXPECT_LE(maxSame, 1e-6 * range) << path;
    EXPECT_LE(maxWork, 1e-6 * range) << path;
    EXPECT_LE(maxMaj, 1e-4) << path;
    EXPECT_LE(maxRef, 3e-2 * range) << path;  // the fp16 evaluator's bound
  }
}

// GPU twin of EmptySpaceSkipping.BlockLevelIsTheMaxOfItsCells / RefinementKeepsBlocksConservative:
// the coarse skip level computed on the device is the max of its cells, and stays so through
// ghost passes and frames that refine. The lattice bounds alone may never under-estimate in
// this scene, so the slices are preset too narrow: every cell's range is collapsed to its
// lattice minimum. Sampled values above it then widen cells, their majorants
// grow, and updateDirtyMajorants must raise their blocks (cuda::atomicMaxFloat in
// dirtyMajorantKernel). Were that atomic max dropped (or a no-op), the blocks holding a refined
// cell would keep their old values, below the cell's new majorant: this test would report
// "after refinement" (block level != bruteBlocks of its cells) for every B, and no raised
// block; were it a plain store, the last dirty cell of a block to write would win and the same
// expectation would fail wherever two refined cells of one block differ.
TEST(CudaPipeline, SkipBlockLevelIsTheMaxOfItsCells) {
  REQUIRE_GPU();
  const auto models = shippedModels();
  const InrModel model = InrModel::loadFile(models.front());
  const CudaInrEvaluator eval(model);
  const auto range = valueRangeFor(model, eval);
  for (int B : {2, 4, 8}) {
    MacrocellOptions o;
    o.dims = Int3{18, 16, 13};  // partial blocks
    o.temporalSlices = 3;
    o.skipBlockCells = B;
    CudaMacrocellGrid grid(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, o);
    ASSERT_EQ(grid.blockCount(), ((18 + B - 1) / B) * ((16 + B - 1) / B) * ((13 + B - 1) / B));
    grid.setTime(model.domain.timeBegin);
    // A TF that is transparent over the lower 70% of the range: many empty blocks.
    TransferFunction tf = TransferFunction::preset(range[0], range[1], 0.8);
    tf.opacity = {{range[0], 0.0}, {range[0] + 0.7 * (range[1] - range[0]), 0.0}, {range[1], 0.8}};
    const TransferFunctionTable table(tf);
    cuda::DeviceTransferFunction dtf;
    dtf.upload(table, nullptr);
    cuda::DeviceBuffer<float> maj(grid.cellCount()), blocks(grid.blockCount());
    grid.computeMajorants(dtf.view(), maj.get(), blocks.get());
    const std::vector<float> cells = maj.download(nullptr);
    EXPECT_TRUE(blocks.download(nullptr) == test::bruteBlocks(o.dims, B, cells)) << "B = " << B;
    const MajorantGridView v = grid.view(maj.get(), blocks.get());
    EXPECT_EQ(v.blockMajorant, blocks.get());
    EXPECT_EQ(1 << v.blockShift, B);
    EXPECT_EQ(grid.view(maj.get()).blockMajorant, nullptr);

    // Too narrow bounds in every slice: [min, min] per cell (cells with no finite value stay
    // empty). The renderer's setTime interpolates these.
    grid.buildAllSlices();
    for (int k = 0; k < grid.temporalSlices(); ++k) {
      std::vector<float> mn, mx, mean;
      grid.downloadSlice(k, mn, mx, mean);
      for (std::size_t c = 0; c < mn.size(); ++c)
        if (mn[c] <= mx[c]) mx[c] = mean[c] = mn[c];
      grid.setSlice(k, mn, mx, mean);
    }

    TrackingOptions topts;
    topts.ghostPassesOnUpdate = 0;  // run below, where their refinements can be counted
    CudaWavefrontRenderer r(eval, grid, topts);
    RenderSettings settings;
    settings.width = settings.height = 48;
    r.setSettings(settings);
    RenderScene scene = testScene(model, range, true);
    scene.transferFunction = tf;
    r.setScene(scene);
    const std::vector<float> blocksBefore = r.blockMajorants();
    ASSERT_TRUE(blocksBefore == test::bruteBlocks(o.dims, B, r.majorants())) << "B = " << B << " collapsed";
    std::size_t refinements = r.runGhostPasses(2).refinements;
    for (int k = 0; k < 3; ++k) refinements += r.renderFrame().refinements;
    const std::vector<float> rb = r.blockMajorants(), rc = r.majorants();
    int raised = 0;
    for (std::size_t b = 0; b < rb.size(); ++b) raised += rb[b] > blocksBefore[b] ? 1 : 0;
    std::printf("B = %d: %zu refinements, %d of %zu blocks raised\n", B, refinements, raised, rb.size());
    ASSERT_GT(refinements, 0u) << "B = " << B << ": the collapsed bounds must refine";
    EXPECT_EQ(grid.refinementCount(), refinements) << "the grid's total counts what the frames counted";
    EXPECT_GT(raised, 0) << "B = " << B << ": refinement raised no block";
    EXPECT_TRUE(rb == test::bruteBlocks(o.dims, B, rc)) << "B = " << B << " after refinement";
  }
  MacrocellOptions off;
  off.skipBlockCells = 0;
  off.temporalSlices = 1;
  const CudaMacrocellGrid noSkip(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, off);
  EXPECT_EQ(noSkip.blockCount(), 0);
  off.skipBlockCells = 3;
  EXPECT_THROW(CudaMacrocellGrid(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, off),
               std::invalid_argument);
}

// GPU twin of EmptySpaceSkipping.ImagesAndQueryCountsIdenticalWithSkippingOnAndOff: the same
// frames with and without the coarse level are bit-identical (empty cells draw nothing).
TEST(CudaPipeline, ImagesIdenticalWithSkippingOnAndOff) {
  REQUIRE_GPU();
  const auto models = shippedModels();
  const InrModel model = InrModel::loadFile(models.front());
  const CudaInrEvaluator eval(model);
  const auto range = valueRangeFor(model, eval);
  struct Out {
    std::vector<float> image;
    FrameStats stats;
  };
  auto render = [&](int block, const RenderScene& scene) {
    MacrocellOptions o = testMacrocells();
    o.skipBlockCells = block;
    CudaMacrocellGrid grid(eval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd, o);
    TrackingOptions topts;
    topts.ghostPassesOnUpdate = 1;
    CudaWavefrontRenderer r(eval, grid, topts);
    RenderSettings settings;
    settings.width = 65;
    settings.height = 63;
    settings.seed = 3;
    Out out;
    out.stats = test::renderFrames(r, settings, scene, 4);
    out.image = r.image().data;
    return out;
  };
  for (const ShadowEstimator est : {ShadowEstimator::Delta, ShadowEstimator::Ratio}) {
    RenderScene scene = testScene(model, range, true);
    scene.shadowEstimator = est;
    scene.transferFunction.opacity = {{range[0], 0.0}, {range[0] + 0.6 * (range[1] - range[0]), 0.0}, {range[1], 0.8}};
    const Out off = render(0, scene), again = render(0, scene);
    if (off.image != again.image || off.stats.totalQueries() != again.stats.totalQueries())
      GTEST_SKIP() << "the GPU pipeline is not bit-reproducible run to run on this device: nothing to compare";
    for (int block : {4, 8}) {
      const Out on = render(block, scene);
      EXPECT_TRUE(on.image == off.image) << "blocks of " << block;
      EXPECT_EQ(on.stats.queries, off.stats.queries) << "blocks of " << block;
      EXPECT_EQ(on.stats.shadowQueries, off.stats.shadowQueries) << "blocks of " << block;
      EXPECT_EQ(on.stats.iterations, off.stats.iterations) << "blocks of " << block;
      EXPECT_EQ(on.stats.shadowIterations, off.stats.shadowIterations) << "blocks of " << block;
      EXPECT_EQ(on.stats.refinements, off.stats.refinements) << "blocks of " << block;
    }
  }
}

TEST(CudaPipeline, ConvergedGpuImageMatchesCpuImage) {
  REQUIRE_GPU();
  const auto models = shippedModels();
  const int size = envInt("INR_GPU_TEST_SIZE", 64), frames = envInt("INR_GPU_TEST_FRAMES", 256);
  for (const auto& path : models) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpuEval(model);
    const CudaInrEvaluator gpuEval(model);
    const auto range = valueRangeFor(model, cpuEval);
    const Box3f box = modelWorldBox(model);
    for (bool shadows : {false, true}) {
      RenderSettings settings;
      settings.width = settings.height = size;
      settings.seed = 9;
      settings.pixelJitter = false;
      const RenderScene scene = testScene(model, range, shadows);

      MacrocellGrid cpuGrid(cpuEval, box, model.domain.timeBegin, model.domain.timeEnd, testMacrocells());
      CpuWavefrontRenderer cpu(cpuEval, cpuGrid);
      const FrameStats cpuTotal = test::renderFrames(cpu, settings, scene, frames);

      CudaMacrocellGrid gpuGrid(gpuEval, box, model.domain.timeBegin, model.domain.timeEnd, testMacrocells());
      CudaWavefrontRenderer gpu(gpuEval, gpuGrid);
      const FrameStats gpuTotal = test::renderFrames(gpu, settings, scene, frames);

      const ImageRGBA a = gpu.image(), b = cpu.image();
      const double psnr = psnrRgb(a, b);
      std::printf("%-24s%s %dx%d, %d frames: PSNR GPU vs CPU %.2f dB; queries/frame GPU %zu CPU %zu; "
                  "iterations/frame GPU %.1f CPU %.1f\n",
                  fs::path(path).filename().c_str(), shadows ? " (shadows)" : "", size, size, frames, psnr,
                  gpuTotal.totalQueries() / frames, cpuTotal.totalQueries() / frames,
                  double(gpuTotal.iterations + gpuTotal.shadowIterations) / frames,
                  double(cpuTotal.iterations + cpuTotal.shadowIterations) / frames);
      EXPECT_GE(psnr, 40.0) << path << (shadows ? " with shadows" : "");
      EXPECT_EQ(nonFinitePixels(a), 0u) << path;
      EXPECT_EQ(gpu.counters().truncatedFrames, 0) << path;
      EXPECT_EQ(gpu.accumulatedFrames(), frames);
      const std::vector<float> r = gpu.residual();
      for (float v : r) ASSERT_TRUE(v >= 0.f && v <= 1.f) << path;
    }
  }
}

TEST(CudaPipeline, PerThreadNetworkMatchesCpuReference) {
  REQUIRE_GPU();
  for (const auto& path : shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpu(model);
    const CudaPerThreadMlp naive(model);
    const float t = float(0.5 * (model.domain.timeBegin + model.domain.timeEnd));
    const std::vector<QueryPoint> pts = test::randomQueryPoints(model, 5003, 5, t);
    std::vector<float> ref(pts.size()), got(pts.size());
    cpu.evaluate(pts.data(), pts.size(), ref.data());
    naive.evaluate(pts.data(), pts.size(), got.data());
    double maxErr = 0, lo = INFINITY, hi = -INFINITY;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      maxErr = std::max(maxErr, std::abs(double(got[i]) - ref[i]));
      lo = std::min(lo, double(ref[i]));
      hi = std::max(hi, double(ref[i]));
    }
    std::printf("%-24s per-thread fp32 network vs CPU: max abs %.3g (range %.3g)\n", fs::path(path).filename().c_str(),
                maxErr, hi - lo);
    EXPECT_LE(maxErr, 1e-3 * std::max(1.0, hi - lo)) << path;
  }
}

TEST(CudaPipeline, NaiveTrackerConvergesToWavefrontImage) {
  REQUIRE_GPU();
  const auto models = shippedModels();
  const InrModel model = InrModel::loadFile(models.front());
  const CudaInrEvaluator gpuEval(model);
  const CudaPerThreadMlp naiveNet(model);
  const auto range = valueRangeFor(model, gpuEval);
  for (bool shadows : {false, true}) {
    RenderSettings settings;
    settings.width = settings.height = 48;
    settings.pixelJitter = false;
    const RenderScene scene = testScene(model, range, shadows);
    auto render = [&](bool naive) {
      CudaMacrocellGrid grid(gpuEval, modelWorldBox(model), model.domain.timeBegin, model.domain.timeEnd,
                             testMacrocells());
      CudaWavefrontRenderer r(gpuEval, grid);
      r.setSettings(settings);
      r.setScene(scene);
      for (int k = 0; k < 128; ++k) naive ? r.renderFrameNaive(naiveNet) : r.renderFrame();
      return r.image();
    };
    const ImageRGBA a = render(true), b = render(false);
    const double psnr = psnrRgb(a, b);
    std::printf("naive vs wavefront%s: PSNR %.2f dB\n", shadows ? " (shadows)" : "", psnr);
    EXPECT_GE(psnr, 40.0);
    EXPECT_EQ(nonFinitePixels(a), 0u);
  }
}

TEST(CudaPipeline, GpuRayMarcherMatchesCpuRayMarcher) {
  REQUIRE_GPU();
  for (const auto& path : shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    const CpuInrEvaluator cpuEval(model);
    const CudaInrEvaluator gpuEval(model);
    const auto range = valueRangeFor(model, cpuEval);
    RenderSettings settings;
    settings.width = settings.height = 40;
    const RenderScene scene = testScene(model, range, false);
    const Box3f box = modelWorldBox(model);
    RayMarchOptions o;
    o.step = length(box.hi - box.lo) / 256.f;
    RayMarchRenderer cpu(cpuEval, box, o);
    CudaRayMarcher gpu(gpuEval, box, o);
    const FrameStats a = test::renderFrames(cpu, settings, scene, 1), b = test::renderFrames(gpu, settings, scene, 1);
    const double psnr = psnrRgb(cpu.image(), gpu.image());
    std::printf("%-24s ray marcher GPU vs CPU: PSNR %.2f dB, queries %zu vs %zu\n", fs::path(path).filename().c_str(),
                psnr, b.queries, a.queries);
    EXPECT_EQ(a.queries, b.queries) << path;
    EXPECT_GE(psnr, 40.0) << path;
  }
}

// The GPU marcher runs the CPU marcher's per-ray code (Render/RayMarch.h): on the same evaluator
// (one fused configuration for every batch size, so each query gets the same value in either
// marcher's batches) the two differ only by compositing (and summing optical depths towards the
// light) in float instead of double. Over the pixels the volume covers: the same pixels, the same
// queries, shadow rays and shadow queries, and every channel within 1e-4 (2e-4 with shadows),
// jittered over several frames, at a parallel and at a perspective camera, without and with
// shadows (in batches of 4096 shadow points, so that a sample's shadow points span batches).
// With gradient shading (each sample's gradient from the same tangent rows in both, lit by
// Shading.h; the device's lighting in fast math) within 1e-3, and the unshaded GPU march of the
// same view visibly different (shading is on).
TEST(CudaPipeline, GpuRayMarcherRunsTheCpuMarchersRays) {
  REQUIRE_GPU();
  for (const auto& path : shippedModels()) {
    const InrModel model = InrModel::loadFile(path);
    CudaEvaluatorOptions options;
    options.autotuneBatch = 0;
    const CudaInrEvaluator eval(model, options);
    const auto range = valueRangeFor(model, eval);
    const Box3f box = modelWorldBox(model);
    RayMarchOptions o;
    o.step = length(box.hi - box.lo) / 200.f;
    o.maxShadowBatch = 4096;
    struct Case {
      bool parallel, shadows, shade, lightKit = false, gradientOpacity = false;
    };
    // Gradient opacity: a ramp around the shipped models' median gradient magnitude (about 0.3).
    for (const Case& k : {Case{false, false, false}, Case{true, false, false}, Case{false, true, false},
                          Case{true, true, false}, Case{false, false, true}, Case{true, true, true},
                          Case{false, false, true, true}, Case{false, false, false, false, true},
                          Case{true, true, false, false, true}, Case{false, true, true, false, true}}) {
      const bool parallel = k.parallel, shadows = k.shadows;
      RenderSettings settings;
      settings.width = 36;
      settings.height = 28;
      RenderScene scene = testScene(model, range, shadows);
      scene.shading.enabled = k.shade;
      scene.shading.lightList = k.lightKit;  // ParaView's default view lights (VTK's light-list lighting)
      if (k.lightKit) scene.shading.lights = paraviewLightKit();
      if (k.gradientOpacity) scene.transferFunction.gradientOpacity = {{0.15, 0.0}, {0.7, 1.0}};
      if (parallel) {
        scene.camera.parallelProjection = true;
        scene.camera.parallelScale = 0.6 * length(box.hi - box.lo);
      }
      RayMarchRenderer cpu(eval, box, o);
      CudaRayMarcher gpu(eval, box, o);
      const FrameStats a = test::renderFrames(cpu, settings, scene, 3), b = test::renderFrames(gpu, settings, scene, 3);
      ImageRGBA flat;  // shaded or gradient opacity cases: the same view without either
      const bool changed = k.shade || k.gradientOpacity;
      if (changed) {
        RenderScene flatScene = scene;
        flatScene.shading.enabled = false;
        flatScene.transferFunction.gradientOpacity.clear();
        CudaRayMarcher unshaded(eval, box, o);
        test::renderFrames(unshaded, settings, flatScene, 3);
        flat = unshaded.image();
      }
      EXPECT_EQ(a.queries, b.queries) << path;
      EXPECT_EQ(a.rays, b.rays) << path;
      if (k.gradientOpacity) {
        // A sample casts a shadow ray only where its factor is above 0, and the GPU's gradient (its
        // fused kernel's tangent rows) rounds differently from the host path's: a sample at the
        // ramp's zero end can fall on either side (on an H100, 1 ray in 40 000 on two models).
        const double rays = double(a.shadowRays), queries = double(a.shadowQueries);
        EXPECT_NEAR(double(b.shadowRays), rays, std::max(4.0, 1e-4 * rays)) << path;
        EXPECT_NEAR(double(b.shadowQueries), queries, std::max(100.0, 1e-4 * queries)) << path;
      } else {
        EXPECT_EQ(a.shadowRays, b.shadowRays) << path;
        EXPECT_EQ(a.shadowQueries, b.shadowQueries) << path;
      }
      EXPECT_EQ(shadows, b.shadowQueries > 0) << path;
      const ImageRGBA ci = cpu.image(), gi = gpu.image();  // both over the scene's background
      std::size_t covered = 0, coverageMismatch = 0;
      double maxError = 0.0, shadingChange = 0.0;
      for (std::size_t i = 0; i < std::size_t(settings.width) * settings.height; ++i) {
        const float ca = ci.data[4 * i + 3], ga = gi.data[4 * i + 3];
        if ((ca > 0.f) != (ga > 0.f)) ++coverageMismatch;
        if (!(ca > 0.f)) continue;
        ++covered;
        for (int c = 0; c < 4; ++c) {
          maxError = std::max(maxError, double(std::fabs(ci.data[4 * i + c] - gi.data[4 * i + c])));
          if (changed) shadingChange = std::max(shadingChange, double(std::fabs(flat.data[4 * i + c] - gi.data[4 * i + c])));
        }
      }
      std::printf("%-24s %s%s%s%s: GPU vs CPU ray marcher on one evaluator: %zu covered pixels, %zu shadow queries, "
                  "max error %.2e%s\n",
                  fs::path(path).filename().c_str(), parallel ? "parallel" : "perspective", shadows ? ", shadows" : "",
                  k.shade ? (k.lightKit ? ", shaded (light kit)" : ", shaded") : "",
                  k.gradientOpacity ? ", gradient opacity" : "", covered, b.shadowQueries, maxError,
                  changed ? (" (without: " + std::to_string(shadingChange) + ")").c_str() : "");
      EXPECT_GT(covered, std::size_t(settings.width * settings.height / 10)) << path;
      EXPECT_EQ(coverageMismatch, 0u) << path;
      EXPECT_LE(maxError, changed ? 1e-3 : shadows ? 2e-4 : 1e-4) << path;
      if (changed) EXPECT_GT(shadingChange, 0.02) << path << ": shading / gradient opacity changed too little to tell";
    }
  }
}

TEST(CudaPipeline, GpuRayMarcherTakesGradientOpacityAfterShadowsWithout) {
  // One marcher renders shadows without gradient opacity, then with it: its shadow buffers must
  // follow the new scene (the same picture as a fresh marcher's), not keep the first one's sizes.
  REQUIRE_GPU();
  const InrModel model = InrModel::loadFile(shippedModels().front());
  const CudaInrEvaluator eval(model);
  const auto range = valueRangeFor(model, eval);
  const Box3f box = modelWorldBox(model);
  RayMarchOptions o;
  o.step = length(box.hi - box.lo) / 200.f;
  o.maxShadowBatch = 4096;
  RenderSettings settings;
  settings.width = 36;
  settings.height = 28;
  RenderScene scene = testScene(model, range, true);
  CudaRayMarcher reused(eval, box, o);
  test::renderFrames(reused, settings, scene, 2);
  scene.transferFunction.gradientOpacity = {{0.15, 0.0}, {0.7, 1.0}};
  test::renderFrames(reused, settings, scene, 2);
  CudaRayMarcher fresh(eval, box, o);
  test::renderFrames(fresh, settings, scene, 2);
  EXPECT_TRUE(reused.image().data == fresh.image().data);
}

class GpuSceneTest : public ::testing::Test {
protected:
  void SetUp() override {
    REQUIRE_GPU();
    const auto models = shippedModels();
    model = std::make_unique<InrModel>(InrModel::loadFile(models.front()));
    eval = std::make_unique<CudaInrEvaluator>(*model);
    range = valueRangeFor(*model, *eval);
    grid = std::make_unique<CudaMacrocellGrid>(*eval, modelWorldBox(*model), model->domain.timeBegin,
                                               model->domain.timeEnd, testMacrocells());
  }
  std::unique_ptr<InrModel> model;
  std::unique_ptr<CudaInrEvaluator> eval;
  std::unique_ptr<CudaMacrocellGrid> grid;
  std::array<float, 2> range{};
};

TEST_F(GpuSceneTest, EmptyTransferFunctionCostsNoQueries) {
  CudaWavefrontRenderer r(*eval, *grid);
  RenderSettings settings;
  settings.width = settings.height = 64;
  r.setSettings(settings);
  RenderScene scene = testScene(*model, range, true);
  scene.shadowEstimator = ShadowEstimator::Delta;
  scene.transferFunction = TransferFunction::transparent(range[0], range[1]);
  r.setScene(scene);
  for (int k = 0; k < 3; ++k) {
    const FrameStats st = r.renderFrame();
    EXPECT_EQ(st.queries, 0u);
    EXPECT_EQ(st.shadowQueries, 0u);
    EXPECT_EQ(st.iterations, 0);
    EXPECT_GT(st.rays, 0u);
  }
  for (float m : r.majorants()) ASSERT_EQ(m, 0.f);
  const ImageRGBA img = r.image();
  for (std::size_t i = 0; i < img.data.size(); i += 4) {
    ASSERT_FLOAT_EQ(img.data[i], scene.background[0]);
    ASSERT_FLOAT_EQ(img.data[i + 3], 0.f);
  }
}

TEST_F(GpuSceneTest, SceneChangesDoOnlyTheWorkTheyNeed) {
  CudaWavefrontRenderer r(*eval, *grid);
  RenderSettings settings;
  settings.width = settings.height = 32;
  r.setSettings(settings);
  RenderScene scene = testScene(*model, range, false);
  r.setScene(scene);
  const CudaPipelineCounters c0 = r.counters();
  EXPECT_EQ(c0.workingGridUpdates, 1);
  EXPECT_EQ(c0.majorantUpdates, 1);
  r.renderFrame();
  r.renderFrame();
  r.setScene(scene);  // unchanged: nothing to do, keeps accumulating
  r.renderFrame();
  EXPECT_EQ(r.accumulatedFrames(), 3);
  EXPECT_EQ(r.counters().workingGridUpdates, 1);
  EXPECT_EQ(r.counters().majorantUpdates, 1);
  EXPECT_EQ(r.counters().accumulationResets, c0.accumulationResets);

  scene.transferFunction = TransferFunction::preset(range[0], range[1], 0.3);  // TF edit: majorants only
  r.setScene(scene);
  EXPECT_EQ(r.counters().workingGridUpdates, 1);
  EXPECT_EQ(r.counters().majorantUpdates, 2);
  EXPECT_EQ(r.accumulatedFrames(), 0);

  scene.time = model->domain.timeBegin + 0.8 * (model->domain.timeEnd - model->domain.timeBegin);
  r.setScene(scene);  // time: working grid + majorants
  EXPECT_EQ(r.counters().workingGridUpdates, 2);
  EXPECT_EQ(r.counters().majorantUpdates, 3);

  r.renderFrame();
  scene.camera.position[0] += 0.1;  // camera: the accumulation is reprojected (the default), nothing else
  r.setScene(scene);
  EXPECT_EQ(r.counters().workingGridUpdates, 2);
  EXPECT_EQ(r.counters().majorantUpdates, 3);
  EXPECT_EQ(r.counters().reprojections, 1);
  EXPECT_EQ(r.accumulatedFrames(), 1);
  EXPECT_EQ(nonFinitePixels(r.image()), 0u);

  QueryReductionSettings exact = r.queryReduction();
  exact.reproject = false;
  r.setQueryReduction(exact);
  scene.camera.position[0] += 0.1;  // camera without reprojection: accumulation reset only
  r.setScene(scene);
  EXPECT_EQ(r.counters().workingGridUpdates, 2);
  EXPECT_EQ(r.counters().majorantUpdates, 3);
  EXPECT_EQ(r.accumulatedFrames(), 0);
  EXPECT_EQ(nonFinitePixels(r.image()), 0u);
}

// CudaMacrocellGrid on a DeviceFieldEvaluator other than the network: the analytic smooth field
// (test::smoothField on host and device). The GPU grid computes the CPU grid's lattice points,
// stencil reductions and interpolation bit for bit (MacrocellLayout), so slices and working
// bounds differ only by the device's sinf / cosf / expf ulps.
TEST(CudaPipeline, MacrocellGridOnAnalyticDeviceFieldMatchesCpu) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField gpuField;
  const test::FunctionField cpuField(test::smoothField);
  {  // the analytic field's host side is the test field
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    std::vector<QueryPoint> pts(1000);
    for (auto& p : pts) p = QueryPoint{u(rng), u(rng), u(rng), 1.f + u(rng)};
    std::vector<float> a(pts.size()), b(pts.size());
    gpuField.evaluate(pts.data(), pts.size(), a.data());
    cpuField.evaluate(pts.data(), pts.size(), b.data());
    for (std::size_t i = 0; i < pts.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-6) << i;
  }
  const Box3f box{{-1.f, -1.f, -1.f}, {1.f, 1.f, 1.f}};
  MacrocellOptions o;
  o.dims = Int3{18, 16, 13};  // partial tiles on every axis
  o.temporalSlices = 5;
  o.boundsPadding = 0.02;
  CudaMacrocellGrid gpu(gpuField, box, 0.0, 2.0, o);
  MacrocellGrid cpu(cpuField, box, 0.0, 2.0, o);
  double maxSlice = 0, maxWork = 0, range = 0;
  for (double t : {0.0, 0.73, 2.0}) {
    gpu.setTime(t);
    cpu.setTime(t);
    const auto r = cpu.workingValueRange();
    range = std::max(range, double(r[1]) - r[0]);
    int k0, k1;
    float w;
    gpu.interpolationWeights(t, k0, k1, w);
    std::vector<float> mn, mx, mean;
    for (int k : {k0, k1}) {
      if (k == k1 && !(w > 0.f)) continue;  // one slice only (a slice time): lazy builds skip k1
      ASSERT_TRUE(gpu.sliceBuilt(k) && cpu.slice(k).built) << "t = " << t;
      gpu.downloadSlice(k, mn, mx, mean);
      const auto& s = cpu.slice(k);
      for (int c = 0; c < gpu.cellCount(); ++c)
        maxSlice = std::max({maxSlice, std::abs(double(mn[c]) - s.min[c]), std::abs(double(mx[c]) - s.max[c]),
                             std::abs(double(mean[c]) - s.mean[c])});
    }
    gpu.downloadWorking(mn, mx, mean);
    for (int c = 0; c < gpu.cellCount(); ++c)
      maxWork = std::max({maxWork, std::abs(double(mn[c]) - cpu.workingMin()[c]),
                          std::abs(double(mx[c]) - cpu.workingMax()[c]),
                          std::abs(double(mean[c]) - cpu.workingMean()[c])});
  }
  std::printf("analytic field: slices %.3g, working %.3g (range %.3g)\n", maxSlice, maxWork, range);
  ASSERT_GT(range, 0.1);
  EXPECT_LE(maxSlice, 1e-5 * range);
  EXPECT_LE(maxWork, 1e-5 * range);
  EXPECT_EQ(gpu.buildStats().slicesBuilt, cpu.buildStats().slicesBuilt);
  EXPECT_EQ(gpu.buildStats().evaluations, cpu.buildStats().evaluations);
}

// ---- homogeneity pruning (Render/Pruning.h) on the GPU, against the CPU backend -------------
// The analytic smooth field on both backends (AnalyticDeviceField: one INR_HD function), so the
// two differ only by ulps of sinf / cosf / expf and by the GPU's concurrent refinement and EMA.

struct PruningRun {
  ImageRGBA image;  // premultiplied
  FrameStats stats;
};

// Oblique view of [-1, 1]^3; translucent everywhere (opacity 0.1 at the bottom of the range),
// so rays take candidates in the near-uniform cells pruning answers.
test::SceneSetup pruningScene(int size) {
  test::SceneSetup s = test::obliqueCubeScene(size, 9);
  s.settings.pixelJitter = false;
  s.scene.transferFunction = TransferFunction::preset(0.0, 1.0, 0.7);
  s.scene.transferFunction.opacity = {{0.0, 0.1}, {1.0, 0.7}};
  s.scene.transferFunction.unitDistance = 0.5;
  test::lightScene(s.scene, true, ShadowEstimator::Ratio);
  return s;
}

template <typename Grid, typename Renderer, typename Field>
PruningRun renderPruned(const Field& field, const QueryReductionSettings& q, int size, int frames) {
  Grid grid(field, test::kCubeBox, 0.0, 1.0, test::cubeMacrocells(16, 4));
  Renderer r(field, grid);
  const test::SceneSetup s = pruningScene(size);
  r.setSettings(s.settings);
  r.setQueryReduction(q);
  PruningRun out;
  out.stats = test::renderFrames(r, s.settings, s.scene, frames);
  out.image = r.premultipliedImage();
  return out;
}

// GPU twin of Pruning.NoCellInTheBandIsBitIdenticalToOff: thresholds that put no cell in the
// band draw nothing and prune nothing, so the frames are those of pruning off, bit for bit,
// although the EMA and the pruned-count reduction run. Also: the estimates start at the means.
TEST(CudaPipeline, PruningWithNoCellInTheBandIsIdenticalToOff) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  auto gpu = [&](const QueryReductionSettings& q) {
    return renderPruned<CudaMacrocellGrid, CudaWavefrontRenderer>(field, q, 48, 3);
  };
  const PruningRun off = gpu(QueryReductionSettings{}), again = gpu(QueryReductionSettings{});
  if (off.image.data != again.image.data || off.stats.totalQueries() != again.stats.totalQueries())
    GTEST_SKIP() << "the GPU pipeline is not bit-reproducible run to run on this device: nothing to compare";
  EXPECT_EQ(off.stats.pruned, 0u);
  for (const QueryReductionSettings& q : {test::pruningAt(0.0, 0.0), test::pruningAt(1e-7, 0.0),
                                            test::pruningAt(1e-7, 1e-7)}) {
    const PruningRun on = gpu(q);
    EXPECT_TRUE(on.image.data == off.image.data) << "epsilon " << q.pruneEpsilon << " falloff " << q.pruneFalloff;
    EXPECT_EQ(on.stats.pruned, 0u);
    EXPECT_EQ(on.stats.queries, off.stats.queries);
    EXPECT_EQ(on.stats.shadowQueries, off.stats.shadowQueries);
    EXPECT_EQ(on.stats.iterations, off.stats.iterations);
  }

  CudaMacrocellGrid grid(field, test::kCubeBox, 0.0, 1.0, test::cubeMacrocells(16, 4));
  grid.setTime(0.3);
  std::vector<float> mn, mx, mean;
  grid.downloadWorking(mn, mx, mean);
  EXPECT_TRUE(grid.downloadExpected() == mean);
}

// Pruning on, both backends, the same seed (common random numbers): the converged images agree
// like unpruned ones do (CudaPipeline.ConvergedGpuImageMatchesCpuImage) and the pruned counts
// agree within the noise of the decisions plus a small systematic allowance (the GPU's EMA and
// refinement run concurrently, so its estimates and bounds differ slightly mid-frame).
TEST(CudaPipeline, PrunedGpuImageMatchesPrunedCpuImage) {
  REQUIRE_GPU();
  const test::AnalyticDeviceField field;
  const int size = envInt("INR_GPU_TEST_SIZE", 64), frames = envInt("INR_GPU_TEST_FRAMES", 256);
  // epsilon 0.08 + falloff 0.02 of the range prunes about a third of the candidates here (CPU:
  // 34.5% over 64 frames, 64^2).
  const QueryReductionSettings q = test::pruningAt(0.08, 0.02);
  const PruningRun cpu = renderPruned<MacrocellGrid, CpuWavefrontRenderer>(
      static_cast<const FieldEvaluator&>(field), q, size, frames);
  const PruningRun gpu = renderPruned<CudaMacrocellGrid, CudaWavefrontRenderer>(
      static_cast<const DeviceFieldEvaluator&>(field), q, size, frames);
  // Over the pixels the volume covers (premultiplied images: background is 0 in both).
  const double psnr = test::psnrOverCoverage(gpu.image, cpu.image, cpu.image);
  const double c = double(cpu.stats.pruned), g = double(gpu.stats.pruned);
  const double candidates = c + double(cpu.stats.totalQueries());
  std::printf("pruning 0.08 + 0.02, %dx%d, %d frames: PSNR GPU vs CPU %.2f dB; pruned GPU %.0f CPU %.0f (%.1f%% of "
              "the CPU's candidates); queries GPU %zu CPU %zu\n",
              size, size, frames, psnr, g, c, 100.0 * c / candidates, gpu.stats.totalQueries(),
              cpu.stats.totalQueries());
  EXPECT_GE(psnr, 40.0);
  EXPECT_GT(c, 0.1 * candidates);  // the comparison is about pruning, not an idle threshold
  EXPECT_LE(std::abs(g - c), 0.03 * c + 5.0 * std::sqrt(c));
  EXPECT_EQ(nonFinitePixels(gpu.image), 0u);
}

}  // namespace
}  // namespace inr
