// Alternating direction method for nonnegative matrix completion (Xu, Yin, Wen, Zhang 2011), in
// the form Huo et al. 2015 give in their Appendix A:
//
//   min ½‖XY − Z‖²_F  s.t.  X = U, Y = V, U ≥ 0, V ≥ 0, P_Ω(Z − M) = 0,
//
//   X ← (Z Yᵀ + αU − Λ)(Y Yᵀ + αI)⁻¹
//   Y ← (XᵀX + βI)⁻¹(Xᵀ Z + βV − Π)
//   Z ← XY + P_Ω(M − XY)
//   U ← max(X + Λ/α, 0),  V ← max(Y + Π/β, 0)
//   Λ ← Λ + γα(X − U),    Π ← Π + γβ(Y − V)
//
// (The appendix's "Λ_{k+1} = Λ_{k+1} + …" and "X_{k+1} Z_kᵀ" are typos for Λ_k and X_{k+1}ᵀ Z_k;
// P_Ω keeps the entries on Ω, as the Z update needs.)
//
// Implementation notes:
// - Z is never formed. It is the low-rank product plus a sparse correction on Ω,
//   Z = XY + S with S = P_Ω(M − XY), so Z Yᵀ = X(YYᵀ) + S Yᵀ and Xᵀ Z = (XᵀX_old) Y + Xᵀ S: one
//   iteration costs O((m + n)q² + |Ω|q) instead of O(mnq), and memory is O((m + n)q + |Ω|).
// - The two inverses are q×q symmetric positive definite systems (Gram matrix + αI, α > 0),
//   solved by LDLT; the α, β regularisation keeps them well conditioned even for rank-deficient
//   factors (q larger than the rank of M, or zero columns).
// - Scale: the iteration runs on M D⁻¹, every column divided by the root mean square of its
//   observed entries d_j (computed via the column's max, so it cannot overflow), in double, and
//   Y is scaled back, Y ← Y D (X, Y ≥ 0 stay nonnegative; XY D = M D⁻¹ D). A column observed only
//   as zeros (or not at all) gets the RMS of all of M_Ω. Why per column: the columns of a
//   lighting-matrix slice are lights whose powers can differ by 12 orders of magnitude; on the raw
//   values the least squares of the ADM only sees the brightest columns, the penalties (a fraction
//   of the Gram matrices' mean eigenvalue) are far too large for the dim ones, and the iteration
//   crawls. (docs/methods/nmf-completion.md measures it.)
//   The rank is invariant (M D⁻¹ has M's rank), and a denormal-scale or huge input behaves like
//   a unit-scale one. observed_residual and the
//   convergence test are measured on the scaled matrix (every column's relative fit counts);
//   the returned observed_residual is recomputed on M itself.
//   NmfOptions::scale_columns = false keeps the single global scale (the RMS of M_Ω). The
//   weighting is part of the objective, not only of the iteration: per column, every column's
//   relative fit counts the same; globally, a column counts by its magnitude, which is what
//   row sums need. sparse-completion therefore keeps the global scale (see there).
// - Penalties: a fixed α, β suits neither the matrix's scale nor the balance between X and Y
//   (XY = (XD)(D⁻¹Y) for any diagonal D > 0), and a penalty much larger than an eigenvalue of
//   YYᵀ freezes that component of X at U. So the penalties adapt: α_k = c·tr(Y_k Y_kᵀ)/q,
//   β_k = c·tr(X_{k+1}ᵀ X_{k+1})/q, a fraction c (penalty_scale = 0.1) of the mean eigenvalue of
//   the Gram matrix each is added to (docs/methods/nmf-completion.md measures both). Changing
//   the penalty between iterations is the usual varying-penalty ADMM (Boyd et al. 2011, Sec.
//   3.4.1); the multipliers are kept unscaled.
// - Rank: q is lowered until |Ω| ≥ min_oversampling · q(m + n − q), the degrees of freedom of a
//   rank-q matrix (Xu et al. assume q is an upper bound of M's rank; with too few entries per row
//   the spare components fit Ω and extrapolate noise everywhere else). Never below 1.
// - Robustness: the best nonnegative iterate (U, V) by observed residual is kept and returned, and
//   the iteration stops at the first non-finite value, so no NaN or Inf ever leaves the solver.
#include "common/matrix/nmf_completion.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/util/rng.h"

