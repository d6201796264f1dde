// `inr render`: volume rendering of a model (delta tracking on the CPU or CUDA backend, or the
// ray-marching / naive baselines), accumulated over frames, written as PNG or linear PFM.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "Args.h"
#include "Commands.h"
#include "RenderJob.h"
#include "Common/ImageIO.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Backends/Refinement.h"
#include "Backends/RenderSession.h"
#include "Backends/SessionRayMarcher.h"
#include "Backends/SessionSurfaceRenderer.h"
#include "Render/BrickDecomposition.h"
#include "Render/CpuWavefrontRenderer.h"
#include "Render/ModelBox.h"
#include "Render/QueryReduction.h"
#include "Render/RayMarcher.h"

namespace inr::cli {

namespace {

nlohmann::json statsJson(const FrameStats& s) {
  return {{"frame", s.frame},
          {"pixels", s.pixels},
          {"rays", s.rays},
          {"queries", s.queries},
          {"iterations", s.iterations},
          {"shadow_rays", s.shadowRays},
          {"shadow_queries", s.shadowQueries},
          {"shadow_iterations", s.shadowIterations},
          {"shading_queries", s.shadingQueries},
          {"gradient_opacity_queries", s.gradientOpacityQueries},
          {"refinements", s.refinements},
          {"residual_sum", s.residualSum},
          {"capped_rays", s.cappedRays},
          {"budget_skipped", s.budgetSkipped},
          {"pruned", s.pruned},
          {"traversal_primitives", s.traversalPrimitives},
          {"traversal_bytes", s.traversalBytes},
          {"ms",
           {{"update", s.updateMs},
            {"setup", s.setupMs},
            {"init", s.initMs},
            {"traverse", s.traverseMs},
            {"evaluate", s.evaluateMs},
            {"shadow_traverse", s.shadowTraverseMs},
            {"shadow_evaluate", s.shadowEvaluateMs},
            {"shading", s.shadingMs},
            {"finalize", s.finalizeMs},
            {"other", s.otherMs},
            {"traversal_build", s.traversalBuildMs},
            {"total", s.totalMs}}}};
}

nlohmann::json queryReductionJson(const QueryReductionSettings& q) {
  return {{"budget", budgetSchemeName(q.budget)},
          {"budget_fraction", q.budgetFraction},
          {"budget_max_skip", q.budgetMaxSkip},
          {"budget_alpha", q.budgetAlpha},
          {"reproject", q.reproject},
          {"prune_epsilon", q.pruneEpsilon},
          {"prune_falloff", q.pruneFalloff}};
}

// NumPy's .npy format (version 1.0): float32 little-endian, shape (height, width, 4), C order:
// the premultiplied RGBA of a brick, readable with numpy.load.
void writeNpyRgba(const std::string& path, const ImageRGBA& image) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(image.height) + ", " +
                       std::to_string(image.width) + ", 4), }";
  // Magic (6) + version (2) + length (2) + header + newline, padded to a multiple of 64.
  const std::size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot write the brick image");
  const unsigned char magic[8] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0};
  f.write(reinterpret_cast<const char*>(magic), 8);
  const unsigned char len[2] = {static_cast<unsigned char>(header.size() & 0xff),
                                static_cast<unsigned char>(header.size() >> 8)};
  f.write(reinterpret_cast<const char*>(len), 2);
  f.write(header.data(), std::streamsize(header.size()));
  static_assert(sizeof(float) == 4, "float32 output");
  f.write(reinterpret_cast<const char*>(image.data.data()), std::streamsize(image.data.size() * sizeof(float)));
  if (!f) throw std::runtime_error(path + ": write failed");
}

