// `adaptive-completion` (Huo et al. 2016, Sec. 5) against brute force: exact when every row is
// observed (ρ = 1), every column that loses anything is sampled fully (σ = 0) and every node is
// refined (β = 0); a moderate error at a fraction of the cost with the defaults; the same bits
// whatever the thread count or the order in which the slices run.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "common/render/render_job.h"
#include "common/gather/gather.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_adaptive_completion {

using testing::Elements;
using testing::ExpectImagesNear;
using testing::TempDir;

RenderSettings Settings(const std::string& method, std::vector<std::string> params, size_t lights,
                        int res) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = res;
  s.lights = lights;
  s.seed = 3;
  s.params = std::move(params);
  return s;
}

RenderOutput Render(const std::string& scene, const std::string& method,
                    std::vector<std::string> params, size_t lights, int res) {
  return RenderScene(scene, Settings(method, std::move(params), lights, res));
}

double Stat(const RenderOutput& out, const char* key) {
  return out.stats["method_stats"][key].get<double>();
}

const std::vector<std::string> kExact = {"rho=1", "sigma=0", "beta=0"};

// Orthographic view of the floor z = 0 lit by `n` point lights of varied colours and intensities
// at heights 0.3–0.7 on both sides of a wall in the plane x = 0 (seen edge-on): every receiver sees
// about half of the lights, and the columns differ in shape and colour.
std::string PointLightsScene(int n) {
  std::string s =
      "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
      "WorldBegin\n";
  for (int i = 0; i < n; ++i) {
    const float x = -0.9f + 1.8f * float(i) / float(n - 1) + (i % 2 ? 0.05f : -0.05f);
    const float y = -0.8f + 1.6f * float((i * 7) % n) / float(n);
    const float z = 0.3f + 0.4f * float((i * 3) % 5) / 4.f;
    const float r = 0.2f + float(i % 3) * 0.4f, g = 1.0f - float(i % 4) * 0.2f, b = 0.5f;
    s += "LightSource \"point\" \"rgb I\" [" + std::to_string(r) + " " + std::to_string(g) + " " +
         std::to_string(b) + "] \"point3 from\" [" + std::to_string(x) + " " + std::to_string(y) +
         " " + std::to_string(z) + "]\n";
  }
  s += "Material \"diffuse\" \"rgb reflectance\" [0.7 0.5 0.3]\n"
       "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
       "  \"integer indices\" [0 1 2 0 2 3]\n"
       "Shape \"trianglemesh\" \"point3 P\" [0 -4 0  0 4 0  0 4 2  0 -4 2]\n"
       "  \"integer indices\" [0 1 2 0 2 3]\n";
  return s;
}

TEST(AdaptiveCompletion, FullSamplingEqualsBruteForceOnPointLightsBehindAWall) {
  TempDir dir;
  const std::string scene = dir.Write("lights.pbrt", PointLightsScene(40));
  RenderOutput brute = Render(scene, "brute", {}, 40, 32);
  ASSERT_EQ(brute.stats["lights"]["total"].get<int>(), 40);
  // K = 1: every inner node is estimated from one sampled column and split; K = 10 (default):
  // nodes of at most 10 lights are evaluated light by light
  for (const char* columns : {"columns=1", "columns=10"}) {
    std::vector<std::string> params = kExact;
    params.push_back(columns);
    RenderOutput exact = Render(scene, "adaptive-completion", params, 40, 32);
    ExpectImagesNear(brute.image, exact.image, 1e-5f);
    // Columns on every row: the completed ones are exact (nothing lost on Ω = every row)
    EXPECT_EQ(Stat(exact, "columns_full"),
              Stat(exact, "basis_size") + Stat(exact, "columns_dropped"));
    EXPECT_EQ(Stat(exact, "negative_channels"), 0.0);
    EXPECT_LE(Elements(exact), Elements(brute));
  }
}

TEST(AdaptiveCompletion, FullSamplingEqualsBruteForceOnCornellBox) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {}, 500, 16);
  RenderOutput exact = Render(scene, "adaptive-completion", kExact, 500, 16);
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
  EXPECT_GT(Stat(exact, "nodes_split"), 0.0);
}

// Glossy receivers and VPLs, several emitters and light kinds (several trees): still exact.
TEST(AdaptiveCompletion, FullSamplingEqualsBruteForceWithGlossyMaterials) {
  const std::string scene = testing::SharedScene("veach-mis");
  RenderOutput brute = Render(scene, "brute", {}, 600, 16);
  RenderOutput exact = Render(scene, "adaptive-completion", kExact, 600, 16);
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
}

