// The isosurface and slice blend modes and cropping (Render/SurfaceMarch.h, SurfaceRenderer.*)
// against analytic answers computed here in double precision: ray-sphere intersections of a
// distance field's level sets, the field sampled where each pixel's ray meets the plane. Each
// check runs beside a control that shows it can fail (a wrong radius, plane, normal or order).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "Render/SurfaceMarch.h"
#include "Render/SurfaceRenderer.h"
#include "TestSupport/TestFields.h"
#include "TestSupport/TestScene.h"

namespace inr {
namespace {

using test::FunctionField;
using test::kCubeBox;

constexpr double kCentre[3] = {0.1, -0.05, 0.02};

// The distance to kCentre: level set r is the sphere of radius r, the gradient the unit vector
// away from the centre.
float distanceField(const QueryPoint& p) {
  const double dx = p.x - kCentre[0], dy = p.y - kCentre[1], dz = p.z - kCentre[2];
  return float(std::sqrt(dx * dx + dy * dy + dz * dz));
}
std::array<float, 3> distanceGradient(const QueryPoint& p) {
  const double dx = p.x - kCentre[0], dy = p.y - kCentre[1], dz = p.z - kCentre[2];
  const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
  return {float(dx / r), float(dy / r), float(dz / r)};
}

// An oblique perspective view of [-1, 1]^3.
RenderScene obliqueScene() {
  RenderScene scene;
  scene.camera = Camera::framing(kCubeBox);
  const auto& f = scene.camera.focalPoint;
  const double d = scene.camera.position[2] - f[2];
  scene.camera.position = {f[0] + 0.45 * d, f[1] + 0.35 * d, f[2] + 0.8 * d};
  scene.background = {0.f, 0.f, 0.f};
  return scene;
}

RenderSettings imageOf(int size) {
  RenderSettings s;
  s.width = s.height = size;
  s.pixelJitter = false;
  return s;
}

// A TF with colour c0 / opacity a0 at x0 and c1 / a1 at x1 (linear between, RGB).
TransferFunction twoPointTf(double x0, std::array<double, 3> c0, double a0, double x1, std::array<double, 3> c1,
                            double a1) {
  TransferFunction tf;
  tf.color = {{x0, c0[0], c0[1], c0[2]}, {x1, c1[0], c1[1], c1[2]}};
  tf.opacity = {{x0, a0}, {x1, a1}};
  return tf;
}

struct Ray {
  double o[3], d[3];
};
// Pixel (px, py)'s ray through its centre, in double, from the camera's float frame.
Ray pixelRay(const CameraView& cam, int px, int py) {
  Vec3f o, d;
  cameraRay(cam, px, py, 0.5f, 0.5f, o, d);
  return Ray{{o.x, o.y, o.z}, {d.x, d.y, d.z}};
}

// Ray parameters where the ray enters and leaves the sphere of radius r around kCentre; false
// when it misses. chord: their distance.
bool sphereHits(const Ray& ray, double r, double& t0, double& t1) {
  const double ox = ray.o[0] - kCentre[0], oy = ray.o[1] - kCentre[1], oz = ray.o[2] - kCentre[2];
  const double b = ox * ray.d[0] + oy * ray.d[1] + oz * ray.d[2];
  const double c = ox * ox + oy * oy + oz * oz - r * r;
  const double disc = b * b - c;
  if (disc < 0) return false;
  t0 = -b - std::sqrt(disc);
  t1 = -b + std::sqrt(disc);
  return true;
}

// ---- Slice -----------------------------------------------------------------------------------

struct SliceCase {
  RenderScene scene = obliqueScene();
  RenderSettings settings = imageOf(48);
  BlendScene blend;
  SliceCase() {
    scene.transferFunction = twoPointTf(0.0, {0.1, 0.2, 0.9}, 0.3, 1.0, {0.9, 0.5, 0.1}, 0.9);
    blend.mode = BlendMode::Slice;
    blend.sliceOrigin = {0.1, 0.05, -0.1};
    blend.sliceNormal = {0.3, -0.2, 1.0};
  }
};

// The expected slice image: at each pixel centre's ray, the plane point (double precision), inside
// the box (pixels within `margin` of its faces are left out: -1 in `use`), the field's value
// through the same TF table, premultiplied by its opacity.
std::vector<Vec4f> expectedSlice(const SliceCase& c, const std::array<double, 3>& origin, std::vector<int>& use,
                                 const Box3f& box = kCubeBox, double margin = 1e-4) {
  const CameraView cam = c.scene.camera.view(c.settings.width, c.settings.height);
  const TransferFunctionTable table(c.scene.transferFunction);
  const TransferFunctionView tf = table.view();
  const int n = c.settings.width * c.settings.height;
  std::vector<Vec4f> out(std::size_t(n), Vec4f{0, 0, 0, 0});
  use.assign(std::size_t(n), 1);
  const auto& nrm = c.blend.sliceNormal;
  for (int i = 0; i < n; ++i) {
    const Ray r = pixelRay(cam, i % c.settings.width, i / c.settings.width);
    const double denom = nrm[0] * r.d[0] + nrm[1] * r.d[1] + nrm[2] * r.d[2];
    const double t = ((origin[0] - r.o[0]) * nrm[0] + (origin[1] - r.o[1]) * nrm[1] + (origin[2] - r.o[2]) * nrm[2]) / denom;
    const double p[3] = {r.o[0] + t * r.d[0], r.o[1] + t * r.d[1], r.o[2] + t * r.d[2]};
    double inside = INFINITY;  // distance inside the box (negative: outside)
    for (int a = 0; a < 3; ++a)
      inside = std::min(inside, std::min(p[a] - component(box.lo, a), component(box.hi, a) - p[a]));
    if (std::fabs(inside) < margin) use[i] = 0;
    if (inside < 0) continue;
    const float v = test::smoothField(QueryPoint{float(p[0]), float(p[1]), float(p[2]), float(c.scene.time)});
    const Vec4f col = lookupTransferFunction(tf, v);
    out[i] = Vec4f{col.x * col.w, col.y * col.w, col.z * col.w, col.w};
  }
  return out;
}

// Largest channel difference over the pixels in use; `covered` counts those with alpha > 0 in a.
float maxDifference(const ImageRGBA& image, const std::vector<Vec4f>& expected, const std::vector<int>& use,
                    int* covered = nullptr) {
  float worst = 0.f;
  int n = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    if (!use[i]) continue;
    const float e[4] = {expected[i].x, expected[i].y, expected[i].z, expected[i].w};
    for (int k = 0; k < 4; ++k) worst = std::max(worst, std::fabs(image.data[4 * i + k] - e[k]));
    if (expected[i].w > 0.f) ++n;
  }
  if (covered) *covered = n;
  return worst;
}

TEST(SliceBlend, ImageIsTheFieldSampledWhereEachPixelMeetsThePlane) {
  SliceCase c;
  FunctionField field(test::smoothField, "smooth");
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0);
  renderer.setSettings(c.settings);
  renderer.setScene(c.scene, c.blend);
  const FrameStats st = renderer.renderFrame();
  const ImageRGBA image = renderer.premultipliedImage();
  std::vector<int> use;
  int covered = 0;
  const float error = maxDifference(image, expectedSlice(c, c.blend.sliceOrigin, use), use, &covered);
  std::printf("slice: %d covered pixels, max channel error %.3g, %zu queries\n", covered, error, st.queries);
  EXPECT_GT(covered, 400);
  EXPECT_LT(error, 2e-5f);
  // One query per pixel whose ray meets the plane inside the box, in one batch.
  EXPECT_EQ(st.queries, field.points());
  EXPECT_GE(st.queries, std::size_t(covered));
  EXPECT_LE(st.queries, std::size_t(covered) + 2 * std::size_t(c.settings.width));  // (+ the box-face margin)
  EXPECT_EQ(st.iterations, 1);
  // Control: the plane moved by 0.02 along its normal's direction gives another image.
  std::vector<int> useShifted;
  const float shifted =
      maxDifference(image, expectedSlice(c, {c.blend.sliceOrigin[0], c.blend.sliceOrigin[1], c.blend.sliceOrigin[2] + 0.02}, useShifted),
                    use);
  EXPECT_GT(shifted, 0.01f);
}

