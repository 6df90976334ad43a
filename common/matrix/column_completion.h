// Column completion of Huo, Wang, Hu, Hua, Bao 2016 (Sec. 5.1.1, Algorithm 2), after the adaptive
// matrix completion of Krishnamurthy and Singh 2014: an orthonormal basis U (length × k) of the
// columns seen so far; a new column observed on a few entries Ω is projected onto U_Ω by least
// squares (Eq. 13) and reconstructed as U·e; when the projection loses too much of the column's
// energy (Eq. 16) the caller samples the column fully and adds it to U.
//
// The class works on real vectors of any length. Colour is the caller's business:
// adaptive-completion stacks a column's three channels into one vector of length 3·rows
// (interleaved per row), so one coefficient vector e serves the three channels, Ω draws whole
// rows (their three entries) and the energy test weighs the channels together. A white light on
// coloured receivers then keeps the rank of the geometry (per-channel bases would need up to
// three directions for it); lights of differing colours add at most three directions per shape.
//
// Numerics. U grows by classical Gram–Schmidt applied twice ("twice is enough"), which keeps
// ‖UᵀU − I‖ at rounding level for any insertion order; a column whose residual after the two
// passes is below drop_tolerance·‖column‖ (zero, or dependent on U to that precision) is not
// added. The least squares of Eq. 13 never forms (U_ΩᵀU_Ω)⁻¹: U_Ω is factored once per (Ω, U)
// by Householder QR with column pivoting, U_Ω Π = Q R, whose numerical rank r counts the pivots
// |R_ii| above rank_tolerance · |R_00|. The solution keeps the r pivoted columns,
// e_Π = R_r⁻¹ Q_rᵀ l_Ω (back substitution) and 0 for the others: the basic least-squares
// solution, bounded by ‖l_Ω‖ / (rank_tolerance · |R_00|) when U_Ω is rank deficient (|Ω| < k,
// repeated or zero rows, a basis direction that vanishes on Ω). The thin Q_r is formed once per
// factorisation so that a projection costs two matrix-vector products. Everything is double:
// elements span many orders of magnitude.
#pragma once

#include <Eigen/Core>
#include <Eigen/QR>
#include <cstdint>
#include <span>
#include <vector>

namespace lightfarm {

struct ColumnCompletionOptions {
  // A column whose residual after re-orthogonalisation is below this fraction of its norm is
  // not added to U.
  double drop_tolerance = 1e-9;
  // Pivots of U_Ω below this fraction of the largest are treated as zero (rank of U_Ω).
  double rank_tolerance = 1e-8;
};

// The projection of a partially observed column onto U_Ω (Huo 2016, Eq. 13: e = E_Ω(l_Ω)).
struct ColumnProjection {
  Eigen::VectorXd coefficients;  // e, length k (the basis size at projection time)
  double observed_l1 = 0;        // ‖l_Ω‖₁
  double residual_l1 = 0;        // ‖l_Ω − U_Ω e‖₁
  double observed_sum = 0;       // Σ l_Ω (the column's energy on Ω for a nonnegative column)
  int rank = 0;                  // numerical rank of U_Ω
  // ‖l_Ω − U_Ω e‖₁ / ‖l_Ω‖₁, the share of the observed energy the projection loses (Eq. 16);
  // 0 for a column that is zero on Ω.
  double LossFraction() const { return observed_l1 > 0 ? residual_l1 / observed_l1 : 0.0; }
};

class ColumnCompletion {
 public:
  explicit ColumnCompletion(size_t length, const ColumnCompletionOptions& options = {});

  size_t length() const { return size_t(basis_.rows()); }
  size_t size() const { return size_t(basis_.cols()); }  // k
  const Eigen::MatrixXd& basis() const { return basis_; }
  const std::vector<uint32_t>& observed() const { return observed_; }

  // Sets Ω (entry indices < length; repeats allowed, order defines the order of l_Ω).
  // An index outside the column is a broken invariant (CHECK).
  void SetObserved(std::vector<uint32_t> indices);

  // Adds the part of `column` (length()) orthogonal to U, normalised. Returns false (U
  // unchanged) when that part is below drop_tolerance·‖column‖ or the column is not finite.
  bool Add(const Eigen::VectorXd& column);

  // Least-squares projection of l_Ω (values at observed(), in that order) onto U_Ω (Eq. 13).
  // Non-finite values are treated as 0.
  ColumnProjection Project(const Eigen::VectorXd& observed_values) const;
  // Projection of a fully known column: e = Uᵀl (exact least squares, U orthonormal).
  Eigen::VectorXd ProjectFull(const Eigen::VectorXd& column) const;
  // U·e; a shorter e (computed before U grew) is padded with zeros.
  Eigen::VectorXd Reconstruct(const Eigen::VectorXd& coefficients) const;
  // Σ_i (U·e)_i in O(k): the energy of a reconstructed column (Σ_i U_i kept per basis vector).
  double ReconstructedSum(const Eigen::VectorXd& coefficients) const;

 private:
  void Factor() const;  // caches the decomposition of U_Ω; U and Ω are unchanged

  ColumnCompletionOptions options_;
  Eigen::MatrixXd basis_;       // length × k, orthonormal columns
  Eigen::VectorXd basis_sums_;  // Σ_i U(i, j) per column j
  std::vector<uint32_t> observed_;
  bool observes_all_ = false;  // Ω = (0, 1, …, length − 1)
  // U_Ω Π = Q R, kept as its rank-r parts
  mutable Eigen::MatrixXd q_;            // |Ω| × r, orthonormal columns
  mutable Eigen::MatrixXd r_;            // r × r, upper triangular
  mutable Eigen::VectorXi permutation_;  // Π: column i of Q R is column permutation_(i) of U_Ω
  mutable bool factored_ = false;
};

// Huo 2016, Eq. 16, in row space: the column fails (must be sampled fully) when
//   (‖l_Ω − U_Ω e‖₁ / ‖l_Ω‖₁) · column_energy > σ · total_energy,
// with column_energy the column's estimated contribution to the slice's sum (its energy scaled
// to every row and divided by its sampling probability) and total_energy that of the current
// cut, Σ_i (U e_all)_i. The paper weighs the loss by ‖e‖₁, the column's projection; a column
// orthogonal to U on Ω has e = 0 and would always pass although it is exactly the column U is
// missing, so the weight here is the column's observed energy, in the same (row) space as the
// total. With σ = 0 every column that loses anything fails; a column zero on Ω never does.
bool FailsEnergyTest(const ColumnProjection& projection, double column_energy, double total_energy,
                     double sigma);

}  // namespace lightfarm
