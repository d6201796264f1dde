#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "Args.h"
#include "Commands.h"
#include "Common/ImageIO.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"

namespace inr::cli {

// An axis-aligned slice through the model at world time T, sampled at pixel centres and written
// as an 8-bit greyscale PNG (value range mapped to black..white) or a float PFM.
int runSlice(int argc, char** argv) {
  Args args(argc, argv, {"time", "axis", "position", "size", "range", "output", "threads"}, {"help"});
  if (args.has("help")) {
    std::puts("usage: inr slice MODEL --time T -o OUT.png|.pfm [--axis x|y|z] [--position P] [--size N]\n"
              "                 [--range LO,HI]\n"
              "  --axis      slice normal (default z)      --position  world coordinate along it (default: centre)\n"
              "  --size      pixels along the longer side (default 512)\n"
              "  --range     values mapped to black..white (default: the model's value range)");
    return 0;
  }
  if (args.positional().size() != 1) throw UsageError("expects exactly one MODEL file");
  if (!args.has("time")) throw UsageError("--time T is required (world time)");
  if (!args.has("output")) throw UsageError("-o OUT.png is required");
  const InrModel model = InrModel::loadFile(args.positional()[0]);
  const auto& b = model.domain.bounds;
  const std::string axisName = args.get("axis", "z");
  if (axisName != "x" && axisName != "y" && axisName != "z") throw UsageError("--axis must be x, y or z");
  const int axis = axisName[0] - 'x';
  const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;  // image axes: (y,z), (x,z) or (x,y)
  const double pos = args.getDouble("position", 0.5 * (b[2 * axis] + b[2 * axis + 1]));
  const long size = args.getInt("size", 512);
  if (size < 2 || size > 16384) throw UsageError("--size must be in [2, 16384]");
  const double extU = b[2 * u + 1] - b[2 * u], extV = b[2 * v + 1] - b[2 * v];
  const int w = int(extU >= extV ? size : std::max(2L, std::lround(size * extU / extV)));
  const int h = int(extV >= extU ? size : std::max(2L, std::lround(size * extV / extU)));

  CpuEvaluatorOptions opts;
  opts.threads = static_cast<int>(args.getInt("threads", 0));
  const CpuInrEvaluator evaluator(model, opts);
  const float t = float(args.getDouble("time", 0));
  std::vector<QueryPoint> pts(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float p[3];
      p[axis] = float(pos);
      p[u] = float(b[2 * u] + extU * (x + 0.5) / w);
      p[v] = float(b[2 * v + 1] - extV * (y + 0.5) / h);  // image row 0 at the top (max v)
      pts[std::size_t(y) * w + x] = {p[0], p[1], p[2], t};
    }
  std::vector<float> values(pts.size());
  evaluator.evaluate(pts.data(), pts.size(), values.data());

  std::array<float, 2> range{};
  if (args.has("range")) {
    const auto r = args.getList("range", 2);
    if (!(r[1] > r[0])) throw UsageError("--range LO,HI needs LO < HI");
    range = {float(r[0]), float(r[1])};
  } else {
    range = valueRangeFor(model, evaluator);
  }
  ImageRGBA image(w, h);
  const bool linear = args.get("output").size() > 4 &&
                      args.get("output").compare(args.get("output").size() - 4, 4, ".pfm") == 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const float g = linear ? values[i] : std::clamp((values[i] - range[0]) / (range[1] - range[0]), 0.f, 1.f);
    image.data[4 * i] = image.data[4 * i + 1] = image.data[4 * i + 2] = g;
    image.data[4 * i + 3] = 1.f;
  }
  writeImage(args.get("output"), image);
  const auto mm = std::minmax_element(values.begin(), values.end());
  std::printf("wrote %s: %dx%d slice %s=%g at t=%g, values [%g, %g], mapped range [%g, %g]\n",
              args.get("output").c_str(), w, h, axisName.c_str(), pos, double(t), *mm.first, *mm.second, range[0],
              range[1]);
  return 0;
}

}  // namespace inr::cli