// The scene from the job and the model's defaults (camera framing the box, preset transfer
// function over the value range, unit distance from the diagonal, light behind the camera).
RenderScene sceneFor(const RenderJob& job, const InrModel& model, const Box3f& box, const FieldEvaluator& evaluator) {
  RenderScene scene;
  scene.time = job.time.value_or(model.domain.timeBegin);
  if (scene.time < model.domain.timeBegin || scene.time > model.domain.timeEnd) {
    std::fprintf(stderr, "inr render: warning: --time %g is outside the model's time range [%g, %g]\n",
                 scene.time, model.domain.timeBegin, model.domain.timeEnd);
  }
  scene.camera = job.camera.value_or(Camera::framing(box));
  if (job.parallelScale) {
    scene.camera.parallelProjection = true;
    scene.camera.parallelScale = *job.parallelScale;
  }
  if (!job.transferFunctionFile.empty()) {
    scene.transferFunction = TransferFunction::fromParaViewJsonFile(job.transferFunctionFile);
    const std::string warning = scene.transferFunction.colorSpaceWarning();
    if (!warning.empty()) std::fprintf(stderr, "inr render: warning: %s\n", warning.c_str());
  } else {
    const auto range = valueRangeFor(model, evaluator);
    scene.transferFunction = TransferFunction::preset(range[0], range[1]);
  }
  if (job.transferFunctionRange) scene.transferFunction.rescale((*job.transferFunctionRange)[0], (*job.transferFunctionRange)[1]);
  scene.transferFunction.gradientOpacity = job.gradientOpacity;
  if (!job.transfer2DFile.empty()) scene.transferFunction.transfer2D = TransferFunction::transfer2DFromJsonFile(job.transfer2DFile);
  scene.transferFunction.unitDistance = job.opacityUnitDistance.value_or(length(box.hi - box.lo) / 64.0);
  scene.background = job.background;
  scene.shadows = job.shadows;
  scene.toLight = job.toLight.value_or(defaultLightDirection(scene.camera));
  scene.ambient = job.ambient;
  scene.shadowEstimator = job.shadowEstimator;
  scene.shading = job.shading;
  // ParaView's headlight where no light is named (nor the light kit): shadows need a direction,
  // so with them shading takes their (default) light.
  scene.shading.headlight = !job.toLight && !job.shadows && !job.shading.lightList;
  return scene;
}

// What a render loop hands back: the image, the frames it took and their statistics.
struct RenderOutcome {
  ImageRGBA image;
  long frames = 0;
  FrameStats total;
  FrameStats first;  // the first frame's, whose update and buffer setup the summary names apart
  std::vector<nlohmann::json> perFrame;
};

void printFrameLine(const RenderJob& job, const FrameStats& st, long k) {
  if (job.quiet) return;
  std::printf("frame %ld/%ld: %zu rays, %zu queries (+%zu shadow) in %d (+%d) iterations, %.1f ms", k + 1, job.frames,
              st.rays, st.queries, st.shadowQueries, st.iterations, st.shadowIterations, st.totalMs);
  // Only when query reduction did something, so the usual line stays as it was.
  if (st.budgetSkipped || st.pruned) std::printf("; %zu pixels skipped, %zu pruned", st.budgetSkipped, st.pruned);
  std::printf("\n");
  std::fflush(stdout);
}

// --method raymarch: the fixed-step marcher on the session's backend (the GPU marcher on CUDA),
// job.frames frames (no split: parseRenderJob refuses one, so job.settings are the run's).
RenderOutcome renderRayMarch(const RenderJob& job, const RenderSession& session, const Box3f& box,
                             const RenderScene& scene, nlohmann::json& report) {
  const std::unique_ptr<SessionRayMarcher> renderer = SessionRayMarcher::create(session, box, job.rayMarch);
  if (!job.quiet) std::printf("ray marcher: %s\n", renderer->description().c_str());
  renderer->setSettings(job.settings);
  renderer->setScene(scene);
  report["marcher"] = renderer->description();
  report["step"] = renderer->step();
  report["shadow_step"] = renderer->shadowStep();
  RenderOutcome r;
  for (long k = 0; k < job.frames; ++k) {
    const FrameStats st = renderer->renderFrame();
    printFrameLine(job, st, k);
    if (r.perFrame.empty()) r.first = st;
    r.total += st;
    r.perFrame.push_back(statsJson(st));
  }
  r.frames = job.frames;
  r.image = renderer->image();
  return r;
}

