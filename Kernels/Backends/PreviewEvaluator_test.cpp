// The reader's preview evaluator (Backends/PreviewEvaluator.h): chunks give the values of one
// call; the CPU's match the model's CPU evaluator; Auto takes the GPU where a usable one is (then
// within the fp16 evaluator's error of the CPU) and otherwise the CPU with the reason said;
// Cuda without a GPU is refused by name.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "Backends/PreviewEvaluator.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Model/InrModel.h"

namespace inr {
namespace {

std::vector<QueryPoint> gridPoints(const InrModel& model, int r, float t) {
  const auto& b = model.domain.bounds;
  std::vector<QueryPoint> p;
  for (int z = 0; z < r; ++z)
    for (int y = 0; y < r; ++y)
      for (int x = 0; x < r; ++x)
        p.push_back(QueryPoint{float(b[0] + (b[1] - b[0]) * x / (r - 1)), float(b[2] + (b[3] - b[2]) * y / (r - 1)),
                               float(b[4] + (b[5] - b[4]) * z / (r - 1)), t});
  return p;
}

std::vector<float> inChunks(PreviewEvaluator& e, const std::vector<QueryPoint>& p, std::size_t* chunks = nullptr) {
  const std::size_t chunk = e.chunkPoints(p.size());
  std::vector<float> out(p.size());
  std::size_t calls = 0;
  for (std::size_t first = 0; first < p.size(); first += chunk, ++calls)
    e.evaluate(p.data() + first, std::min(chunk, p.size() - first), out.data() + first);
  if (chunks) *chunks = calls;
  return out;
}

TEST(PreviewEvaluator, ChunksGiveTheValuesOfOneCallAndTheCpuEvaluators) {
  const InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/real/siren_cylinder_vorticity_small.inr");
  PreviewEvaluatorOptions o;
  o.backend = RenderBackend::Cpu;
  PreviewEvaluator preview(model, o);
  EXPECT_EQ(preview.backend(), RenderBackend::Cpu);
  EXPECT_EQ(preview.description(), "CPU");
  const std::vector<QueryPoint> p = gridPoints(model, 64, float(model.domain.timeBegin));  // 2^18 points
  std::size_t chunks = 0;
  const std::vector<float> chunked = inChunks(preview, p, &chunks);
  EXPECT_GE(chunks, 4u);  // progress steps
  std::vector<float> one(p.size());
  preview.evaluate(p.data(), p.size(), one.data());
  EXPECT_EQ(chunked, one);
  const CpuInrEvaluator reference(model);
  std::vector<float> ref(p.size());
  reference.evaluate(p.data(), p.size(), ref.data());
  float worst = 0.f, range = 0.f;
  for (std::size_t i = 0; i < p.size(); ++i) {
    worst = std::max(worst, std::abs(one[i] - ref[i]));
    range = std::max(range, std::abs(ref[i]));
  }
  EXPECT_LE(worst, 1e-5f * std::max(1.f, range));
  // A small grid is one chunk.
  EXPECT_EQ(preview.chunkPoints(512), preview.chunkPoints(1000));
  EXPECT_GE(preview.chunkPoints(512), 512u);
}

TEST(PreviewEvaluator, AutoTakesTheGpuWhereThereIsOneElseSaysWhy) {
  const InrModel model = InrModel::loadFile(std::string(INR_TEST_DATA_DIR) + "/real/ffn_mri_head_small.inr");
  std::string why;
  const bool gpu = cudaBackendAvailable(&why);
  PreviewEvaluator preview(model);
  const std::vector<QueryPoint> p = gridPoints(model, 48, float(model.domain.timeBegin));
  const std::vector<float> values = inChunks(preview, p);
  std::vector<float> ref(p.size());
  CpuInrEvaluator(model).evaluate(p.data(), p.size(), ref.data());
  double worst = 0.0, lo = ref[0], hi = ref[0];
  for (std::size_t i = 0; i < p.size(); ++i) {
    worst = std::max(worst, double(std::abs(values[i] - ref[i])));
    lo = std::min(lo, double(ref[i]));
    hi = std::max(hi, double(ref[i]));
  }
  std::printf("auto preview: %s; largest difference from the CPU evaluator %.3g of a value range %.3g\n",
              preview.description().c_str(), worst, hi - lo);
  if (gpu) {
    EXPECT_EQ(preview.backend(), RenderBackend::Cuda);
    EXPECT_EQ(preview.description().rfind("CUDA: ", 0), 0u) << preview.description();
    EXPECT_LE(worst, 1e-2 * (hi - lo));  // the fp16 evaluator's error
  } else {
    EXPECT_EQ(preview.backend(), RenderBackend::Cpu);
    EXPECT_NE(preview.description().find("CUDA unavailable: " + why), std::string::npos) << preview.description();
    EXPECT_LE(worst, 1e-5 * std::max(1.0, hi - lo));
    PreviewEvaluatorOptions cuda;
    cuda.backend = RenderBackend::Cuda;
    try {
      PreviewEvaluator refused(model, cuda);
      ADD_FAILURE() << "a preview on the GPU without one was not refused";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("CUDA is unavailable"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace inr
