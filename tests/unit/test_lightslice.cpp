// LightSlice (Ou & Pellacini 2011): exact when every light is its own cluster; the per-slice
// refinement only splits global clusters, so the local objective never increases and no light
// is lost; the same bits whatever the thread count or task order; finite images on degenerate
// inputs (every element zero, a single light).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>

#include "common/render/render_job.h"
#include "common/gather/gather.h"
#include "common/gather/lightslice.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "common/util/rng.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_lightslice {

using testing::ExpectImagesNear;
using testing::TempDir;

RenderSettings Settings(const std::string& method, std::vector<std::string> params, size_t lights,
                        int res) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = res;
  s.lights = lights;
  s.seed = 7;
  s.params = std::move(params);
  return s;
}

// One path per receiver sample for every method, so brute force has lightslice's receivers
// (lightslice takes no coverage rows: GatherMethod::takes_coverage_rows).
RenderOutput Render(const std::string& scene, const std::string& method,
                    std::vector<std::string> params, size_t lights, int res) {
  if (method != "lightslice") params.push_back("coverage=1");
  return RenderScene(scene, Settings(method, std::move(params), lights, res));
}

double Stat(const RenderOutput& out, const char* key) {
  return out.stats["method_stats"][key].get<double>();
}

// --- The method against brute force --------------------------------------------------------

// local_clusters >= n: every light its own cluster with weight 1, so each slice sums every
// column of its rows exactly once — brute force up to the order of the double sums.
TEST(LightSlice, EveryLightItsOwnLocalClusterEqualsBruteForce) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {}, 500, 16);
  ASSERT_GT(brute.image.MeanLuminance(), 0);
  for (const char* global : {"global_clusters=5", "global_clusters=100000"}) {
    RenderOutput ls = Render(scene, "lightslice", {global, "local_clusters=100000"}, 500, 16);
    ExpectImagesNear(brute.image, ls.image, 1e-5f);
    const double slices = ls.stats["slices"].get<double>();
    EXPECT_EQ(Stat(ls, "lightslice.local_clusters"),
              slices * ls.stats["lights"]["total"].get<double>())
        << global;
    EXPECT_EQ(Stat(ls, "lightslice.local_objective"), 0.0) << global;
  }
}

// Glossy receivers and VPLs, several emitters: still exact.
TEST(LightSlice, EveryLightItsOwnLocalClusterEqualsBruteForceWithGlossyMaterials) {
  const std::string scene = testing::SharedScene("veach-mis");
  RenderOutput brute = Render(scene, "brute", {}, 800, 16);
  RenderOutput ls = Render(scene, "lightslice", {"local_clusters=100000"}, 800, 16);
  ExpectImagesNear(brute.image, ls.image, 1e-5f);
}

// Default method parameters with slices of 200 rows (32² at 800 rows would be one slice): a
// fraction of the matrix, an image close to brute force. Measured: rel_l2 0.034 with 6.5% of
// the elements. Without camera paths: the light they add is the same in both images, and with
// it the same difference (rmse 0.0293) is rel_l2 0.055 against a smaller ‖brute‖₂ (the visible
// light no longer aliased), which would measure the light's edges, not LightSlice.
TEST(LightSlice, DefaultsAreCloseToBruteForceAtAFractionOfTheCost) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {"rows_per_slice=200", "camera_paths=0"}, 5000, 32);
  RenderOutput ls = Render(scene, "lightslice", {"rows_per_slice=200", "camera_paths=0"}, 5000, 32);
  const ErrorMetrics m = CompareImages(brute.image, ls.image);
  EXPECT_GT(m.rel_l2, 0.0);  // an estimate, not a copy
  EXPECT_LT(m.rel_l2, 0.05);
  EXPECT_LT(double(testing::Elements(ls)), 0.2 * double(testing::Elements(brute)));
  // The refinement split clusters: the local objective fell below the global grouping's.
  EXPECT_LT(Stat(ls, "lightslice.local_objective"), Stat(ls, "lightslice.local_objective_unrefined"));
  EXPECT_GT(Stat(ls, "lightslice.artifact_bytes"), 0.0);
  EXPECT_EQ(Stat(ls, "lightslice.sampled_rows"), ls.stats["slices"].get<double>());
}

// --- The per-slice refinement on matrices of our own ---------------------------------------

