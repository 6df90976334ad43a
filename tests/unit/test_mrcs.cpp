// Matrix row-column sampling (Hašan 2007): the clustering's closed forms against their O(n²)
// definitions, unbiasedness (also with columns that are dark in every sampled row), the
// degenerate shapes (identical columns, c >= n, r = 1), determinism across thread counts, and the
// method against brute force on a real scene.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstring>
#include <set>

#include "common/render/render_job.h"
#include "common/gather/mrcs_clustering.h"
#include "common/util/rng.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_mrcs {

// Entries uniform in [0, 1): a dense non-negative "reduced matrix".
Eigen::MatrixXf RandomMatrix(int rows, int cols, uint64_t seed) {
  Rng rng(seed);
  Eigen::MatrixXf m(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) m(i, j) = rng.Uniform();
  return m;
}

// The definitions, pair by pair: w_i w_j ‖x̄_i − x̄_j‖² (x̄ = 0 for a zero column).
double PairCost(const Eigen::MatrixXf& x, int i, int j) {
  Eigen::VectorXd a = x.col(i).cast<double>(), b = x.col(j).cast<double>();
  double wa = a.norm(), wb = b.norm();
  if (wa == 0 || wb == 0) return 0;
  return wa * wb * (a / wa - b / wb).squaredNorm();
}

double PairwiseObjective(const Eigen::MatrixXf& x, const std::vector<std::vector<uint32_t>>& cs) {
  double total = 0;
  for (const auto& c : cs)
    for (uint32_t i : c)
      for (uint32_t j : c) total += PairCost(x, int(i), int(j));
  return total;
}

// Σ_k weight_k · A(:, rep_k) for one seed's representatives.
Eigen::VectorXd Estimate(const Eigen::MatrixXf& full, const MrcsClustering& clustering,
                         uint64_t seed) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(full.rows());
  for (size_t k = 0; k < clustering.clusters.size(); ++k) {
    MrcsRepresentative rep = MrcsChooseRepresentative(clustering.clusters[k], seed, uint32_t(k));
    sum += rep.weight * full.col(rep.light).cast<double>();
  }
  return sum;
}

// Every light in exactly one cluster, pmfs summing to 1 and positive wherever a light may
// contribute: the conditions under which Σ_k φ_rep / pmf is unbiased.
void ExpectValidPartition(const MrcsClustering& c, size_t n) {
  std::vector<int> seen(n, 0);
  for (const MrcsCluster& cluster : c.clusters) {
    ASSERT_EQ(cluster.lights.size(), cluster.pmf.size());
    double total = 0;
    for (size_t k = 0; k < cluster.lights.size(); ++k) {
      ++seen[cluster.lights[k]];
      EXPECT_GT(cluster.pmf[k], 0.0) << "light " << cluster.lights[k] << " can never be chosen";
      total += cluster.pmf[k];
    }
    EXPECT_NEAR(total, 1.0, 1e-12);
  }
  for (size_t j = 0; j < n; ++j) EXPECT_EQ(seen[j], 1) << "light " << j;
}

TEST(MrcsClustering, AlphaIdentityEqualsPairSum) {
  Eigen::MatrixXf x = RandomMatrix(12, 150, 7);
  x.col(5).setZero();       // a dark column: α = 0, and it adds nothing to the others
  x.col(9) = 3 * x.col(8);  // collinear pair: no cost between them
  std::vector<double> alpha = MrcsAlpha(x);
  ASSERT_EQ(alpha.size(), 150u);
  for (int i = 0; i < 150; ++i) {
    double direct = 0;
    for (int j = 0; j < 150; ++j) direct += PairCost(x, i, j);
    EXPECT_NEAR(alpha[size_t(i)], direct, 1e-4 * direct + 1e-12) << "column " << i;
  }
  EXPECT_EQ(alpha[5], 0.0);
}

TEST(MrcsClustering, ObjectiveClosedFormEqualsPairSum) {
  Eigen::MatrixXf x = RandomMatrix(6, 90, 11);
  x.col(3).setZero();
  std::vector<std::vector<uint32_t>> clusters(7);
  for (uint32_t j = 0; j < 90; ++j) clusters[(j * 5) % 7].push_back(j);
  double direct = PairwiseObjective(x, clusters);
  EXPECT_GT(direct, 0);
  EXPECT_NEAR(MrcsObjective(x, clusters), direct, 1e-6 * direct);
}