TEST(SliceBlend, OpaqueSliceKeepsTheColourMapAtFullAlpha) {
  SliceCase c;
  c.blend.sliceOpaque = true;
  FunctionField field(test::smoothField, "smooth");
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0);
  renderer.setSettings(c.settings);
  renderer.setScene(c.scene, c.blend);
  renderer.renderFrame();
  const ImageRGBA image = renderer.premultipliedImage();
  std::vector<int> use;
  std::vector<Vec4f> expected = expectedSlice(c, c.blend.sliceOrigin, use);
  const TransferFunctionTable table(c.scene.transferFunction);
  for (Vec4f& e : expected) {
    if (!(e.w > 0.f)) continue;
    e = Vec4f{e.x / e.w, e.y / e.w, e.z / e.w, 1.f};
  }
  EXPECT_LT(maxDifference(image, expected, use), 1e-4f);
}

TEST(SliceBlend, CropBoxClipsThePlane) {
  SliceCase c;
  c.blend.crop = true;
  c.blend.cropBox = Box3f{{-1.f, -0.4f, -1.f}, {0.3f, 1.f, 1.f}};
  FunctionField field(test::smoothField, "smooth");
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0);
  renderer.setSettings(c.settings);
  renderer.setScene(c.scene, c.blend);
  renderer.renderFrame();
  std::vector<int> use, useWhole;
  const std::vector<Vec4f> expected = expectedSlice(c, c.blend.sliceOrigin, use, c.blend.cropBox);
  int covered = 0, coveredWhole = 0;
  EXPECT_LT(maxDifference(renderer.premultipliedImage(), expected, use, &covered), 2e-5f);
  // Control: the uncropped expectation covers more pixels and does not match.
  const std::vector<Vec4f> whole = expectedSlice(c, c.blend.sliceOrigin, useWhole);
  EXPECT_GT(maxDifference(renderer.premultipliedImage(), whole, use, &coveredWhole), 0.05f);
  EXPECT_LT(covered + 100, coveredWhole);
}