// --blend isosurface / slice: the surface renderer on the session's backend, job.frames frames
// (the first is the exact picture; later jittered ones anti-alias it).
RenderOutcome renderSurface(const RenderJob& job, const RenderSession& session, const InrModel& model, const Box3f& box,
                            const RenderScene& scene, nlohmann::json& report) {
  SurfaceOptions options = job.surface;
  options.macrocells.temporalSlices = session.options().macrocells.temporalSlices;  // (a static model: 1)
  const std::unique_ptr<SessionSurfaceRenderer> renderer =
      SessionSurfaceRenderer::create(session, box, model.domain.timeBegin, model.domain.timeEnd, options);
  if (!job.quiet) std::printf("surface renderer: %s\n", renderer->description().c_str());
  BlendScene blend = job.blend;
  if (blend.mode == BlendMode::Slice && !job.sliceOriginGiven) {
    const Vec3f c = (box.lo + box.hi) * 0.5f;
    blend.sliceOrigin = {c.x, c.y, c.z};
  }
  renderer->setSettings(job.settings);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    renderer->setScene(scene, blend);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--blend ") + blendModeName(blend.mode) + ": " + e.what());
  }
  const double setupMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json b = {{"mode", blendModeName(blend.mode)}, {"renderer", renderer->description()}, {"setup_ms", setupMs}};
  if (blend.mode == BlendMode::Isosurface) {
    const MacrocellBuildStats m = renderer->macrocellBuildStats();
    b["isovalues"] = blend.isovalues;
    b["step"] = renderer->step();
    b["tolerance"] = renderer->tolerance();
    b["macrocells"] = {{"dims", {options.macrocells.dims.x, options.macrocells.dims.y, options.macrocells.dims.z}},
                       {"temporal_slices", options.macrocells.temporalSlices},
                       {"bounds_padding", options.macrocells.boundsPadding},
                       {"slices_built", m.slicesBuilt},
                       {"build_seconds", m.seconds},
                       {"lattice_queries", m.evaluations}};
    if (!job.quiet)
      std::printf("isosurface: %zu isovalue(s), step %g, tolerance %g (model units); candidate macrocells: %d slice(s) "
                  "built in %.3f s (%zu lattice queries)\n",
                  blend.isovalues.size(), renderer->step(), renderer->tolerance(), m.slicesBuilt, m.seconds,
                  m.evaluations);
  } else {
    b["slice_origin"] = blend.sliceOrigin;
    b["slice_normal"] = blend.sliceNormal;
    b["slice_opaque"] = blend.sliceOpaque;
  }
  if (blend.crop)
    b["crop"] = {blend.cropBox.lo.x, blend.cropBox.hi.x, blend.cropBox.lo.y, blend.cropBox.hi.y, blend.cropBox.lo.z,
                 blend.cropBox.hi.z};
  report["blend"] = b;
  RenderOutcome r;
  for (long k = 0; k < job.frames; ++k) {
    const FrameStats st = renderer->renderFrame();
    if (!job.quiet) {
      std::printf("frame %ld/%ld: %zu rays, %zu queries (+%zu gradient) in %d iterations, %.1f ms (update %.1f)\n",
                  k + 1, job.frames, st.rays, st.queries, st.shadingQueries, st.iterations, st.totalMs, st.updateMs);
      std::fflush(stdout);
    }
    if (r.perFrame.empty()) r.first = st;
    r.total += st;
    r.perFrame.push_back(statsJson(st));
  }
  r.frames = job.frames;
  r.image = renderer->image();
  return r;
}