TEST(MrcsClustering, ObjectiveDecreasesAsClustersGrow) {
  // Columns near 24 directions with random energies, plus noise: structure to find.
  Eigen::MatrixXf basis = RandomMatrix(30, 24, 3);
  Eigen::MatrixXf noise = RandomMatrix(30, 2000, 4);
  Rng rng(5);
  Eigen::MatrixXf x(30, 2000);
  for (int j = 0; j < 2000; ++j)
    x.col(j) = (0.1f + rng.Uniform()) * basis.col(int(rng.UniformInt(24))) + 0.05f * noise.col(j);
  double previous = MrcsObjective(x, {[] {
                                    std::vector<uint32_t> all(2000);
                                    for (uint32_t j = 0; j < 2000; ++j) all[j] = j;
                                    return all;
                                  }()});
  for (size_t c : {6, 12, 24, 48, 96, 192, 384}) {
    std::vector<std::vector<uint32_t>> clusters = MrcsClusterPoints(x, c, 1);
    EXPECT_EQ(clusters.size(), c);
    double objective = MrcsObjective(x, clusters);
    EXPECT_LT(objective, previous) << "c = " << c;
    previous = objective;
  }
  // Once c reaches the number of directions, only the noise is left: far below one cluster.
  EXPECT_LT(MrcsObjective(x, MrcsClusterPoints(x, 48, 1)),
            0.05 * MrcsObjective(x, MrcsClusterPoints(x, 1, 1)));
}

TEST(MrcsClustering, SameSeedSamePartitionWithOneOrTwoThreads) {
  Eigen::MatrixXf x = RandomMatrix(20, 5000, 21);
  std::vector<std::vector<uint32_t>> one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = MrcsClusterPoints(x, 300, 9);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = MrcsClusterPoints(x, 300, 9);
  }
  EXPECT_EQ(one, two);
  EXPECT_NE(one, MrcsClusterPoints(x, 300, 10));
}

TEST(MrcsClustering, PartitionIsValidWithAndWithoutProjection) {
  Eigen::MatrixXf reduced = RandomMatrix(80, 700, 13);
  for (int c = 0; c < 40; ++c) reduced.col(c * 17).setZero();  // 40 dark columns
  std::vector<float> power(700, 1.f);
  for (int projection : {0, 20}) {
    MrcsClusterOptions options;
    options.clusters = 100;
    options.projection = projection;
    options.zero_share = 0.05;
    MrcsClustering c = MrcsClusterColumns(reduced, power, options, 2);
    ExpectValidPartition(c, 700);
    EXPECT_EQ(c.clusters.size(), 100u);
    EXPECT_EQ(c.zero_norm_columns, 40u);
    EXPECT_EQ(c.zero_norm_clusters, 5u);  // round(0.05 · 100)
    for (const MrcsCluster& cluster : c.clusters)
      for (uint32_t j : cluster.lights) EXPECT_EQ(cluster.zero_norm, j % 17 == 0 && j < 680);
  }
  // By default the dark columns get their share of the columns: round(100 · 40/700) = 6.
  MrcsClusterOptions defaults;
  defaults.clusters = 100;
  MrcsClustering c = MrcsClusterColumns(reduced, power, defaults, 2);
  ExpectValidPartition(c, 700);
  EXPECT_EQ(c.clusters.size(), 100u);
  EXPECT_EQ(c.zero_norm_clusters, 6u);
}

TEST(MrcsClustering, EnoughClustersGiveEveryColumnWeightOne) {
  Eigen::MatrixXf reduced = RandomMatrix(5, 40, 17);
  reduced.col(7).setZero();
  std::vector<float> power(40, 2.f);
  MrcsClusterOptions options;
  options.clusters = 40;
  MrcsClustering c = MrcsClusterColumns(reduced, power, options, 3);
  ASSERT_EQ(c.clusters.size(), 40u);
  ExpectValidPartition(c, 40);
  for (size_t k = 0; k < 40; ++k) {
    MrcsRepresentative rep = MrcsChooseRepresentative(c.clusters[k], 3, uint32_t(k));
    EXPECT_EQ(rep.weight, 1.0);
  }
  Eigen::MatrixXf full = RandomMatrix(30, 40, 18);
  Eigen::VectorXd exact = full.cast<double>().rowwise().sum();
  EXPECT_LT((Estimate(full, c, 3) - exact).norm(), 1e-12 * exact.norm());
}

TEST(MrcsClustering, IdenticalColumnsAreEstimatedExactly) {
  // Every column the same: any representative scaled by s_k/‖ρ‖ = |C_k| is exact.
  Eigen::VectorXf column = RandomMatrix(50, 1, 19).col(0);
  Eigen::MatrixXf full = column.replicate(1, 300);
  Eigen::MatrixXf reduced = full.topRows(10);
  std::vector<float> power(300, 1.f);
  MrcsClusterOptions options;
  options.clusters = 30;
  Eigen::VectorXd exact = full.cast<double>().rowwise().sum();
  for (uint64_t seed : {1, 2, 3}) {
    MrcsClustering c = MrcsClusterColumns(reduced, power, options, seed);
    ExpectValidPartition(c, 300);
    EXPECT_EQ(c.clusters.size(), 30u);  // splitting still spends the budget
    EXPECT_NEAR(c.objective, 0.0, 1e-6 * 300 * 300);
    EXPECT_LT((Estimate(full, c, seed) - exact).norm(), 1e-5 * exact.norm());
  }
}

