// Virtual ray lights (Novák 2012; Huo 2016, Sec. 3.1): the VRL → surface point (Eq. 5) and
// VRL → eye segment (Eq. 3) elements against composite Gauss–Legendre quadrature of their
// integrals in a homogeneous medium without occluders (the mean over differently seeded rows
// estimates the expectation: the estimators are unbiased), VRL generation and its plan switch,
// the VRL light tree, and the gather methods on a media scene with VRL columns.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <memory>
#include <string>

#include "common/render/render_job.h"
#include "common/render/serialize.h"
#include "common/lights/light_generation.h"
#include "common/lights/light_tree.h"
#include "common/matrix/lighting_matrix.h"
#include "common/scene/phase.h"
#include "tests/common/fog_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_vrl {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kSigmaA = 0.3, kSigmaS = 0.9, kSigmaT = kSigmaA + kSigmaS, kEyeG = 0.4;

using testing::FogScene;  // tests/common/fog_scene.h

// Composite 8-point Gauss–Legendre on [a, b] with `panels` equal panels.
double GaussLegendre(const std::function<double(double)>& f, double a, double b, int panels) {
  static constexpr std::array<double, 4> x = {0.1834346424956498, 0.5255324099163290,
                                              0.7966664774136267, 0.9602898564975363};
  static constexpr std::array<double, 4> w = {0.3626837833783620, 0.3137066458778873,
                                              0.2223810344533745, 0.1012285362903763};
  const double h = (b - a) / panels;
  double sum = 0;
  for (int p = 0; p < panels; ++p) {
    const double mid = a + (p + 0.5) * h, half = 0.5 * h;
    for (size_t k = 0; k < 4; ++k)
      sum += w[k] * half * (f(mid - half * x[k]) + f(mid + half * x[k]));
  }
  return sum;
}