// ---- Isosurface ------------------------------------------------------------------------------

struct IsoCase {
  RenderScene scene = obliqueScene();
  RenderSettings settings = imageOf(48);
  BlendScene blend;
  SurfaceOptions options;
  IsoCase() {
    blend.mode = BlendMode::Isosurface;
    blend.isovalues = {0.5};
    scene.camera.viewAngle = 16.0;  // the spheres fill much of the picture
    scene.transferFunction = twoPointTf(0.0, {1, 1, 1}, 1.0, 1.0, {1, 1, 1}, 1.0);
  }
};

// The world distance (here the model distance: no transform) from each pixel centre to the
// sphere of radius r, INFINITY where the ray misses; use[i] = 0 where the ray grazes it (its
// chord shorter than `minChord`, which a march of that step may miss) or misses by less than that.
std::vector<double> sphereDepth(const IsoCase& c, double r, double minChord, std::vector<int>& use) {
  const CameraView cam = c.scene.camera.view(c.settings.width, c.settings.height);
  const int n = c.settings.width * c.settings.height;
  std::vector<double> out(std::size_t(n), INFINITY);
  use.assign(std::size_t(n), 1);
  for (int i = 0; i < n; ++i) {
    const Ray ray = pixelRay(cam, i % c.settings.width, i / c.settings.width);
    double t0, t1;
    // Grazing rays (or near misses) are left out: whether the march sees them depends on the step.
    double t0w, t1w;
    if (sphereHits(ray, r + minChord, t0w, t1w) && !(sphereHits(ray, r, t0, t1) && t1 - t0 >= minChord)) use[i] = 0;
    if (sphereHits(ray, r, t0, t1)) out[i] = t0;
  }
  return out;
}

// Checks the frame's hits against the sphere's exact depths; returns the frame's iterations.
int expectHitsOnTheSphereWithinTheTolerance(const IsoCase& c);

// Every refinement width (R points per round: R-section) finds the hits within the tolerance;
// the wider, the fewer rounds (iterations) a frame takes.
TEST(IsosurfaceBlend, HitsLieOnTheExactSurfaceWithinTheTolerance) {
  int lastIterations = 1 << 30, firstIterations = 0;
  for (const int refinePoints : {2, 8, 32, kMaxSurfaceRefinePoints}) {
    SCOPED_TRACE("refinePoints " + std::to_string(refinePoints));
    IsoCase c;
    c.options.toleranceFraction = 1e-2f;
    c.options.maxMarchSamples = kMaxSurfaceSamples;  // so that the march does not set the count
    c.options.refinePoints = refinePoints;
    const int iterations = expectHitsOnTheSphereWithinTheTolerance(c);
    EXPECT_LE(iterations, lastIterations);
    if (firstIterations == 0) firstIterations = iterations;
    lastIterations = iterations;
  }
  EXPECT_LT(lastIterations, firstIterations);  // one round per hit against five
}

// The points of a refinement round: R while R + 1 parts are longer than the tolerance, then the
// fewest that reach it.
TEST(IsosurfaceBlend, RefinementRoundsAskWhatReachesTheTolerance) {
  SurfaceConstants sc;
  sc.tolerance = 1e-3f;
  sc.refinePoints = 8;
  SurfaceRay r;
  auto count = [&](float length) {
    r.ta = 2.f;
    r.tb = 2.f + length;
    return surfaceRefineCount(sc, r);
  };
  EXPECT_EQ(count(1.f), 8);           // 1000 tolerances long: 9 parts
  EXPECT_EQ(count(9.5e-3f), 8);       // 9.5 tolerances: still 9 parts at most
  EXPECT_EQ(count(3.5e-3f), 3);       // 3.5 tolerances: 4 parts
  EXPECT_EQ(count(1.2e-3f), 1);       // 1.2 tolerances: halved
  sc.refinePoints = 32;
  EXPECT_EQ(count(1.f), 32);
  EXPECT_EQ(count(1.f / 33.f), 30);   // the second round from one step: 31 parts
  EXPECT_FLOAT_EQ(surfaceRefineT(1.f, 2.f, 0, 3), 1.25f);
  EXPECT_FLOAT_EQ(surfaceRefineT(1.f, 2.f, 2, 3), 1.75f);
}