// The brick's description beside its .npy: what the compositing script needs to order the
// bricks, and what the run cost.
void writeBrickDescription(const RenderJob& job, const RenderSession& session, const Brick& b, const Camera& c,
                           const RenderOutcome& r, double renderSeconds, double estimatedPsnr) {
  nlohmann::json meta;
  meta["brick"] = {{"index", job.splitIndex.index}, {"count", job.splitIndex.count}};
  meta["split"] = splitKindName(job.split);
  meta["box"] = {b.box.lo.x, b.box.hi.x, b.box.lo.y, b.box.hi.y, b.box.lo.z, b.box.hi.z};
  meta["cells"] = {b.cellLo.x, b.cellHi.x, b.cellLo.y, b.cellHi.y, b.cellLo.z, b.cellHi.z};
  meta["camera"] = {{"position", c.position}, {"focal_point", c.focalPoint}, {"parallel", c.parallelProjection}};
  meta["seed"] = job.settings.seed;  // the brick's own (parseRenderJob varies it per brick)
  meta["width"] = job.settings.width;
  meta["height"] = job.settings.height;
  meta["frames"] = r.frames;
  meta["queries"] = r.total.queries;
  meta["shadow_queries"] = r.total.shadowQueries;
  meta["shading_queries"] = r.total.shadingQueries;
  meta["gradient_opacity_queries"] = r.total.gradientOpacityQueries;
  meta["render_seconds"] = renderSeconds;
  meta["ms_per_frame"] = r.total.totalMs / std::max<long>(1, r.frames);
  meta["estimated_psnr_db"] = estimatedPsnr;
  meta["backend"] = session.description();
  const std::string metaPath = job.output.substr(0, job.output.size() - 4) + ".brick.json";
  std::ofstream js(metaPath);
  if (!js) throw std::runtime_error(metaPath + ": cannot write the brick description");
  js << meta.dump(2) << "\n";
}

// --method delta / naive: the session's wavefront tracker, frame by frame under the refinement
// driver (the plugin's stop rule) until converged or job.frames.
RenderOutcome renderTracking(const RenderJob& job, const RenderSettings& settings, RenderSession& session,
                             const RenderScene& scene, const std::optional<Brick>& brick, nlohmann::json& report) {
  const MacrocellOptions& mopts = job.session.macrocells;
  session.setSettings(settings);
  const auto t0 = std::chrono::steady_clock::now();
  session.setScene(scene);
  const double setupMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const MacrocellInfo mi = session.macrocellInfo();
  if (!job.quiet) {
    std::printf("macrocells: %dx%dx%d x %d slices; built %d slice(s) in %.3f s (%zu lattice queries)%s\n", mi.dims.x,
                mi.dims.y, mi.dims.z, mi.temporalSlices, mi.slicesBuilt, mi.buildSeconds, mi.latticeQueries,
                mopts.lazySlices && mi.temporalSlices > mi.slicesBuilt ? "; lazy build" : "");
    if (mopts.lazySlices && mi.temporalSlices > mi.slicesBuilt) {
      std::printf("macrocells: building all %d slices up front would take about %.2f s more\n", mi.temporalSlices,
                  mi.sliceSeconds() * (mi.temporalSlices - mi.slicesBuilt));
    }
  }
  report["macrocells"] = {{"dims", {mi.dims.x, mi.dims.y, mi.dims.z}},
                          {"temporal_slices", mi.temporalSlices},
                          {"slices_built", mi.slicesBuilt},
                          {"build_seconds", mi.buildSeconds},
                          {"lattice_queries", mi.latticeQueries},
                          {"setup_ms", setupMs},
                          {"lazy", mopts.lazySlices},
                          {"skip_block", mi.skipBlockCells},
                          {"bounds_padding", mi.boundsPadding},
                          {"ghost_passes", job.ghostPasses},
                          {"refine", session.trackingOptions().refineMacrocells}};
  if (job.ghostPasses > 0) {
    const FrameStats g = session.runGhostPasses(job.ghostPasses);
    if (!job.quiet) {
      std::printf("ghost passes: %d, %zu queries, %zu cells refined, %.1f ms\n", job.ghostPasses, g.queries,
                  g.refinements, g.totalMs);
    }
    report["ghost_passes"] = statsJson(g);
  }
  // One frame per request, so each frame is reported; the driver's stop rule is the plugin's.
  RefinementOptions ro;
  ro.maximumFrames = int(job.frames);
  ro.convergenceTarget = job.convergeTarget;
  RefinementDriver driver(ro);
  RenderOutcome r;
  const auto tRender = std::chrono::steady_clock::now();
  while (!driver.converged()) {
    const RefinementDriver::Step step = driver.advance(session, job.method == RenderMethod::Naive);
    if (step.framesRendered == 0) break;
    printFrameLine(job, step.total, session.accumulatedFrames() - 1);
    if (r.perFrame.empty()) r.first = step.total;
    r.total += step.total;
    nlohmann::json js = statsJson(step.total);
    js["estimated_psnr_db"] = driver.estimate();
    js["covered_pixels"] = step.total.coveredPixels;
    r.perFrame.push_back(js);
  }
  const double renderSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tRender).count();
  r.frames = session.accumulatedFrames();
  report["convergence"] = {{"target", job.convergeTarget},
                           {"estimate", driver.estimate()},
                           {"frames", r.frames},
                           {"converged", job.convergeTarget > 0.0 && driver.estimate() >= job.convergeTarget},
                           {"seconds", renderSeconds}};
  if (job.convergeTarget > 0.0) {
    const bool reached = driver.estimate() >= job.convergeTarget;
    std::printf("convergence: %s after %ld frame(s) in %.3f s (estimated PSNR over the volume %.2f dB, target %g dB)\n",
                reached ? "reached" : "NOT reached (frame limit)", r.frames, renderSeconds, driver.estimate(),
                job.convergeTarget);
  }
  if (settings.sampleShare.count > 1 && !job.quiet) {
    // The estimate above is this share's own; the shares' average has N times the samples.
    std::printf("sample share %d/%d: the average of all %d shares at these frames estimates about %.2f dB\n",
                settings.sampleShare.index, settings.sampleShare.count, settings.sampleShare.count,
                driver.estimate() + 10.0 * std::log10(double(settings.sampleShare.count)));
  }
  report["macrocells"]["refinements"] = session.macrocellInfo().refinements;
  r.image = job.writesNpy() ? session.premultipliedImage() : session.image();
  if (brick) writeBrickDescription(job, session, *brick, scene.camera, r, renderSeconds, driver.estimate());
  return r;
}

}  // namespace

