// NMF-ADMM (common/matrix/nmf_completion.*) on inputs at the edges of double/float range and of
// its own assumptions: every answer is finite and nonnegative, the iteration count stays within
// the cap, and where the answer is known (zero matrix, low-rank matrix at any scale) it is met.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "common/matrix/nmf_completion.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_nmf_hard_cases {

// A nonnegative rank-r matrix, entries of order 1.
Eigen::MatrixXd LowRank(int m, int n, int r, uint64_t seed) {
  Rng rng(seed, 1);
  Eigen::MatrixXd a(m, r), b(r, n);
  for (int i = 0; i < m; ++i)
    for (int k = 0; k < r; ++k) a(i, k) = rng.UniformDouble();
  for (int k = 0; k < r; ++k)
    for (int j = 0; j < n; ++j) b(k, j) = rng.UniformDouble();
  return a * b;
}

// Entries of m (scaled by `scale`, stored as float) on a random fraction of the positions.
std::vector<MatrixEntry> Observe(const Eigen::MatrixXd& m, double fraction, uint64_t seed,
                                 double scale = 1) {
  Rng rng(seed, 2);
  std::vector<MatrixEntry> out;
  for (int i = 0; i < m.rows(); ++i)
    for (int j = 0; j < m.cols(); ++j)
      if (rng.UniformDouble() < fraction)
        out.push_back({uint32_t(i), uint32_t(j), float(m(i, j) * scale)});
  return out;
}

void ExpectWellFormed(const NmfResult& r, int rows, int cols, const NmfOptions& options) {
  ASSERT_EQ(r.X.rows(), rows);
  ASSERT_EQ(r.Y.cols(), cols);
  ASSERT_EQ(r.X.cols(), r.Y.rows());
  EXPECT_TRUE(r.X.allFinite());
  EXPECT_TRUE(r.Y.allFinite());
  if (r.X.size() > 0) {
    EXPECT_GE(r.X.minCoeff(), 0.0);
  }
  if (r.Y.size() > 0) {
    EXPECT_GE(r.Y.minCoeff(), 0.0);
  }
  EXPECT_TRUE(std::isfinite(r.observed_residual));
  EXPECT_LE(r.iterations, options.max_iterations);
  const Eigen::MatrixXd product = r.X * r.Y;
  EXPECT_TRUE(product.allFinite());
}

TEST(NmfHardCases, ZeroMatrixGivesZeroFactors) {
  NmfOptions options;
  const Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(30, 20);
  for (double fraction : {0.0, 0.3, 1.0}) {
    const auto observed = Observe(zero, fraction, 1);
    NmfResult r = CompleteNonnegative(30, 20, observed, options, 7);
    ExpectWellFormed(r, 30, 20, options);
    EXPECT_EQ((r.X * r.Y).cwiseAbs().maxCoeff(), 0.0) << fraction;
    EXPECT_EQ(r.observed_residual, 0.0);
  }
  // An empty matrix, too.
  NmfResult empty = CompleteNonnegative(0, 0, {}, options, 7);
  EXPECT_EQ(empty.X.size(), 0);
}

TEST(NmfHardCases, RankLargerThanTheMatrixIsCappedAndStillFits) {
  const Eigen::MatrixXd truth = LowRank(6, 5, 1, 3);
  const auto observed = Observe(truth, 0.7, 4);
  for (double oversampling : {0.0, 2.0}) {
    NmfOptions options;
    options.rank = 100;
    options.min_oversampling = oversampling;
    options.max_iterations = 300;
    options.tolerance = 1e-8;
    NmfResult r = CompleteNonnegative(6, 5, observed, options, 9);
    ExpectWellFormed(r, 6, 5, options);
    EXPECT_LE(r.X.cols(), 5);
    // More factors than the data determine: the fit of Ω is still good.
    EXPECT_LT(r.observed_residual, 0.05) << oversampling;
  }
}

// The solver normalises by the observed values' scale, so a matrix at float's denormal edge and
// one near its overflow edge are completed as well as the same matrix at unit scale.
TEST(NmfHardCases, DenormalAndHugeScalesBehaveLikeUnitScale) {
  const Eigen::MatrixXd truth = LowRank(40, 30, 3, 5);
  NmfOptions options;
  options.rank = 3;
  options.max_iterations = 200;
  options.tolerance = 1e-7;
  const NmfResult unit = CompleteNonnegative(40, 30, Observe(truth, 0.5, 6), options, 11);
  ExpectWellFormed(unit, 40, 30, options);
  const double unit_error = (unit.X * unit.Y - truth).norm() / truth.norm();
  ASSERT_LT(unit_error, 0.05);
  // 1e-41 is deep in float's denormals (min normal 1.2e-38): ~15 significant bits remain.
  for (double scale : {1e-41, 1e-38, 1e30, 1e35}) {
    const NmfResult r = CompleteNonnegative(40, 30, Observe(truth, 0.5, 6, scale), options, 11);
    ExpectWellFormed(r, 40, 30, options);
    const double error = (r.X * r.Y / scale - truth).norm() / truth.norm();
    EXPECT_LT(error, unit_error + (scale < 1e-40 ? 1e-3 : 1e-5)) << "scale " << scale;
  }
}