Eigen::MatrixXf RandomLocal(int rows, int cols, uint64_t seed, double zero_column_share) {
  Rng rng(seed);
  Eigen::MatrixXf m(rows, cols);
  for (int j = 0; j < cols; ++j) {
    const bool dark = double(rng.Uniform()) < zero_column_share;
    for (int i = 0; i < rows; ++i) m(i, j) = dark ? 0.f : (rng.Uniform() < 0.3f ? 0.f : rng.Uniform());
  }
  return m;
}

// Every light in exactly one cluster, each pmf a distribution that can pick every light that
// can contribute (lit, or dark with power).
void ExpectValidClustering(const LightSliceLocalClustering& r, size_t n,
                           const std::vector<float>& power, const Eigen::MatrixXf& local) {
  std::vector<int> seen(n, 0);
  for (const MrcsCluster& c : r.clustering.clusters) {
    ASSERT_EQ(c.lights.size(), c.pmf.size());
    ASSERT_FALSE(c.lights.empty());
    double total = 0;
    for (size_t k = 0; k < c.lights.size(); ++k) {
      ASSERT_LT(c.lights[k], n);
      ++seen[c.lights[k]];
      ASSERT_TRUE(std::isfinite(c.pmf[k]));
      total += c.pmf[k];
      const bool lit = local.col(c.lights[k]).norm() > 0;
      EXPECT_EQ(c.zero_norm, !lit);
      if (lit || power[c.lights[k]] > 0) {
        EXPECT_GT(c.pmf[k], 0.0) << "light " << c.lights[k];
      }
    }
    EXPECT_NEAR(total, 1.0, 1e-9);
  }
  for (size_t j = 0; j < n; ++j) EXPECT_EQ(seen[j], 1) << "light " << j;
}

TEST(LightSlice, RefinementNeverIncreasesTheLocalObjectiveAndOnlySplitsGlobalClusters) {
  const int n = 400, d = 9, global_count = 12;
  const Eigen::MatrixXf local = RandomLocal(d, n, 11, 0.2);
  std::vector<uint32_t> global_of(n);
  std::vector<float> power(n);
  Rng rng(12);
  for (int j = 0; j < n; ++j) {
    global_of[size_t(j)] = rng.UniformInt(global_count);
    power[size_t(j)] = 0.5f + rng.Uniform();
  }
  double previous = std::numeric_limits<double>::infinity();
  double unrefined = -1;
  for (size_t count : {1, 5, 12, 20, 40, 80, 160, 320, 399, 400}) {
    LightSliceLocalOptions options;
    options.clusters = count;
    const LightSliceLocalClustering r = LightSliceRefine(local, global_of, power, options, 5);
    ExpectValidClustering(r, n, power, local);
    if (unrefined < 0) unrefined = r.global_objective;
    EXPECT_EQ(r.global_objective, unrefined);  // the starting point does not depend on C_local
    EXPECT_LE(r.clustering.objective, r.global_objective * (1 + 1e-12)) << count;
    EXPECT_LE(r.clustering.objective, previous * (1 + 1e-12)) << count;
    previous = r.clustering.objective;
    // Lit lights stay inside their global cluster (refinement splits, never merges).
    for (const MrcsCluster& c : r.clustering.clusters) {
      if (c.zero_norm) continue;
      for (uint32_t j : c.lights) EXPECT_EQ(global_of[j], global_of[c.lights.front()]);
    }
    if (count >= 40) {
      EXPECT_LT(r.clustering.objective, 0.9 * r.global_objective) << count;
      EXPECT_GE(r.clustering.clusters.size(), std::min<size_t>(count, n) - 1) << count;
    }
  }
  EXPECT_EQ(previous, 0.0);  // every light its own cluster
}

