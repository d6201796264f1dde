// libFuzzer target: InrModel::loadBytes on arbitrary bytes. Every input must either load a model
// that satisfies the invariants the renderer relies on, or throw a ModelError whose message starts
// with the file's label. Anything else (a crash, a sanitizer report, another exception type, a
// violated invariant) is a finding. Built by INR_FUZZ=ON; run by Tools/run-fuzz.sh.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>

#include "Model/InrModel.h"

namespace {

constexpr const char* kLabel = "fuzz.inr";

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "invariant violated by an accepted model: %s\n", what);
  std::abort();
}

bool fp32(double v) { return std::isfinite(v) && std::fabs(v) <= std::numeric_limits<float>::max(); }

void checkLayers(const std::vector<inr::Layer>& layers) {
  for (const inr::Layer& L : layers) {
    if (L.inWidth < 1 || L.outWidth < 1) violated("layer width < 1");
    if (!std::isfinite(L.param) || !std::isfinite(L.residualScale)) violated("non-finite layer parameter");
    for (float w : L.weight)
      if (!std::isfinite(w)) violated("non-finite weight");
    for (float b : L.bias)
      if (!std::isfinite(b)) violated("non-finite bias");
    checkLayers(L.body);
    checkLayers(L.shortcut);
  }
}

void checkModel(const inr::InrModel& m) {
  const auto& d = m.domain;
  for (int i = 0; i < 3; ++i)
    if (!fp32(d.bounds[2 * i]) || !fp32(d.bounds[2 * i + 1]) || !fp32(d.bounds[2 * i + 1] - d.bounds[2 * i]) ||
        !(d.bounds[2 * i + 1] > d.bounds[2 * i]))
      violated("box or extent not finite and positive in fp32");
  if (!fp32(d.timeBegin) || !fp32(d.timeEnd) || !fp32(d.timeEnd - d.timeBegin) || !(d.timeEnd > d.timeBegin))
    violated("time range not finite and positive in fp32");
  for (const inr::AxisMap& a : d.toNetwork)
    if (!fp32(a.scale) || !fp32(a.offset) || a.scale == 0) violated("world -> network map not finite");
  for (double t : {d.timeBegin, d.timeEnd, 0.5 * (d.timeBegin + d.timeEnd)}) {
    float a, b;
    m.output.affineAt(t, a, b);
    if (!std::isfinite(a) || !std::isfinite(b)) violated("output map not finite");
  }
  if (m.valueRange && !((*m.valueRange)[0] < (*m.valueRange)[1])) violated("value range not an interval");
  const int width = m.architecture.maxWidth();
  if (width < 1 || width > (1 << 17)) violated("absurd network width");
  checkLayers(m.architecture.layers);
  (void)m.architecture.parameterCount();
  (void)m.architecture.summary();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    checkModel(inr::InrModel::loadBytes(data, size, kLabel));
  } catch (const inr::ModelError& e) {
    if (std::strncmp(e.what(), kLabel, std::strlen(kLabel)) != 0 || e.what()[std::strlen(kLabel)] != ':') {
      std::fprintf(stderr, "ModelError without the file name: %s\n", e.what());
      std::abort();
    }
  }
  return 0;
}