namespace lightfarm {

namespace {

struct Observation {
  uint32_t row, col;
  double value;
};

// Sorted by (col, row), duplicates averaged, values sanitised to finite and ≥ 0.
std::vector<Observation> CollectObservations(int rows, int cols,
                                             std::span<const MatrixEntry> observed) {
  std::vector<Observation> obs;
  obs.reserve(observed.size());
  for (const MatrixEntry& e : observed) {
    if (e.row >= uint32_t(rows) || e.col >= uint32_t(cols))
      throw std::invalid_argument("CompleteNonnegative: entry (" + std::to_string(e.row) + ", " +
                                  std::to_string(e.col) + ") outside a " + std::to_string(rows) +
                                  "×" + std::to_string(cols) + " matrix");
    const double v = double(e.value);
    obs.push_back({e.row, e.col, std::isfinite(v) && v > 0 ? v : 0.0});
  }
  std::sort(obs.begin(), obs.end(), [](const Observation& a, const Observation& b) {
    return a.col != b.col ? a.col < b.col : a.row < b.row;
  });
  // Merge repeated entries into their mean.
  size_t out = 0;
  for (size_t i = 0; i < obs.size();) {
    size_t j = i;
    double sum = 0;
    for (; j < obs.size() && obs[j].row == obs[i].row && obs[j].col == obs[i].col; ++j)
      sum += obs[j].value;
    obs[out++] = {obs[i].row, obs[i].col, sum / double(j - i)};
    i = j;
  }
  obs.resize(out);
  return obs;
}

bool AllFinite(const Eigen::MatrixXd& a) { return a.allFinite(); }

// The per-entry kernels on length-q columns: plain loops, which the compiler vectorises, are
// several times faster here than Eigen's dynamic-size column expressions.
double Dot(int q, const double* a, const double* b) {
  double sum = 0;
  for (int k = 0; k < q; ++k) sum += a[k] * b[k];
  return sum;
}
void Axpy(int q, double s, const double* x, double* y) {
  for (int k = 0; k < q; ++k) y[k] += s * x[k];
}

// penalty_scale × the mean eigenvalue of a q×q Gram matrix, kept away from 0 so that the system
// it regularises stays positive definite and U = P₊(X + Λ/α) stays finite.
double AdaptivePenalty(double penalty_scale, const Eigen::MatrixXd& gram) {
  return std::max(1e-12, penalty_scale * gram.trace() / double(gram.rows()));
}

// Root mean square of obs[begin, end)'s values, via their max so that it cannot overflow.
double RootMeanSquare(const std::vector<Observation>& obs, size_t begin, size_t end) {
  double max_value = 0;
  for (size_t e = begin; e < end; ++e) max_value = std::max(max_value, obs[e].value);
  if (max_value == 0) return 0;
  double mean_square = 0;
  for (size_t e = begin; e < end; ++e)
    mean_square += (obs[e].value / max_value) * (obs[e].value / max_value);
  return max_value * std::sqrt(mean_square / double(end - begin));
}

}  // namespace

NmfResult CompleteNonnegative(int rows, int cols, std::span<const MatrixEntry> observed,
                              const NmfOptions& options, uint64_t seed) {
  // Validate the options
  if (rows < 0 || cols < 0)
    throw std::invalid_argument("CompleteNonnegative: negative matrix size");
  if (options.rank < 1)
    throw std::invalid_argument("CompleteNonnegative: rank must be >= 1, got " +
                                std::to_string(options.rank));
  if (options.max_iterations < 0)
    throw std::invalid_argument("CompleteNonnegative: max_iterations must be >= 0");
  if (!(options.gamma > 0 && options.gamma < 1.6180339887498949))
    throw std::invalid_argument("CompleteNonnegative: gamma must lie in (0, 1.618…), got " +
                                std::to_string(options.gamma));
  if (!(options.tolerance >= 0) || !(options.alpha >= 0) || !(options.beta >= 0) ||
      !(options.penalty_scale > 0) || !(options.min_oversampling >= 0))
    throw std::invalid_argument(
        "CompleteNonnegative: tolerance, alpha, beta, min_oversampling must be >= 0 and "
        "penalty_scale > 0");

  const std::vector<Observation> obs = CollectObservations(rows, cols, observed);
  // Rank: at most the matrix's, and at most what the observations determine: a rank-q matrix
  // has q(m + n − q) degrees of freedom, which the observed entries must outnumber
  // min_oversampling times (else the factors fit Ω and extrapolate freely elsewhere).
  int q = std::min({options.rank, rows, cols});
  if (options.min_oversampling > 0)
    while (q > 1 && options.min_oversampling * double(q) * double(rows + cols - q) >
                        double(obs.size()))
      --q;
  NmfResult result;
  result.X = Eigen::MatrixXd::Zero(rows, q);
  result.Y = Eigen::MatrixXd::Zero(q, cols);
  if (q == 0) return result;

  // Every entry observed: M itself is an exact nonnegative factorisation (with I)
  if (obs.size() == size_t(rows) * size_t(cols)) {
    Eigen::MatrixXd m(rows, cols);
    for (const Observation& o : obs) m(o.row, o.col) = o.value;
    if (cols <= rows) {
      result.X = std::move(m);
      result.Y = Eigen::MatrixXd::Identity(cols, cols);
    } else {
      result.X = Eigen::MatrixXd::Identity(rows, rows);
      result.Y = std::move(m);
    }
    result.complete = true;
    return result;
  }

  // Normalise the observed values to unit root mean square, per column (see the file comment)
  const size_t nobs = obs.size();
  const double scale = RootMeanSquare(obs, 0, nobs);
  if (scale == 0) return result;  // nothing but zeros observed: the zero matrix fits exactly
  Eigen::VectorXd column_scale = Eigen::VectorXd::Constant(cols, scale);
  if (options.scale_columns)
    for (size_t begin = 0; begin < nobs;) {  // obs is sorted by column
      size_t end = begin;
      while (end < nobs && obs[end].col == obs[begin].col) ++end;
      const double d = RootMeanSquare(obs, begin, end);
      if (d > 0) column_scale(obs[begin].col) = d;
      begin = end;
    }
  std::vector<double> value(nobs);
  double norm_m2 = 0, mean_value = 0;
  for (size_t e = 0; e < nobs; ++e) {
    value[e] = obs[e].value / column_scale(obs[e].col);
    norm_m2 += value[e] * value[e];
    mean_value += value[e];
  }
  mean_value /= double(nobs);
  const double norm_m = std::sqrt(norm_m2);

  // Penalties: fixed when given, else a fixed fraction of the mean eigenvalue of the Gram matrix
  // they regularise, recomputed every iteration (see the file comment)
  const bool adaptive_alpha = !(options.alpha > 0), adaptive_beta = !(options.beta > 0);
  double alpha = options.alpha, beta = options.beta;
  const double gamma = options.gamma;

  // Random nonnegative start with E[XY] = mean observed value: entries uniform in [0, c) give
  // E[(XY)_ij] = q c²/4.
  // Factors are kept as Xt = Xᵀ (q×m) and Y (q×n), column-major, so that the row of X and the
  // column of Y an entry needs are both contiguous.
  Rng rng(seed, uint64_t(RngStream::kCompletion));
  const double c = std::sqrt(4.0 * mean_value / double(q));
  Eigen::MatrixXd Xt(q, rows), Y(q, cols);
  for (Eigen::Index j = 0; j < Xt.cols(); ++j)
    for (int k = 0; k < q; ++k) Xt(k, j) = c * rng.UniformDouble();
  for (Eigen::Index j = 0; j < Y.cols(); ++j)
    for (int k = 0; k < q; ++k) Y(k, j) = c * rng.UniformDouble();
  Eigen::MatrixXd Ut = Xt, V = Y;
  Eigen::MatrixXd Lt = Eigen::MatrixXd::Zero(q, rows), Pi = Eigen::MatrixXd::Zero(q, cols);
  const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(q, q);

  // S = P_Ω(M − XY), the sparse part of Z
  std::vector<double> s(nobs);
  auto update_correction = [&] {
    for (size_t e = 0; e < nobs; ++e)
      s[e] = value[e] - Dot(q, Xt.col(obs[e].row).data(), Y.col(obs[e].col).data());
  };
  // ‖P_Ω(UV − M)‖_F / ‖P_Ω(M)‖_F
  auto observed_residual = [&](const Eigen::MatrixXd& ut, const Eigen::MatrixXd& v) {
    double r2 = 0;
    for (size_t e = 0; e < nobs; ++e) {
      const double d = value[e] - Dot(q, ut.col(obs[e].row).data(), v.col(obs[e].col).data());
      r2 += d * d;
    }
    return std::sqrt(r2) / norm_m;
  };
  update_correction();

  Eigen::MatrixXd best_Ut = Ut, best_V = V;
  double best_residual = observed_residual(Ut, V);
  double previous_residual = best_residual;
  int iterations = 0;
  Eigen::MatrixXd At(q, rows), B(q, cols);
  for (int k = 0; k < options.max_iterations; ++k) {
    // X update: Xᵀ = (YYᵀ + αI)⁻¹ (Y Zᵀ + αUᵀ − Λᵀ), with Y Zᵀ = (YYᵀ)Xᵀ + Y Sᵀ
    const Eigen::MatrixXd yyt = Y * Y.transpose();
    if (adaptive_alpha) alpha = AdaptivePenalty(options.penalty_scale, yyt);
    At.noalias() = yyt * Xt;
    for (size_t e = 0; e < nobs; ++e)
      Axpy(q, s[e], Y.col(obs[e].col).data(), At.col(obs[e].row).data());
    At += alpha * Ut - Lt;
    Eigen::MatrixXd Xt_new = (yyt + alpha * identity).ldlt().solve(At);

    // Y update: Y = (XᵀX + βI)⁻¹ (Xᵀ Z + βV − Π), with Xᵀ Z = (Xᵀ X_old) Y + Xᵀ S
    const Eigen::MatrixXd xtx = Xt_new * Xt_new.transpose();
    if (adaptive_beta) beta = AdaptivePenalty(options.penalty_scale, xtx);
    B.noalias() = (Xt_new * Xt.transpose()) * Y;
    for (size_t e = 0; e < nobs; ++e)
      Axpy(q, s[e], Xt_new.col(obs[e].row).data(), B.col(obs[e].col).data());
    B += beta * V - Pi;
    Eigen::MatrixXd Y_new = (xtx + beta * identity).ldlt().solve(B);
    if (!AllFinite(Xt_new) || !AllFinite(Y_new)) break;
    Xt = std::move(Xt_new);
    Y = std::move(Y_new);

    // Z update (its sparse part), projections onto the nonnegative orthant, multipliers
    update_correction();
    Ut = (Xt + Lt / alpha).cwiseMax(0.0);
    V = (Y + Pi / beta).cwiseMax(0.0);
    Lt += (gamma * alpha) * (Xt - Ut);
    Pi += (gamma * beta) * (Y - V);
    iterations = k + 1;

    // Convergence on the observed residual of the nonnegative factors
    const double residual = observed_residual(Ut, V);
    if (!std::isfinite(residual)) break;
    if (residual < best_residual) {
      best_residual = residual;
      best_Ut = Ut;
      best_V = V;
    }
    if (residual < options.tolerance ||
        std::abs(previous_residual - residual) < options.tolerance * previous_residual)
      break;
    previous_residual = residual;
  }

  // Undo the normalisation: the global scale half on each factor (neither overflows), the
  // columns' own scales relative to it on Y
  const double root = std::sqrt(scale);
  result.X = best_Ut.transpose() * root;
  result.Y = best_V * root;
  if (options.scale_columns)
    for (int j = 0; j < cols; ++j) result.Y.col(j) *= column_scale(j) / scale;
  result.iterations = iterations;
  // The residual on M itself, relative to the largest value so that its squares cannot overflow
  double max_value = 0;
  for (const Observation& o : obs) max_value = std::max(max_value, o.value);
  double r2 = 0, m2 = 0;
  for (const Observation& o : obs) {
    const double fitted = result.X.row(o.row).dot(result.Y.col(o.col));
    r2 += ((fitted - o.value) / max_value) * ((fitted - o.value) / max_value);
    m2 += (o.value / max_value) * (o.value / max_value);
  }
  result.observed_residual = std::isfinite(r2) ? std::sqrt(r2 / m2) : best_residual;
  return result;
}

Eigen::VectorXd FactoredRowSums(const NmfResult& result) {
  const Eigen::VectorXd column_sums = result.Y.rowwise().sum();  // Y·1
  return result.X * column_sums;
}

}  // namespace lightfarm
