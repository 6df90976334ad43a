// Column completion (Huo 2016, Sec. 5.1.1; Krishnamurthy and Singh 2014): exact recovery of
// columns in the span of U from a few of their entries, an orthonormal U after hundreds of
// insertions, finite bounded answers on every degenerate U_Ω, and the energy-loss test (Eq. 16).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "common/matrix/column_completion.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_column_completion {

double Gaussian(Rng& rng) {
  const double u1 = 1.0 - rng.UniformDouble(), u2 = rng.UniformDouble();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

Eigen::MatrixXd RandomMatrix(int rows, int cols, Rng& rng) {
  Eigen::MatrixXd a(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) a(i, j) = Gaussian(rng);
  return a;
}

// `count` distinct entries of [0, n), uniformly.
std::vector<uint32_t> DrawEntries(uint32_t n, uint32_t count, Rng& rng) {
  std::vector<uint32_t> pool(n);
  for (uint32_t i = 0; i < n; ++i) pool[i] = i;
  for (uint32_t i = 0; i < count; ++i) std::swap(pool[i], pool[i + rng.UniformInt(n - i)]);
  pool.resize(count);
  return pool;
}

Eigen::VectorXd Gather(const Eigen::VectorXd& column, const std::vector<uint32_t>& entries) {
  Eigen::VectorXd out(Eigen::Index(entries.size()));
  for (size_t i = 0; i < entries.size(); ++i) out(Eigen::Index(i)) = column(entries[i]);
  return out;
}

double OrthonormalityError(const ColumnCompletion& cc) {
  const Eigen::MatrixXd& u = cc.basis();
  const Eigen::MatrixXd gram = u.transpose() * u;
  return (gram - Eigen::MatrixXd::Identity(gram.rows(), gram.cols())).cwiseAbs().maxCoeff();
}

TEST(ColumnCompletion, RecoversExactLowRankColumnsFromTenToThirtyPercentOfEntries) {
  const int m = 600, r = 8;
  Rng rng(11);
  const Eigen::MatrixXd span = RandomMatrix(m, r, rng);
  ColumnCompletion cc(m);
  // The basis from r fully sampled columns of the span (not the span's own vectors)
  for (int j = 0; j < r; ++j) ASSERT_TRUE(cc.Add(span * RandomMatrix(r, 1, rng)));
  ASSERT_EQ(cc.size(), size_t(r));
  for (double fraction : {0.1, 0.2, 0.3}) {
    for (int trial = 0; trial < 20; ++trial) {
      cc.SetObserved(DrawEntries(m, uint32_t(fraction * m), rng));
      // A nonnegative-and-negative column of the span, with a large dynamic range
      const Eigen::VectorXd column = span * RandomMatrix(r, 1, rng) * std::pow(10.0, trial % 7 - 3);
      const ColumnProjection p = cc.Project(Gather(column, cc.observed()));
      EXPECT_EQ(p.rank, r);
      EXPECT_LT(p.LossFraction(), 1e-8);
      const Eigen::VectorXd rebuilt = cc.Reconstruct(p.coefficients);
      EXPECT_LT((rebuilt - column).norm() / column.norm(), 1e-5) << fraction << " " << trial;
      EXPECT_FALSE(FailsEnergyTest(p, 1.0, 1.0, 1e-6));
    }
  }
  // A column outside the span is not recovered, and says so through its loss
  cc.SetObserved(DrawEntries(m, 60, rng));
  const Eigen::VectorXd outside = RandomMatrix(m, 1, rng);
  const ColumnProjection p = cc.Project(Gather(outside, cc.observed()));
  EXPECT_GT(p.LossFraction(), 0.5);
  EXPECT_TRUE(FailsEnergyTest(p, 1.0, 1.0, 0.005));
}

// Rows whose magnitudes span 12 orders (a bright highlight and dim corners in one slice): the
// basis stays orthonormal and columns of the span are still recovered from 20% of the entries,
// the small entries included (entry-wise relative error).
TEST(ColumnCompletion, RecoversColumnsWhoseEntriesSpanTwelveOrdersOfMagnitude) {
  const int m = 500, r = 6;
  Rng rng(21);
  Eigen::MatrixXd span = RandomMatrix(m, r, rng);
  for (int i = 0; i < m; ++i) span.row(i) *= std::pow(10.0, -6.0 + 12.0 * rng.UniformDouble());
  ColumnCompletion cc(m);
  for (int j = 0; j < r; ++j) ASSERT_TRUE(cc.Add(span * RandomMatrix(r, 1, rng)));
  EXPECT_LT(OrthonormalityError(cc), 1e-6);
  // Only draws where U_Ω has full rank can recover the column (a few rows dominate U)
  int full_rank_draws = 0;
  for (int trial = 0; trial < 20; ++trial) {
    cc.SetObserved(DrawEntries(m, m / 5, rng));
    const Eigen::VectorXd column = span * RandomMatrix(r, 1, rng);
    const ColumnProjection p = cc.Project(Gather(column, cc.observed()));
    ASSERT_TRUE(p.coefficients.allFinite());
    if (p.rank < r) continue;
    ++full_rank_draws;
    const Eigen::VectorXd rebuilt = cc.Reconstruct(p.coefficients);
    EXPECT_LT((rebuilt - column).norm() / column.norm(), 1e-5) << trial;
    // the largest entry-wise error relative to the row's own scale
    double worst = 0;
    for (int i = 0; i < m; ++i)
      worst = std::max(worst, std::abs(rebuilt(i) - column(i)) / span.row(i).norm());
    EXPECT_LT(worst, 1e-3) << trial;
  }
  EXPECT_GE(full_rank_draws, 15);  // measured: 20 of 20
}

TEST(ColumnCompletion, BasisStaysOrthonormalAfterHundredsOfInsertions) {
  const int m = 400;
  Rng rng(5);
  ColumnCompletion cc(m);
  size_t accepted = 0, dropped_exact = 0;
  for (int i = 0; i < 600; ++i) {
    Eigen::VectorXd column;
    const int kind = i % 4;
    if (kind == 0 || cc.size() == 0) {
      column = RandomMatrix(m, 1, rng);  // new direction
    } else if (kind == 1) {
      // nearly dependent: a combination of U plus a 1e-7 relative perturbation
      column = cc.basis() * RandomMatrix(int(cc.size()), 1, rng);
      column += 1e-7 * column.norm() * RandomMatrix(m, 1, rng) / std::sqrt(double(m));
    } else if (kind == 2) {
      // exactly dependent, at a scale 12 orders of magnitude away
      column = 1e12 * cc.basis() * RandomMatrix(int(cc.size()), 1, rng);
    } else {
      // a column with a few huge and many tiny entries
      column = RandomMatrix(m, 1, rng) * 1e-6;
      column.head(3) *= 1e12;
    }
    const size_t before = cc.size();
    const bool added = cc.Add(column);
    EXPECT_EQ(cc.size(), before + (added ? 1 : 0));
    accepted += added;
    if (kind == 2 && i > 0) dropped_exact += !added;
    if (cc.size() == size_t(m)) break;
  }
  EXPECT_GT(accepted, 300u);
  EXPECT_GE(dropped_exact, 100u);  // every exactly dependent column is refused
  EXPECT_LT(OrthonormalityError(cc), 1e-6);
  EXPECT_TRUE(cc.basis().allFinite());
  // Once U spans everything nothing more is added
  while (cc.size() < size_t(m)) ASSERT_TRUE(cc.Add(RandomMatrix(m, 1, rng)));
  EXPECT_FALSE(cc.Add(RandomMatrix(m, 1, rng)));
  EXPECT_LT(OrthonormalityError(cc), 1e-6);
}

TEST(ColumnCompletion, ExactMultiplesZeroAndNonFiniteColumnsAreNotAdded) {
  const int m = 50;
  Rng rng(2);
  ColumnCompletion cc(m);
  const Eigen::VectorXd c = RandomMatrix(m, 1, rng);
  EXPECT_TRUE(cc.Add(c));
  EXPECT_FALSE(cc.Add(1e6 * c));
  EXPECT_FALSE(cc.Add(-1e-6 * c));
  EXPECT_FALSE(cc.Add(Eigen::VectorXd::Zero(m)));
  Eigen::VectorXd bad = RandomMatrix(m, 1, rng);
  bad(3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(cc.Add(bad));
  bad(3) = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(cc.Add(bad));
  EXPECT_EQ(cc.size(), 1u);
  EXPECT_NEAR(cc.basis().col(0).norm(), 1.0, 1e-12);
}

// Every degenerate U_Ω: finite coefficients, bounded by what l_Ω allows, no NaN.
TEST(ColumnCompletion, DegenerateObservationsGiveFiniteBoundedProjections) {
  const int m = 200, k = 10;
  Rng rng(9);
  ColumnCompletion cc(m);
  // Basis vectors supported on the first half only, with magnitudes over 12 orders
  for (int j = 0; j < k; ++j) {
    Eigen::VectorXd c = Eigen::VectorXd::Zero(m);
    c.head(m / 2) = RandomMatrix(m / 2, 1, rng) * std::pow(10.0, 2 * (j % 7) - 6);
    ASSERT_TRUE(cc.Add(c));
  }
  ASSERT_LT(OrthonormalityError(cc), 1e-6);
  const Eigen::VectorXd column = cc.basis() * RandomMatrix(k, 1, rng) * 1e6;

  auto expect_sane = [&](const std::vector<uint32_t>& omega, const char* what) -> ColumnProjection {
    cc.SetObserved(omega);
    const Eigen::VectorXd observed = Gather(column, omega);
    const ColumnProjection p = cc.Project(observed);
    EXPECT_EQ(p.coefficients.size(), k) << what;
    EXPECT_TRUE(p.coefficients.allFinite()) << what;
    EXPECT_TRUE(std::isfinite(p.residual_l1)) << what;
    EXPECT_LE(p.rank, std::min<int>(k, int(omega.size()))) << what;
    // Least squares: the fit on Ω is an orthogonal projection, never more energy than the data
    // (‖U_Ω e‖ ≤ ‖l_Ω‖); the rank-revealing solver keeps only directions with pivots above the
    // tolerance, so the coefficients stay near the column's own (‖Uᵀl‖ = ‖l‖; a 1e4 margin)
    EXPECT_LE(p.coefficients.norm(), 1e4 * column.norm()) << what;
    const Eigen::VectorXd rebuilt = cc.Reconstruct(p.coefficients);
    EXPECT_TRUE(rebuilt.allFinite()) << what;
    EXPECT_LE(Gather(rebuilt, omega).norm(), observed.norm() * (1 + 1e-9) + 1e-300) << what;
    return p;
  };

  // |Ω| < k: fewer equations than unknowns
  expect_sane({3, 17, 40}, "|Ω| < k");
  // One entry observed twenty times
  std::vector<uint32_t> same(20, 7);
  expect_sane(same, "duplicate rows");
  // Every row twice
  std::vector<uint32_t> twice = DrawEntries(m / 2, 30, rng);
  twice.insert(twice.end(), twice.begin(), twice.end());
  expect_sane(twice, "duplicated Ω");
  // U vanishes on Ω (the second half): rank 0, nothing is projected, everything is lost
  std::vector<uint32_t> zero_rows;
  for (uint32_t i = m / 2; i < uint32_t(m); i += 3) zero_rows.push_back(i);
  {
    cc.SetObserved(zero_rows);
    Eigen::VectorXd l = Eigen::VectorXd::Ones(Eigen::Index(zero_rows.size()));
    const ColumnProjection p = cc.Project(l);
    EXPECT_EQ(p.rank, 0);
    EXPECT_EQ(p.coefficients.norm(), 0.0);
    EXPECT_DOUBLE_EQ(p.LossFraction(), 1.0);
    EXPECT_TRUE(FailsEnergyTest(p, 1.0, 1.0, 0.005));
  }
  // Half of Ω on zero rows, half on the support: the supported part is recovered exactly
  {
    std::vector<uint32_t> mixed = DrawEntries(m / 2, 60, rng);
    mixed.insert(mixed.end(), zero_rows.begin(), zero_rows.end());
    const ColumnProjection p = expect_sane(mixed, "zero rows");
    EXPECT_LT((cc.Reconstruct(p.coefficients) - column).norm() / column.norm(), 1e-6);
  }
  // Non-finite observations count as 0
  {
    cc.SetObserved(DrawEntries(m / 2, 40, rng));
    Eigen::VectorXd l = Gather(column, cc.observed());
    l(0) = std::numeric_limits<double>::quiet_NaN();
    l(1) = -std::numeric_limits<double>::infinity();
    const ColumnProjection p = cc.Project(l);
    EXPECT_TRUE(p.coefficients.allFinite());
    EXPECT_TRUE(std::isfinite(p.observed_l1) && std::isfinite(p.residual_l1));
  }
  // A column that is zero on Ω loses nothing and never fails
  {
    cc.SetObserved(DrawEntries(m, 30, rng));
    const ColumnProjection p = cc.Project(Eigen::VectorXd::Zero(30));
    EXPECT_EQ(p.LossFraction(), 0.0);
    EXPECT_FALSE(FailsEnergyTest(p, 0.0, 0.0, 0.0));
  }
  // Broken invariants (CHECK) stop the process with the values compared.
  EXPECT_DEATH(cc.SetObserved({uint32_t(m)}), "CHECK failed: size_t\\(i\\) < length\\(\\)");
  EXPECT_DEATH(cc.Project(Eigen::VectorXd::Zero(3)), "CHECK failed: .*\\(3 vs 30\\)");
}

TEST(ColumnCompletion, EmptyBasisProjectsNothing) {
  ColumnCompletion cc(30);
  cc.SetObserved({1, 2, 3});
  const ColumnProjection p = cc.Project(Eigen::Vector3d(1, -2, 3));
  EXPECT_EQ(p.coefficients.size(), 0);
  EXPECT_DOUBLE_EQ(p.observed_l1, 6.0);
  EXPECT_DOUBLE_EQ(p.residual_l1, 6.0);
  EXPECT_DOUBLE_EQ(p.observed_sum, 2.0);
  EXPECT_EQ(cc.Reconstruct(p.coefficients).norm(), 0.0);
  // With nothing accumulated yet (total 0) any column with energy fails: the first columns
  // build the basis
  EXPECT_TRUE(FailsEnergyTest(p, 1e-30, 0.0, 0.005));
}

TEST(ColumnCompletion, FullObservationIsTheOrthogonalProjection) {
  const int m = 90;
  Rng rng(4);
  ColumnCompletion cc(m);
  for (int j = 0; j < 6; ++j) ASSERT_TRUE(cc.Add(RandomMatrix(m, 1, rng)));
  std::vector<uint32_t> all(m);
  for (int i = 0; i < m; ++i) all[size_t(i)] = uint32_t(i);
  cc.SetObserved(all);
  const Eigen::VectorXd column = RandomMatrix(m, 1, rng);
  const ColumnProjection p = cc.Project(column);
  const Eigen::VectorXd full = cc.ProjectFull(column);
  EXPECT_LT((p.coefficients - full).norm(), 1e-12 * column.norm());
  // The same through the rank-revealing solver (Ω in another order)
  std::reverse(all.begin(), all.end());
  cc.SetObserved(all);
  const ColumnProjection q = cc.Project(Gather(column, all));
  EXPECT_LT((q.coefficients - full).norm(), 1e-10 * column.norm());
}

TEST(ColumnCompletion, CoefficientsFromASmallerBasisStillReconstruct) {
  const int m = 40;
  Rng rng(8);
  ColumnCompletion cc(m);
  ASSERT_TRUE(cc.Add(RandomMatrix(m, 1, rng)));
  ASSERT_TRUE(cc.Add(RandomMatrix(m, 1, rng)));
  const Eigen::VectorXd column = cc.basis() * Eigen::Vector2d(2, -1);
  const Eigen::VectorXd e = cc.ProjectFull(column);
  const double sum = cc.ReconstructedSum(e);
  for (int j = 0; j < 5; ++j) ASSERT_TRUE(cc.Add(RandomMatrix(m, 1, rng)));
  EXPECT_LT((cc.Reconstruct(e) - column).norm(), 1e-12 * column.norm());
  EXPECT_NEAR(cc.ReconstructedSum(e), column.sum(), 1e-12 * column.lpNorm<1>());
  EXPECT_DOUBLE_EQ(cc.ReconstructedSum(e), sum);
  EXPECT_DEATH(cc.Reconstruct(Eigen::VectorXd::Zero(8)), "CHECK failed: coefficients.size\\(\\) <= basis_.cols\\(\\)");
}

// Huo 2016, Eq. 16: loss fraction × column energy against σ × total energy.
TEST(ColumnCompletion, EnergyLossTest) {
  ColumnProjection p;
  p.observed_l1 = 2.0;
  p.residual_l1 = 1.0;                                  // half the energy lost
  EXPECT_FALSE(FailsEnergyTest(p, 1.0, 100.0, 0.005));  // 0.5 ≤ 0.5
  EXPECT_TRUE(FailsEnergyTest(p, 1.01, 100.0, 0.005));  // 0.505 > 0.5
  EXPECT_FALSE(FailsEnergyTest(p, 0.5, 100.0, 0.005));
  EXPECT_TRUE(FailsEnergyTest(p, 1e-12, 100.0, 0.0));  // σ = 0: any loss fails
  p.residual_l1 = 0;
  EXPECT_FALSE(FailsEnergyTest(p, 1e12, 1.0, 0.0));  // nothing lost never fails
}

}  // namespace test_column_completion
}  // namespace lightfarm
