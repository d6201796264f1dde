// parseRenderJob: what `inr render`'s options turn into, and the usage errors, each of which must
// name the option at fault. No model is loaded: the parser never opens a file.
#include "RenderJob.h"

#include <gtest/gtest.h>

#include <array>
#include <string>
#include <vector>

#include "Args.h"

namespace inr::cli {
namespace {

std::vector<std::string> withModel(std::vector<std::string> extra, const std::string& output = "out.png") {
  std::vector<std::string> args{"model.inr", "-o", output};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

// The message of the UsageError that parsing `args` throws ("" when it throws none).
std::string usageError(const std::vector<std::string>& args) {
  try {
    parseRenderJob(args);
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}

TEST(RenderJob, DefaultsAreTheDocumentedOnes) {
  const RenderJob job = parseRenderJob(withModel({}));
  EXPECT_FALSE(job.help);
  EXPECT_EQ(job.model, "model.inr");
  EXPECT_EQ(job.output, "out.png");
  EXPECT_EQ(job.method, RenderMethod::Delta);
  EXPECT_EQ(job.settings.width, 512);
  EXPECT_EQ(job.settings.height, 512);
  EXPECT_EQ(job.settings.seed, 1u);
  EXPECT_TRUE(job.settings.pixelJitter);
  EXPECT_EQ(job.frames, 64);
  EXPECT_EQ(job.convergeTarget, 0.0);
  EXPECT_EQ(job.split, SplitKind::None);
  EXPECT_EQ(job.session.backend, RenderBackend::Auto);
  EXPECT_FALSE(job.session.allowFallback);  // an explicit backend that cannot run is an error
  const TrackingOptions recommended = TrackingOptions::recommended();
  EXPECT_EQ(job.session.tracking.estimator, recommended.estimator);
  EXPECT_EQ(job.session.tracking.majorantScale, recommended.majorantScale);
  EXPECT_TRUE(job.session.macrocells.lazySlices);
  EXPECT_FALSE(job.timeSlices.has_value());
  // Model-dependent defaults are left to the runner.
  EXPECT_FALSE(job.time.has_value());
  EXPECT_FALSE(job.camera.has_value());
  EXPECT_FALSE(job.opacityUnitDistance.has_value());
  EXPECT_FALSE(job.toLight.has_value());
  EXPECT_TRUE(job.transferFunctionFile.empty());
  EXPECT_FALSE(job.shadows);
  EXPECT_EQ(job.shadowEstimator, ShadowEstimator::Delta);
  EXPECT_FALSE(job.shading.enabled);
}

TEST(RenderJob, ShadingOptionsReachTheScene) {
  const RenderJob plain = parseRenderJob(withModel({"--shade"}));
  EXPECT_TRUE(plain.shading.enabled);
  EXPECT_EQ(plain.shading.diffuse, ShadingOptions{}.diffuse);
  EXPECT_EQ(plain.shading.specularPower, ShadingOptions{}.specularPower);
  const RenderJob job = parseRenderJob(
      withModel({"--shade", "--ambient", "0.1", "--diffuse", "0.7", "--specular", "0.3", "--specular-power", "24"}));
  EXPECT_EQ(job.ambient, 0.1f);
  EXPECT_EQ(job.shading.diffuse, 0.7f);
  EXPECT_EQ(job.shading.specular, 0.3f);
  EXPECT_EQ(job.shading.specularPower, 24.f);
  EXPECT_FALSE(job.shading.lightList);
  // ParaView's default view lights: its light kit, five camera lights.
  const RenderJob kit = parseRenderJob(withModel({"--shade", "--light-kit"}));
  EXPECT_TRUE(kit.shading.lightList);
  EXPECT_EQ(kit.shading.lights, paraviewLightKit());
  EXPECT_EQ(kit.shading.lights.size(), 5u);
  EXPECT_THROW(parseRenderJob(withModel({"--light-kit"})), UsageError);
  EXPECT_THROW(parseRenderJob(withModel({"--shade", "--light-kit", "--shadows"})), UsageError);
  EXPECT_THROW(parseRenderJob(withModel({"--shade", "--light-kit", "--light", "0,1,0"})), UsageError);
}

TEST(RenderJob, GradientOpacityNodesAndTheirErrors) {
  EXPECT_TRUE(parseRenderJob(withModel({})).gradientOpacity.empty());
  const RenderJob job = parseRenderJob(withModel({"--gradient-opacity", "0,0,2.5,1"}));
  ASSERT_EQ(job.gradientOpacity.size(), 2u);
  EXPECT_EQ(job.gradientOpacity[1].x, 2.5);
  EXPECT_EQ(job.gradientOpacity[1].alpha, 1.0);
  EXPECT_NE(usageError(withModel({"--gradient-opacity", "0,0,1"})).find("pairs"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--gradient-opacity", "0,1.5"})).find("[0, 1]"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--gradient-opacity", "-1,0"})).find(">= 0"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--gradient-opacity", "2,0,1,1"})).find("increase"), std::string::npos);
}

TEST(RenderJob, Transfer2DFileIsKept) {
  EXPECT_TRUE(parseRenderJob(withModel({})).transfer2DFile.empty());
  EXPECT_EQ(parseRenderJob(withModel({"--tf2d", "boxes.json"})).transfer2DFile, "boxes.json");
  EXPECT_NE(usageError(withModel({"--tf2d", ""})).find("--tf2d needs a file name"), std::string::npos);
}

TEST(RenderJob, OptionsReachTheirFields) {
  const RenderJob job = parseRenderJob(withModel(
      {"--size", "40x30", "--seed", "7", "--frames", "5", "--time", "0.25", "--camera", "1,2,3,0,0,0,0,0,1,40",
       "--tf", "tf.json", "--tf-range", "-1,2", "--opacity-unit-distance", "0.5", "--background", "0.1,0.2,0.3",
       "--shadows", "--light", "0,1,0", "--ambient", "0.4", "--shadow-estimator", "ratio", "--macrocells", "8,16,32",
       "--time-slices", "3", "--eager-slices", "--skip-block", "2", "--ghost-passes", "1", "--no-refine",
       "--backend", "cpu", "--threads", "2", "--estimator", "delta", "--budget", "stbn", "--budget-fraction", "0.5",
       "--converge", "35", "--stats-json", "s.json", "--quiet", "--no-jitter"}));
  EXPECT_EQ(job.settings.width, 40);
  EXPECT_EQ(job.settings.height, 30);
  EXPECT_EQ(job.settings.seed, 7u);
  EXPECT_FALSE(job.settings.pixelJitter);
  EXPECT_EQ(job.frames, 5);
  EXPECT_EQ(job.convergeTarget, 35.0);
  ASSERT_TRUE(job.time.has_value());
  EXPECT_EQ(*job.time, 0.25);
  ASSERT_TRUE(job.camera.has_value());
  EXPECT_EQ(job.camera->position, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(job.camera->viewUp, (std::array<double, 3>{0, 0, 1}));
  EXPECT_EQ(job.camera->viewAngle, 40.0);
  EXPECT_EQ(job.transferFunctionFile, "tf.json");
  ASSERT_TRUE(job.transferFunctionRange.has_value());
  EXPECT_EQ((*job.transferFunctionRange)[0], -1.0);
  EXPECT_EQ(*job.opacityUnitDistance, 0.5);
  EXPECT_EQ(job.background[2], 0.3f);
  EXPECT_TRUE(job.shadows);
  EXPECT_EQ(*job.toLight, (std::array<double, 3>{0, 1, 0}));
  EXPECT_EQ(job.ambient, 0.4f);
  EXPECT_EQ(job.shadowEstimator, ShadowEstimator::Ratio);
  EXPECT_EQ(job.session.macrocells.dims.x, 8);
  EXPECT_EQ(job.session.macrocells.dims.z, 32);
  EXPECT_EQ(job.timeSlices.value_or(0), 3);
  EXPECT_FALSE(job.session.macrocells.lazySlices);
  EXPECT_EQ(job.session.macrocells.skipBlockCells, 2);
  EXPECT_EQ(job.ghostPasses, 1);
  EXPECT_FALSE(job.session.tracking.refineMacrocells);
  EXPECT_EQ(job.session.backend, RenderBackend::Cpu);
  EXPECT_EQ(job.threads, 2);
  EXPECT_EQ(job.session.cpuThreads, 2);
  EXPECT_EQ(job.session.tracking.estimator, PrimaryEstimator::Delta);
  EXPECT_EQ(job.queryReduction.budget, BudgetScheme::Stbn);
  EXPECT_EQ(job.queryReduction.budgetFraction, 0.5);
  EXPECT_EQ(job.statsJson, "s.json");
  EXPECT_TRUE(job.quiet);
}

TEST(RenderJob, RayMarchWithoutJitterTakesOneFrame) {
  const RenderJob job = parseRenderJob(withModel({"--method", "raymarch", "--no-jitter", "--step", "0.01"}));
  EXPECT_EQ(job.method, RenderMethod::RayMarch);
  EXPECT_EQ(job.frames, 1);
  EXPECT_EQ(job.rayMarch.step, 0.01f);
  EXPECT_EQ(parseRenderJob(withModel({"--method", "raymarch"})).frames, 64);
}

TEST(RenderJob, SplitsSetSeedAndPixelShare) {
  const RenderJob brick = parseRenderJob(withModel({"--brick", "1/4", "--seed", "9"}, "b.npy"));
  EXPECT_EQ(brick.split, SplitKind::Brick);
  EXPECT_EQ(brick.splitIndex.index, 1);
  EXPECT_EQ(brick.splitIndex.count, 4);
  EXPECT_EQ(brick.settings.seed, brickSeed(9u, 1));  // bricks vary the seed
  EXPECT_NE(brick.settings.seed, 9u);
  EXPECT_EQ(brick.settings.pixelShare.count, 1);

  const RenderJob share = parseRenderJob(withModel({"--pixel-share", "1/2", "--seed", "9"}, "s.npy"));
  EXPECT_EQ(share.split, SplitKind::PixelShare);
  EXPECT_EQ(share.settings.seed, 9u);  // shares keep it: they add up to the whole image
  EXPECT_EQ(share.settings.pixelShare.index, 1);
  EXPECT_EQ(share.settings.pixelShare.count, 2);
  EXPECT_TRUE(share.writesNpy());

  // Sample shares keep the seed too (their frames differ) and render every pixel.
  const RenderJob samples = parseRenderJob(withModel({"--sample-share", "2/3", "--seed", "9"}, "m.npy"));
  EXPECT_EQ(samples.split, SplitKind::SampleShare);
  EXPECT_EQ(samples.settings.seed, 9u);
  EXPECT_EQ(samples.settings.sampleShare.index, 2);
  EXPECT_EQ(samples.settings.sampleShare.count, 3);
  EXPECT_EQ(samples.settings.pixelShare.count, 1);
  EXPECT_FALSE(samples.settings.clipToBrick);
  EXPECT_TRUE(samples.writesNpy());
  EXPECT_STREQ(samples.splitOption(), "--sample-share");
  EXPECT_EQ(parseRenderJob(withModel({"--sample-share", "0/1"}, "m.npy")).settings.sampleShare.count, 1);
}

TEST(RenderJob, HelpNeedsNothingElse) {
  EXPECT_TRUE(parseRenderJob({"--help"}).help);
  const std::string usage = renderUsage();
  for (const char* option : {"--method", "--estimator", "--budget", "--brick", "--pixel-share", "--sample-share",
                             "--stats-json"})
    EXPECT_NE(usage.find(option), std::string::npos) << option;
}

// Each bad command line is a UsageError whose message names the option (or the argument) at fault.
TEST(RenderJob, BadValuesAreUsageErrorsNamingTheOption) {
  struct Case {
    std::vector<std::string> extra;
    std::string output;
    std::string named;
  };
  const std::vector<Case> cases = {
      {{"--size", "40"}, "out.png", "--size"},
      {{"--size", "40x"}, "out.png", "--size"},
      {{"--size", "0x5"}, "out.png", "--size"},
      {{"--seed", "-1"}, "out.png", "--seed"},
      {{"--frames", "0"}, "out.png", "--frames"},
      {{"--frames", "two"}, "out.png", "--frames"},
      {{"--time", "abc"}, "out.png", "--time"},
      {{"--method", "march"}, "out.png", "--method"},
      {{"--converge", "0"}, "out.png", "--converge"},
      {{"--converge", "40", "--method", "raymarch"}, "out.png", "--converge"},
      {{"--macrocells", "2,3"}, "out.png", "--macrocells"},
      {{"--macrocells", "0"}, "out.png", "--macrocells"},
      {{"--time-slices", "0"}, "out.png", "--time-slices"},
      {{"--bounds-padding", "-1"}, "out.png", "--bounds-padding"},
      {{"--skip-block", "3"}, "out.png", "--skip-block"},
      {{"--ghost-passes", "-1"}, "out.png", "--ghost-passes"},
      {{"--backend", "metal"}, "out.png", "--backend"},
      {{"--traversal", "bvh"}, "out.png", "--traversal"},
      {{"--gas-min-majorant", "-1"}, "out.png", "--gas-min-majorant"},
      {{"--threads", "0"}, "out.png", "--threads"},
      {{"--camera", "1,2,3"}, "out.png", "--camera"},
      {{"--camera", "0,0,0,0,0,0,0,1,0,30"}, "out.png", "--camera"},  // position equals focal point
      {{"--parallel-scale", "-1"}, "out.png", "--parallel-scale"},
      {{"--tf-range", "1,0"}, "out.png", "--tf-range"},
      {{"--opacity-unit-distance", "0"}, "out.png", "--opacity-unit-distance"},
      {{"--background", "1,1"}, "out.png", "--background"},
      {{"--light", "0,0,0"}, "out.png", "--light"},
      {{"--ambient", "2"}, "out.png", "--ambient"},
      {{"--shadow-estimator", "exact"}, "out.png", "--shadow-estimator"},
      {{"--diffuse", "0.5"}, "out.png", "--shade"},  // a coefficient without shading
      {{"--shade", "--diffuse", "-1"}, "out.png", "--diffuse"},
      {{"--shade", "--specular", "nan"}, "out.png", "--specular"},
      {{"--shade", "--specular-power", "129"}, "out.png", "--specular-power"},
      {{"--shade", "--specular-power", "x"}, "out.png", "--specular-power"},
      {{"--step", "0"}, "out.png", "--step"},
      {{"--shadow-step", "-1"}, "out.png", "--shadow-step"},
      {{"--budget", "everything"}, "out.png", "--budget"},
      {{"--budget-fraction", "0"}, "out.png", "--budget-fraction"},
      {{"--budget-max-skip", "-2"}, "out.png", "--budget-max-skip"},
      {{"--budget", "stbn", "--method", "raymarch"}, "out.png", "--budget"},
      {{"--reproject", "--no-reproject"}, "out.png", "--reproject"},
      {{"--estimator", "exact"}, "out.png", "--estimator"},
      {{"--majorant-scale", "0"}, "out.png", "--majorant-scale"},
      {{"--estimator", "ratio", "--method", "raymarch"}, "out.png", "--estimator"},
      {{"--brick", "2/2"}, "b.npy", "--brick"},
      {{"--brick", "0/2"}, "out.png", ".npy"},
      {{"--brick", "0/2", "--method", "naive"}, "b.npy", "--brick"},
      {{"--pixel-share", "0/0"}, "s.npy", "--pixel-share"},
      {{"--pixel-share", "0/2", "--brick", "0/2"}, "s.npy", "give one"},
      {{"--sample-share", "2/2"}, "m.npy", "--sample-share"},
      {{"--sample-share", "0/0"}, "m.npy", "--sample-share"},
      {{"--sample-share", "-1/2"}, "m.npy", "--sample-share"},
      {{"--sample-share", "1"}, "m.npy", "--sample-share"},
      {{"--sample-share", "0/5000"}, "m.npy", "--sample-share"},
      {{"--sample-share", "0/2"}, "out.png", "--sample-share"},
      {{"--sample-share", "0/2", "--method", "raymarch"}, "m.npy", "--sample-share"},
      {{"--sample-share", "0/2", "--method", "naive"}, "m.npy", "--sample-share"},
      {{"--sample-share", "0/2", "--pixel-share", "1/2"}, "m.npy", "--pixel-share and --sample-share"},
      {{"--sample-share", "0/2", "--brick", "1/2"}, "m.npy", "--brick and --sample-share"},
      {{"--bogus"}, "out.png", "--bogus"},
      {{"--frames"}, "out.png", "--frames"},
      {{}, "out.jpg", "-o"},
  };
  for (const Case& c : cases) {
    const std::vector<std::string> args = withModel(c.extra, c.output);
    std::string line;
    for (const std::string& a : args) line += a + " ";
    const std::string message = usageError(args);
    EXPECT_NE(message.find(c.named), std::string::npos) << "inr render " << line << "-> '" << message << "'";
  }
}

TEST(RenderJob, ModelAndOutputAreRequired) {
  EXPECT_NE(usageError({"-o", "out.png"}).find("MODEL"), std::string::npos);
  EXPECT_NE(usageError({"a.inr", "b.inr", "-o", "out.png"}).find("MODEL"), std::string::npos);
  EXPECT_NE(usageError({"a.inr"}).find("-o"), std::string::npos);
}

TEST(RenderJob, BlendModesAndTheirOptions) {
  const RenderJob composite = parseRenderJob(withModel({}));
  EXPECT_EQ(composite.blend.mode, BlendMode::Composite);
  EXPECT_FALSE(composite.blend.crop);

  const RenderJob iso = parseRenderJob(withModel({"--blend", "isosurface", "--iso", "0.25,0.75", "--iso-step", "0.5",
                                                  "--iso-tolerance", "0.01", "--iso-refine-points", "100"}));
  EXPECT_EQ(iso.blend.mode, BlendMode::Isosurface);
  EXPECT_EQ(iso.blend.isovalues, (std::vector<double>{0.25, 0.75}));
  EXPECT_FLOAT_EQ(iso.surface.stepFraction, 0.5f);
  EXPECT_FLOAT_EQ(iso.surface.toleranceFraction, 0.01f);
  EXPECT_EQ(iso.surface.refinePoints, 100);
  EXPECT_EQ(parseRenderJob(withModel({"--blend", "isosurface", "--iso", "1"})).surface.refinePoints, 0);  // backend's
  EXPECT_EQ(iso.frames, 1);               // exact in one frame
  EXPECT_TRUE(iso.shading.enabled);       // lit unless --no-shade
  EXPECT_FALSE(parseRenderJob(withModel({"--blend", "isosurface", "--iso", "1", "--no-shade"})).shading.enabled);
  EXPECT_EQ(iso.surface.macrocells.boundsPadding, SurfaceOptions{}.macrocells.boundsPadding);  // its own default
  const RenderJob cells = parseRenderJob(withModel({"--blend", "isosurface", "--iso", "1", "--macrocells", "16",
                                                    "--bounds-padding", "0.1", "--skip-block", "8"}));
  EXPECT_EQ(cells.surface.macrocells.dims.y, 16);
  EXPECT_EQ(cells.surface.macrocells.boundsPadding, 0.1);
  EXPECT_EQ(cells.surface.macrocells.skipBlockCells, 8);

  const RenderJob slice = parseRenderJob(withModel({"--blend", "slice", "--slice-origin", "1,2,3", "--slice-normal",
                                                    "0,1,0", "--slice-opaque", "--crop", "-1,1,-2,2,0,0.5"}));
  EXPECT_EQ(slice.blend.mode, BlendMode::Slice);
  EXPECT_TRUE(slice.sliceOriginGiven);
  EXPECT_EQ(slice.blend.sliceOrigin, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(slice.blend.sliceNormal, (std::array<double, 3>{0, 1, 0}));
  EXPECT_TRUE(slice.blend.sliceOpaque);
  EXPECT_FALSE(slice.shading.enabled);
  ASSERT_TRUE(slice.blend.crop);
  EXPECT_FLOAT_EQ(slice.blend.cropBox.lo.y, -2.f);
  EXPECT_FLOAT_EQ(slice.blend.cropBox.hi.z, 0.5f);
  EXPECT_FALSE(parseRenderJob(withModel({"--blend", "slice"})).sliceOriginGiven);  // the runner: box centre
}

TEST(RenderJob, BlendUsageErrorsNameTheOption) {
  EXPECT_NE(usageError(withModel({"--blend", "mip"})).find("--blend"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "isosurface"})).find("--iso"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--iso", "1"})).find("--iso needs --blend isosurface"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--iso", "1"})).find("--iso needs --blend isosurface"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "isosurface", "--iso", "1,x"})).find("--iso"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "isosurface", "--iso", "1", "--iso-step", "0"})).find("--iso-step"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "isosurface", "--iso", "1", "--iso-tolerance", "2"})).find("--iso-tolerance"),
            std::string::npos);
  for (const char* bad : {"0", "1025"})
    EXPECT_NE(usageError(withModel({"--blend", "isosurface", "--iso", "1", "--iso-refine-points", bad}))
                  .find("--iso-refine-points must be in [1, 1024]"),
              std::string::npos)
        << bad;
  EXPECT_NE(usageError(withModel({"--iso-refine-points", "8"})).find("--iso-refine-points needs --blend isosurface"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--slice-normal", "0,0,1"})).find("--slice-normal needs --blend slice"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--slice-normal", "0,0,0"})).find("--slice-normal"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--slice-origin", "1,2"})).find("--slice-origin"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--crop", "0,1,0,1,0"})).find("--crop"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--crop", "0,1,1,0,0,1"})).find("--crop"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--crop", "0,1,0,1,0,1", "--method", "raymarch"})).find("--crop"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--crop", "0,1,0,1,0,1", "--brick", "0/2"}, "out.npy")).find("--crop"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--method", "raymarch"})).find("--method"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--shadows"})).find("--shadows"), std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "isosurface", "--iso", "1", "--converge", "40"})).find("--converge"),
            std::string::npos);
  EXPECT_NE(usageError(withModel({"--blend", "slice", "--no-shade"})).find("--no-shade"), std::string::npos);
  // The options are accepted where they apply (the control for the errors above).
  EXPECT_EQ(usageError(withModel({"--blend", "slice", "--slice-normal", "0,0,1", "--crop", "0,1,0,1,0,1"})), "");
  EXPECT_EQ(usageError(withModel({"--crop", "0,1,0,1,0,1"})), "");
}

}  // namespace
}  // namespace inr::cli