// Unbiasedness over seeds of the total Σ_i estimate_i, including columns that are zero on the
// sampled rows but not elsewhere (dropping them, as the paper does in practice, would be biased).
TEST(MrcsClustering, DarkSampledColumnsKeepTheEstimateUnbiased) {
  const int m = 40, n = 80, r = 8;
  Eigen::MatrixXf full = RandomMatrix(m, n, 23);
  for (int j = 0; j < 12; ++j) full.block(0, j, r, 1).setZero();  // dark on the sampled rows
  for (int j = 12; j < n; j += 5) full.col(j) *= 8.f;                // uneven energies
  Eigen::MatrixXf reduced = full.topRows(r);
  std::vector<float> power(n);
  Rng prng(29);
  for (float& p : power) p = 0.2f + prng.Uniform();
  MrcsClusterOptions options;
  options.clusters = 16;
  options.zero_share = 0.1;
  const double exact = full.cast<double>().sum();
  const double dark = full.leftCols(12).cast<double>().sum();
  const int kSeeds = 400;
  double sum = 0, sum2 = 0;
  for (int s = 0; s < kSeeds; ++s) {
    MrcsClustering c = MrcsClusterColumns(reduced, power, options, uint64_t(1000 + s));
    ASSERT_EQ(c.zero_norm_columns, 12u);
    ASSERT_EQ(c.zero_norm_clusters, 2u);  // round(0.1 · 16)
    double total = Estimate(full, c, uint64_t(1000 + s)).sum();
    sum += total;
    sum2 += total * total;
  }
  const double mean = sum / kSeeds;
  const double sigma_mean = std::sqrt((sum2 / kSeeds - mean * mean) / (kSeeds - 1));
  EXPECT_GT(sigma_mean, 0);
  EXPECT_LT(std::abs(mean - exact), 4 * sigma_mean) << "mean " << mean << " exact " << exact;
  EXPECT_GT(dark, 20 * sigma_mean) << "the test could not tell a biased estimator";
}

TEST(MrcsClustering, SingleRowStillSpendsTheBudgetAndIsExactOnThatRow) {
  // r = 1: every reduced column points the same way, α ≡ 0, the objective is 0 for any
  // partition; the estimate of the sampled row itself is exact, of the others unbiased.
  Eigen::MatrixXf full = RandomMatrix(20, 200, 31);
  Eigen::MatrixXf reduced = full.topRows(1);
  std::vector<float> power(200, 1.f);
  MrcsClusterOptions options;
  options.clusters = 25;
  MrcsClustering c = MrcsClusterColumns(reduced, power, options, 4);
  ExpectValidPartition(c, 200);
  EXPECT_EQ(c.clusters.size(), 25u);
  Eigen::VectorXd estimate = Estimate(full, c, 4);
  double exact_row0 = full.row(0).cast<double>().sum();
  EXPECT_NEAR(estimate[0], exact_row0, 1e-5 * exact_row0);
}

// --- The method on a real scene -----------------------------------------------------------

RenderSettings SmallSettings(int size, size_t lights, std::vector<std::string> params) {
  RenderSettings s;
  s.method = "mrcs";
  s.width = s.height = size;
  s.lights = lights;
  s.seed = 5;
  s.params = std::move(params);
  return s;
}

std::vector<RGBAccum> RunWithSeed(Plan& plan, uint64_t seed) {
  for (SubMatrixTask& t : plan.tasks) t.seed = seed;
  return RunStagesLocally(plan, nullptr, nullptr).row_sums;
}

TEST(Mrcs, AColumnPerLightEqualsBruteForce) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderSettings s = SmallSettings(16, 500, {"columns=100000"});
  RenderOutput mrcs = RenderScene(scene, s);
  s.method = "brute";
  s.params.clear();
  RenderOutput brute = RenderScene(scene, s);
  ASSERT_TRUE(mrcs.image.SameSize(brute.image));
  ASSERT_GT(brute.image.MeanLuminance(), 0);
  for (size_t p = 0; p < brute.image.PixelCount(); ++p)
    for (int c = 0; c < 3; ++c) {
      float ref = brute.image.pixels[p][c];
      EXPECT_NEAR(mrcs.image.pixels[p][c], ref, 1e-4f * std::abs(ref) + 1e-12f) << "pixel " << p;
    }
  EXPECT_EQ(mrcs.stats["method_stats"]["mrcs.clusters"], double(mrcs.stats["lights"]["total"]));
}

