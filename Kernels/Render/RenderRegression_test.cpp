// Bit-for-bit regression of the CPU pipeline (cases and fingerprint in RenderRegressionCases.h)
// over analytic fields, which keep the fingerprints free of the evaluator's GEMM (no Eigen, no
// threads). Recorded at commit 56ccb3c, before the host-side fold of issue 10.
#include <gtest/gtest.h>

#include <cstdio>

#include "Render/DeltaTrackingRenderer.h"
#include "Render/RenderRegressionCases.h"
#include "Render/TestFields.h"

namespace inr {
namespace {

const std::uint64_t kExpected[] = {
    0x84a26e95d93ca64full,  // dense
    0xf37845cf3ca24ff6ull,  // sparse
    0xf37845cf3ca24ff6ull,  // sparse-no-skip (skipping changes nothing)
    0x364e8e82fc5ef30dull,  // shadows-delta
    0x964874d6eb304df7ull,  // shadows-ratio
    0x09f6952b93decdf2ull,  // ghost-passes
    0x794d795ca3da03beull,  // coarse-refine
    0xde1ec63dc22325c1ull,  // depth-limit
    0x0514a17856a10d0eull,  // naive
};

TEST(RenderRegression, ImagesAndCountsBitIdenticalToRecorded) {
  const Box3f box{{-1, -1, -1}, {1, 1, 1}};
  const auto& cases = regression::cases();
  ASSERT_EQ(cases.size(), sizeof(kExpected) / sizeof(kExpected[0]));
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const regression::Case& c = cases[k];
    test::FunctionField f(c.sparse ? test::sparseField : test::smoothField);
    MacrocellGrid grid(f, box, 0.0, 2.0, regression::macrocells(c));
    DeltaTrackingRenderer r(f, grid, regression::tracking(c));
    const std::uint64_t h = regression::fingerprint(r, regression::scene(c, box, 0.f, 1.f, 0.7), 1.3,
                                                    [&](DeltaTrackingRenderer& rr) {
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
