// Nonnegative matrix completion (Xu et al. 2011 ADM): exact recovery of a low-rank matrix from a
// fraction of its entries, and well-defined answers on every degenerate input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "common/matrix/nmf_completion.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_nmf_completion {

double Gaussian(Rng& rng) {
  const double u1 = 1.0 - rng.UniformDouble(), u2 = rng.UniformDouble();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

// A nonnegative rank-r matrix with sparse nonnegative factors (half their entries zero), the
// kind of test problem Xu et al. use.
Eigen::MatrixXd RandomNonnegativeLowRank(int m, int n, int r, uint64_t seed) {
  Rng rng(seed, 1);
  Eigen::MatrixXd a(m, r), b(r, n);
  for (int i = 0; i < m; ++i)
    for (int k = 0; k < r; ++k) a(i, k) = std::max(0.0, Gaussian(rng));
  for (int k = 0; k < r; ++k)
    for (int j = 0; j < n; ++j) b(k, j) = std::max(0.0, Gaussian(rng));
  return a * b;
}

std::vector<MatrixEntry> Sample(const Eigen::MatrixXd& m, double fraction, uint64_t seed) {
  Rng rng(seed, 2);
  std::vector<MatrixEntry> out;
  for (int i = 0; i < m.rows(); ++i)
    for (int j = 0; j < m.cols(); ++j)
      if (rng.UniformDouble() < fraction) out.push_back({uint32_t(i), uint32_t(j), float(m(i, j))});
  return out;
}

std::vector<MatrixEntry> All(const Eigen::MatrixXd& m) { return Sample(m, 2.0, 0); }

// Finite, nonnegative factors of the documented shapes.
void ExpectWellFormed(const NmfResult& r, int rows, int cols) {
  EXPECT_EQ(r.X.rows(), rows);
  EXPECT_EQ(r.Y.cols(), cols);
  EXPECT_EQ(r.X.cols(), r.Y.rows());
  EXPECT_TRUE(r.X.allFinite());
  EXPECT_TRUE(r.Y.allFinite());
  if (r.X.size() > 0) {
    EXPECT_GE(r.X.minCoeff(), 0.0);
  }
  if (r.Y.size() > 0) {
    EXPECT_GE(r.Y.minCoeff(), 0.0);
  }
  EXPECT_TRUE(std::isfinite(r.observed_residual));
}

TEST(NmfCompletion, RecoversExactLowRankMatrixFromThirtyPercentOfEntries) {
  const int m = 200, n = 150, r = 8;
  const Eigen::MatrixXd truth = RandomNonnegativeLowRank(m, n, r, 11);
  const std::vector<MatrixEntry> observed = Sample(truth, 0.3, 12);
  NmfOptions options;
  options.rank = r;
  // The ADM converges linearly after a start-up phase: measured relative errors on this problem
  // are 5e-2 after 50 iterations, 3e-3 after 100, 3e-4 after 150, 2e-6 after 276 (converged).
  options.max_iterations = 300;
  options.tolerance = 1e-6;
  NmfResult result = CompleteNonnegative(m, n, observed, options, 5);
  ExpectWellFormed(result, m, n);
  EXPECT_EQ(result.X.cols(), r);
  EXPECT_FALSE(result.complete);
  const double rel = (result.X * result.Y - truth).norm() / truth.norm();
  EXPECT_LT(rel, 1e-3);
  EXPECT_LT(result.observed_residual, 1e-3);
  // The factored row sums are the completed matrix's row sums.
  const Eigen::VectorXd sums = FactoredRowSums(result);
  EXPECT_LT((sums - truth.rowwise().sum()).norm() / truth.rowwise().sum().norm(), 1e-3);
}

TEST(NmfCompletion, DefaultIterationBudgetStopsAtItsLimitAndImproves) {
  const Eigen::MatrixXd truth = RandomNonnegativeLowRank(120, 100, 6, 21);
  const std::vector<MatrixEntry> observed = Sample(truth, 0.3, 22);
  NmfOptions options;
  options.rank = 6;
  options.tolerance = 0;  // run the whole budget
  NmfOptions few = options;
  few.max_iterations = 5;
  NmfResult a = CompleteNonnegative(120, 100, observed, few, 1);
  NmfResult b = CompleteNonnegative(120, 100, observed, options, 1);
  EXPECT_EQ(a.iterations, 5);
  EXPECT_EQ(b.iterations, 100);
  EXPECT_LT(b.observed_residual, 0.1 * a.observed_residual);
}

TEST(NmfCompletion, SameSeedGivesTheSameBits) {
  const Eigen::MatrixXd truth = RandomNonnegativeLowRank(60, 50, 4, 31);
  const std::vector<MatrixEntry> observed = Sample(truth, 0.4, 32);
  NmfOptions options;
  options.rank = 4;
  NmfResult a = CompleteNonnegative(60, 50, observed, options, 9);
  NmfResult b = CompleteNonnegative(60, 50, observed, options, 9);
  EXPECT_EQ(a.X, b.X);
  EXPECT_EQ(a.Y, b.Y);
}

TEST(NmfCompletion, CompletelyObservedMatrixIsReproducedExactly) {
  Rng rng(3, 3);
  Eigen::MatrixXd m(7, 5);
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j < 5; ++j) m(i, j) = double(rng.Uniform());
  for (const Eigen::MatrixXd& mat : {m, Eigen::MatrixXd(m.transpose())}) {
    NmfResult r = CompleteNonnegative(int(mat.rows()), int(mat.cols()), All(mat), NmfOptions{}, 0);
    ExpectWellFormed(r, int(mat.rows()), int(mat.cols()));
    EXPECT_TRUE(r.complete);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(r.X * r.Y, mat);  // exact: one factor is the identity
    EXPECT_EQ(FactoredRowSums(r), mat.rowwise().sum());
  }
}