TEST(LightSlice, RefinementHandlesAllDarkAndSingleLightInputs) {
  // Every local column zero: only power-sampled dark clusters, each light in one of them.
  const Eigen::MatrixXf zero = Eigen::MatrixXf::Zero(4, 50);
  std::vector<uint32_t> global_of(50, 0);
  std::vector<float> power(50, 1.f);
  power[3] = 0.f;  // a black light: pmf 0 is fine, the cluster's pmf still sums to 1
  LightSliceLocalOptions options;
  options.clusters = 6;
  const LightSliceLocalClustering dark = LightSliceRefine(zero, global_of, power, options, 1);
  ExpectValidClustering(dark, 50, power, zero);
  EXPECT_EQ(dark.clustering.zero_norm_columns, 50u);
  EXPECT_EQ(dark.clustering.clusters.size(), 6u);
  EXPECT_EQ(dark.clustering.objective, 0.0);
  // All power zero as well: uniform pmf.
  std::vector<float> black(50, 0.f);
  ExpectValidClustering(LightSliceRefine(zero, global_of, black, options, 1), 50, black, zero);
  // One light, one local row: its own cluster with pmf 1.
  Eigen::MatrixXf one(1, 1);
  one(0, 0) = 2.f;
  const LightSliceLocalClustering single =
      LightSliceRefine(one, std::vector<uint32_t>{0}, std::vector<float>{1.f}, options, 1);
  ASSERT_EQ(single.clustering.clusters.size(), 1u);
  EXPECT_EQ(single.clustering.clusters[0].pmf[0], 1.0);
  // No local rows at all (a slice without sampled rows): every light is dark.
  const LightSliceLocalClustering none =
      LightSliceRefine(Eigen::MatrixXf(0, 50), global_of, power, options, 1);
  ExpectValidClustering(none, 50, power, Eigen::MatrixXf::Zero(1, 50));
}

// --- Determinism ---------------------------------------------------------------------------

// Runs the stages as the coordinator would, with the tasks of each stage in reverse order.
std::vector<RGBAccum> RunReversed(const Plan& plan) {
  const GatherContext ctx = plan.context();
  const GatherMethod& method = *plan.method;
  std::vector<RGBAccum> sums(plan.matrix->rows());
  StageArtifact artifact;
  for (int stage = 0; stage < method.stage_count(); ++stage) {
    std::vector<SubMatrixTask> tasks = method.PlanStage(stage, ctx, plan.tasks, artifact);
    std::vector<TaskOutput> outputs(tasks.size());
    for (size_t t = tasks.size(); t-- > 0;) outputs[t] = RunGatherTask(method, ctx, tasks[t], artifact);
    if (stage + 1 < method.stage_count()) {
      artifact = method.Combine(stage, ctx, outputs);
    } else {
      for (size_t t = 0; t < tasks.size(); ++t)
        for (size_t i = 0; i < tasks[t].rows.size(); ++i)
          sums[tasks[t].rows[i]] = outputs[t].row_sums[i];
    }
  }
  return sums;
}

std::vector<RGBAccum> RunWithSeed(Plan& plan, uint64_t seed) {
  for (SubMatrixTask& t : plan.tasks) t.seed = seed;
  return RunStagesLocally(plan, nullptr, nullptr).row_sums;
}

bool SameBits(const std::vector<RGBAccum>& a, const std::vector<RGBAccum>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(RGBAccum)) == 0;
}

TEST(LightSlice, SameSeedSameBitsWithOneOrTwoThreadsAndAnyTaskOrder) {
  Plan plan = BuildPlan(testing::SharedScene("cornell-box"),
                        Settings("lightslice",
                                 {"rows_per_slice=200", "global_clusters=30", "local_clusters=60",
                                  "slice_rows=2", "projection=4"},
                                 2000, 24),
                        nullptr);
  ASSERT_GT(plan.tasks.size(), 2u);
  std::vector<RGBAccum> one, two, reversed;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = RunWithSeed(plan, 77);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = RunWithSeed(plan, 77);
    reversed = RunReversed(plan);
  }
  EXPECT_TRUE(SameBits(one, two));
  EXPECT_TRUE(SameBits(one, reversed));
  EXPECT_FALSE(SameBits(one, RunWithSeed(plan, 78)));  // the seed is used
}

