// Bit-for-bit regression of the CPU pipeline (cases and fingerprint in RenderRegressionCases.h)
// over analytic fields, which keep the fingerprints free of the evaluator's GEMM (no Eigen, no
// threads). Recorded at commit 56ccb3c, before the host-side fold of issue 10.
#include <gtest/gtest.h>

#include <cstdio>

#include "Render/CpuWavefrontRenderer.h"
#include "TestSupport/RenderRegressionCases.h"
#include "TestSupport/TestFields.h"

namespace inr {
namespace {

const std::uint64_t kExpected[] = {
    0x1adc4df3a8c68a90ull,  // dense
    0xcd91515fa37e72ceull,  // sparse
    0xcd91515fa37e72ceull,  // sparse-no-skip (skipping changes nothing)
    0x33a14b4e079c7664ull,  // shadows-delta
    0xd1de76ef7f79d487ull,  // shadows-ratio
    0xc63adfcf0bcd70eeull,  // ghost-passes
    0x51bb869964dabd64ull,  // coarse-refine
    0x19bb74443f2cb12full,  // depth-limit
    0xc58d901d4368fd69ull,  // naive
};

TEST(RenderRegression, ImagesAndCountsBitIdenticalToRecorded) {
  const Box3f box{{-1, -1, -1}, {1, 1, 1}};
  const auto& cases = regression::cases();
  ASSERT_EQ(cases.size(), sizeof(kExpected) / sizeof(kExpected[0]));
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const regression::Case& c = cases[k];
    test::FunctionField f(c.sparse ? test::sparseField : test::smoothField);
    MacrocellGrid grid(f, box, 0.0, 2.0, regression::macrocells(c));
    CpuWavefrontRenderer r(f, grid, regression::tracking(c));
    const std::uint64_t h = regression::fingerprint(r, regression::scene(c, box, 0.f, 1.f, 0.7), 1.3,
                                                    [&](CpuWavefrontRenderer& rr) {
                                                      return c.naive ? rr.renderFrameNaive() : rr.renderFrame();
                                                    });
    if (regression::recording()) std::printf("    0x%016llxull,  // %s\n", (unsigned long long)h, c.name);
    EXPECT_EQ(h, kExpected[k]) << c.name;
    // Not vacuous: the coarse grids refine macrocells (the counts are in the fingerprint).
    if (c.cells < 12) EXPECT_GT(grid.refinementCount(), 0u) << c.name;
  }
}

}  // namespace
}  // namespace inr