TEST(NmfCompletion, AllZeroAndEmptyObservationsGiveTheZeroMatrix) {
  const Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(40, 30);
  for (const std::vector<MatrixEntry>& obs : {Sample(zero, 0.3, 1), std::vector<MatrixEntry>{}}) {
    NmfResult r = CompleteNonnegative(40, 30, obs, NmfOptions{}, 0);
    ExpectWellFormed(r, 40, 30);
    EXPECT_EQ((r.X * r.Y).cwiseAbs().maxCoeff(), 0.0);
    EXPECT_EQ(r.observed_residual, 0.0);
  }
}

TEST(NmfCompletion, RankOneMatrixIsFittedAtItsRankAndAtALargerOne) {
  Eigen::VectorXd u = Eigen::VectorXd::LinSpaced(200, 0.1, 2.0);
  Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(150, 3.0, 0.5);
  const Eigen::MatrixXd m = u * v.transpose();
  const std::vector<MatrixEntry> observed = Sample(m, 0.3, 4);
  NmfOptions exact;
  exact.rank = 1;
  NmfResult r1 = CompleteNonnegative(200, 150, observed, exact, 2);
  ExpectWellFormed(r1, 200, 150);
  EXPECT_LT((r1.X * r1.Y - m).norm() / m.norm(), 1e-3);
  // Rank 16, capped by the oversampling rule (|Ω| ≥ 2 q (m + n − q); ~9000 entries allow 13),
  // fits Ω just as well but, without regularisation, the spare components extrapolate: measured
  // relative error 0.09 off Ω.
  NmfResult r16 = CompleteNonnegative(200, 150, observed, NmfOptions{}, 2);
  ExpectWellFormed(r16, 200, 150);
  int allowed = 16;
  while (2.0 * allowed * (350 - allowed) > double(observed.size())) --allowed;
  EXPECT_EQ(r16.X.cols(), allowed);
  EXPECT_GE(allowed, 10);
  EXPECT_LT(r16.observed_residual, 0.02);
  EXPECT_LT((r16.X * r16.Y - m).norm() / m.norm(), 0.15);
}

TEST(NmfCompletion, FullRankNoiseTerminatesWithFiniteNonnegativeFactors) {
  Rng rng(5, 5);
  Eigen::MatrixXd m(60, 45);
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 45; ++j) m(i, j) = double(rng.Uniform());
  NmfOptions options;
  options.rank = 4;
  NmfResult r = CompleteNonnegative(60, 45, Sample(m, 0.5, 6), options, 3);
  ExpectWellFormed(r, 60, 45);
  EXPECT_LE(r.iterations, options.max_iterations);
  // A rank-4 fit of uniform noise cannot be exact, but it does capture the mean.
  EXPECT_GT(r.observed_residual, 0.05);
  EXPECT_LT(r.observed_residual, 0.6);
}

