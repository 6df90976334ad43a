// Participating media: the Henyey–Greenstein phase function, homogeneous and grid media
// (closed form, ratio tracking, delta tracking, majorant DDA), the NanoVDB loader, scene-level
// medium walks through interface surfaces, and scene errors with file:line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "common/scene/medium.h"
#include "common/scene/phase.h"
#include "common/scene/scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_media {

// Upper critical value of chi-square with k degrees of freedom at p ≈ 1e-4 (Wilson–Hilferty).
double ChiSquareCritical(int k) {
  const double z = 3.719;
  double a = 2.0 / (9.0 * k);
  return k * std::pow(1 - a + z * std::sqrt(a), 3.0);
}

// Pearson chi-square over bins, pooling bins with an expected count below 5 into one.
double ChiSquare(const std::vector<double>& observed, const std::vector<double>& expected,
                 int* dof) {
  double chi2 = 0, pooled_o = 0, pooled_e = 0;
  int bins = 0;
  for (size_t i = 0; i < observed.size(); ++i) {
    if (expected[i] < 5) {
      pooled_o += observed[i];
      pooled_e += expected[i];
      continue;
    }
    chi2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
    ++bins;
  }
  if (pooled_e > 0) {
    chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / std::max(pooled_e, 1e-12);
    ++bins;
  }
  *dof = bins - 1;
  return chi2;
}

// ∫ 2π p(μ) dμ over [a, b] by composite Simpson in double.
double IntegrateHG(double a, double b, float g, int n) {
  double h = (b - a) / n, sum = 0;
  for (int i = 0; i <= n; ++i) {
    double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
    sum += w * double(HenyeyGreenstein(float(a + i * h), g));
  }
  return 2 * 3.14159265358979323846 * sum * h / 3;
}

class PhaseTest : public ::testing::TestWithParam<float> {};

TEST_P(PhaseTest, Normalised) {
  float g = GetParam();
  // The forward peak of g = 0.99 is ~(1-g)² wide in μ: a fine grid there, a coarse one elsewhere.
  double total = IntegrateHG(-1, 0.9, g, 200000) + IntegrateHG(0.9, 1, g, 2000000);
  EXPECT_NEAR(total, 1.0, 1e-4) << "g = " << g;
}

TEST_P(PhaseTest, SamplingMatchesEvaluation) {
  const float g = GetParam();
  const int kCos = 48, kPhi = 8, kSamples = 400000;
  // Cosine bin edges dense towards the peak (forward for g >= 0, backward otherwise).
  std::vector<double> edges(kCos + 1);
  for (int k = 0; k <= kCos; ++k) {
    double s = std::pow(double(k) / kCos, 3.0);
    edges[k] = g >= 0 ? 1 - 2 * s : -1 + 2 * s;
  }
  if (g >= 0) std::reverse(edges.begin(), edges.end());  // ascending
  const Vec3 w_in = Normalize(Vec3{1, 2, 3});
  Frame frame(w_in);
  std::vector<double> observed(size_t(kCos) * kPhi, 0), expected(size_t(kCos) * kPhi, 0);
  Rng rng(HashSeed({42, uint64_t(g * 1000 + 5000)}));
  for (int i = 0; i < kSamples; ++i) {
    float pdf = 0;
    Vec3 w = SampleHenyeyGreenstein(w_in, g, rng.Uniform(), rng.Uniform(), &pdf);
    ASSERT_TRUE(IsFinite(w) && std::isfinite(pdf) && pdf > 0);
    ASSERT_NEAR(Length(w), 1.f, 1e-4f);
    // Near the g = 0.99 peak p changes by 3/(1-g)² per unit cosθ: float rounding of the frame
    // change alone moves the re-evaluated pdf by ~0.2%.
    ASSERT_NEAR(pdf, HenyeyGreenstein(Dot(w, w_in), g), 1e-2f * pdf);
    Vec3 l = frame.ToLocal(w);
    double mu = Clamp(double(l.z), -1.0, 1.0);
    double phi = std::atan2(double(l.y), double(l.x));
    if (phi < 0) phi += 2 * 3.14159265358979323846;
    int ci = int(std::upper_bound(edges.begin(), edges.end(), mu) - edges.begin()) - 1;
    ci = std::clamp(ci, 0, kCos - 1);
    int pi = std::min(int(phi / (2 * 3.14159265358979323846) * kPhi), kPhi - 1);
    observed[size_t(ci) * kPhi + pi] += 1;
  }
  for (int c = 0; c < kCos; ++c) {
    double p = IntegrateHG(edges[c], edges[c + 1], g, 4000);
    for (int k = 0; k < kPhi; ++k) expected[size_t(c) * kPhi + k] = p / kPhi * kSamples;
  }
  int dof = 0;
  double chi2 = ChiSquare(observed, expected, &dof);
  EXPECT_LT(chi2, ChiSquareCritical(dof)) << "g = " << g << ", dof " << dof;
}

