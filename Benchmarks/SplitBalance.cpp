// Bricks against an image-space split (issue 16, item 1): how evenly each split spreads the INR
// queries over N ranks, how much work it adds in total, and whether the composite equals the
// single-rank image. Every "rank" is rendered one after another in this process (the work per
// rank, not wall time, is what is compared).
//   bricks       k-d bricks on macrocell boundaries (Render/BrickDecomposition.h), primary rays
//                clipped to the brick, shadow rays through the whole box, composited front to
//                back in visibility order
//   image space  every rank renders the full depth of an interleaved subset of pixels (pixel
//                (x, y) belongs to rank (x + y) mod N; the others are masked with a zero depth
//                limit), composited by summing (the subsets are disjoint)
// Usage: split_balance_benchmark MODEL... [--size WxH] [--frames F] [--ranks 2,4] [--shadows]
//        [--oblique] [--backend cpu|cuda|auto] [--csv FILE]
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "Backends/RenderSession.h"
#include "Render/BrickDecomposition.h"
#include "Render/ModelBox.h"
#include "ShippedScene.h"

using namespace inr;

namespace {

struct RankRun {
  std::vector<float> premultiplied;
  double queries = 0, ms = 0;
};

RankRun renderRank(RenderSession& s, const RenderScene& scene, const RenderSettings& settings, int frames) {
  s.setSettings(settings);
  s.setScene(scene);
  RankRun r;
  for (int k = 0; k < frames; ++k) {
    const FrameStats st = s.renderFrame();
    r.queries += double(st.totalQueries());
    r.ms += st.totalMs;
  }
  r.premultiplied = s.premultipliedImage().data;
  return r;
}

double psnrOverVolume(const std::vector<float>& a, const std::vector<float>& b) {
  double se = 0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < a.size(); p += 4) {
    if (!(a[p + 3] > 0.01f || b[p + 3] > 0.01f)) continue;
    for (int c = 0; c < 4; ++c) se += double(a[p + c] - b[p + c]) * (a[p + c] - b[p + c]);
    n += 4;
  }
  return n == 0 ? NAN : se == 0 ? INFINITY : 10.0 * std::log10(double(n) / se);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> models;
  int width = 128, height = 128, frames = 64;
  std::vector<int> ranks{2, 4};
  bool shadows = false, oblique = false;
  std::string csvPath, backend = "cpu";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--size") {
      const std::string v = next();
      width = std::stoi(v.substr(0, v.find('x')));
      height = std::stoi(v.substr(v.find('x') + 1));
    } else if (a == "--frames") {
      frames = std::stoi(next());
    } else if (a == "--ranks") {
      ranks.clear();
      const std::string v = next();
      for (std::size_t p = 0; p < v.size();) {
        const std::size_t q = v.find(',', p);
        ranks.push_back(std::stoi(v.substr(p, q - p)));
        p = q == std::string::npos ? v.size() : q + 1;
      }
    } else if (a == "--shadows") {
      shadows = true;
    } else if (a == "--oblique") {
      oblique = true;
    } else if (a == "--backend") {
      backend = next();
    } else if (a == "--csv") {
      csvPath = next();
    } else {
      models.push_back(a);
    }
  }
  if (models.empty()) {
    std::fprintf(stderr, "usage: split_balance_benchmark MODEL... [--size WxH] [--frames F] [--ranks 2,4] "
                         "[--shadows] [--oblique] [--backend B] [--csv FILE]\n");
    return 2;
  }
  std::ofstream csv;
  if (!csvPath.empty()) {
    csv.open(csvPath);
    csv << "model,shadows,oblique,scheme,ranks,queries_whole,queries_min,queries_max,queries_mean,"
           "max_over_mean,sum_over_whole,ms_max,psnr_vs_whole_db,psnr_whole_vs_whole_db\n";
  }
  std::printf("%-28s %-11s %5s %12s %12s %12s %8s %8s %9s %9s\n", "model", "scheme", "ranks", "q whole", "q min/rank",
              "q max/rank", "max/mean", "sum/1", "dB vs 1", "dB 1 vs 1");
  for (const std::string& path : models) {
    const InrModel model = InrModel::loadFile(path);
    RenderSessionOptions o;
    o.backend = parseRenderBackend(backend);
    o.macrocells.temporalSlices = 1;
    const auto session = RenderSession::create(model, o);
    RenderScene scene = bench::shippedScene(model, path, session->evaluator());
    const Box3f box = modelWorldBox(model);
    if (oblique) {  // 35 degrees around the up axis and 30 degrees up: bricks overlap in depth
      const auto& f = scene.camera.focalPoint;
      const auto& p = scene.camera.position;
      const double dist = std::hypot(p[0] - f[0], p[1] - f[1], p[2] - f[2]);
      const double az = 35.0 * M_PI / 180.0, el = 30.0 * M_PI / 180.0;
      scene.camera.position = {f[0] + dist * std::cos(el) * std::sin(az), f[1] + dist * std::sin(el),
                               f[2] + dist * std::cos(el) * std::cos(az)};
    }
    scene.shadows = shadows;
    if (shadows) scene.toLight = defaultLightDirection(scene.camera);
    RenderSettings base;
    base.width = width;
    base.height = height;
    const RankRun whole = renderRank(*session, scene, base, frames);
    RenderSettings other = base;
    other.seed = 77;
    const double noiseFloor = psnrOverVolume(whole.premultiplied, renderRank(*session, scene, other, frames).premultiplied);
    const std::string name = path.substr(path.find_last_of('/') + 1);
    for (int n : ranks) {
      for (const char* scheme : {"bricks", "image"}) {
        std::vector<RankRun> runs;
        std::vector<float> composite(whole.premultiplied.size(), 0.f);
        if (std::string(scheme) == "bricks") {
          const std::vector<Brick> bricks = brickDecomposition(box, o.macrocells.dims, n);
          for (int r = 0; r < n; ++r) {
            RenderSettings s = base;
            s.clipToBrick = true;
            s.brick = bricks[std::size_t(r)].box;
            s.seed = brickSeed(base.seed, r);
            runs.push_back(renderRank(*session, scene, s, frames));
          }
          for (int r : brickVisibilityOrder(bricks, toVec3(scene.camera.position))) {
            const std::vector<float>& src = runs[std::size_t(r)].premultiplied;
            for (std::size_t p = 0; p < composite.size(); p += 4) {
              const float t = 1.f - composite[p + 3];
              for (int c = 0; c < 4; ++c) composite[p + c] += t * src[p + c];
            }
          }
        } else {
          for (int r = 0; r < n; ++r) {
            RenderScene masked = scene;
            masked.depthLimit.assign(std::size_t(width) * height, 0.f);
            for (int y = 0; y < height; ++y)
              for (int x = 0; x < width; ++x)
                if ((x + y) % n == r) masked.depthLimit[std::size_t(y) * width + x] = INFINITY;
            runs.push_back(renderRank(*session, masked, base, frames));
            for (std::size_t p = 0; p < composite.size(); ++p) composite[p] += runs.back().premultiplied[p];
          }
        }
        double qmin = 1e300, qmax = 0, qsum = 0, msMax = 0;
        for (const RankRun& r : runs) {
          qmin = std::min(qmin, r.queries);
          qmax = std::max(qmax, r.queries);
          qsum += r.queries;
          msMax = std::max(msMax, r.ms);
        }
        const double mean = qsum / n, psnr = psnrOverVolume(composite, whole.premultiplied);
        std::printf("%-28s %-11s %5d %12.0f %12.0f %12.0f %8.3f %8.3f %9.2f %9.2f\n", name.c_str(), scheme, n,
                    whole.queries, qmin, qmax, qmax / mean, qsum / whole.queries, psnr, noiseFloor);
        if (csv) {
          csv << name << ',' << shadows << ',' << oblique << ',' << scheme << ',' << n << ',' << whole.queries << ','
              << qmin << ',' << qmax << ',' << mean << ',' << qmax / mean << ',' << qsum / whole.queries << ','
              << msMax << ',' << psnr << ',' << noiseFloor << '\n';
        }
      }
    }
  }
  return 0;
}
