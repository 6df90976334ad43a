// MRCS clustering (common/gather/mrcs.cpp, mrcs_clustering.h) on degenerate reduced matrices:
// every column zero, every column identical, c ≥ n, a single sampled row, and values at float's
// range limits. The partition stays valid (each column once, pmf > 0 summing to 1) and the
// estimate Σ_k A(:, rep_k)/pmf stays finite, and exact where the answer is known.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <vector>

#include "common/gather/mrcs_clustering.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_mrcs_hard_cases {

void ExpectValidPartition(const MrcsClustering& c, size_t n) {
  std::vector<int> seen(n, 0);
  for (const MrcsCluster& cluster : c.clusters) {
    ASSERT_FALSE(cluster.lights.empty());
    ASSERT_EQ(cluster.lights.size(), cluster.pmf.size());
    double total = 0;
    for (size_t k = 0; k < cluster.lights.size(); ++k) {
      ASSERT_LT(cluster.lights[k], n);
      ++seen[cluster.lights[k]];
      EXPECT_TRUE(std::isfinite(cluster.pmf[k]));
      EXPECT_GT(cluster.pmf[k], 0.0);
      total += cluster.pmf[k];
    }
    EXPECT_NEAR(total, 1.0, 1e-12);
  }
  for (size_t j = 0; j < n; ++j) EXPECT_EQ(seen[j], 1) << "column " << j;
  EXPECT_TRUE(std::isfinite(c.objective));
  EXPECT_GE(c.objective, 0.0);
}

// Σ_k weight_k · A(:, rep_k), in double.
Eigen::VectorXd Estimate(const Eigen::MatrixXd& full, const MrcsClustering& c, uint64_t seed) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(full.rows());
  for (size_t k = 0; k < c.clusters.size(); ++k) {
    const MrcsRepresentative rep = MrcsChooseRepresentative(c.clusters[k], seed, uint32_t(k));
    EXPECT_TRUE(std::isfinite(rep.weight));
    sum += rep.weight * full.col(rep.light);
  }
  return sum;
}

std::vector<float> UnitPower(size_t n) { return std::vector<float>(n, 1.f); }

TEST(MrcsHardCases, EveryReducedColumnZero) {
  const int r = 20, n = 300;
  const Eigen::MatrixXf reduced = Eigen::MatrixXf::Zero(r, n);
  for (size_t c : {size_t(1), size_t(17), size_t(299), size_t(300), size_t(1000)}) {
    MrcsClusterOptions options;
    options.clusters = c;
    const MrcsClustering clustering = MrcsClusterColumns(reduced, UnitPower(n), options, 3);
    ExpectValidPartition(clustering, n);
    EXPECT_EQ(clustering.zero_norm_columns, size_t(n));
    EXPECT_EQ(clustering.clusters.size(), std::min<size_t>(c, n));
  }
  // Zero power too: nothing to prefer, the pmf is uniform and still valid.
  MrcsClusterOptions options;
  options.clusters = 10;
  ExpectValidPartition(MrcsClusterColumns(reduced, std::vector<float>(n, 0.f), options, 3), n);
}

TEST(MrcsHardCases, IdenticalColumnsAtAnyScaleAreEstimatedExactly) {
  const int r = 8, n = 200;
  for (float value : {1e-42f, 1e-30f, 1.f, 1e18f, 1e30f}) {
    const Eigen::MatrixXf reduced = Eigen::MatrixXf::Constant(r, n, value);
    for (size_t c : {size_t(1), size_t(7), size_t(150)}) {
      MrcsClusterOptions options;
      options.clusters = c;
      const MrcsClustering clustering = MrcsClusterColumns(reduced, UnitPower(n), options, 5);
      ExpectValidPartition(clustering, n);
      const Eigen::MatrixXd full = reduced.cast<double>();
      const Eigen::VectorXd estimate = Estimate(full, clustering, 9);
      const Eigen::VectorXd exact = full.rowwise().sum();
      for (int i = 0; i < r; ++i)
        EXPECT_NEAR(estimate[i] / exact[i], 1.0, 1e-9) << "value " << value << " c " << c;
    }
  }
}

TEST(MrcsHardCases, EnoughClustersGiveTheExactSum) {
  const int r = 4, n = 50;
  Rng rng(1);
  Eigen::MatrixXf reduced(r, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < r; ++i) reduced(i, j) = j % 5 == 0 ? 0.f : rng.Uniform();
  for (size_t c : {size_t(50), size_t(51), size_t(100000)}) {
    MrcsClusterOptions options;
    options.clusters = c;
    const MrcsClustering clustering = MrcsClusterColumns(reduced, UnitPower(n), options, 5);
    ExpectValidPartition(clustering, n);
    ASSERT_EQ(clustering.clusters.size(), size_t(n));
    const Eigen::MatrixXd full = reduced.cast<double>();
    EXPECT_LT((Estimate(full, clustering, 1) - full.rowwise().sum()).norm(), 1e-12);
  }
}

TEST(MrcsHardCases, OneSampledRowWithProjectionAndWithout) {
  const int n = 500;
  Rng rng(2);
  Eigen::MatrixXf reduced(1, n);
  for (int j = 0; j < n; ++j) reduced(0, j) = j % 3 == 0 ? 0.f : rng.Uniform();
  for (int projection : {0, 1, 50}) {
    MrcsClusterOptions options;
    options.clusters = 40;
    options.projection = projection;
    const MrcsClustering clustering = MrcsClusterColumns(reduced, UnitPower(n), options, 8);
    ExpectValidPartition(clustering, n);
    // With one row every non-zero column points the same way: the reduced estimate is exact.
    const Eigen::MatrixXd full = reduced.cast<double>();
    EXPECT_NEAR(Estimate(full, clustering, 4)[0], full.sum(), 1e-9 * full.sum()) << projection;
  }
}

// Reduced columns from float's smallest denormal to its largest finite value in one matrix.
TEST(MrcsHardCases, ColumnsSpanningTheWholeFloatRange) {
  const int r = 6, n = 400;
  Rng rng(4);
  Eigen::MatrixXf reduced(r, n);
  for (int j = 0; j < n; ++j) {
    const float scale = std::pow(10.f, -45.f + 83.f * float(j) / float(n - 1));
    for (int i = 0; i < r; ++i) reduced(i, j) = std::min(rng.Uniform() * scale, 3e38f);
  }
  for (size_t c : {size_t(1), size_t(30), size_t(200)})
    for (int projection : {0, 3}) {
      MrcsClusterOptions options;
      options.clusters = c;
      options.projection = projection;
      const MrcsClustering clustering = MrcsClusterColumns(reduced, UnitPower(n), options, 6);
      ExpectValidPartition(clustering, n);
      const Eigen::VectorXd estimate = Estimate(reduced.cast<double>(), clustering, 2);
      EXPECT_TRUE(estimate.allFinite()) << c << " " << projection;
      EXPECT_GE(estimate.minCoeff(), 0.0);
    }
}

}  // namespace test_mrcs_hard_cases
}  // namespace lightfarm