INSTANTIATE_TEST_SUITE_P(HG, PhaseTest, ::testing::Values(-0.9f, 0.f, 0.5f, 0.99f));

TEST(Phase, SmallGIsIsotropicAndContinuous) {
  for (float g : {1e-7f, -1e-6f, 1e-4f, 2e-3f}) {
    EXPECT_NEAR(HenyeyGreenstein(0.3f, g), kInv4Pi, 0.01f * kInv4Pi);
    for (float u : {0.f, 0.25f, 0.5f, 0.999f}) {
      float c = SampleHenyeyGreensteinCos(u, g);
      EXPECT_NEAR(c, 2 * u - 1, 0.01f) << "g " << g << " u " << u;
    }
  }
  // The forward peak stays finite for g = 0.99 (the denominator is (1-g)^3).
  float peak = HenyeyGreenstein(1.f, 0.99f);
  EXPECT_TRUE(std::isfinite(peak));
  EXPECT_NEAR(peak, (1 - 0.99f * 0.99f) / (4 * kPi * std::pow(0.01f, 3.f)), peak * 1e-3f);
}

// ---- Media -------------------------------------------------------------------------------

std::unique_ptr<Scene> BuildScene(const std::string& world, const std::string& dir = "/tmp") {
  SceneDescription desc = ParseSceneString(
      "Film \"rgb\" \"integer xresolution\" [4] \"integer yresolution\" [4]\n"
      "LookAt 0 0 10  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n" + world,
      "test.pbrt", dir);
  return Scene::Build(desc, SceneBuildOptions{});
}

template <typename F>
void ExpectSceneError(F&& f, const std::string& prefix, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "expected a SceneError " << prefix << " ... " << what;
  } catch (const SceneError& e) {
    std::string msg = e.what();
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
}

TEST(Media, HomogeneousTransmittanceIsExponential) {
  Medium m = Medium::Homogeneous(RGB(0.1f, 0.5f, 2.f), RGB(0.3f, 0.f, 1.f), 0.2f);
  Rng rng(1);
  for (float d : {0.f, 0.01f, 0.7f, 3.f, 40.f}) {
    RGB T = m.Transmittance({{1, 2, 3}, {0, 0, 1}, d}, rng);
    EXPECT_NEAR(T.r, std::exp(-0.4f * d), 1e-6f);
    EXPECT_NEAR(T.g, std::exp(-0.5f * d), 1e-6f);
    EXPECT_NEAR(T.b, std::exp(-3.f * d), 1e-6f);
  }
  // An empty channel transmits fully even along an infinite ray (no 0·∞ NaN).
  Medium empty = Medium::Homogeneous(RGB(0.f), RGB(0.f, 0.f, 1.f), 0.f);
  RGB T = empty.Transmittance({{0, 0, 0}, {1, 0, 0}, kInfinity}, rng);
  EXPECT_EQ(T.r, 1.f);
  EXPECT_EQ(T.b, 0.f);
}

