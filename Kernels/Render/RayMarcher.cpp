#include "Render/RayMarcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "Render/CpuParallel.h"
#include "Render/CounterRng.h"
#include "Render/Evaluate.h"
#include "Render/RayMarch.h"
#include "Render/Finalize.h"
#include "Render/AccumulationImage.h"
#include "Common/Stopwatch.h"

namespace inr {

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
  validateLighting(scene);
  if (scene.shading.enabled && !evaluator_.providesGradient())
    throw std::invalid_argument("shading: the evaluator " + evaluator_.name() + " computes no gradients");
  if (scene.transferFunction.usesGradient() && !evaluator_.providesGradient())
    throw std::invalid_argument(scene.transferFunction.gradientUseName() + ": the evaluator " + evaluator_.name() +
                                " computes no gradients");
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
  const std::uint32_t frame = sampleShareFrame(settings_.sampleShare, std::uint32_t(frameIndex_));
  Vec3f toLight = normalize(Vec3f{float(scene_.toLight[0]), float(scene_.toLight[1]),
                                  float(scene_.toLight[2])});
  if (cam.transformed) toLight = normalize(applyLinear(cam.modelFromWorld, toLight));  // model space
  const bool shadows = scene_.shadows;
  const float ambient = scene_.ambient;
  // Gradient shading, gradient opacity and 2D transfer functions: every sample's value comes with
  // its gradient (Shading.h, Evaluate.h); shadow samples too when the TF uses the gradient.
  const ShadingConstants shading = shadingConstants(scene_.shading, cam);
  const bool gradientOpacity = usesGradient(tf);
  const bool withGradients = shading.enabled || gradientOpacity;
  st.pixels = std::size_t(n);
  std::vector<float> gradients, shadowGradients;
  // Sample k's gradient term from its gradient in g (1, unread, when the TF does not use it).
  auto opacityScaleAt = [&](const std::vector<float>& g, std::size_t k) {
    return gradientOpacity ? gradientTermOf(tf, Vec3f{g[3 * k], g[3 * k + 1], g[3 * k + 2]}) : 1.f;
  };

  std::vector<MarchRay> segs;
  std::vector<QueryPoint> points;
  std::vector<float> values;
  std::vector<int> firstSample;  // each ray's first sample in the chunk's batch
  std::vector<QueryPoint> shadowPoints;
  std::vector<float> shadowValues;
  struct ShadowJob {
    int sample;          // index into the chunk's primary samples
    int first, count;    // shadow points
    float ds;
  };
  std::vector<ShadowJob> jobs;
  std::vector<float> lightT;  // transmittance to the light per primary sample