int expectHitsOnTheSphereWithinTheTolerance(const IsoCase& c) {
  FunctionField field(distanceField, "distance", distanceGradient);
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, c.options);
  renderer.setSettings(c.settings);
  renderer.setScene(c.scene, c.blend);
  const int iterations = renderer.renderFrame().iterations;
  const std::vector<float>& depth = renderer.surfaceDepth();
  std::vector<int> use;
  const std::vector<double> exact = sphereDepth(c, 0.5, 2.0 * renderer.step(), use);
  // Control: the sphere of a radius larger by twice the tolerance.
  std::vector<int> useControl;
  const std::vector<double> wrong = sphereDepth(c, 0.5 + 2.0 * renderer.tolerance(), 2.0 * renderer.step(), useControl);
  double worst = 0.0, worstControl = 0.0;
  int hits = 0, missesAgree = 0, used = 0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    if (!use[i]) continue;
    ++used;
    if (std::isinf(exact[i])) {
      missesAgree += std::isinf(depth[i]) ? 1 : 0;
      continue;
    }
    ++hits;
    worst = std::max(worst, std::fabs(double(depth[i]) - exact[i]));
    if (useControl[i] && !std::isinf(wrong[i])) worstControl = std::max(worstControl, std::fabs(double(depth[i]) - wrong[i]));
  }
  std::printf("isosurface, %d refinement points: %d hits, max depth error %.3g (tolerance %.3g), control %.3g, "
              "%d iterations\n", c.options.refinePoints, hits, worst, double(renderer.tolerance()), worstControl,
              iterations);
  EXPECT_GT(hits, 300);
  EXPECT_EQ(missesAgree, used - hits);  // no surface where the ray misses the sphere
  // Float ray parameters (about 4 units from the eye) add a few units of float rounding.
  EXPECT_LE(worst, double(renderer.tolerance()) + 4e-6);
  EXPECT_GT(worstControl, double(renderer.tolerance()) + 4e-6);
  return iterations;
}

// The shaded sphere (white, headlight, no specular): ambient + diffuse |N.E| at the analytic hit.
std::vector<Vec4f> expectedShadedSphere(const IsoCase& c, double r, float ambient, float diffuse, std::vector<int>& use,
                                        double minChord) {
  const CameraView cam = c.scene.camera.view(c.settings.width, c.settings.height);
  const int n = c.settings.width * c.settings.height;
  std::vector<Vec4f> out(std::size_t(n), Vec4f{0, 0, 0, 0});
  const std::vector<double> depth = sphereDepth(c, r, minChord, use);
  for (int i = 0; i < n; ++i) {
    if (std::isinf(depth[i])) continue;
    const Ray ray = pixelRay(cam, i % c.settings.width, i / c.settings.width);
    double p[3], nrm[3], e[3];
    for (int a = 0; a < 3; ++a) p[a] = ray.o[a] + depth[i] * ray.d[a];
    for (int a = 0; a < 3; ++a) nrm[a] = (p[a] - kCentre[a]) / r;
    const double eye[3] = {c.scene.camera.position[0], c.scene.camera.position[1], c.scene.camera.position[2]};
    double el = 0;
    for (int a = 0; a < 3; ++a) el += (eye[a] - p[a]) * (eye[a] - p[a]);
    for (int a = 0; a < 3; ++a) e[a] = (eye[a] - p[a]) / std::sqrt(el);
    const double facing = std::fabs(nrm[0] * e[0] + nrm[1] * e[1] + nrm[2] * e[2]);
    const float v = std::min(1.f, float(ambient + diffuse * facing));
    out[i] = Vec4f{v, v, v, 1.f};
  }
  return out;
}

TEST(IsosurfaceBlend, ShadingUsesTheNetworksGradientAtTheHit) {
  IsoCase c;
  c.scene.shading.enabled = true;
  c.scene.shading.headlight = true;
  c.scene.shading.specular = 0.f;
  c.scene.shading.diffuse = 0.7f;
  c.scene.ambient = 0.25f;
  auto render = [&](FunctionField& field) {
    SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, c.options);
    renderer.setSettings(c.settings);
    renderer.setScene(c.scene, c.blend);
    const FrameStats st = renderer.renderFrame();
    EXPECT_EQ(st.shadingQueries, field.gradientPoints());  // one gradient per hit, nothing else
    return std::make_pair(renderer.premultipliedImage(), 2.0 * renderer.step());
  };
  FunctionField field(distanceField, "distance", distanceGradient);
  const auto [image, minChord] = render(field);
  std::vector<int> use;
  const std::vector<Vec4f> expected = expectedShadedSphere(c, 0.5, 0.25f, 0.7f, use, minChord);
  int covered = 0;
  const float error = maxDifference(image, expected, use, &covered);
  // Control: the same values with the gradient of a sphere centred elsewhere.
  FunctionField wrongNormals(distanceField, "wrong normals", [](const QueryPoint& p) {
    return distanceGradient(QueryPoint{p.x + 0.3f, p.y, p.z, p.t});
  });
  const float control = maxDifference(render(wrongNormals).first, expected, use);
  std::printf("shaded isosurface: %d covered pixels, max channel error %.3g, control %.3g\n", covered, error, control);
  EXPECT_GT(covered, 300);
  EXPECT_LT(error, 2e-3f);
  EXPECT_GT(control, 0.05f);
}

// An evaluator that records every value query after record() (not the macrocell build's).
class RecordingField : public FieldEvaluator {
public:
  void evaluate(const QueryPoint* p, std::size_t n, float* out) const override {
    for (std::size_t i = 0; i < n; ++i) out[i] = distanceField(p[i]);
    if (recording_) points_.insert(points_.end(), p, p + n);
  }
  std::string name() const override { return "recording distance"; }
  void record() { recording_ = true; }
  const std::vector<QueryPoint>& points() const { return points_; }

private:
  bool recording_ = false;
  mutable std::vector<QueryPoint> points_;
};