// Scene walk: a ray through an interface sphere of radius 1 filled with fog crosses exactly
// the chord, and interfaces do not occlude shadow rays.
TEST(Media, SceneTransmittanceThroughInterfaceSphere) {
  auto scene = BuildScene(
      "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.2 0.2 0.2]\n"
      "  \"rgb sigma_s\" [0.3 0.5 0.7] \"float scale\" [2]\n"
      "AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\n"
      "Translate 0 0 0\nShape \"sphere\" \"float radius\" [1]\nAttributeEnd\n");
  ASSERT_TRUE(scene->has_media());
  ASSERT_EQ(scene->media().size(), 1u);
  Rng rng(7);
  // Through the centre: chord 2. σ_t = 2·(0.2 + σ_s).
  RGB T = scene->Transmittance({-5, 0, 0}, {5, 0, 0}, -1, rng);
  EXPECT_NEAR(T.r, std::exp(-2 * 2 * 0.5f), 1e-4f);
  EXPECT_NEAR(T.g, std::exp(-2 * 2 * 0.7f), 1e-4f);
  EXPECT_NEAR(T.b, std::exp(-2 * 2 * 0.9f), 1e-4f);
  // Off-centre at height 0.6: chord 2·0.8.
  T = scene->Transmittance({-5, 0.6f, 0}, {5, 0.6f, 0}, -1, rng);
  EXPECT_NEAR(T.r, std::exp(-1.6f * 2 * 0.5f), 1e-4f);
  // Starting inside the fog (the caller knows its medium): from the centre out, chord 1.
  T = scene->Transmittance({0, 0, 0}, {5, 0, 0}, 0, rng);
  EXPECT_NEAR(T.r, std::exp(-1.f * 2 * 0.5f), 1e-4f);
  // Medium pieces: vacuum, fog, vacuum.
  std::vector<MediumSegment> seg;
  scene->MediumSegments({-5, 0, 0}, {1, 0, 0}, 10, -1, &seg);
  ASSERT_EQ(seg.size(), 3u);
  EXPECT_EQ(seg[0].medium, -1);
  EXPECT_EQ(seg[1].medium, 0);
  EXPECT_EQ(seg[2].medium, -1);
  EXPECT_NEAR(seg[1].t0, 4.f, 1e-3f);
  EXPECT_NEAR(seg[1].t1, 6.f, 1e-3f);
  // Shadow ray through the interface sphere: not occluded.
  RTCRay ray{};
  ray.org_x = -5;
  ray.dir_x = 10;
  ray.tnear = 0;
  ray.tfar = 1;
  ray.mask = kMaskAll;
  scene->Occluded(&ray, 1);
  EXPECT_GE(ray.tfar, 0.f);
  // The camera intersection sees the interface (paths need it to switch media).
  SurfaceHit hit;
  ASSERT_TRUE(scene->Intersect({{-5, 0, 0}, {1, 0, 0}, kInfinity}, &hit));
  EXPECT_EQ(scene->MediumAfter(hit, {1, 0, 0}, -1), 0);
  EXPECT_EQ(scene->MediumAfter(hit, {-1, 0, 0}, 0), -1);
}

TEST(Media, OpaqueSurfacesStillOccludeAndNoMediaMeansNoTransmittance) {
  auto scene = BuildScene("Shape \"sphere\" \"float radius\" [1]\n");
  EXPECT_FALSE(scene->has_media());
  RTCRay ray{};
  ray.org_x = -5;
  ray.dir_x = 10;
  ray.tfar = 1;
  scene->Occluded(&ray, 1);
  EXPECT_LT(ray.tfar, 0.f);
  Rng rng(1);
  RGB T = scene->Transmittance({-5, 0, 0}, {5, 0, 0}, -1, rng);
  EXPECT_EQ(T, RGB(1.f));
}

// A 4x3x2 grid under a transform: densities at voxel centres, the majorant bounds every
// lookup, and ratio tracking agrees with quadrature of exp(-∫σ_t).
const char* kGridMedium =
    "AttributeBegin\nTranslate 1 -1 0.5\nScale 2 1 3\n"
    "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" [4]\n"
    "  \"integer ny\" [3] \"integer nz\" [2] \"point3 p0\" [0 0 0] \"point3 p1\" [1 1 1]\n"
    "  \"float density\" [0 1 2 3  4 5 6 7  0.5 0.5 0.5 0.5   1 0 1 0  2 0 2 0  3 3 3 3]\n"
    "  \"rgb sigma_a\" [0.5 1 0.25] \"rgb sigma_s\" [0.5 0.5 0.5] \"float g\" [0.3]\n"
    "AttributeEnd\n"
    "MediumInterface \"\" \"smoke\"\nShape \"sphere\" \"float radius\" [0.01]\n";