TEST(Mrcs, MeanOverSeedsConvergesToBruteForce) {
  // One light set and receiver set (plan seed fixed); only the method's seed varies.
  Plan plan = BuildPlan(testing::SharedScene("cornell-box"),
                        SmallSettings(8, 200, {"rows=8", "columns=12", "projection=4"}), nullptr);
  std::vector<RGBAccum> mrcs_first = RunWithSeed(plan, 100);
  Plan& p = plan;
  std::unique_ptr<GatherMethod> mrcs = std::move(p.method);
  p.method = CreateGatherMethod("brute", OptionMap());
  std::vector<RGBAccum> brute = RunWithSeed(plan, 0);
  p.method = std::move(mrcs);
  ASSERT_EQ(mrcs_first.size(), brute.size());
  // Totals per channel, and the four image quadrants' luminance (rows are pixel-major).
  auto summarise = [&](const std::vector<RGBAccum>& rows) {
    std::vector<double> out(7, 0.0);
    for (size_t i = 0; i < rows.size(); ++i) {
      out[0] += rows[i].r;
      out[1] += rows[i].g;
      out[2] += rows[i].b;
      uint32_t pixel = plan.receivers->samples[plan.receivers->points[i].sample].pixel;
      int qx = int(pixel % 8) / 4, qy = int(pixel / 8) / 4;
      out[size_t(3 + 2 * qy + qx)] += 0.2126 * rows[i].r + 0.7152 * rows[i].g + 0.0722 * rows[i].b;
    }
    return out;
  };
  const std::vector<double> exact = summarise(brute);
  const int kSeeds = 64;
  std::vector<double> sum(7, 0.0), sum2(7, 0.0);
  for (int s = 0; s < kSeeds; ++s) {
    std::vector<double> v = summarise(RunWithSeed(plan, uint64_t(100 + s)));
    for (size_t k = 0; k < 7; ++k) {
      sum[k] += v[k];
      sum2[k] += v[k] * v[k];
    }
  }
  for (size_t k = 0; k < 7; ++k) {
    ASSERT_GT(exact[k], 0) << k;
    double mean = sum[k] / kSeeds;
    double sigma_mean = std::sqrt(std::max(0.0, sum2[k] / kSeeds - mean * mean) / (kSeeds - 1));
    EXPECT_GT(sigma_mean, 1e-6 * exact[k]) << "estimates do not vary: is the seed used?";
    EXPECT_LT(std::abs(mean - exact[k]), 4 * sigma_mean)
        << "summary " << k << ": mean " << mean << " exact " << exact[k];
  }
}

TEST(Mrcs, SameSeedSameBitsWithOneOrTwoThreads) {
  Plan plan = BuildPlan(testing::SharedScene("cornell-box"),
                        SmallSettings(32, 2500, {"rows=40", "columns=80", "projection=10"}),
                        nullptr);
  std::vector<RGBAccum> one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = RunWithSeed(plan, 77);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    two = RunWithSeed(plan, 77);
  }
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(std::memcmp(one.data(), two.data(), one.size() * sizeof(RGBAccum)), 0);
  std::vector<RGBAccum> other = RunWithSeed(plan, 78);
  EXPECT_NE(std::memcmp(one.data(), other.data(), one.size() * sizeof(RGBAccum)), 0);
}

TEST(Mrcs, OneSampledRowRendersEveryColumnBudget) {
  RenderSettings s = SmallSettings(16, 300, {"rows=1", "columns=40"});
  RenderOutput out = RenderScene(testing::SharedScene("cornell-box"), s);
  EXPECT_EQ(out.image.CountNonFinite(), 0u);
  EXPECT_GT(out.image.MeanLuminance(), 0);
  const nlohmann::json& stats = out.stats["method_stats"];
  EXPECT_EQ(stats["mrcs.sampled_rows"], 1.0);
  EXPECT_EQ(stats["mrcs.clusters"], 40.0);
  // r rows of n elements, then c columns of m elements.
  const double m = out.stats["matrix"]["rows"], n = out.stats["lights"]["total"];
  EXPECT_EQ(double(out.stats["matrix"]["elements_evaluated"]), n + 40 * m);
}

TEST(Mrcs, RejectsInvalidParameters) {
  for (const char* bad : {"rows=0", "columns=0", "projection=-1", "zero_share=2", "color_average=x"})
    EXPECT_THROW(CreateGatherMethod("mrcs", OptionMap::Parse({bad})), OptionError) << bad;
  EXPECT_EQ(CreateGatherMethod("mrcs", OptionMap())->stage_count(), 2);
}

}  // namespace test_mrcs
}  // namespace lightfarm