// How many of `points` lie in no candidate cell (nor on the face of one), for the candidate mask
// of `grid` (cells of [-1, 1]^3).
std::size_t pointsOutsideCandidates(const std::vector<QueryPoint>& points, const std::vector<float>& candidates,
                                    const Int3& dims) {
  std::size_t outside = 0;
  for (const QueryPoint& q : points) {
    const float p[3] = {q.x, q.y, q.z};
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      const int n = component(dims, a);
      const float x = (p[a] + 1.f) * 0.5f * float(n);  // cell coordinate
      lo[a] = std::clamp(int(std::floor(x - 1e-3f)), 0, n - 1);
      hi[a] = std::clamp(int(std::floor(x + 1e-3f)), 0, n - 1);
    }
    bool inCandidate = false;
    for (int z = lo[2]; z <= hi[2]; ++z)
      for (int y = lo[1]; y <= hi[1]; ++y)
        for (int x = lo[0]; x <= hi[0]; ++x)
          inCandidate = inCandidate || candidates[std::size_t(linearCellIndex(dims, Int3{x, y, z}))] > 0.f;
    outside += inCandidate ? 0 : 1;
  }
  return outside;
}

TEST(IsosurfaceBlend, CellsWhoseRangeExcludesEveryIsovalueCostNoQueries) {
  IsoCase c;
  c.blend.isovalues = {0.3};
  auto run = [&](bool skip, std::vector<float>* mask) {
    IsoCase k = c;
    k.options.skipCells = skip;
    RecordingField field;
    SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, k.options);
    renderer.setSettings(k.settings);
    renderer.setScene(k.scene, k.blend);
    field.record();
    renderer.renderFrame();
    if (mask) *mask = renderer.candidateCells();
    return field.points();
  };
  std::vector<float> mask;
  const std::vector<QueryPoint> skipped = run(true, &mask);
  const Int3 dims = SurfaceOptions{}.macrocells.dims;
  const std::size_t candidates = std::size_t(std::count(mask.begin(), mask.end(), 1.f));
  const std::size_t outside = pointsOutsideCandidates(skipped, mask, dims);
  // Control: sampling every cell queries the cells the mask excludes.
  const std::vector<QueryPoint> all = run(false, nullptr);
  const std::size_t outsideAll = pointsOutsideCandidates(all, mask, dims);
  std::printf("candidate cells %zu of %zu; queries %zu (outside candidates %zu), every cell: %zu (%zu)\n", candidates,
              mask.size(), skipped.size(), outside, all.size(), outsideAll);
  EXPECT_GT(candidates, 0u);
  EXPECT_LT(candidates, mask.size() / 4);
  EXPECT_GT(skipped.size(), 0u);
  EXPECT_EQ(outside, 0u);
  EXPECT_GT(outsideAll, all.size() / 4);
}

TEST(IsosurfaceBlend, TransparentIsovaluesCostNoQueries) {
  // The TF's opacity is 0 up to 0.35, then rises to 1 at 0.6: the 0.3 surface is not drawn, and
  // not sampled.
  auto queries = [](std::vector<double> isovalues) {
    IsoCase c;
    c.blend.isovalues = std::move(isovalues);
    c.scene.transferFunction = twoPointTf(0.0, {1, 1, 1}, 0.0, 0.6, {1, 1, 1}, 1.0);
    c.scene.transferFunction.opacity = {{0.0, 0.0}, {0.35, 0.0}, {0.6, 1.0}};
    FunctionField field(distanceField, "distance", distanceGradient);
    SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, c.options);
    renderer.setSettings(c.settings);
    renderer.setScene(c.scene, c.blend);
    return renderer.renderFrame().queries;
  };
  EXPECT_EQ(queries({0.3}), 0u);
  EXPECT_GT(queries({0.45}), 0u);  // control: a visible one is sampled
  EXPECT_EQ(queries({0.3, 0.45}), queries({0.45}));
}