struct DVec {
  double x, y, z;
};
DVec D(Vec3 v) { return {double(v.x), double(v.y), double(v.z)}; }
DVec Along(DVec o, DVec d, double t) { return {o.x + d.x * t, o.y + d.y * t, o.z + d.z * t}; }
double DotD(DVec a, DVec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
DVec Sub(DVec a, DVec b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }

double HG(double cos_theta, double g) {
  double denom = 1 + g * g - 2 * g * cos_theta;
  return (1 - g * g) / (4 * kPiD * denom * std::sqrt(denom));
}

VirtualLight MakeVrl(Vec3 p, Vec3 d, float length, float g, float power) {
  VirtualLight L;
  L.kind = VirtualLightKind::kVRL;
  L.p = p;
  L.n = Normalize(d);
  L.ng = L.n;
  L.wi = -L.n;
  L.length = length;
  L.g = g;
  L.power = RGB(power);
  L.medium = 0;
  L.depth = 1;
  return L;
}

// Mean of element (row i, column 0) over `rows` identically placed rows (each seeded by its row
// index: independent estimates), with its standard error.
struct MeanAndError {
  double mean = 0, error = 0;
};
MeanAndError MeanOverRows(const LightingMatrix& m, int rows, MatrixCounters* counters) {
  double sum = 0, sum2 = 0;
  for (int i = 0; i < rows; ++i) {
    double v = double(m.Element(uint32_t(i), 0, counters).g);
    sum += v;
    sum2 += v * v;
  }
  MeanAndError out;
  out.mean = sum / rows;
  out.error = std::sqrt(std::max(0.0, sum2 / rows - out.mean * out.mean) / (rows - 1));
  return out;
}

struct Fixture {
  std::unique_ptr<Scene> scene = FogScene();
  ReceiverSet receivers;
  LightSet lights;
};

// --- VRL → surface point (Huo 2016, Eq. 5) --------------------------------------------------

struct PointCase {
  const char* name;
  Vec3 p, d;
  float length, g;
  bool clamp;
};

// Lambertian receiver at the origin, normal +y, inside the fog.
ShadingPoint Receiver(uint32_t material) {
  ShadingPoint sp;
  sp.p = {0, 0, 0};
  sp.ng = sp.ns = {0, 1, 0};
  sp.wo = Normalize(Vec3{0, 1, 1});
  sp.throughput = RGB(1.f);
  sp.material = material;
  sp.medium_out = sp.medium_in = 0;
  return sp;
}

double PointQuadrature(const VirtualLight& L, double clamp_distance) {
  const DVec o = D(L.p), d = D(L.n);
  const double dmin2 = clamp_distance * clamp_distance;
  auto f = [&](double s) {
    DVec y = Along(o, d, s);
    double dist2 = DotD(y, y), dist = std::sqrt(dist2);
    DVec w = {y.x / dist, y.y / dist, y.z / dist};  // receiver (origin) → VRL point
    if (w.y <= 0) return 0.0;
    return double(L.power.g) * std::exp(-kSigmaT * s) * kSigmaS * HG(-DotD(d, w), double(L.g)) *
           std::exp(-kSigmaT * dist) * (0.5 / kPiD) * w.y / std::max(dist2, dmin2);
  };
  return GaussLegendre(f, 0, double(L.length), 4000);
}

TEST(VrlElements, VrlToSurfacePointMatchesQuadrature) {
  const PointCase cases[] = {
      {"generic", {-3, 1.5f, 1}, {1, 0.1f, -0.2f}, 6, 0.5f, false},
      {"backward-phase", {2, 3, -1}, {-0.5f, -0.2f, 0.4f}, 5, -0.6f, false},
      // Nearly in the receiver's tangent plane: cos θ_x stays below 0.02.
      {"grazing", {-4, 0.05f, 0.3f}, {1, 0, 0}, 8, -0.3f, false},
      // Passes 0.02 above the receiver (clamp distance ~0.37): the clamp bounds the peak.
      {"near-singular-clamped", {-2, 0.02f, 0}, {1, 0, 0}, 4, 0.8f, true},
      // Starts next to the receiver and leaves it.
      {"starts-at-receiver", {0.01f, 0.03f, 0}, {0.3f, 1, 0.2f}, 5, 0.2f, true},
  };
  for (const PointCase& c : cases) {
    SCOPED_TRACE(c.name);
    Fixture f;
    const auto& mats = f.scene->materials();
    uint32_t diffuse = 0;
    while (mats[diffuse].type != MaterialType::kDiffuse) ++diffuse;
    f.receivers.width = f.receivers.height = 1;
    f.receivers.samples.resize(1);
    const int copies = 8192;
    for (int i = 0; i < copies; ++i) f.receivers.points.push_back(Receiver(diffuse));
    f.lights.lights.push_back(MakeVrl(c.p, c.d, c.length, c.g, 4.f));
    MatrixOptions opt;
    opt.clamp = c.clamp ? 0.01f : 0.f;
    opt.segment_samples = 16;
    LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
    if (c.clamp) {
      EXPECT_GT(m.clamp_distance(), 0.3f);
    }
    MatrixCounters counters;
    const MeanAndError got = MeanOverRows(m, copies, &counters);
    const double expect = PointQuadrature(f.lights.lights[0], double(m.clamp_distance()));
    EXPECT_GT(expect, 0.0);
    // Within 4 standard errors of the mean (measured: 0.01–0.6% of the value with 8192 rows ×
    // 16 samples) plus 0.1% for the estimator's float arithmetic against the double quadrature
    // (the backward-phase case's stratified samples are precise enough to show a 0.06% offset),
    // and the estimate is that precise: a bias above ~3% cannot pass.
    EXPECT_NEAR(got.mean, expect, 4 * got.error + 1e-3 * expect)
        << "got " << got.mean << " ± " << got.error << " expected " << expect;
    EXPECT_LT(got.error, 0.0075 * expect) << got.error;
    // Every sample's shadow segment is attenuated (generalized visibility).
    EXPECT_GT(counters.transmittance_evals, 0u);
    EXPECT_LE(counters.shadow_rays, uint64_t(16) * uint64_t(copies));
  }
}

// --- VRL → eye segment (Huo 2016, Eq. 3) ----------------------------------------------------

EyeSegment TestSegment() {
  EyeSegment s;
  s.o = {-4, 1, 2};
  s.d = Normalize(Vec3{1, 0.2f, -0.3f});
  s.length = 7.5f;
  s.throughput = RGB(1.f);
  s.medium = 0;
  s.depth = 1;
  return s;
}

// Gauss–Legendre on [a, b] with `panels` panels, plus `fine` more within `width` of `peak` (where
// a near-singular integrand needs them).
double GaussLegendrePeaked(const std::function<double(double)>& f, double a, double b, double peak, double width,
                           int panels, int fine) {
  const double lo = std::clamp(peak - width, a, b), hi = std::clamp(peak + width, a, b);
  double sum = 0;
  if (lo > a) sum += GaussLegendre(f, a, lo, std::max(1, int(panels * (lo - a) / (b - a)) + 1));
  if (hi > lo) sum += GaussLegendre(f, lo, hi, fine);
  if (b > hi) sum += GaussLegendre(f, hi, b, std::max(1, int(panels * (b - hi) / (b - a)) + 1));
  return sum;
}

double SegmentQuadrature(const EyeSegment& seg, const VirtualLight& L, double clamp_distance) {
  const DVec eo = D(seg.o), ed = D(seg.d), lo = D(L.p), ld = D(L.n);
  const double dmin2 = clamp_distance * clamp_distance;
  // The closest approach of the two lines: the outer integral's peak.
  const DVec r = Sub(eo, lo);
  const double bb = DotD(ed, ld), dd = DotD(ed, r), ee = DotD(ld, r), den = 1 - bb * bb;
  const double t_peak = den > 1e-12 ? (bb * ee - dd) / den : 0.0;
  auto over_t = [&](double t) {
    DVec x = Along(eo, ed, t);
    auto over_s = [&](double s) {
      DVec y = Along(lo, ld, s);
      DVec dv = Sub(y, x);
      double dist2 = DotD(dv, dv), dist = std::sqrt(dist2);
      DVec w = {dv.x / dist, dv.y / dist, dv.z / dist};  // eye point → VRL point
      return std::exp(-kSigmaT * t) * kSigmaS * HG(DotD(w, ed), kEyeG) * std::exp(-kSigmaT * dist) /
             std::max(dist2, dmin2) * double(L.power.g) * std::exp(-kSigmaT * s) * kSigmaS *
             HG(-DotD(ld, w), double(L.g));
    };
    // The inner integral peaks where y_s is closest to x_t.
    return GaussLegendrePeaked(over_s, 0, double(L.length), DotD(Sub(x, lo), ld), 0.2, 300, 400);
  };
  return GaussLegendrePeaked(over_t, 0, double(seg.length), t_peak, 0.2, 300, 400);
}

struct SegmentCase {
  const char* name;
  Vec3 p, d;
  float length, g;
  bool clamp;
};

TEST(VrlElements, VrlToEyeSegmentMatchesQuadrature) {
  const EyeSegment seg = TestSegment();
  const Vec3 on_seg = seg.o + seg.d * 3.f;  // a point of the eye segment
  const SegmentCase cases[] = {
      {"skew", {-1, 4, -2}, {0.2f, -1, 0.5f}, 6, 0.6f, false},
      {"skew-backward", {3, -2, 1}, {-1, 0.3f, 0.1f}, 5, -0.5f, false},
      // Nearly parallel to the eye segment, 0.5 beside it (sin θ ≈ 0.01).
      {"near-parallel", seg.o + Vec3{0, 0.5f, 0}, seg.d + Vec3{0, 0.01f, 0}, 7, 0.3f, false},
      // Exactly parallel: Novák's pdf degenerates to uniform.
      {"parallel", seg.o + Vec3{0, 1, 0}, seg.d, 5, 0.3f, false},
      // Crosses the eye segment 0.01 away (clamp distance ~0.37).
      {"near-intersecting-clamped", on_seg + Vec3{0, 0, 0.01f} - Normalize(Vec3{-0.3f, 1, 0.4f}) * 2.f,
       {-0.3f, 1, 0.4f}, 4, 0.7f, true},
  };
  for (const SegmentCase& c : cases) {
    SCOPED_TRACE(c.name);
    Fixture f;
    f.receivers.width = f.receivers.height = 1;
    f.receivers.samples.resize(1);
    const int copies = 8192;
    for (int i = 0; i < copies; ++i) f.receivers.segments.push_back(seg);
    f.lights.lights.push_back(MakeVrl(c.p, c.d, c.length, c.g, 5.f));
    MatrixOptions opt;
    opt.clamp = c.clamp ? 0.01f : 0.f;
    opt.segment_samples = 16;
    LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
    MatrixCounters counters;
    const MeanAndError got = MeanOverRows(m, copies, &counters);
    const double expect = SegmentQuadrature(seg, f.lights.lights[0], double(m.clamp_distance()));
    EXPECT_GT(expect, 0.0);
    // Within 4 standard errors of the mean (measured: 0.01–0.6% of the value with 8192 rows ×
    // 16 samples) plus 0.1% for the estimator's float arithmetic against the double quadrature
    // (the backward-phase case's stratified samples are precise enough to show a 0.06% offset),
    // and the estimate is that precise: a bias above ~3% cannot pass.
    EXPECT_NEAR(got.mean, expect, 4 * got.error + 1e-3 * expect)
        << "got " << got.mean << " ± " << got.error << " expected " << expect;
    EXPECT_LT(got.error, 0.0075 * expect) << got.error;
    EXPECT_GT(counters.transmittance_evals, 0u);
  }
}

// A media row with coverage (EyeSegment::pieces; receivers.h): K film positions, of which 3 have
// a piece, each piece's throughput scaled by 3 / K. The element is the mean over the K positions
// of their pieces' integrals, whichever piece the row names itself and whatever the samples per
// element: 16 stratified ones, or 1 (the default), each sample on a piece of its own.
TEST(VrlElements, CoverageRowIsTheMeanOverItsFilmPositions) {
  const EyeSegment base = TestSegment();
  std::vector<EyeSegment> pieces = {base, base, base};
  pieces[1].o = base.o + Vec3{0, 0.4f, 0.1f};
  pieces[2].d = Normalize(base.d + Vec3{0, 0.15f, 0.05f});
  pieces[2].length = 6.f;
  constexpr int kPositions = 4;
  const VirtualLight vrl = MakeVrl({-1, 4, -2}, {0.2f, -1, 0.5f}, 6, 0.6f, 5.f);
  double expect = 0;
  for (const EyeSegment& p : pieces) expect += SegmentQuadrature(p, vrl, 0.0) / kPositions;
  for (int samples : {16, 1}) {
    SCOPED_TRACE(samples);
    Fixture f;
    f.receivers.width = f.receivers.height = 1;
    f.receivers.samples.resize(1);
    f.receivers.segment_pieces = pieces;
    for (EyeSegment& p : f.receivers.segment_pieces) p.throughput *= 3.f / float(kPositions);
    EyeSegment row = f.receivers.segment_pieces[1];
    row.first_piece = 0;
    row.pieces = 3;
    const int copies = samples == 1 ? 65536 : 8192;
    for (int i = 0; i < copies; ++i) f.receivers.segments.push_back(row);
    f.lights.lights.push_back(vrl);
    MatrixOptions opt;
    opt.clamp = 0.f;
    opt.segment_samples = samples;
    LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
    MatrixCounters counters;
    const MeanAndError got = MeanOverRows(m, copies, &counters);
    EXPECT_NEAR(got.mean, expect, 4 * got.error + 1e-3 * expect)
        << "got " << got.mean << " ± " << got.error << " expected " << expect;
    EXPECT_LT(got.error, 0.01 * expect) << got.error;
    // Not the row's own piece alone, nor the sum of the pieces.
    EXPECT_GT(std::abs(got.mean - SegmentQuadrature(pieces[1], vrl, 0.0)), 8 * got.error);
  }
}

// A VRL deeper than the row's path budget contributes nothing (pbrt's maxdepth: the VRL's own
// scattering event counts), and an element is the same whichever method asks for it.
TEST(VrlElements, DepthBudgetAndDeterminism) {
  Fixture f;
  f.receivers.width = f.receivers.height = 1;
  f.receivers.samples.resize(1);
  f.receivers.segments.push_back(TestSegment());
  VirtualLight L = MakeVrl({-1, 4, -2}, {0.2f, -1, 0.5f}, 6, 0.6f, 5.f);
  f.lights.lights.push_back(L);
  L.depth = 5;  // 5 + segment depth 1 > maxdepth 5
  f.lights.lights.push_back(L);
  LightingMatrix m(*f.scene, f.receivers, f.lights, MatrixOptions{});
  MatrixCounters c;
  const RGB a = m.Element(0, 0, &c);
  EXPECT_GT(a.g, 0.f);
  EXPECT_EQ(m.Element(0, 1, &c).g, 0.f);
  std::vector<RGB> row(2);
  m.Row(0, row, &c);
  EXPECT_EQ(row[0].g, a.g);
}

// --- Generation, plan switch and gather methods on a media scene -------------------------------

// Without caustic photons (test_caustics.cpp): they are not what these tests are about and would
// take most of their time.
RenderOutput RenderCaustic(const std::string& method, std::vector<std::string> params) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = 16;
  s.lights = 300;
  s.params = std::move(params);
  s.params.push_back("caustic_photons=0");
  return RenderScene(testing::SharedScene("volumetric-caustic"), s);
}