// Media (Huo 2016's own setting): eye-segment rows sliced by segment similarity (METIS, with and
// without boundary refinement) and medium VPLs in the tree; still exact in the limit, also with
// the near lights summed apart (near_distance).
TEST(AdaptiveCompletion, FullSamplingEqualsBruteForceInMedia) {
  const std::string scene = testing::SharedScene("volumetric-caustic");
  // Both kinds of media lights (VRLs by default, medium VPLs), with and without refinement.
  for (const char* media_lights : {"vrl", "vpl"})
  for (const char* refine : {"segment_refine=0", "segment_refine=1"}) {
    // No caustic photons: they add the same light to every method (test_caustics.cpp) and would
    // take most of the time here.
    const std::vector<std::string> common = {"segment_rows_per_slice=100", refine,
                                             std::string("media_lights=") + media_lights,
                                             "caustic_photons=0"};
    RenderOutput brute = Render(scene, "brute", common, 300, 16);
    ASSERT_GT(brute.stats["receivers"]["segments"].get<int>(), 200);
    ASSERT_GT(brute.stats["lights"][media_lights == std::string("vrl") ? "vrl" : "medium_vpl"].get<int>(), 0);
    ASSERT_GT(brute.stats["slices"].get<int>(), 3);
    for (const char* near : {"near_distance=0", "near_distance=0.3"}) {
      std::vector<std::string> params = kExact;
      params.insert(params.end(), common.begin(), common.end());
      params.push_back(near);
      RenderOutput exact = Render(scene, "adaptive-completion", params, 300, 16);
      EXPECT_EQ(exact.stats["receivers"]["segments"], brute.stats["receivers"]["segments"]);
      ExpectImagesNear(brute.image, exact.image, 1e-5f);
      EXPECT_EQ(Stat(exact, "negative_channels"), 0.0);
      EXPECT_LE(Elements(exact), Elements(brute));
    }
  }
}

// Media with the defaults: the near lights' spiky columns summed exactly (near_distance, see
// the method's header) are what keeps the completion from losing a large share of the
// in-scattered light. Measured (seed 3, 24², 1000 lights, slices of ~300 rows): near_distance=0
// rel_l1 ≈ 0.19; default 0.1: ≈ 0.010 with 46% of the elements (the slices span much of this tiny
// image's medium; 64², 2000 lights, default slices: 0.013 with 16%).
TEST(AdaptiveCompletion, NearLightsKeepMediaAccurate) {
  const std::string scene = testing::SharedScene("volumetric-caustic");
  const std::vector<std::string> slices = {"rows_per_slice=300", "segment_rows_per_slice=300",
                                           "caustic_photons=0"};  // the method's own error only
  std::vector<std::string> without_params = slices;
  without_params.push_back("near_distance=0");
  RenderOutput brute = Render(scene, "brute", slices, 1000, 24);
  RenderOutput ac = Render(scene, "adaptive-completion", slices, 1000, 24);
  RenderOutput without = Render(scene, "adaptive-completion", without_params, 1000, 24);
  const ErrorMetrics m = CompareImages(brute.image, ac.image);
  EXPECT_GT(m.rel_l1, 0.0);
  EXPECT_LT(m.rel_l1, 0.03);
  EXPECT_LT(m.rel_l2, 0.03);
  EXPECT_LT(double(Elements(ac)), 0.6 * double(Elements(brute)));
  EXPECT_GT(Stat(ac, "near_columns"), 0.0);
  EXPECT_EQ(Stat(without, "near_columns"), 0.0);
  EXPECT_GT(CompareImages(brute.image, without.image).rel_l1, 4 * m.rel_l1);
}