TEST(IsosurfaceBlend, TwoIsovaluesCompositeFrontToBack) {
  IsoCase c;
  c.blend.isovalues = {0.6, 0.3};  // any order
  c.scene.transferFunction = twoPointTf(0.3, {1, 0, 0}, 0.5, 0.6, {0, 0, 1}, 0.25);
  c.options.toleranceFraction = 1e-2f;
  FunctionField field(distanceField, "distance");
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, c.options);
  renderer.setSettings(c.settings);
  renderer.setScene(c.scene, c.blend);
  renderer.renderFrame();
  const ImageRGBA image = renderer.premultipliedImage();
  const CameraView cam = c.scene.camera.view(c.settings.width, c.settings.height);
  const double minChord = 2.0 * renderer.step();
  struct Layer {
    double t;
    Vec4f c;  // colour, alpha
  };
  const Vec4f red{1, 0, 0, 0.5f}, blue{0, 0, 1, 0.25f};
  // Along the ray (front to back), or (the control) the inner sphere's two hits before the outer
  // one's, as compositing per isovalue would.
  auto composite = [](std::vector<Layer> layers, bool alongRay) {
    std::stable_sort(layers.begin(), layers.end(), [&](const Layer& a, const Layer& b) {
      return alongRay ? a.t < b.t : a.c.x > b.c.x;
    });
    double T = 1, r = 0, g = 0, b = 0;
    for (const Layer& l : layers) {
      r += T * l.c.w * l.c.x;
      g += T * l.c.w * l.c.y;
      b += T * l.c.w * l.c.z;
      T *= 1 - l.c.w;
    }
    return Vec4f{float(r), float(g), float(b), float(1 - T)};
  };
  std::vector<Vec4f> expected(image.data.size() / 4), reversed(expected.size());
  std::vector<int> use(expected.size(), 1);
  int layered = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const Ray ray = pixelRay(cam, int(i) % c.settings.width, int(i) / c.settings.width);
    std::vector<Layer> layers;
    for (const auto& [radius, colour] : {std::pair{0.3, red}, std::pair{0.6, blue}}) {
      double t0, t1, a, b;
      if (sphereHits(ray, radius + minChord, a, b) && !(sphereHits(ray, radius, t0, t1) && t1 - t0 >= minChord)) use[i] = 0;
      if (sphereHits(ray, radius, t0, t1)) {
        layers.push_back({t0, colour});
        layers.push_back({t1, colour});
      }
    }
    if (layers.size() == 4) ++layered;
    expected[i] = composite(layers, true);
    reversed[i] = composite(layers, false);
  }
  int covered = 0;
  const float error = maxDifference(image, expected, use, &covered);
  const float control = maxDifference(image, reversed, use);
  std::printf("two isovalues: %d covered, %d through both spheres, max error %.3g, per isovalue %.3g\n", covered,
              layered, error, control);
  EXPECT_GT(layered, 100);
  EXPECT_LT(error, 1e-4f);
  EXPECT_GT(control, 0.1f);
}

TEST(IsosurfaceBlend, CropBoxClipsTheRays) {
  IsoCase c;
  c.blend.crop = true;
  c.blend.cropBox = Box3f{{-1.f, -1.f, -1.f}, {0.2f, 1.f, 1.f}};
  FunctionField field(distanceField, "distance", distanceGradient);
  auto render = [&](bool crop) {
    IsoCase k = c;
    k.blend.crop = crop;
    SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, k.options);
    renderer.setSettings(k.settings);
    renderer.setScene(k.scene, k.blend);
    renderer.renderFrame();
    return renderer.surfaceDepth();
  };
  const std::vector<float> cropped = render(true), whole = render(false);
  const CameraView cam = c.scene.camera.view(c.settings.width, c.settings.height);
  int outsideCrop = 0, hitsCropped = 0, lost = 0, moved = 0;
  for (std::size_t i = 0; i < cropped.size(); ++i) {
    if (!std::isinf(whole[i]) && std::isinf(cropped[i])) ++lost;
    if (std::isinf(cropped[i])) continue;
    ++hitsCropped;
    const Ray ray = pixelRay(cam, int(i) % c.settings.width, int(i) / c.settings.width);
    const double x = ray.o[0] + cropped[i] * ray.d[0];
    if (x > 0.2 + 1e-4) ++outsideCrop;
    if (std::fabs(cropped[i] - whole[i]) > 1e-3) ++moved;  // the far side seen through the cut
  }
  std::printf("cropped isosurface: %d hits, %d lost, %d moved to the far side\n", hitsCropped, lost, moved);
  EXPECT_GT(hitsCropped, 100);
  EXPECT_EQ(outsideCrop, 0);
  EXPECT_GT(lost + moved, 50);  // control: the crop changes what is seen
}

TEST(IsosurfaceBlend, OpaqueGeometryHidesWhatLiesBehindIt) {
  // Opaque geometry just in front of the sphere over the left half of the picture (the depth
  // limit, a world distance per pixel): no surface there; the right half is unchanged.
  IsoCase c;
  FunctionField field(distanceField, "distance", distanceGradient);
  std::vector<int> use;
  const std::vector<double> exact = sphereDepth(c, 0.5, 0.0, use);
  auto render = [&](bool limit) {
    IsoCase k = c;
    if (limit) {
      k.scene.depthLimit.assign(exact.size(), INFINITY);
      for (std::size_t i = 0; i < exact.size(); ++i)
        if (int(i) % k.settings.width < k.settings.width / 2 && !std::isinf(exact[i]))
          k.scene.depthLimit[i] = float(exact[i] - 0.05);
    }
    SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, k.options);
    renderer.setSettings(k.settings);
    renderer.setScene(k.scene, k.blend);
    renderer.renderFrame();
    return renderer.surfaceDepth();
  };
  const std::vector<float> limited = render(true), open = render(false);
  int hiddenLeft = 0, visibleLeft = 0, changedRight = 0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    const bool left = int(i) % c.settings.width < c.settings.width / 2;
    if (left && !std::isinf(open[i])) {
      ++visibleLeft;  // control: without the geometry the surface is there
      hiddenLeft += std::isinf(limited[i]) ? 1 : 0;
    }
    if (!left && !(limited[i] == open[i] || (std::isinf(limited[i]) && std::isinf(open[i])))) ++changedRight;
  }
  EXPECT_GT(visibleLeft, 100);
  EXPECT_EQ(hiddenLeft, visibleLeft);
  EXPECT_EQ(changedRight, 0);
}