void ExpectFiniteNonBlack(const RenderOutput& out) {
  EXPECT_EQ(out.stats["film"]["nan_samples"], 0);
  double sum = 0;
  for (const RGB& p : out.image.pixels) {
    ASSERT_TRUE(p.IsFinite());
    sum += double(p.Luminance());
  }
  EXPECT_GT(sum, 0.0);
}

TEST(VrlGeneration, MediaSceneMakesVrlsByDefaultAndVplsOnRequest) {
  RenderOutput vrl = RenderCaustic("brute", {});
  EXPECT_GT(vrl.stats["lights"]["vrl"].get<uint64_t>(), 0u);
  EXPECT_EQ(vrl.stats["lights"]["medium_vpl"].get<uint64_t>(), 0u);  // never both
  ExpectFiniteNonBlack(vrl);
  RenderOutput vpl = RenderCaustic("brute", {"media_lights=vpl"});
  EXPECT_EQ(vpl.stats["lights"]["vrl"].get<uint64_t>(), 0u);
  EXPECT_GT(vpl.stats["lights"]["medium_vpl"].get<uint64_t>(), 0u);
  ExpectFiniteNonBlack(vpl);
  // Same seed, same bits.
  RenderOutput again = RenderCaustic("brute", {});
  ASSERT_EQ(again.image.pixels.size(), vrl.image.pixels.size());
  for (size_t i = 0; i < vrl.image.pixels.size(); ++i)
    ASSERT_EQ(again.image.pixels[i].g, vrl.image.pixels[i].g) << i;
  EXPECT_THROW(RenderCaustic("brute", {"media_lights=beams"}), OptionError);
}

