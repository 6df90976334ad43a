// MediumTrack (common/scene/medium_track.h): exact transmittance in a trilinear grid (against
// quadrature and against ratio tracking), the in-scattering weight W, and sampling that follows
// its pdf; closed forms in homogeneous media.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/scene/medium_track.h"
#include "common/scene/scene.h"

namespace lightfarm {
namespace test_medium_track {

std::unique_ptr<Scene> BuildScene(const std::string& world) {
  SceneDescription desc = ParseSceneString(
      "Film \"rgb\" \"integer xresolution\" [4] \"integer yresolution\" [4]\n"
      "LookAt 0 0 10  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n" + world,
      "test.pbrt", "/tmp");
  return Scene::Build(desc, SceneBuildOptions{});
}

// A 4×3×2 chromatic grid in the world box [1, 3] × [-1, 0] × [0.5, 3.5], with empty cells and
// strong gradients (the density's domain is exactly that box).
const char* kGrid =
    "AttributeBegin\nTranslate 1 -1 0.5\nScale 2 1 3\n"
    "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" [4]\n"
    "  \"integer ny\" [3] \"integer nz\" [2] \"point3 p0\" [0 0 0] \"point3 p1\" [1 1 1]\n"
    "  \"float density\" [0 1 2 3  4 5 6 7  0.5 0.5 0.5 0.5   1 0 1 0  2 0 2 0  3 3 3 3]\n"
    "  \"rgb sigma_a\" [0.5 1 0.25] \"rgb sigma_s\" [0.5 0.5 0.5] \"float g\" [0.3]\n"
    "AttributeEnd\n"
    "MediumInterface \"\" \"smoke\"\nShape \"sphere\" \"float radius\" [0.01]\n";

// ∫_0^t density along the ray by the composite midpoint rule (double).
double DensityIntegral(const Medium& m, const MediumRay& ray, float t, int n) {
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += double(m.Density(ray.o + ray.d * (t * (float(i) + 0.5f) / float(n))));
  return sum * double(t) / n;
}

TEST(MediumTrack, GridTransmittanceIsExactInsideTheDomain) {
  auto scene = BuildScene(kGrid);
  const Medium& m = scene->media().at(0);
  // Corner to corner of the box, just inside: every point is in the density's domain.
  const Vec3 a{1.01f, -0.99f, 0.51f}, b{2.99f, -0.01f, 3.49f};
  const MediumRay ray{a, Normalize(b - a), Length(b - a)};
  const MediumTrack track(m, ray);
  ASSERT_GT(track.knots(), 8u);
  const RGB st = m.sigma_t();
  for (float f : {0.05f, 0.3f, 0.5f, 0.77f, 0.999f}) {
    const float t = f * ray.tmax;
    const double depth = DensityIntegral(m, ray, t, 400000);
    const MediumTrack::Point p = track.At(t);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(double(p.tr[c]), std::exp(-double(st[c]) * depth), 2e-5) << "t " << t << " channel " << c;
    EXPECT_NEAR(p.sigma_s.g, m.sigma_s().g * m.Density(ray.o + ray.d * t), 1e-5f);
  }
}

TEST(MediumTrack, GridTransmittanceMatchesRatioTracking) {
  auto scene = BuildScene(kGrid);
  const Medium& m = scene->media().at(0);
  // From outside the box, through it and out: the track clips to the domain as tracking does.
  const MediumRay ray{{0.7f, -0.9f, 0.2f}, Normalize(Vec3{1.5f, 0.8f, 2.9f}), 3.8f};
  const MediumTrack track(m, ray);
  ASSERT_GT(track.support_begin(), 0.f);
  ASSERT_LT(track.support_end(), ray.tmax);
  Rng rng(HashSeed({21, 5}));
  for (float t : {0.8f, 1.6f, 2.4f, 3.8f}) {
    const int n = 40000;
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (int i = 0; i < n; ++i) {
      const RGB T = m.Transmittance({ray.o, ray.d, t}, rng);
      for (int c = 0; c < 3; ++c) {
        sum[c] += double(T[c]);
        sum2[c] += double(T[c]) * double(T[c]);
      }
    }
    const RGB exact = t >= ray.tmax ? track.TransmittanceToEnd() : track.At(t).tr;
    for (int c = 0; c < 3; ++c) {
      const double mean = sum[c] / n;
      const double sd = std::sqrt(std::max(sum2[c] / n - mean * mean, 1e-12) / n);
      EXPECT_NEAR(double(exact[c]), mean, 4 * sd + 1e-5) << "t " << t << " channel " << c;
    }
  }
}

// W = ∫ mean_c σ_s,c Tr_c dt, the pdf integrates to one and is what Sample draws, and Quantile
// inverts the weight's cdf.
void ExpectConsistentSampling(const MediumTrack& track, float len) {
  const int n = 200000;
  double w = 0, pdf_total = 0;
  for (int i = 0; i < n; ++i) {
    const float t = len * (float(i) + 0.5f) / float(n);
    const MediumTrack::Point p = track.At(t);
    w += double((p.sigma_s * p.tr).Average()) * double(len) / n;
    pdf_total += double(track.Pdf(t)) * double(len) / n;
  }
  EXPECT_NEAR(double(track.weight()), w, 2e-3 * w);
  EXPECT_NEAR(pdf_total, 1.0, 2e-3);
  // Samples against the pdf's bins.
  const int kBins = 32, kSamples = 200000;
  std::vector<double> observed(kBins, 0), expected(kBins, 0);
  Rng rng(HashSeed({9, uint64_t(len * 1000)}));
  for (int i = 0; i < kSamples; ++i) {
    float pdf = 0;
    const float t = track.Sample(rng.Uniform(), &pdf);
    ASSERT_GT(pdf, 0.f);
    ASSERT_NEAR(pdf, track.Pdf(t), 1e-5f * pdf);
    ASSERT_GT(double((track.At(t).sigma_s).Max()), 0.0) << "a sample where nothing scatters";
    observed[size_t(std::min(int(t / len * kBins), kBins - 1))] += 1;
  }
  for (int b = 0; b < kBins; ++b) {
    double p = 0;
    for (int i = 0; i < 2000; ++i)
      p += double(track.Pdf(len * (float(b) + (float(i) + 0.5f) / 2000.f) / kBins)) * double(len) / kBins / 2000;
    expected[size_t(b)] = p * kSamples;
  }
  double chi2 = 0;
  int dof = -1;
  for (int b = 0; b < kBins; ++b) {
    if (expected[size_t(b)] < 5) {
      EXPECT_LT(observed[size_t(b)], 30) << "bin " << b;
      continue;
    }
    chi2 += (observed[size_t(b)] - expected[size_t(b)]) * (observed[size_t(b)] - expected[size_t(b)]) / expected[size_t(b)];
    ++dof;
  }
  ASSERT_GT(dof, 4);
  EXPECT_LT(chi2, 3.0 * dof + 30) << dof << " degrees of freedom";
  // Quantile is monotone and matches the sampled cdf.
  float prev = -1;
  for (int i = 0; i <= 16; ++i) {
    const float t = track.Quantile(float(i) / 16);
    EXPECT_GE(t, prev);
    prev = t;
  }
}

TEST(MediumTrack, GridWeightAndSampling) {
  auto scene = BuildScene(kGrid);
  const Medium& m = scene->media().at(0);
  const MediumRay ray{{0.7f, -0.9f, 0.2f}, Normalize(Vec3{1.5f, 0.8f, 2.9f}), 3.8f};
  const MediumTrack track(m, ray);
  ASSERT_GT(track.weight(), 0.05f);
  ExpectConsistentSampling(track, ray.tmax);
}

TEST(MediumTrack, HomogeneousClosedForms) {
  // Grey: W = albedo · (1 − Tr(ℓ)).
  const Medium grey = Medium::Homogeneous(RGB(0.25f), RGB(0.75f), 0.f);
  const MediumTrack g(grey, {{0, 0, 0}, {0, 0, 1}, 2.f});
  EXPECT_NEAR(g.weight(), 0.75f * (1 - std::exp(-2.f)), 1e-6f);
  EXPECT_NEAR(g.At(1.f).tr.r, std::exp(-1.f), 1e-6f);
  EXPECT_NEAR(g.Quantile(0.5f), -std::log(1 - 0.5f * (1 - std::exp(-2.f))), 1e-5f);
  ExpectConsistentSampling(g, 2.f);
  // Chromatic, one channel that does not scatter.
  const Medium chroma = Medium::Homogeneous(RGB(0.1f, 0.5f, 2.f), RGB(0.3f, 0.f, 1.f), 0.2f);
  const MediumTrack c(chroma, {{1, 2, 3}, {1, 0, 0}, 1.5f});
  const float expect = (0.3f / 0.4f * (1 - std::exp(-0.4f * 1.5f)) + 1.f / 3.f * (1 - std::exp(-3.f * 1.5f))) / 3.f;
  EXPECT_NEAR(c.weight(), expect, 1e-6f);
  ExpectConsistentSampling(c, 1.5f);
}

TEST(MediumTrack, NothingScattersOutsideTheGrid) {
  auto scene = BuildScene(kGrid);
  const Medium& m = scene->media().at(0);
  const MediumTrack miss(m, {{-5, 5, 0}, {1, 0, 0}, 10.f});
  EXPECT_TRUE(miss.empty());
  EXPECT_EQ(miss.At(3.f).tr.r, 1.f);
  EXPECT_EQ(miss.Pdf(3.f), 0.f);
  const MediumTrack degenerate(m, {{2, -0.5f, 1}, {0, 0, 1}, 0.f});
  EXPECT_TRUE(degenerate.empty());
}

}  // namespace test_medium_track
}  // namespace lightfarm