TEST(Media, UniformGridDensityFollowsTransform) {
  auto scene = BuildScene(kGridMedium);
  const Medium& m = scene->media().at(0);
  EXPECT_FALSE(m.homogeneous());
  EXPECT_FLOAT_EQ(m.g(), 0.3f);
  // Voxel (x, y, z) centre in medium space is ((x+.5)/4, (y+.5)/3, (z+.5)/2); world = T·S·p.
  auto world = [](int x, int y, int z) {
    return Vec3{1 + 2 * (x + 0.5f) / 4, -1 + (y + 0.5f) / 3, 0.5f + 3 * (z + 0.5f) / 2};
  };
  EXPECT_NEAR(m.Density(world(3, 0, 0)), 3.f, 1e-4f);
  EXPECT_NEAR(m.Density(world(2, 1, 0)), 6.f, 1e-4f);
  EXPECT_NEAR(m.Density(world(0, 2, 1)), 3.f, 1e-4f);
  EXPECT_NEAR(m.Density(world(1, 1, 1)), 0.f, 1e-4f);
  EXPECT_EQ(m.Density({-5, 0, 0}), 0.f);
  EXPECT_FLOAT_EQ(m.MaxDensity(), 7.f);
  Bounds3 b = m.WorldBounds();
  EXPECT_NEAR(b.lo.x, 1.f, 1e-4f);
  EXPECT_NEAR(b.hi.z, 3.5f, 1e-4f);
}

TEST(Media, RatioTrackingMatchesQuadrature) {
  auto scene = BuildScene(kGridMedium);
  const Medium& m = scene->media().at(0);
  const MediumRay ray{{0.7f, -0.9f, 0.2f}, Normalize(Vec3{1.5f, 0.8f, 2.9f}), 3.8f};
  // Quadrature of the optical depth with the same trilinear density.
  const int n = 200000;
  double tau = 0;
  for (int i = 0; i < n; ++i) {
    float t = (float(i) + 0.5f) / n * ray.tmax;
    tau += double(m.Density(ray.o + ray.d * t)) * double(ray.tmax) / n;
  }
  ASSERT_GT(tau, 0.5);  // the ray really crosses the grid
  RGB st = m.sigma_t();
  // Majorant: every point's density is bounded by its DDA piece's majorant.
  m.ForEachMajorant(ray, [&](float t0, float t1, float smaj) {
    for (int k = 0; k <= 20; ++k) {
      float t = t0 + (t1 - t0) * float(k) / 20;
      EXPECT_LE(m.Density(ray.o + ray.d * t) * st.Max(), smaj * 1.0001f + 1e-6f);
    }
    return true;
  });
  const int kEstimates = 40000;
  Rng rng(HashSeed({3, 4}));
  double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0}, passed = 0;
  for (int i = 0; i < kEstimates; ++i) {
    RGB T = m.Transmittance(ray, rng);
    for (int c = 0; c < 3; ++c) {
      sum[c] += double(T[c]);
      sum2[c] += double(T[c]) * double(T[c]);
    }
    // Delta tracking: the chance of leaving without a real collision is T (max channel).
    passed += m.SampleFreePath(ray, rng).scattered ? 0 : 1;
  }
  for (int c = 0; c < 3; ++c) {
    double mean = sum[c] / kEstimates;
    double sd = std::sqrt(std::max(sum2[c] / kEstimates - mean * mean, 1e-12) / kEstimates);
    double expect = std::exp(-tau * double(st[c]));
    EXPECT_NEAR(mean, expect, 4 * sd + 1e-4) << "channel " << c;
  }
  double expect_pass = std::exp(-tau * double(st.Max()));
  double sd = std::sqrt(expect_pass * (1 - expect_pass) / kEstimates);
  EXPECT_NEAR(passed / kEstimates, expect_pass, 4 * sd + 1e-4);
}