TEST(VrlGeneration, SurfaceOnlySceneHasNoVrls) {
  RenderSettings s;
  s.width = s.height = 8;
  s.lights = 200;
  RenderOutput out = RenderScene(testing::SharedScene("cornell-box"), s);
  EXPECT_EQ(out.stats["lights"]["vrl"].get<uint64_t>(), 0u);
  EXPECT_GT(out.stats["lights"]["vpl"].get<uint64_t>(), 0u);
}

// Every VRL is a free flight inside the scene's one medium with a positive length, carrying
// the path's flux.
TEST(VrlGeneration, VrlsLieInTheMedium) {
  SceneDescription desc = ParseSceneFile(testing::SharedScene("volumetric-caustic"));
  SceneBuildOptions build;
  build.width = build.height = 8;
  std::unique_ptr<Scene> scene = Scene::Build(desc, build);
  LightGenerationOptions opt;
  opt.target_lights = 400;
  opt.max_depth = scene->hints().max_depth;
  opt.seed = 3;
  opt.medium_lights = MediumLights::kVRL;
  LightSet set = GenerateLights(*scene, opt);
  ASSERT_GT(set.stats.vrls, 0u);
  EXPECT_EQ(set.stats.medium_vpls, 0u);
  size_t counted = 0;
  for (const VirtualLight& l : set.lights) {
    if (l.kind != VirtualLightKind::kVRL) continue;
    ++counted;
    EXPECT_GT(l.length, 0.f);
    EXPECT_NEAR(Length(l.n), 1.f, 1e-4f);
    EXPECT_EQ(l.medium, 0);
    EXPECT_GE(l.depth, 1);
    EXPECT_LT(int(l.depth), opt.max_depth);
    EXPECT_TRUE(l.power.IsFinite());
    EXPECT_GT(l.power.Max(), 0.f);
    EXPECT_LE(Length(l.End() - scene->bounds().Center()), scene->bounds().Radius() * 1.02f);
  }
  EXPECT_EQ(counted, set.stats.vrls);
}

