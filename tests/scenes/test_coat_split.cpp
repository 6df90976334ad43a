// Mixed vertices (docs/rendering.md, "Mixed vertices"): a clear coat over a grey base, seen in
// front of a diffuse backdrop under a small area light. A camera sample that reaches the plane
// both becomes a receiver on the base and follows the coat's reflection, so no sample loses the
// base; the choice it replaces (follow the coat with probability p, else a receiver weighted
// 1/(1−p)) has the same expectation but leaves a pixel whose samples all followed the coat black.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/farm/render_job.h"
#include "tests/common/glossy_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_coat_split {

using testing::CoatedPlane;
using testing::PixelRect;
using testing::TempDir;

RenderOutput Render(const std::string& path, const std::string& method, int spp,
                    std::vector<std::string> params = {}, uint64_t seed = 3) {
  RenderSettings s;
  s.method = method;
  s.spp = spp;
  s.lights = 2000;
  s.seed = seed;
  s.params = std::move(params);
  return RenderScene(path, s);
}

double Lum(const RGB& c) { return double(c.Luminance()); }

double RegionMean(const Image& img, PixelRect r) {
  double s = 0;
  for (int y = r.y0; y < r.y0 + r.h; ++y)
    for (int x = r.x0; x < r.x0 + r.w; ++x) s += Lum(img.at(x, y));
  return s / double(r.w * r.h);
}

// Pixels of the plane darker than 0.3× the smallest truth value in their 3×3 neighbourhood: the
// black specks of a sample that lost the base (the truth's own edges never count).
int DarkSpecks(const Image& img, const Image& truth) {
  const PixelRect r = testing::kGlossyPlane;
  int n = 0;
  for (int y = r.y0; y < r.y0 + r.h; ++y)
    for (int x = r.x0; x < r.x0 + r.w; ++x) {
      double lo = INFINITY;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= truth.width || yy >= truth.height) continue;
          lo = std::min(lo, Lum(truth.at(xx, yy)));
        }
      n += Lum(img.at(x, y)) < 0.3 * lo;
    }
  return n;
}

// The default (auto, its own light count and camera paths) at one sample per pixel: no pixel of
// the plane is black, for a smooth (delta) coat and a sharp one; the choice leaves dozens. At
// 16 samples per pixel the default agrees with the path tracer region by region.
TEST(CoatSplit, TheDefaultHasNoBlackPixelAndMatchesThePathTracer) {
  TempDir dir;
  for (float roughness : {0.f, 0.001f}) {
    const std::string path = dir.Write("coated.pbrt", CoatedPlane(roughness));
    const Image truth = Render(path, "path", 1024).image;
    const RenderOutput split = Render(path, "auto", 1);
    const RenderOutput choice = Render(path, "auto", 1, {"coat_splits=0"});
    const int split_specks = DarkSpecks(split.image, truth), choice_specks = DarkSpecks(choice.image, truth);
    std::printf("roughness %g: dark pixels on the plane %d split, %d chosen (of %d)\n", roughness, split_specks,
                choice_specks, testing::kGlossyPlane.w * testing::kGlossyPlane.h);
    EXPECT_EQ(split_specks, 0) << "roughness " << roughness;
    EXPECT_GT(choice_specks, 5) << "roughness " << roughness;
    EXPECT_GT(split.stats["receivers"]["split_vertices"].get<double>(), 0);
    EXPECT_EQ(choice.stats["receivers"]["split_vertices"], 0);

    const RenderOutput out = Render(path, "auto", 16);
    for (PixelRect r : {testing::kGlossyBlob, testing::kGlossyBackdrop, testing::kGlossyPlane}) {
      const double t = RegionMean(truth, r), m = RegionMean(out.image, r);
      EXPECT_NEAR(m, t, 0.05 * t) << "roughness " << roughness << ", region at (" << r.x0 << ", " << r.y0
                                  << "): path " << t;
    }
  }
}

// The split's rows sum to the choice's expectation: with the same light set (same seed) brute
// force differs only in its camera side, so over four seeds the plane's mean agrees within the
// seeds' standard error, for one split per path and for three (the coat's reflection of the
// backdrop splits no further here, but the light's does not either: one plane).
TEST(CoatSplit, SplitRowsHaveTheChoicesExpectation) {
  TempDir dir;
  const std::string path = dir.Write("coated.pbrt", CoatedPlane(0.f));
  auto plane_mean = [&](const std::string& splits, double* se) {
    std::vector<double> v;
    for (uint64_t seed = 1; seed <= 4; ++seed) {
      const RenderOutput out = Render(path, "brute", 8, {"coat_splits=" + splits}, seed);
      v.push_back(RegionMean(out.image, testing::kGlossyPlane));
    }
    double mean = 0, var = 0;
    for (double x : v) mean += x / double(v.size());
    for (double x : v) var += (x - mean) * (x - mean) / double(v.size() - 1);
    *se = std::sqrt(var / double(v.size()));
    return mean;
  };
  double se0, se1, se3;
  const double choice = plane_mean("0", &se0), one = plane_mean("1", &se1), three = plane_mean("3", &se3);
  std::printf("plane mean: choice %.5f ± %.5f, one split %.5f ± %.5f, three %.5f ± %.5f\n", choice, se0, one, se1,
              three, se3);
  // Four standard errors, and never tighter than 0.5% (the light sets' own noise is shared).
  EXPECT_NEAR(one, choice, std::max(4 * std::hypot(se0, se1), 0.005 * choice));
  EXPECT_NEAR(three, choice, std::max(4 * std::hypot(se0, se3), 0.005 * choice));
  // The split is the lower-variance estimator of the two.
  EXPECT_LT(se1, se0);
}

// Rows per sample: more than one where the plane splits, and none of it on a purely diffuse
// scene, where the counters stay zero and every sample has at most one receiver. Same bits for
// any thread count.
TEST(CoatSplit, CountersAreZeroOnDiffuseScenesAndBitsIndependentOfThreads) {
  TempDir dir;
  RenderSettings s;
  s.method = "brute";
  s.width = s.height = 48;
  s.lights = 2000;
  s.params = {"coat_splits=4"};
  const RenderOutput diffuse = RenderScene(testing::SourcePath("scenes/cornell-box/scene.pbrt"), s);
  EXPECT_EQ(diffuse.stats["receivers"]["split_vertices"], 0);
  EXPECT_LE(diffuse.stats["receivers"]["points_per_sample"].get<double>(), 1.0);

  const std::string path = dir.Write("coated.pbrt", CoatedPlane(0.001f));
  RenderOutput one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = Render(path, "lightcuts", 2);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = Render(path, "lightcuts", 2);
  }
  EXPECT_GT(one.stats["receivers"]["points_per_sample"].get<double>(), 1.0);
  EXPECT_EQ(one.stats["receivers"], two.stats["receivers"]);
  EXPECT_TRUE(testing::SameBits(one.image, two.image));
}

}  // namespace test_coat_split
}  // namespace lightfarm