TEST(NmfCompletion, RankIsClampedToTheMatrixAndToTheObservations) {
  const Eigen::MatrixXd m = RandomNonnegativeLowRank(5, 7, 2, 41);
  const std::vector<MatrixEntry> observed = Sample(m, 0.6, 42);
  ASSERT_EQ(observed.size(), 21u);
  NmfOptions options;
  options.rank = 16;
  options.min_oversampling = 0;  // only rank ≤ min(m, n)
  NmfResult r = CompleteNonnegative(5, 7, observed, options, 4);
  ExpectWellFormed(r, 5, 7);
  EXPECT_EQ(r.X.cols(), 5);
  EXPECT_FALSE(r.complete);
  EXPECT_LT(r.observed_residual, 0.05);
  // 21 entries determine no more than rank 1 at the default oversampling of 2 (1·11·2 > 21 is
  // the floor: the rank never drops below 1).
  NmfResult capped = CompleteNonnegative(5, 7, observed, NmfOptions{}, 4);
  ExpectWellFormed(capped, 5, 7);
  EXPECT_EQ(capped.X.cols(), 1);
  // Degenerate shapes.
  ExpectWellFormed(CompleteNonnegative(1, 1, std::vector<MatrixEntry>{}, options, 0), 1, 1);
  ExpectWellFormed(CompleteNonnegative(0, 9, std::vector<MatrixEntry>{}, options, 0), 0, 9);
}

TEST(NmfCompletion, DenormalAndHugeScalesBehaveLikeUnitScale) {
  const Eigen::MatrixXd unit = RandomNonnegativeLowRank(80, 60, 3, 51);
  const std::vector<MatrixEntry> observed = Sample(unit, 0.4, 52);
  NmfOptions options;
  options.rank = 3;
  NmfResult reference = CompleteNonnegative(80, 60, observed, options, 6);
  ASSERT_LT(reference.observed_residual, 0.01);
  // Scale by a power of two so that the float inputs are exactly scaled copies; 2^-140 puts most
  // entries among float denormals (below 2^-126), 2^100 near the top of the float range.
  for (float scale : {std::ldexp(1.f, -140), std::ldexp(1.f, 100)}) {
    std::vector<MatrixEntry> scaled = observed;
    for (MatrixEntry& e : scaled) e.value *= scale;
    NmfResult r = CompleteNonnegative(80, 60, scaled, options, 6);
    ExpectWellFormed(r, 80, 60);
    // Denormals lose mantissa bits, so compare residuals loosely.
    EXPECT_NEAR(r.observed_residual, reference.observed_residual, 0.01) << scale;
    const double rel = (r.X * r.Y / double(scale) - unit).norm() / unit.norm();
    EXPECT_LT(rel, 0.05) << scale;
  }
}

TEST(NmfCompletion, AFewHugeEntriesAndBadValuesStayFinite) {
  const Eigen::MatrixXd unit = RandomNonnegativeLowRank(50, 40, 3, 61);
  std::vector<MatrixEntry> observed = Sample(unit, 0.4, 62);
  observed[3].value = 3e38f;
  observed[10].value = 1e30f;
  observed[20].value = std::numeric_limits<float>::quiet_NaN();
  observed[21].value = std::numeric_limits<float>::infinity();
  observed[22].value = -5.f;
  observed.push_back(observed[5]);  // a repeated entry
  NmfResult r = CompleteNonnegative(50, 40, observed, NmfOptions{}, 7);
  ExpectWellFormed(r, 50, 40);
  // The fit is dominated by the 3e38 entry, which it must reproduce.
  const MatrixEntry& e = observed[3];
  EXPECT_NEAR(r.X.row(e.row).dot(r.Y.col(e.col)) / 3e38, 1.0, 0.05);
  EXPECT_TRUE((r.X * r.Y).allFinite());
}

TEST(NmfCompletion, InvalidArgumentsThrow) {
  std::vector<MatrixEntry> outside = {{10, 0, 1.f}};
  EXPECT_THROW(CompleteNonnegative(5, 5, outside, NmfOptions{}, 0), std::invalid_argument);
  NmfOptions bad;
  bad.gamma = 1.7;
  EXPECT_THROW(CompleteNonnegative(5, 5, std::vector<MatrixEntry>{}, bad, 0),
               std::invalid_argument);
  bad = NmfOptions{};
  bad.rank = 0;
  EXPECT_THROW(CompleteNonnegative(5, 5, std::vector<MatrixEntry>{}, bad, 0),
               std::invalid_argument);
}

}  // namespace test_nmf_completion
}  // namespace lightfarm