// Methods that treat columns generically through LightingMatrix handle VRL columns; lightcuts
// (no media rows) never gets any.
TEST(VrlGeneration, GatherMethodsHandleVrlColumns) {
  for (const char* method : {"adaptive-completion", "sparse-completion", "mrcs", "lightslice"}) {
    SCOPED_TRACE(method);
    RenderOutput out = RenderCaustic(method, {});
    EXPECT_GT(out.stats["lights"]["vrl"].get<uint64_t>(), 0u);
    ExpectFiniteNonBlack(out);
  }
  RenderOutput lc = RenderCaustic("lightcuts", {});
  EXPECT_EQ(lc.stats["lights"]["vrl"].get<uint64_t>(), 0u);
  ExpectFiniteNonBlack(lc);
}

// --- VRLs and medium VPLs estimate the same light ------------------------------------------------

// A point light inside a homogeneous fog sphere above a diffuse floor (maxdepth 3). Over
// several light-generation seeds, the light that the medium lights (VRL columns with
// media_lights=vrl, medium-VPL columns with vpl) send to a floor point and to an eye segment
// has the same mean: both are unbiased estimates of single scattering off the particle flux.
TEST(VrlConsistency, VrlsAndMediumVplsAgreeOnAverage) {
  SceneDescription desc = ParseSceneString(
      "Integrator \"volpath\" \"integer maxdepth\" [3]\n"
      "LookAt 0 0 10  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
      "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.1 0.1 0.1]\n"
      "  \"rgb sigma_s\" [0.6 0.6 0.6] \"float g\" [0.3]\n"
      "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
      "Shape \"sphere\" \"float radius\" [3]\nAttributeEnd\n"
      "AttributeBegin\nMediumInterface \"\" \"fog\"\n"
      "LightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 1 0]\nAttributeEnd\n"
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-2 -1 -2  2 -1 -2  2 -1 2  -2 -1 2]\n"
      "  \"integer indices\" [0 2 1 0 3 2]\n",
      "fog-light.pbrt", "/tmp");
  std::unique_ptr<Scene> scene = Scene::Build(desc, SceneBuildOptions{});
  const auto& mats = scene->materials();
  uint32_t diffuse = 0;
  while (mats[diffuse].type != MaterialType::kDiffuse) ++diffuse;
  ReceiverSet receivers;
  receivers.width = receivers.height = 1;
  receivers.samples.resize(1);
  ShadingPoint sp = Receiver(diffuse);
  sp.p = {0.5f, -1, 0.3f};
  receivers.points.push_back(sp);
  EyeSegment seg;
  seg.o = {-2, 0.5f, 1};
  seg.d = Normalize(Vec3{1, -0.1f, -0.2f});
  seg.length = 3.5f;
  seg.throughput = RGB(1.f);
  seg.medium = 0;
  seg.depth = 1;
  receivers.segments.push_back(seg);
  const int seeds = 32;
  // [mode][row]: per-seed sums of the medium lights' columns.
  std::array<std::array<std::vector<double>, 2>, 2> sums;
  for (int mode = 0; mode < 2; ++mode) {
    for (int seed = 0; seed < seeds; ++seed) {
      LightGenerationOptions opt;
      opt.target_lights = 8000;
      opt.max_depth = 3;
      opt.seed = uint64_t(seed);
      opt.medium_lights = mode == 0 ? MediumLights::kVRL : MediumLights::kVPL;
      LightSet lights = GenerateLights(*scene, opt);
      ASSERT_GT(mode == 0 ? lights.stats.vrls : lights.stats.medium_vpls, 100u);
      MatrixOptions mopt;
      mopt.clamp = 0.002f;  // tiny: the two kinds' clamp losses differ, but negligibly here
      mopt.segment_samples = 4;
      LightingMatrix m(*scene, receivers, lights, mopt);
      MatrixCounters c;
      std::vector<RGB> row(m.cols());
      for (uint32_t r = 0; r < 2; ++r) {
        m.Row(r, row, &c);
        double sum = 0;
        for (size_t j = 0; j < row.size(); ++j) {
          VirtualLightKind kind = lights.lights[j].kind;
          if (kind == VirtualLightKind::kVRL || kind == VirtualLightKind::kMediumVPL)
            sum += double(row[j].g);
        }
        sums[size_t(mode)][r].push_back(sum);
      }
    }
  }
  for (size_t r = 0; r < 2; ++r) {
    SCOPED_TRACE(r == 0 ? "surface point" : "eye segment");
    double mean[2], var_of_mean[2];
    for (size_t mode = 0; mode < 2; ++mode) {
      const std::vector<double>& v = sums[mode][r];
      double s = 0, s2 = 0;
      for (double x : v) {
        s += x;
        s2 += x * x;
      }
      mean[mode] = s / double(v.size());
      var_of_mean[mode] = std::max(0.0, s2 / double(v.size()) - mean[mode] * mean[mode]) /
                          double(v.size() - 1);
    }
    const double se = std::sqrt(var_of_mean[0] + var_of_mean[1]);
    ::testing::Test::RecordProperty(r == 0 ? "point_vrl_vpl_se" : "segment_vrl_vpl_se",
                                    std::to_string(mean[0]) + " " + std::to_string(mean[1]) + " " +
                                        std::to_string(se));
    EXPECT_GT(mean[0], 0.0);
    EXPECT_NEAR(mean[0], mean[1], 4 * se) << "vrl " << mean[0] << " vpl " << mean[1] << " se " << se;
    EXPECT_LT(se, 0.04 * mean[1]) << "vrl " << mean[0] << " vpl " << mean[1] << " se " << se;
  }
}