// Every light that can contribute has a positive probability in its cluster, weighted by
// 1/probability: the mean over method seeds converges to brute force (assert within 4σ).
TEST(LightSlice, MeanOverSeedsConvergesToBruteForce) {
  // One light set and receiver set (plan seed fixed); only the method's seed varies.
  Plan plan = BuildPlan(testing::SharedScene("cornell-box"),
                        Settings("lightslice",
                                 {"rows_per_slice=16", "global_clusters=6", "local_clusters=12"},
                                 200, 8),
                        nullptr);
  std::unique_ptr<GatherMethod> lightslice = std::move(plan.method);
  plan.method = CreateGatherMethod("brute", OptionMap());
  const std::vector<RGBAccum> brute = RunWithSeed(plan, 0);
  plan.method = std::move(lightslice);
  auto channels = [](const std::vector<RGBAccum>& rows) {
    std::vector<double> out(3, 0.0);
    for (const RGBAccum& r : rows) {
      out[0] += r.r;
      out[1] += r.g;
      out[2] += r.b;
    }
    return out;
  };
  const std::vector<double> exact = channels(brute);
  const int kSeeds = 64;
  std::vector<double> sum(3, 0.0), sum2(3, 0.0);
  for (int s = 0; s < kSeeds; ++s) {
    const std::vector<double> v = channels(RunWithSeed(plan, uint64_t(100 + s)));
    for (size_t c = 0; c < 3; ++c) {
      sum[c] += v[c];
      sum2[c] += v[c] * v[c];
    }
  }
  for (size_t c = 0; c < 3; ++c) {
    ASSERT_GT(exact[c], 0) << c;
    const double mean = sum[c] / kSeeds;
    const double sigma_mean =
        std::sqrt(std::max(0.0, sum2[c] / kSeeds - mean * mean) / (kSeeds - 1));
    EXPECT_GT(sigma_mean, 1e-6 * exact[c]) << "estimates do not vary: is the seed used?";
    EXPECT_LT(std::abs(mean - exact[c]), 4 * sigma_mean)
        << "channel " << c << ": mean " << mean << " exact " << exact[c];
  }
}

// --- Degenerate scenes ---------------------------------------------------------------------

// A floor z = 0 seen from above, lit only by `lights` point lights, either above it or below
// (every element zero: the floor faces away and blocks them).
std::string FloorScene(int lights, bool below) {
  std::string s =
      "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
      "WorldBegin\n";
  for (int k = 0; k < lights; ++k)
    s += "LightSource \"point\" \"rgb I\" [1 1 1] \"point3 from\" [" + std::to_string(0.3 * k) +
         " 0.1 " + (below ? "-0.5" : "0.5") + "]\n";
  s += "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
       "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
       "  \"integer indices\" [0 1 2 0 2 3]\n";
  return s;
}

TEST(LightSlice, EveryElementZeroGivesABlackFiniteImage) {
  TempDir dir;
  const std::string scene = dir.Write("below.pbrt", FloorScene(3, true));
  RenderOutput ls = Render(scene, "lightslice",
                           {"global_clusters=1", "local_clusters=1", "rows_per_slice=64"}, 3, 16);
  ASSERT_EQ(ls.stats["lights"]["total"].get<int>(), 3);
  EXPECT_EQ(ls.image.CountNonFinite(), 0u);
  EXPECT_EQ(ls.image.MeanLuminance(), 0.0);
  // Every light dark on every sampled row: each slice spent its one cluster on them.
  const double slices = ls.stats["slices"].get<double>();
  ASSERT_GT(slices, 1);
  EXPECT_EQ(Stat(ls, "lightslice.local_dark_lights"), 3 * slices);
  EXPECT_EQ(Stat(ls, "lightslice.local_dark_clusters"), slices);
}

TEST(LightSlice, ASingleLightEqualsBruteForce) {
  TempDir dir;
  const std::string scene = dir.Write("one.pbrt", FloorScene(1, false));
  RenderOutput brute = Render(scene, "brute", {}, 1, 16);
  RenderOutput ls = Render(scene, "lightslice", {"rows_per_slice=64"}, 1, 16);
  ASSERT_EQ(ls.stats["lights"]["total"].get<int>(), 1);
  ASSERT_GT(brute.image.MeanLuminance(), 0);
  EXPECT_EQ(ls.image.CountNonFinite(), 0u);
  ExpectImagesNear(brute.image, ls.image, 1e-5f);
}

TEST(LightSlice, RejectsInvalidParameters) {
  for (const char* bad : {"global_clusters=0", "local_clusters=0", "neighbors=-1", "slice_rows=0",
                          "projection=-1", "dark_share=2", "dark_share=x"})
    EXPECT_THROW(CreateGatherMethod("lightslice", OptionMap::Parse({bad})), OptionError) << bad;
  OptionMap ok = OptionMap::Parse({"global_clusters=50", "local_clusters=80", "neighbors=4",
                                   "slice_rows=2", "projection=0", "dark_share=0.1"});
  auto method = CreateGatherMethod("lightslice", ok);
  EXPECT_EQ(method->name(), "lightslice");
  EXPECT_EQ(method->stage_count(), 2);
  ok.RejectUnused();  // every parameter was read
}

}  // namespace test_lightslice
}  // namespace lightfarm