TEST(NmfHardCases, AFewHugeEntriesStayFiniteAndDominateNothingElse) {
  Eigen::MatrixXd m = LowRank(50, 40, 2, 8);
  m(3, 4) = 3e38;  // float's largest values
  m(10, 20) = 1e38;
  m(49, 39) = std::numeric_limits<float>::max();
  NmfOptions options;
  options.rank = 4;
  const auto observed = Observe(m, 0.4, 9);
  const NmfResult r = CompleteNonnegative(50, 40, observed, options, 3);
  ExpectWellFormed(r, 50, 40, options);
  // Row sums (what sparse-completion uses) are finite and no larger than the matrix can explain.
  const Eigen::VectorXd sums = FactoredRowSums(r);
  EXPECT_TRUE(sums.allFinite());
  EXPECT_LE(sums.maxCoeff(), 40.0 * double(std::numeric_limits<float>::max()));
}

TEST(NmfHardCases, NonFiniteAndNegativeObservationsAreTreatedAsZero) {
  const Eigen::MatrixXd truth = LowRank(20, 20, 2, 10);
  auto observed = Observe(truth, 0.6, 11);
  observed.push_back({0, 0, std::numeric_limits<float>::quiet_NaN()});
  observed.push_back({1, 1, std::numeric_limits<float>::infinity()});
  observed.push_back({2, 2, -std::numeric_limits<float>::infinity()});
  observed.push_back({3, 3, -1e30f});
  NmfOptions options;
  options.rank = 2;
  const NmfResult r = CompleteNonnegative(20, 20, observed, options, 1);
  ExpectWellFormed(r, 20, 20, options);
}

// Columns spanning 12 orders of magnitude (a bright light beside a dim one in one slice): finite,
// nonnegative, the observed entries fitted and the row sums (what sparse-completion uses)
// accurate. With one global scale the ADM converges much more slowly than at unit scale; the
// per-column RMS scaling (NmfOptions::scale_columns, the default) makes it as fast.
TEST(NmfHardCases, ColumnsSpanningTwelveOrdersOfMagnitude) {
  const int m = 60, n = 48;
  Eigen::MatrixXd truth = LowRank(m, n, 2, 12);
  const Eigen::MatrixXd unit_truth = truth;
  for (int j = 0; j < n; ++j) truth.col(j) *= std::pow(10.0, -6.0 + 12.0 * j / (n - 1));
  NmfOptions options;
  options.rank = 2;
  options.max_iterations = 300;
  options.tolerance = 1e-8;
  auto row_sum_error = [&](const Eigen::MatrixXd& t, const NmfOptions& o) {
    const NmfResult r = CompleteNonnegative(m, n, Observe(t, 0.6, 13), o, 2);
    ExpectWellFormed(r, m, n, o);
    EXPECT_LT(r.observed_residual, 0.02);
    const Eigen::VectorXd sums = FactoredRowSums(r), exact = t.rowwise().sum();
    // Every column's own relative error, too: the dim columns are not sacrificed.
    const Eigen::MatrixXd product = r.X * r.Y;
    double worst_column = 0;
    for (int j = 0; j < n; ++j)
      worst_column = std::max(worst_column, (product.col(j) - t.col(j)).norm() / t.col(j).norm());
    return std::pair{(sums - exact).norm() / exact.norm(), worst_column};
  };
  const auto [scaled, scaled_column] = row_sum_error(truth, options);
  const auto [unit, unit_column] = row_sum_error(unit_truth, options);
  NmfOptions global = options;
  global.scale_columns = false;
  const auto [unscaled, unscaled_column] = row_sum_error(truth, global);
  std::printf("row-sum error: per-column scaling %.3g, one global scale %.3g, equal columns %.3g; "
              "worst column %.3g / %.3g / %.3g\n",
              scaled, unscaled, unit, scaled_column, unscaled_column, unit_column);
  // Measured: 2.7e-5 (per-column), 0.16 (global), 6.2e-5 (equal columns); worst column 6.2e-4,
  // 0.36 and 6.2e-4.
  EXPECT_LT(scaled, 1e-3);
  EXPECT_LT(scaled_column, 5e-3);
  EXPECT_LT(scaled, 2 * unit + 1e-4);
  EXPECT_LT(scaled, unscaled);
}

TEST(NmfHardCases, SingleRowSingleColumnAndOneObservation) {
  NmfOptions options;
  for (auto [rows, cols] : {std::pair{1, 50}, std::pair{50, 1}, std::pair{1, 1}}) {
    std::vector<MatrixEntry> one = {{0, 0, 2.5f}};
    const NmfResult r = CompleteNonnegative(rows, cols, one, options, 4);
    ExpectWellFormed(r, rows, cols, options);
  }
  // Every observation in one row: the other rows are undetermined, and stay finite.
  std::vector<MatrixEntry> row0;
  for (uint32_t j = 0; j < 30; ++j) row0.push_back({0, j, float(j + 1)});
  const NmfResult r = CompleteNonnegative(30, 30, row0, options, 4);
  ExpectWellFormed(r, 30, 30, options);
}

TEST(NmfHardCases, DuplicateObservationsAreAveragedNotSummed) {
  std::vector<MatrixEntry> observed;
  for (uint32_t i = 0; i < 10; ++i)
    for (uint32_t j = 0; j < 10; ++j) {
      observed.push_back({i, j, 1.f});
      observed.push_back({i, j, 3.f});  // every entry observed twice: mean 2
    }
  NmfOptions options;
  const NmfResult r = CompleteNonnegative(10, 10, observed, options, 1);
  EXPECT_TRUE(r.complete);
  EXPECT_NEAR((r.X * r.Y).maxCoeff(), 2.0, 1e-12);
  EXPECT_NEAR((r.X * r.Y).minCoeff(), 2.0, 1e-12);
}

}  // namespace test_nmf_hard_cases
}  // namespace lightfarm
