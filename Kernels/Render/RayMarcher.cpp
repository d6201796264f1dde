#include "Render/RayMarcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Render/CpuParallel.h"
#include "Render/CounterRng.h"
#include "Render/Finalize.h"
#include "Render/AccumulationImage.h"

namespace inr {

namespace {
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

RayMarchRenderer::RayMarchRenderer(const FieldEvaluator& evaluator, const Box3f& box,
                                   RayMarchOptions options)
    : evaluator_(evaluator), box_(box), options_(options) {
  const float diag = length(box.hi - box.lo);
  step_ = options.step > 0.f ? options.step : diag / 512.f;
  shadowStep_ = options.shadowStep > 0.f ? options.shadowStep : 2.f * step_;
  if (!(step_ > 0.f) || !(shadowStep_ > 0.f)) throw std::invalid_argument("ray-march step must be > 0");
  accum_.assign(std::size_t(settings_.width) * settings_.height, Vec4f{0, 0, 0, 0});
}

void RayMarchRenderer::setSettings(const RenderSettings& settings) {
  if (settings.width <= 0 || settings.height <= 0) throw std::invalid_argument("image size must be positive");
  validateImageWindow(settings.window, settings.width, settings.height);
  settings_ = settings;
  accum_.assign(std::size_t(settings_.width) * settings_.height, Vec4f{0, 0, 0, 0});
  resetAccumulation();
}

void RayMarchRenderer::setScene(const RenderScene& scene) {
  const std::size_t pixels = std::size_t(settings_.width) * settings_.height;
  if (!scene.depthLimit.empty() && scene.depthLimit.size() != pixels) {
    throw std::invalid_argument("depth limit must have one value per pixel");
  }
  scene.camera.view(settings_.width, settings_.height);  // validates
  scene_ = scene;
  tfTable_ = std::make_unique<TransferFunctionTable>(scene.transferFunction);
  haveScene_ = true;
  resetAccumulation();
}

void RayMarchRenderer::resetAccumulation() {
  std::fill(accum_.begin(), accum_.end(), Vec4f{0, 0, 0, 0});
  frameIndex_ = 0;
}

FrameStats RayMarchRenderer::renderFrame() {
  if (!haveScene_) throw std::logic_error("renderFrame: setScene first");
  const auto tFrame = Clock::now();
  FrameStats st;
  st.method = "raymarch";
  st.frame = frameIndex_;
  const CameraView cam = scene_.camera.view(settings_.width, settings_.height);
  const TransferFunctionView tf = tfTable_->view();
  const int W = settings_.width, n = settings_.width * settings_.height;
  const std::uint32_t frame = std::uint32_t(frameIndex_);
  Vec3f toLight = normalize(Vec3f{float(scene_.toLight[0]), float(scene_.toLight[1]),
                                  float(scene_.toLight[2])});
  if (cam.transformed) toLight = normalize(applyLinear(cam.modelFromWorld, toLight));  // model space
  const bool shadows = scene_.shadows;
  const float ambient = scene_.ambient;
  st.pixels = std::size_t(n);

  struct RaySeg {
    Vec3f o, d;
    float t0, ds;
    int first, count;  // sample range in the chunk's batch
  };
  std::vector<RaySeg> segs;
  std::vector<QueryPoint> points;
  std::vector<float> values;
  std::vector<QueryPoint> shadowPoints;
  std::vector<float> shadowValues;
  struct ShadowJob {
    int sample;          // index into the chunk's primary samples
    int first, count;    // shadow points
    float ds;
  };
  std::vector<ShadowJob> jobs;
  std::vector<float> lightT;  // transmittance to the light per primary sample

  for (int chunk0 = 0; chunk0 < n; chunk0 += options_.chunkPixels) {
    const int chunkN = std::min(options_.chunkPixels, n - chunk0);
    segs.assign(chunkN, RaySeg{});
    auto t0 = Clock::now();
    int total = 0;
    for (int k = 0; k < chunkN; ++k) {
      const int i = chunk0 + k;
      const ImageWindow& win = settings_.window;  // keyed like the delta tracker's pixels
      const std::uint32_t key = win.fullWidth == 0 ? std::uint32_t(i)
                                                   : std::uint32_t(i / W + win.y) * std::uint32_t(win.fullWidth) +
                                                         std::uint32_t(i % W + win.x);
      RngStream rng{key, frame, settings_.seed, 0u};
      const float u0 = rng.next(), u1 = rng.next();  // same draws as the delta tracker's jitter
      const float shift = settings_.pixelJitter ? rng.next() : 0.5f;
      RaySeg& s = segs[k];
      cameraRayWorld(cam, i % W, i / W, settings_.pixelJitter ? u0 : 0.5f,
                     settings_.pixelJitter ? u1 : 0.5f, s.o, s.d);
      const float modelPerWorld = worldRayToModel(cam, s.o, s.d);  // model space from here on
      float tEnter, tExit;
      s.first = total;
      s.count = 0;
      if (!intersectBox(box_, s.o, s.d, tEnter, tExit)) continue;
      if (!scene_.depthLimit.empty()) tExit = std::min(tExit, scene_.depthLimit[i] * modelPerWorld);
      if (!(tEnter < tExit)) continue;
      const float len = tExit - tEnter;
      s.count = std::max(1, int(std::ceil(len / step_)));
      s.ds = len / float(s.count);
      s.t0 = tEnter + shift * s.ds;
      total += s.count;
      ++st.rays;
    }
    points.resize(total);
    values.resize(total);
#pragma omp parallel for schedule(static) if (total >= kParallelMinItems)
    for (int k = 0; k < chunkN; ++k) {
      const RaySeg& s = segs[k];
      for (int j = 0; j < s.count; ++j) {
        const Vec3f p = s.o + s.d * (s.t0 + float(j) * s.ds);
        points[s.first + j] = QueryPoint{p.x, p.y, p.z, float(scene_.time)};
      }
    }
    st.initMs += msSince(t0);
    t0 = Clock::now();
    if (total > 0) evaluator_.evaluate(points.data(), std::size_t(total), values.data());
    st.queries += std::size_t(total);
    if (total > 0) st.iterations += 1;
    st.evaluateMs += msSince(t0);

    lightT.assign(total, 1.f);
    if (shadows) {
      // Transmittance towards the light for every sample that can contribute (sigma > 0).
      t0 = Clock::now();
      jobs.clear();
      std::size_t pending = 0;
      auto flush = [&]() {
        if (jobs.empty()) return;
        const auto te = Clock::now();
        shadowValues.resize(pending);
        evaluator_.evaluate(shadowPoints.data(), pending, shadowValues.data());
        st.shadowQueries += pending;
        st.shadowIterations += 1;
        st.shadowEvaluateMs += msSince(te);
        for (const ShadowJob& j : jobs) {
          double tau = 0.0;
          for (int q = 0; q < j.count; ++q) {
            const float v = shadowValues[j.first + q];
            if (isFiniteValue(v)) tau += extinctionAt(tf, v) * j.ds;
          }
          lightT[j.sample] = float(std::exp(-tau));
        }
        jobs.clear();
        pending = 0;
      };
      shadowPoints.resize(options_.maxShadowBatch);
      for (int k = 0; k < chunkN; ++k) {
        const RaySeg& s = segs[k];
        for (int j = 0; j < s.count; ++j) {
          const float v = values[s.first + j];
          if (!isFiniteValue(v) || !(extinctionAt(tf, v) > 0.f)) continue;
          const QueryPoint& q0 = points[s.first + j];
          const Vec3f p{q0.x, q0.y, q0.z};
          float te, tx;
          if (!intersectBox(box_, p, toLight, te, tx) || !(tx > 0.f)) continue;
          const int m = std::max(1, int(std::ceil(tx / shadowStep_)));
          if (pending + std::size_t(m) > options_.maxShadowBatch) flush();
          if (std::size_t(m) > options_.maxShadowBatch) shadowPoints.resize(m);
          const float ds = tx / float(m);
          ++st.shadowRays;
          jobs.push_back(ShadowJob{s.first + j, int(pending), m, ds});
          for (int q = 0; q < m; ++q) {
            const Vec3f sp = p + toLight * ((float(q) + 0.5f) * ds);
            shadowPoints[pending++] = QueryPoint{sp.x, sp.y, sp.z, float(scene_.time)};
          }
        }
      }
      flush();
      st.shadowTraverseMs += msSince(t0);  // includes the shadow evaluations
    }

    t0 = Clock::now();
#pragma omp parallel for schedule(static) if (total >= kParallelMinItems)
    for (int k = 0; k < chunkN; ++k) {
      const RaySeg& s = segs[k];
      double T = 1.0, r = 0.0, g = 0.0, b = 0.0;
      for (int j = 0; j < s.count; ++j) {
        const float v = values[s.first + j];
        if (!isFiniteValue(v)) continue;  // NaN output: empty space, as in the delta tracker
        const Vec4f c = lookupTransferFunction(tf, v);
        const double sigma = opacityToExtinction(c.w, tf.invUnitDistance);
        const double alpha = -std::expm1(-sigma * s.ds);
        double w = T * alpha;
        if (shadows) w *= ambient + (1.0 - ambient) * lightT[s.first + j];
        r += w * c.x;
        g += w * c.y;
        b += w * c.z;
        T *= 1.0 - alpha;
      }
      const Vec4f est{float(r), float(g), float(b), float(1.0 - T)};
      const int i = chunk0 + k;
      const Vec4f prev = accum_[i];
      const float wgt = 1.f / float(frameIndex_ + 1);
      accum_[i] = Vec4f{prev.x + (est.x - prev.x) * wgt, prev.y + (est.y - prev.y) * wgt,
                        prev.z + (est.z - prev.z) * wgt, prev.w + (est.w - prev.w) * wgt};
    }
    st.finalizeMs += msSince(t0);
  }
  ++frameIndex_;
  st.totalMs = msSince(tFrame);
  return st;
}

ImageRGBA RayMarchRenderer::premultipliedImage() const {
  return accumulationImage(accum_, settings_.width, settings_.height, nullptr);
}

ImageRGBA RayMarchRenderer::image() const {
  return accumulationImage(accum_, settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