// Free-path distances: chi-square against the (truncated) exponential, for the closed form of
// homogeneous media and for delta tracking in a constant-density grid region.
void ExpectExponentialFreePaths(const Medium& m, const MediumRay& ray, float sigma) {
  const int kBins = 16, kSamples = 100000;
  std::vector<double> observed(kBins + 1, 0), expected(kBins + 1, 0);
  Rng rng(HashSeed({11, uint64_t(sigma * 100)}));
  for (int i = 0; i < kSamples; ++i) {
    FreePathSample s = m.SampleFreePath(ray, rng);
    ASSERT_TRUE(s.weight.IsFinite());
    if (!s.scattered) {
      observed[kBins] += 1;
      continue;
    }
    ASSERT_GE(s.t, 0.f);
    ASSERT_LT(s.t, ray.tmax);
    observed[std::min(int(s.t / ray.tmax * kBins), kBins - 1)] += 1;
  }
  for (int b = 0; b < kBins; ++b) {
    double a = double(ray.tmax) * b / kBins, c = double(ray.tmax) * (b + 1) / kBins;
    expected[b] = kSamples * (std::exp(-double(sigma) * a) - std::exp(-double(sigma) * c));
  }
  expected[kBins] = kSamples * std::exp(-double(sigma) * double(ray.tmax));
  int dof = 0;
  double chi2 = ChiSquare(observed, expected, &dof);
  EXPECT_LT(chi2, ChiSquareCritical(dof)) << "sigma " << sigma;
}

TEST(Media, DeltaTrackingFreePathsAreExponential) {
  Medium h = Medium::Homogeneous(RGB(0.5f), RGB(1.5f), 0.f);
  ExpectExponentialFreePaths(h, {{0, 0, 0}, {0, 1, 0}, 1.2f}, 2.f);
  // 8³ grid of ones over [0,1]³: density is exactly 1 between the first and last sample centres
  // ([1/16, 15/16] per axis); the majorant cells there are 1 too.
  std::string ones;
  for (int i = 0; i < 512; ++i) ones += "1 ";
  auto scene = BuildScene(
      "MakeNamedMedium \"g\" \"string type\" \"uniformgrid\" \"integer nx\" [8] \"integer ny\" [8]"
      " \"integer nz\" [8] \"float density\" [" + ones + "] \"rgb sigma_a\" [1 1 1]"
      " \"rgb sigma_s\" [2 2 2]\nMediumInterface \"g\" \"\"\nShape \"sphere\" \"float radius\" [0.1]\n");
  const Medium& g = scene->media().at(0);
  ExpectExponentialFreePaths(g, {{0.5f, 0.5f, 0.07f}, {0, 0, 1}, 0.8f}, 3.f);
  // Albedo of the scattering events: σ_s/σ_t.
  Rng rng(5);
  for (int i = 0; i < 100; ++i) {
    FreePathSample s = g.SampleFreePath({{0.5f, 0.5f, 0.07f}, {0, 0, 1}, 0.8f}, rng);
    if (s.scattered) {
      EXPECT_NEAR(s.weight.r, 2.f / 3.f, 1e-6f);
    }
  }
}