int runRenderJob(const RenderJob& job) {
  if (job.threads > 0) omp_set_num_threads(job.threads);
  const InrModel model = InrModel::loadFile(job.model);
  const Box3f box = modelWorldBox(model);

  RenderSessionOptions sopts = job.session;
  sopts.macrocells.temporalSlices = job.timeSlices.value_or(model.domain.usesTime() ? sopts.macrocells.temporalSlices : 1);
  // The part of the box this run renders: a brick (primary rays clipped to it), or the whole box
  // for a pixel or sample share.
  RenderSettings settings = job.settings;
  std::optional<Brick> brick;
  if (job.split == SplitKind::PixelShare || job.split == SplitKind::SampleShare) {
    Brick whole;
    whole.box = box;
    whole.cellLo = Int3{0, 0, 0};
    whole.cellHi = sopts.macrocells.dims;
    brick = whole;
  } else if (job.split == SplitKind::Brick) {
    try {
      brick = brickDecomposition(box, sopts.macrocells.dims, job.splitIndex.count)[std::size_t(job.splitIndex.index)];
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--brick: ") + e.what());
    }
    settings.clipToBrick = true;
    settings.brick = brick->box;
  }
  if (job.blend.crop && !job.surfaceBlend()) {
    // The composite's crop: camera rays clipped to the box as a brick's are.
    const Box3f& c = job.blend.cropBox;
    const Box3f clip{{std::max(c.lo.x, box.lo.x), std::max(c.lo.y, box.lo.y), std::max(c.lo.z, box.lo.z)},
                     {std::min(c.hi.x, box.hi.x), std::min(c.hi.y, box.hi.y), std::min(c.hi.z, box.hi.z)}};
    if (!(clip.lo.x < clip.hi.x && clip.lo.y < clip.hi.y && clip.lo.z < clip.hi.z))
      throw UsageError("--crop: the box does not overlap the model's box");
    settings.clipToBrick = true;
    settings.brick = clip;
  }

  double lastShown = -1.0;
  if (!job.quiet) {
    sopts.progress = [&](double fraction, const std::string& phase) {
      if (fraction == 0.0 || fraction == 1.0 || fraction - lastShown >= 0.25) {
        std::printf("%s: %3.0f%%\n", phase.c_str(), 100.0 * fraction);
        std::fflush(stdout);
        lastShown = fraction == 1.0 ? -1.0 : fraction;
      }
    };
  }
  const std::unique_ptr<RenderSession> session = RenderSession::create(model, sopts);
  const FieldEvaluator& evaluator = session->evaluator();
  if (!job.quiet) std::printf("backend: %s\n", session->description().c_str());
  session->setQueryReduction(job.queryReduction);
  const RenderScene scene = sceneFor(job, model, box, evaluator);

  nlohmann::json report;
  report["model"] = job.model;
  report["method"] = renderMethodName(job.method);
  if (job.method == RenderMethod::Delta && !job.surfaceBlend()) {
    const TrackingOptions& t = session->trackingOptions();
    report["estimator"] = {{"name", primaryEstimatorName(t.estimator)},
                           {"majorant_scale", t.majorantScale},
                           {"residual_scale", t.residualScale},
                           {"points_per_iteration", t.pointsPerIteration},
                           {"roulette_threshold", t.rouletteThreshold},
                           {"level_ratio", t.levelRatio},
                           {"max_level", t.maxLevel},
                           {"comb_minimum_steps", t.combMinimumSteps},
                           {"comb_floor_depth", t.combFloorDepth},
                           {"jitter", t.stratifiedJitter ? "stratified" : "random"},
                           {"jitter_control_frames", t.jitterControlFrames},
                           {"fallback_majorant_scale", t.fallbackMajorantScale}};
  }
  report["width"] = settings.width;
  report["height"] = settings.height;
  report["time"] = scene.time;
  report["frames_requested"] = job.frames;
  if (job.split != SplitKind::None)
    report["split"] = {{"kind", splitKindName(job.split)}, {"index", job.splitIndex.index}, {"count", job.splitIndex.count}};
  report["threads"] = omp_get_max_threads();
  report["evaluator"] = evaluator.name();
  report["backend"] = session->description();
  // What the session holds, read back: the settings every frame below ran with.
  if (job.method != RenderMethod::RayMarch && !job.surfaceBlend()) report["query_reduction"] = queryReductionJson(session->queryReduction());

  report["blend_mode"] = blendModeName(job.blend.mode);
  const RenderOutcome r = job.surfaceBlend()                ? renderSurface(job, *session, model, box, scene, report)
                          : job.method == RenderMethod::RayMarch ? renderRayMarch(job, *session, box, scene, report)
                                                                 : renderTracking(job, settings, *session, scene, brick, report);

  if (job.writesNpy()) writeNpyRgba(job.output, r.image);
  else writeImage(job.output, r.image);
  const double n = double(r.frames);
  const FrameStats& total = r.total;
  // The wavefront tracker's line names its estimator (ratio, delta, march), not the method.
  const std::string summaryMethod = job.surfaceBlend()               ? std::string(blendModeName(job.blend.mode))
                                    : job.method == RenderMethod::Delta
                                        ? primaryEstimatorName(session->trackingOptions().estimator)
                                        : renderMethodName(job.method);
  std::printf("%s: %s %dx%d, %ld frame(s), t=%g: %.0f rays, %.0f queries (+%.0f shadow), %.1f iterations per "
              "frame; %.1f ms per frame (traverse %.1f, evaluate %.1f, shadows %.1f, finalize %.1f) -> %s\n",
              job.model.c_str(), summaryMethod.c_str(), settings.width, settings.height, r.frames, scene.time,
              total.rays / n, total.queries / n, total.shadowQueries / n, total.iterations / n, total.totalMs / n,
              total.traverseMs / n, total.evaluateMs / n, (total.shadowTraverseMs + total.shadowEvaluateMs) / n,
              total.finalizeMs / n, job.output.c_str());
  if (r.frames > 0 && !job.quiet)
    std::printf("first frame's setup: update %.1f ms, buffers %.1f ms (in its frame time and the mean above)\n",
                r.first.updateMs, r.first.setupMs);
  if (!job.statsJson.empty()) {
    report["total"] = statsJson(total);
    report["frames"] = r.perFrame;
    std::ofstream js(job.statsJson);
    if (!js) throw std::runtime_error(job.statsJson + ": cannot write statistics");
    js << report.dump(2) << "\n";
  }
  return 0;
}

int runRender(int argc, char** argv) {
  const RenderJob job = parseRenderJob(std::vector<std::string>(argv, argv + argc));
  if (job.help) {
    std::fputs(renderUsage().c_str(), stdout);
    return 0;
  }
  return runRenderJob(job);
}

}  // namespace inr::cli