// A frame in parts (renderFramePart with no time to spare: one step per call, a chunk of pixels
// for the slice, one march iteration for the isosurface) is the whole frame bit for bit, with the
// same figures; until its last part it is not accumulated. A new scene in the middle drops the
// part-frame (control: it would otherwise finish early, with the old scene's pixels in it).
void expectPartsMakeTheFrame(const RenderScene& scene, const BlendScene& blend, FunctionField& field,
                             int minParts, int maxParts, int chunkPixels = 500) {
  SurfaceOptions options;
  options.chunkPixels = chunkPixels;  // 500: 48^2 pixels in 5 chunks
  const RenderSettings settings = imageOf(48);
  SurfaceRenderer whole(field, kCubeBox, 0.0, 1.0, options), parts(field, kCubeBox, 0.0, 1.0, options);
  whole.setSettings(settings);
  whole.setScene(scene, blend);
  const FrameStats wholeStats = whole.renderFrame();
  parts.setSettings(settings);
  parts.setScene(scene, blend);
  auto renderInParts = [&](FrameStats* stats) {
    int calls = 0;
    double progress = 0.0;
    bool done = false;
    while (!done && calls < 10000) {
      done = parts.renderFramePart(0.0, stats);
      ++calls;
      if (!done) {
        EXPECT_GE(parts.frameProgress(), progress);
        progress = parts.frameProgress();
        EXPECT_EQ(parts.accumulatedFrames(), 0);
      }
    }
    return calls;
  };
  FrameStats partStats;
  const int calls = renderInParts(&partStats);
  EXPECT_GE(calls, minParts);
  EXPECT_LE(calls, maxParts);
  EXPECT_EQ(parts.accumulatedFrames(), 1);
  EXPECT_EQ(parts.frameProgress(), 0.0);
  EXPECT_EQ(partStats.queries, wholeStats.queries);
  EXPECT_EQ(partStats.shadingQueries, wholeStats.shadingQueries);
  EXPECT_EQ(partStats.iterations, wholeStats.iterations);
  EXPECT_EQ(partStats.pixels, wholeStats.pixels);
  EXPECT_EQ(parts.premultipliedImage().data, whole.premultipliedImage().data);
  EXPECT_EQ(parts.surfaceDepth(), whole.surfaceDepth());
  // A new scene after a few parts: the frame starts over (as many parts again).
  parts.renderFramePart(0.0, nullptr);
  parts.renderFramePart(0.0, nullptr);
  parts.renderFramePart(0.0, nullptr);
  RenderScene moved = scene;
  moved.camera.position[0] += 0.3;
  parts.setScene(moved, blend);
  EXPECT_EQ(parts.frameProgress(), 0.0);
  whole.setScene(moved, blend);
  const FrameStats movedStats = whole.renderFrame();
  FrameStats movedParts;
  renderInParts(&movedParts);
  EXPECT_EQ(movedParts.queries, movedStats.queries);
  EXPECT_EQ(parts.premultipliedImage().data, whole.premultipliedImage().data);
}

TEST(SliceBlend, FrameInPartsIsTheWholeFrame) {
  SliceCase c;
  FunctionField field(test::smoothField, "smooth");
  expectPartsMakeTheFrame(c.scene, c.blend, field, 5, 5);  // one chunk of pixels per part
}

TEST(IsosurfaceBlend, FrameInPartsIsTheWholeFrame) {
  IsoCase c;
  c.scene.shading.enabled = true;
  FunctionField field(distanceField, "distance", distanceGradient);
  // One march iteration per part, and one more for a chunk whose last step found no sample left
  // to query: between the whole frame's iterations and that plus the chunks. With 5 chunks, and
  // with one chunk for the whole picture (its figures must add up over parts inside one chunk).
  for (const int chunkPixels : {500, 48 * 48}) {
    SurfaceOptions options;
    options.chunkPixels = chunkPixels;
    SurfaceRenderer probe(field, kCubeBox, 0.0, 1.0, options);
    probe.setSettings(imageOf(48));
    probe.setScene(c.scene, c.blend);
    const int iterations = probe.renderFrame().iterations;
    const int chunks = (48 * 48 + chunkPixels - 1) / chunkPixels;
    EXPECT_GT(iterations, chunks * 3);  // several iterations per chunk: parts end inside chunks
    expectPartsMakeTheFrame(c.scene, c.blend, field, iterations, iterations + chunks, chunkPixels);
  }
}