  const ImageWindow& win = settings_.window;  // keyed like the delta tracker's pixels
  for (int chunk0 = 0; chunk0 < n; chunk0 += options_.chunkPixels) {
    const int chunkN = std::min(options_.chunkPixels, n - chunk0);
    segs.resize(std::size_t(chunkN));
    firstSample.resize(std::size_t(chunkN));
    auto t0 = Clock::now();
    int total = 0;
    for (int k = 0; k < chunkN; ++k) {
      const int i = chunk0 + k;
      const float depth = scene_.depthLimit.empty() ? INFINITY : scene_.depthLimit[i];
      segs[k] = marchCameraRay(cam, box_, i, marchPixelKey(i, W, win.x, win.y, win.fullWidth), frame, settings_.seed,
                               settings_.pixelJitter, depth, step_);
      firstSample[k] = total;
      total += segs[k].count;
      if (segs[k].count > 0) ++st.rays;
    }
    points.resize(total);
    values.resize(total);
#pragma omp parallel for schedule(static) if (total >= kParallelMinItems)
    for (int k = 0; k < chunkN; ++k) {
      const MarchRay& s = segs[k];
      for (int j = 0; j < s.count; ++j) {
        const Vec3f p = marchSample(s, j);
        points[firstSample[k] + j] = QueryPoint{p.x, p.y, p.z, float(scene_.time)};
      }
    }
    st.initMs += msSince(t0);
    t0 = Clock::now();
    if (total > 0 && withGradients) {
      gradients.resize(3 * std::size_t(total));
      evaluator_.evaluateWithGradient(points.data(), std::size_t(total), values.data(), gradients.data());
    } else if (total > 0) {
      evaluator_.evaluate(points.data(), std::size_t(total), values.data());
    }
    st.queries += std::size_t(total);
    if (gradientOpacity) st.gradientOpacityQueries += std::size_t(total);
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
        if (gradientOpacity) {
          shadowGradients.resize(3 * pending);
          evaluator_.evaluateWithGradient(shadowPoints.data(), pending, shadowValues.data(), shadowGradients.data());
        } else {
          evaluator_.evaluate(shadowPoints.data(), pending, shadowValues.data());
        }
        st.shadowQueries += pending;
        if (gradientOpacity) st.gradientOpacityQueries += pending;
        st.shadowIterations += 1;
        st.shadowEvaluateMs += msSince(te);
        for (const ShadowJob& j : jobs) {
          double tau = 0.0;
          for (int q = 0; q < j.count; ++q) {
            const std::size_t sq = std::size_t(j.first + q);
            tau += marchExtinction(tf, shadowValues[sq], opacityScaleAt(shadowGradients, sq)) * j.ds;
          }
          lightT[j.sample] = float(std::exp(-tau));
        }
        jobs.clear();
        pending = 0;
      };
      shadowPoints.resize(options_.maxShadowBatch);
      for (int k = 0; k < chunkN; ++k) {
        for (int j = 0; j < segs[k].count; ++j) {
          const int sample = firstSample[k] + j;
          if (!marchSampleEmits(tf, values[sample], opacityScaleAt(gradients, std::size_t(sample)))) continue;
          const QueryPoint& q0 = points[sample];
          const Vec3f p{q0.x, q0.y, q0.z};
          const MarchShadowRay ray = marchShadowRay(box_, p, toLight, shadowStep_);
          if (ray.count == 0) continue;
          const int m = ray.count;
          if (pending + std::size_t(m) > options_.maxShadowBatch) flush();
          if (std::size_t(m) > options_.maxShadowBatch) shadowPoints.resize(m);
          ++st.shadowRays;
          jobs.push_back(ShadowJob{sample, int(pending), m, ray.ds});
          for (int q = 0; q < m; ++q) {
            const Vec3f sp = marchShadowSample(p, toLight, ray, q);
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
      const MarchRay& s = segs[k];
      MarchCompositor<double> ray;
      for (int j = 0; j < s.count; ++j) {
        const int sample = firstSample[k] + j;
        const float scale = opacityScaleAt(gradients, std::size_t(sample));
        if (shading.enabled) {
          const float* g = &gradients[3 * std::size_t(sample)];
          const QueryPoint& q = points[sample];
          const SampleLight light =
              sampleLightAt(cam, shading, toLight, Vec3f{q.x, q.y, q.z}, Vec3f{g[0], g[1], g[2]});
          ray.addLit(tf, values[sample], s.ds, ambient, light, shadows ? lightT[sample] : 1.f, scale);
        } else {
          ray.add(tf, values[sample], s.ds, shadows ? marchLightFactor<double>(ambient, lightT[sample]) : 1.0, scale);
        }
      }
      const int i = chunk0 + k;
      accum_[i] = accumulateMean(accum_[i], ray.estimate(), frameIndex_);
    }
    st.finalizeMs += msSince(t0);
  }
  ++frameIndex_;
  st.closeTiming(0.0, msSince(tFrame));
  return st;
}

ImageRGBA RayMarchRenderer::premultipliedImage() const {
  return accumulationImage(accum_, settings_.width, settings_.height, nullptr);
}

ImageRGBA RayMarchRenderer::image() const {
  return accumulationImage(accum_, settings_.width, settings_.height, &scene_.background);
}

}  // namespace inr
