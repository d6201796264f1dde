// Bit-for-bit regression of the GPU pipeline (label `cuda`; cases and fingerprint in
// Render/RenderRegressionCases.h) on a shipped SIREN through the fused evaluator. The GPU's
// results depend on its architecture (tensor-core fp16 arithmetic, the fused kernel's launch
// configuration), so the fingerprints are recorded per compute capability; on other GPUs the
// test skips, saying so. Recorded at commit 56ccb3c, before the host-side fold of issue 10.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "Common/Cuda/CudaDevice.h"
#include "Evaluator/Cuda/CudaInrEvaluator.h"
#include "Evaluator/Cuda/CudaPerThreadMlp.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/Cuda/CudaWavefrontRenderer.h"
#include "Render/Cuda/CudaMacrocellGrid.h"
#include "Render/ModelBox.h"
#include "TestSupport/RenderRegressionCases.h"

namespace inr {
namespace {

// sm_90, recorded on an H100 at 56ccb3c and reproduced by the folded pipeline in the same run.
const std::uint64_t kExpectedSm90[] = {
    0xd788b942b1dbfdf6ull,  // dense
    0xd788b942b1dbfdf6ull,  // sparse (the GPU cases render the shipped SIREN: same as dense)
    0xd788b942b1dbfdf6ull,  // sparse-no-skip (skipping changes nothing)
    0xefaa94910f834ee8ull,  // shadows-delta
    0x35f35929186fdfb3ull,  // shadows-ratio
    0x82435cdc7216bf34ull,  // ghost-passes
    0x47c382afd886ecedull,  // coarse-refine
    0x65427a4528ec5c42ull,  // depth-limit
    0x710e0c6c08a41f69ull,  // naive
};

TEST(CudaRenderRegression, ImagesAndCountsBitIdenticalToRecorded) {
  const CudaDeviceInfo dev = queryCudaDevice();
  if (!dev.usable) GTEST_SKIP() << "no GPU: " << dev.reason;
  const bool recorded = dev.major == 9 && dev.minor == 0;
  if (!recorded && !regression::recording())
    GTEST_SKIP() << "fingerprints are recorded for sm_90 only; this GPU is sm_" << dev.major << dev.minor;
  const InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/models/siren_blobs.inr");
  CudaEvaluatorOptions eo;
  eo.autotuneBatch = 0;  // a fixed launch configuration: timing must not pick the arithmetic
  const CudaInrEvaluator eval(model, eo);
  const CudaPerThreadMlp naiveNet(model);
  const auto range = valueRangeFor(model, eval);
  const Box3f box = modelWorldBox(model);
  const double t0 = model.domain.timeBegin, span = model.domain.timeEnd - model.domain.timeBegin;
  const auto& cases = regression::cases();
  ASSERT_EQ(cases.size(), sizeof(kExpectedSm90) / sizeof(kExpectedSm90[0]));
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const regression::Case& c = cases[k];
    CudaMacrocellGrid grid(eval, box, model.domain.timeBegin, model.domain.timeEnd, regression::macrocells(c));
    CudaWavefrontRenderer r(eval, grid, regression::tracking(c));
    const std::uint64_t h =
        regression::fingerprint(r, regression::scene(c, box, range[0], range[1], t0 + 0.35 * span), t0 + 0.65 * span,
                                [&](CudaWavefrontRenderer& rr) {
                                  return c.naive ? rr.renderFrameNaive(naiveNet) : rr.renderFrame();
                                },
                                /*withRefinementCounts=*/false);
    if (regression::recording()) std::printf("    0x%016llxull,  // %s\n", (unsigned long long)h, c.name);
    if (recorded) EXPECT_EQ(h, kExpectedSm90[k]) << c.name;
  }
}

}  // namespace
}  // namespace inr
