#include "common/matrix/column_completion.h"

#include <cmath>

#include "common/util/check.h"

namespace lightfarm {

namespace {

Eigen::VectorXd FiniteOrZero(const Eigen::VectorXd& v) {
  return v.unaryExpr([](double x) { return std::isfinite(x) ? x : 0.0; });
}

}  // namespace

ColumnCompletion::ColumnCompletion(size_t length, const ColumnCompletionOptions& options)
    : options_(options), basis_(Eigen::Index(length), 0), basis_sums_(0) {
  CHECK(options.drop_tolerance >= 0 && options.rank_tolerance >= 0);
}

void ColumnCompletion::SetObserved(std::vector<uint32_t> indices) {
  for (uint32_t i : indices) CHECK_LT(size_t(i), length());
  observed_ = std::move(indices);
  factored_ = false;
  // Ω = every entry once, in order: U_Ω = U, orthonormal, and the least squares is Uᵀl
  observes_all_ = observed_.size() == length();
  for (size_t i = 0; observes_all_ && i < observed_.size(); ++i) observes_all_ = observed_[i] == i;
}

bool ColumnCompletion::Add(const Eigen::VectorXd& column) {
  CHECK_EQ(column.size(), basis_.rows());
  if (!column.allFinite()) return false;
  const double norm = column.stableNorm();
  if (!(norm > 0)) return false;
  // Scale first so that the squares below neither overflow nor underflow.
  Eigen::VectorXd residual = column / norm;
  // Re-orthogonalised classical Gram–Schmidt: the second pass removes what rounding left of U's
  // directions after the first, so U stays orthonormal to rounding for nearly dependent columns.
  for (int pass = 0; pass < 2 && size() > 0; ++pass)
    residual -= basis_ * (basis_.transpose() * residual);
  const double left = residual.norm();
  if (!(left > options_.drop_tolerance)) return false;
  residual /= left;
  basis_.conservativeResize(Eigen::NoChange, basis_.cols() + 1);
  basis_.col(basis_.cols() - 1) = residual;
  basis_sums_.conservativeResize(basis_sums_.size() + 1);
  basis_sums_(basis_sums_.size() - 1) = residual.sum();
  factored_ = false;
  return true;
}

void ColumnCompletion::Factor() const {
  if (factored_) return;
  factored_ = true;
  q_.resize(Eigen::Index(observed_.size()), 0);
  r_.resize(0, 0);
  permutation_.resize(0);
  if (size() == 0 || observed_.empty() || observes_all_) return;
  Eigen::MatrixXd sub(Eigen::Index(observed_.size()), basis_.cols());
  for (size_t r = 0; r < observed_.size(); ++r) sub.row(Eigen::Index(r)) = basis_.row(observed_[r]);
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(sub.rows(), sub.cols());
  qr.setThreshold(options_.rank_tolerance);
  qr.compute(sub);
  const Eigen::Index rank = qr.rank();
  q_ = qr.householderQ() * Eigen::MatrixXd::Identity(sub.rows(), rank);
  r_ = qr.matrixR().topLeftCorner(rank, rank).triangularView<Eigen::Upper>();
  permutation_ = qr.colsPermutation().indices().head(rank);
}

ColumnProjection ColumnCompletion::Project(const Eigen::VectorXd& observed_values) const {
  CHECK_EQ(size_t(observed_values.size()), observed_.size());  // one value per index of Ω
  Factor();
  const Eigen::VectorXd values = FiniteOrZero(observed_values);
  ColumnProjection p;
  p.observed_l1 = values.lpNorm<1>();
  p.observed_sum = values.sum();
  p.coefficients = Eigen::VectorXd::Zero(basis_.cols());
  if (size() == 0 || observed_.empty()) {
    p.residual_l1 = p.observed_l1;
    return p;
  }
  // Huo 2016, Eq. 13: e = argmin ‖U_Ω e − l_Ω‖₂, restricted to U_Ω's numerical rank
  if (observes_all_) {
    p.rank = int(size());
    p.coefficients = basis_.transpose() * values;
    p.residual_l1 = (values - basis_ * p.coefficients).lpNorm<1>();
    return p;
  }
  p.rank = int(q_.cols());
  const Eigen::VectorXd c = q_.transpose() * values;
  const Eigen::VectorXd y = r_.triangularView<Eigen::Upper>().solve(c);
  if (y.allFinite())  // cannot fail with pivots above the threshold; never propagate NaN
    for (Eigen::Index i = 0; i < y.size(); ++i) p.coefficients(permutation_(i)) = y(i);
  p.residual_l1 = (values - q_ * c).lpNorm<1>();
  return p;
}

Eigen::VectorXd ColumnCompletion::ProjectFull(const Eigen::VectorXd& column) const {
  CHECK_EQ(column.size(), basis_.rows());
  return basis_.transpose() * FiniteOrZero(column);
}

Eigen::VectorXd ColumnCompletion::Reconstruct(const Eigen::VectorXd& coefficients) const {
  CHECK_LE(coefficients.size(), basis_.cols());
  return basis_.leftCols(coefficients.size()) * coefficients;
}

double ColumnCompletion::ReconstructedSum(const Eigen::VectorXd& coefficients) const {
  CHECK_LE(coefficients.size(), basis_sums_.size());
  return basis_sums_.head(coefficients.size()).dot(coefficients);
}

bool FailsEnergyTest(const ColumnProjection& projection, double column_energy, double total_energy,
                     double sigma) {
  // Huo 2016, Eq. 16 (row-space form, see the header)
  const double lost = projection.LossFraction() * std::abs(column_energy);
  return lost > sigma * std::abs(total_energy);
}

}  // namespace lightfarm