// As a frame's rays finish, the remaining rays take more march samples per batch
// (SurfaceOptions::maxMarchSamples): fewer iterations, the same image, depth and hits. Control:
// with the growth off (maxMarchSamples = K) the frame takes more iterations.
TEST(IsosurfaceBlend, MarchSamplesGrowAsRaysFinishWithoutChangingTheImage) {
  IsoCase c;
  c.blend.isovalues = {0.3, 0.5};
  c.scene.shading.enabled = true;
  c.scene.transferFunction = twoPointTf(0.0, {1, 0.5, 0.2}, 0.4, 1.0, {0.2, 0.5, 1}, 1.0);
  FunctionField field(distanceField, "distance", distanceGradient);
  for (const int chunkPixels : {700, 48 * 48}) {
    SurfaceOptions fixed, growing;
    fixed.chunkPixels = growing.chunkPixels = chunkPixels;
    fixed.maxMarchSamples = fixed.samplesPerIteration;
    growing.maxMarchSamples = kMaxSurfaceSamples;
    SurfaceRenderer a(field, kCubeBox, 0.0, 1.0, fixed), b(field, kCubeBox, 0.0, 1.0, growing);
    a.setSettings(c.settings);
    b.setSettings(c.settings);
    a.setScene(c.scene, c.blend);
    b.setScene(c.scene, c.blend);
    const FrameStats sa = a.renderFrame(), sb = b.renderFrame();
    std::printf("march samples growing: chunk %d, iterations %d (fixed K: %d), queries %zu (%zu)\n", chunkPixels,
                sb.iterations, sa.iterations, sb.queries, sa.queries);
    // The refinements (K points each, whatever the growth) bound what the growth can save here.
    EXPECT_LT(sb.iterations, sa.iterations) << "chunk " << chunkPixels;
    EXPECT_EQ(sb.shadingQueries, sa.shadingQueries);
    EXPECT_EQ(sb.rays, sa.rays);
    EXPECT_EQ(b.premultipliedImage().data, a.premultipliedImage().data);
    EXPECT_EQ(b.surfaceDepth(), a.surfaceDepth());
    EXPECT_GT(sa.shadingQueries, 500u);  // the scene has surfaces to find
  }
  SurfaceOptions bad;
  bad.maxMarchSamples = bad.samplesPerIteration - 1;
  EXPECT_THROW(SurfaceRenderer(field, kCubeBox, 0.0, 1.0, bad), std::invalid_argument);
  // The CPU's own choice (0): no growth.
  SurfaceRenderer cpuDefault(field, kCubeBox, 0.0, 1.0);
  cpuDefault.setSettings(c.settings);
  cpuDefault.setScene(c.scene, c.blend);
  EXPECT_EQ(cpuDefault.surfaceConstants().maxMarchSamples, cpuDefault.options().samplesPerIteration);
}

// The candidate macrocells built ahead (what a GUI does off its event loop): setScene at that
// time then queries nothing; at a time between other slices it builds them (the control).
TEST(IsosurfaceBlend, MacrocellsBuiltAheadLeaveSetSceneNoQueries) {
  IsoCase c;
  c.options.macrocells.temporalSlices = 4;
  FunctionField field(distanceField, "distance", distanceGradient);
  SurfaceRenderer renderer(field, kCubeBox, 0.0, 1.0, c.options);
  renderer.setSettings(c.settings);
  c.scene.time = 0.2;
  EXPECT_FALSE(renderer.macrocellsBuiltFor(0.2));
  renderer.buildMacrocellsFor(0.2);
  EXPECT_TRUE(renderer.macrocellsBuiltFor(0.2));
  EXPECT_GT(field.points(), 0u);
  field.resetCounts();
  renderer.setScene(c.scene, c.blend);
  EXPECT_EQ(field.points(), 0u);
  EXPECT_FALSE(renderer.macrocellsBuiltFor(0.9));  // the last two slices are not built yet
  c.scene.time = 0.9;
  renderer.setScene(c.scene, c.blend);
  EXPECT_GT(field.points(), 0u);
  EXPECT_TRUE(renderer.macrocellsBuiltFor(0.9));
}

TEST(BlendScene, ParaViewCroppingBoxAndValidation) {
  const Box3f b = paraviewCroppingBox(Box3f{{-1.f, 0.f, 2.f}, {1.f, 4.f, 6.f}}, {0.5, -1.0, 0.0}, {0.5, 1.0, 2.0});
  EXPECT_FLOAT_EQ(b.lo.x, 0.f);
  EXPECT_FLOAT_EQ(b.hi.x, 1.f);
  EXPECT_FLOAT_EQ(b.lo.y, -1.f);
  EXPECT_FLOAT_EQ(b.hi.y, 3.f);
  EXPECT_FLOAT_EQ(b.lo.z, 4.f);
  EXPECT_FLOAT_EQ(b.hi.z, 12.f);
  BlendScene s;
  s.mode = BlendMode::Isosurface;
  EXPECT_THROW(s.validate(), std::invalid_argument);  // no isovalue
  s.isovalues = {0.5, NAN};
  EXPECT_THROW(s.validate(), std::invalid_argument);
  s.isovalues = {0.5};
  EXPECT_NO_THROW(s.validate());
  s.mode = BlendMode::Slice;
  s.sliceNormal = {0, 0, 0};
  EXPECT_THROW(s.validate(), std::invalid_argument);
  s.sliceNormal = {0, 1, 0};
  s.crop = true;
  s.cropBox = Box3f{{0.f, 0.f, 0.f}, {-1.f, 1.f, 1.f}};
  EXPECT_THROW(s.validate(), std::invalid_argument);
  EXPECT_EQ(parseBlendMode("Isosurface"), BlendMode::Isosurface);
  EXPECT_THROW(parseBlendMode("mip"), std::invalid_argument);
}

}  // namespace
}  // namespace inr