TEST(Media, ExtremeOpticalDepthsStayFinite) {
  Rng rng(9);
  for (float albedo : {0.f, 1.f}) {
    for (float tau : {1e-8f, 1e-4f, 1.f, 100.f, 1e4f}) {
      Medium h = Medium::Homogeneous(RGB(1 - albedo), RGB(albedo), 0.9f);
      MediumRay ray{{0, 0, 0}, {1, 0, 0}, tau};
      RGB T = h.Transmittance(ray, rng);
      EXPECT_TRUE(T.IsFinite());
      EXPECT_NEAR(T.r, std::exp(-tau), 1e-6f);
      for (int i = 0; i < 100; ++i) {
        FreePathSample s = h.SampleFreePath(ray, rng);
        ASSERT_TRUE(s.weight.IsFinite() && std::isfinite(s.t));
        if (s.scattered) {
          ASSERT_EQ(s.weight.r, albedo);
        }
      }
    }
  }
  // A dense grid (σ_t·d up to 1e4) through ratio and delta tracking.
  auto scene = BuildScene(
      "MakeNamedMedium \"g\" \"string type\" \"uniformgrid\" \"integer nx\" [2] \"integer ny\" [1]"
      " \"integer nz\" [1] \"float density\" [1 0.5] \"rgb sigma_a\" [5000 0 1e-8]"
      " \"rgb sigma_s\" [5000 1e-8 0]\nMediumInterface \"g\" \"\"\nShape \"sphere\" \"float radius\" [0.1]\n");
  const Medium& g = scene->media().at(0);
  for (int i = 0; i < 200; ++i) {
    MediumRay ray{{-1, 0.5f, 0.5f}, {1, 0, 0}, 3};
    RGB T = g.Transmittance(ray, rng);
    ASSERT_TRUE(T.IsFinite());
    ASSERT_GE(T.Max(), 0.f);
    FreePathSample s = g.SampleFreePath(ray, rng);
    ASSERT_TRUE(s.weight.IsFinite());
  }
}

TEST(Media, NanoVDBCloudLoads) {
  const std::string file = testing::SharedDir() + "/media/wdas-cloud/wdas_cloud_sixteenth.nvdb";
  auto scene = BuildScene("MakeNamedMedium \"cloud\" \"string type\" \"nanovdb\" \"string filename\" \"" +
                          file + "\" \"rgb sigma_a\" [0.1 0.1 0.1] \"rgb sigma_s\" [1 1 1]\n"
                          "MediumInterface \"cloud\" \"\"\nShape \"sphere\" \"float radius\" [1]\n");
  const Medium& m = scene->media().at(0);
  Bounds3 b = m.WorldBounds();
  // The grid's world box (index box -66..59, -21..64, -90..63 at 10/3 units per voxel).
  EXPECT_NEAR(b.lo.x, -220.f, 0.5f);
  EXPECT_NEAR(b.lo.y, -70.f, 0.5f);
  EXPECT_NEAR(b.lo.z, -300.f, 0.5f);
  EXPECT_NEAR(b.hi.x, 200.f, 0.5f);
  EXPECT_NEAR(b.hi.y, 216.67f, 0.5f);
  EXPECT_NEAR(b.hi.z, 213.33f, 0.5f);
  EXPECT_GT(m.MaxDensity(), 0.5f);
  EXPECT_LE(m.MaxDensity(), 1.0001f);
  // A ray through the middle crosses real density: transmittance strictly inside (0, 1).
  Rng rng(2);
  double mean = 0;
  for (int i = 0; i < 200; ++i)
    mean += double(m.Transmittance({{-300, 50, 0}, {1, 0, 0}, 600}, rng).r) / 200;
  EXPECT_LT(mean, 0.99);
  EXPECT_GE(mean, 0.0);
}

TEST(Media, SceneErrorsNameFileAndLine) {
  ExpectSceneError([] { BuildScene("\nMakeNamedMedium \"m\" \"string type\" \"foggy\"\n"); },
                   "test.pbrt:6:", "unsupported medium type \"foggy\"");
  ExpectSceneError(
      [] {
        BuildScene("MakeNamedMedium \"m\" \"string type\" \"nanovdb\"\n"
                   "  \"string filename\" \"no-such-cloud.nvdb\"\n");
      },
      "test.pbrt:6:", "cannot open");
  ExpectSceneError(
      [] { BuildScene("MakeNamedMedium \"m\" \"string type\" \"homogeneous\"\n  \"rgb sigmaa\" [1 1 1]\n"); },
      "test.pbrt:6:", "unused parameter \"rgb sigmaa\"");
  ExpectSceneError(
      [] {
        BuildScene("MakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" [2]\n"
                   "  \"float density\" [1]\n");
      },
      "test.pbrt:6:", "\"density\" has 1 values");
  ExpectSceneError(
      [] { BuildScene("MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"float g\" [1]\n"); },
      "test.pbrt:5:", "\"g\" must lie in (-1, 1)");
}

}  // namespace test_media
}  // namespace lightfarm