// --- Light tree and serialization ---------------------------------------------------------------

TEST(VrlLightTree, VrlsGetTheirOwnTreeWhoseBoundsCoverBothEnds) {
  LightSet set;
  Rng rng(7);
  for (int i = 0; i < 300; ++i) {
    Vec3 p{rng.Uniform() * 10, rng.Uniform() * 10, rng.Uniform() * 10};
    Vec3 d{rng.Uniform() - 0.5f, rng.Uniform() - 0.5f, rng.Uniform() - 0.5f};
    if (i % 3 == 0) {
      VirtualLight pt;
      pt.kind = VirtualLightKind::kPoint;
      pt.p = p;
      pt.power = RGB(1.f);
      set.lights.push_back(pt);
    } else {
      set.lights.push_back(MakeVrl(p, d, 1 + 5 * rng.Uniform(), 0.3f, rng.Uniform()));
    }
  }
  LightTree tree = LightTree::Build(set, 1);
  ASSERT_EQ(tree.roots().size(), 2u);
  int vrl_roots = 0;
  for (uint32_t root : tree.roots()) {
    const LightTreeNode& r = tree.node(root);
    if (r.kind != VirtualLightKind::kVRL) continue;
    ++vrl_roots;
    EXPECT_EQ(r.count, 200u);
    double power = 0;
    for (uint32_t k = r.first; k < r.first + r.count; ++k) {
      const VirtualLight& l = set.lights[tree.order()[k]];
      ASSERT_EQ(l.kind, VirtualLightKind::kVRL);
      power += double(l.power.g);
      for (Vec3 e : {l.p, l.End()})
        for (int a = 0; a < 3; ++a) {
          EXPECT_GE(e[a], r.bounds.lo[a]);
          EXPECT_LE(e[a], r.bounds.hi[a]);
        }
    }
    EXPECT_NEAR(double(r.intensity.g), power, 1e-4 * power);
    // Every node below covers its VRLs' both ends.
    for (uint32_t i = root; i < root + 2 * r.count - 1; ++i) {
      const LightTreeNode& node = tree.node(i);
      EXPECT_EQ(node.kind, VirtualLightKind::kVRL);
      for (uint32_t k = node.first; k < node.first + node.count; ++k) {
        const VirtualLight& l = set.lights[tree.order()[k]];
        for (Vec3 e : {l.p, l.End()})
          for (int a = 0; a < 3; ++a) {
            ASSERT_GE(e[a], node.bounds.lo[a]);
            ASSERT_LE(e[a], node.bounds.hi[a]);
          }
      }
    }
  }
  EXPECT_EQ(vrl_roots, 1);
}

TEST(VrlLightTree, SerializationKeepsVrls) {
  LightSet set;
  set.lights.push_back(MakeVrl({1, 2, 3}, {0, 1, 0}, 2.5f, -0.2f, 3.f));
  set.stats.vrls = 1;
  LightSet back = DeserializeLightSet(SerializeLightSet(set));
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back.lights[0].kind, VirtualLightKind::kVRL);
  EXPECT_EQ(back.lights[0].length, 2.5f);
  EXPECT_EQ(back.lights[0].g, -0.2f);
  EXPECT_EQ(back.stats.vrls, 1u);
}

}  // namespace test_vrl
}  // namespace lightfarm