// Near lights sampled per row (near_samples = K) instead of summed exactly, with everything else
// exact (ρ = 1, σ = 0, β = 0), so that the image differs from the exact near sum only by the
// sampling: at most K entries per row, fewer elements, noise that falls with K, and no bias (each
// row draws on its own stream, so the pixel differences are independent with mean zero: their
// mean stays within four standard errors of 0; weights 20% too large fail it at K = 64 and 256).
// A slice with at most K near lights sums them exactly: the same bits.
TEST(AdaptiveCompletion, NearLightsSampledPerRowAreUnbiasedAndConverge) {
  const std::string scene = testing::SharedScene("volumetric-caustic");
  std::vector<std::string> common = kExact;
  common.insert(common.end(), {"segment_rows_per_slice=100", "caustic_photons=0", "near_distance=0.3"});
  const RenderOutput exact = Render(scene, "adaptive-completion", common, 600, 24);
  ASSERT_GT(Stat(exact, "near_columns"), 100.0);
  EXPECT_EQ(Stat(exact, "near_entries"), 0.0);
  auto sampled = [&](int k) {
    std::vector<std::string> params = common;
    params.push_back("near_samples=" + std::to_string(k));
    return Render(scene, "adaptive-completion", params, 600, 24);
  };
  const double rows = exact.stats["receivers"]["segments"].get<double>() +
                      exact.stats["receivers"]["points"].get<double>();
  double previous_error = kInfinity;
  RenderOutput sampled64;
  for (const int k : {8, 64, 256}) {
    const RenderOutput out = sampled(k);
    if (k == 64) sampled64 = out;
    EXPECT_GT(Stat(out, "near_entries"), 0.0);
    EXPECT_LE(Stat(out, "near_entries"), k * rows);
    EXPECT_LT(Elements(out), Elements(exact));
    const double error = CompareImages(exact.image, out.image).rel_l1;
    EXPECT_GT(error, 0.0);
    EXPECT_LT(error, 0.7 * previous_error) << "K " << k;
    previous_error = error;
    double sum = 0, sum2 = 0, reference = 0;
    const size_t n = exact.image.pixels.size();
    for (size_t i = 0; i < n; ++i) {
      const double d = double(out.image.pixels[i].Luminance()) - double(exact.image.pixels[i].Luminance());
      sum += d;
      sum2 += d * d;
      reference += double(exact.image.pixels[i].Luminance());
    }
    const double mean = sum / double(n), stderr_mean = std::sqrt((sum2 / double(n) - mean * mean) / double(n - 1));
    EXPECT_GT(stderr_mean, 0.0);
    EXPECT_LT(std::abs(mean), 4 * stderr_mean) << "K " << k << ": mean " << mean << ", image mean " << reference / double(n);
  }
  {  // the draws do not depend on the threads
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    EXPECT_TRUE(testing::SameBits(sampled(64).image, sampled64.image));
  }
  const RenderOutput all = sampled(1 << 20);  // more than any slice's near lights
  EXPECT_EQ(Stat(all, "near_entries"), 0.0);
  EXPECT_TRUE(testing::SameBits(exact.image, all.image));
}

// The defaults: an approximation (not a copy), at a fraction of the cost, that completes most
// columns from Ω; a tighter energy test samples more columns fully and errs less.
// Measured at these settings (seed 3, one 1003-row slice): rel_l2 ≈ 0.015, rel_l1 ≈ 0.046 with
// 5% of the elements; sigma=0.002: rel_l1 ≈ 0.032 with 10%.
TEST(AdaptiveCompletion, DefaultSettingsApproximateAtAFractionOfTheCost) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {}, 5000, 32);
  RenderOutput ac = Render(scene, "adaptive-completion", {}, 5000, 32);
  const ErrorMetrics m = CompareImages(brute.image, ac.image);
  EXPECT_GT(m.rel_l2, 0.0);
  EXPECT_LT(m.rel_l2, 0.03);
  EXPECT_LT(m.rel_l1, 0.08);
  EXPECT_LT(double(Elements(ac)), 0.1 * double(Elements(brute)));
  EXPECT_GT(Stat(ac, "columns_completed"), 10 * Stat(ac, "columns_full"));
  EXPECT_EQ(Stat(ac, "columns_full"), Stat(ac, "basis_size") + Stat(ac, "columns_dropped"));
  EXPECT_GT(Stat(ac, "nodes_split"), 0.0);
  EXPECT_GT(Stat(ac, "observed_residual"), 0.0);
  RenderOutput tighter = Render(scene, "adaptive-completion", {"sigma=0.002"}, 5000, 32);
  EXPECT_GT(Stat(tighter, "columns_full"), Stat(ac, "columns_full"));
  EXPECT_GT(Elements(tighter), Elements(ac));
  EXPECT_LT(CompareImages(brute.image, tighter.image).rel_l1, 0.8 * m.rel_l1);
  // A looser split test (Eq. 17) stops the traversal earlier: fewer nodes, fewer elements
  RenderOutput coarser = Render(scene, "adaptive-completion", {"beta=0.05"}, 5000, 32);
  EXPECT_LT(Stat(coarser, "nodes_split"), 0.7 * Stat(ac, "nodes_split"));
  EXPECT_LT(Elements(coarser), Elements(ac));
}

TEST(AdaptiveCompletion, SameBitsWithOneAndTwoThreads) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput a, b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    a = Render(scene, "adaptive-completion", {"rows_per_slice=300"}, 2000, 24);
  }
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    b = Render(scene, "adaptive-completion", {"rows_per_slice=300"}, 2000, 24);
  }
  ASSERT_GT(a.stats["slices"].get<int>(), 1);
  ASSERT_TRUE(a.image.SameSize(b.image));
  for (size_t i = 0; i < a.image.pixels.size(); ++i)
    ASSERT_EQ(a.image.pixels[i], b.image.pixels[i]) << "pixel " << i;
  EXPECT_EQ(Elements(a), Elements(b));
  EXPECT_EQ(a.stats["method_stats"], b.stats["method_stats"]);
}

// A farm runs slices in any order, retries them, and runs each on any worker: a slice's rows
// depend only on (seed, stage, task).
TEST(AdaptiveCompletion, SameBitsWhateverTheTaskOrder) {
  const std::string scene = testing::SharedScene("cornell-box");
  PhaseTimes times;
  const Plan plan =
      BuildPlan(scene, Settings("adaptive-completion", {"rows_per_slice=200"}, 2000, 24), &times);
  ASSERT_GT(plan.tasks.size(), 2u);
  const GatherContext ctx = plan.context();
  std::vector<TaskOutput> forward(plan.tasks.size()), backward(plan.tasks.size());
  for (size_t t = 0; t < plan.tasks.size(); ++t)
    forward[t] = plan.method->RunTask(ctx, plan.tasks[t], {});
  for (size_t t = plan.tasks.size(); t-- > 0;)
    backward[t] = plan.method->RunTask(ctx, plan.tasks[t], {});
  // and once more, interleaved with another task, on two threads
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    const TaskOutput again = plan.method->RunTask(ctx, plan.tasks[1], {});
    ASSERT_EQ(again.row_sums.size(), forward[1].row_sums.size());
    for (size_t i = 0; i < again.row_sums.size(); ++i) {
      EXPECT_EQ(again.row_sums[i].r, forward[1].row_sums[i].r);
      EXPECT_EQ(again.row_sums[i].b, forward[1].row_sums[i].b);
    }
  }
  for (size_t t = 0; t < plan.tasks.size(); ++t) {
    ASSERT_EQ(forward[t].row_sums.size(), plan.tasks[t].rows.size());
    for (size_t i = 0; i < forward[t].row_sums.size(); ++i) {
      ASSERT_EQ(forward[t].row_sums[i].r, backward[t].row_sums[i].r) << t << " " << i;
      ASSERT_EQ(forward[t].row_sums[i].g, backward[t].row_sums[i].g) << t << " " << i;
      ASSERT_EQ(forward[t].row_sums[i].b, backward[t].row_sums[i].b) << t << " " << i;
    }
    EXPECT_EQ(forward[t].counters.elements, backward[t].counters.elements);
    EXPECT_EQ(forward[t].stats, backward[t].stats);
  }
}

TEST(AdaptiveCompletion, InvalidParametersAreRejected) {
  for (const char* bad : {"rho=0", "rho=1.5", "columns=0", "sigma=-1", "beta=-0.1",
                          "omega_per_basis=-1", "rank_tolerance=2", "near_distance=-1",
                          "near_samples=-1"}) {
    OptionMap params = OptionMap::Parse({bad});
    EXPECT_THROW(CreateGatherMethod("adaptive-completion", params), OptionError) << bad;
  }
  OptionMap ok = OptionMap::Parse({"rho=0.2", "columns=4", "sigma=0.01", "beta=0.02",
                                   "omega_per_basis=1.5", "rank_tolerance=0.01", "near_samples=64"});
  auto method = CreateGatherMethod("adaptive-completion", ok);
  EXPECT_EQ(method->name(), "adaptive-completion");
  EXPECT_TRUE(method->needs_light_tree());
  ok.RejectUnused();  // every parameter was read
}

}  // namespace test_adaptive_completion
}  // namespace lightfarm
