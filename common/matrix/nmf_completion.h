// Nonnegative low-rank matrix completion: M ≈ X·Y with X ≥ 0 (m×q), Y ≥ 0 (q×n), fitted to the
// entries of M observed on a set Ω, by the alternating direction method of Xu, Yin, Wen and
// Zhang 2011 ("An alternating direction algorithm for matrix completion with nonnegative
// factors"), as Huo et al. 2015 (Sec. 5 and Appendix A) use it to complete lighting-matrix slices.
//
// The solver works on one real matrix; colour is the caller's business (sparse-completion runs it
// once per RGB channel on the same Ω: a channel of a lighting matrix has the rank of its geometry,
// while stacking the channels would add the lights' and materials' colours to the rank).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

namespace lightfarm {

// One observed entry M(row, col) = value.
struct MatrixEntry {
  uint32_t row = 0, col = 0;
  float value = 0;
};

struct NmfOptions {
  int rank = 16;             // q, Huo 2015's choice for 800-row slices
  // The rank actually used is lowered until the observed entries number at least this many times
  // the factors' degrees of freedom q(m + n − q) (0: only rank ≤ min(m, n)).
  double min_oversampling = 2;
  int max_iterations = 100;  // Huo 2015, Sec. 5
  // Stop when the relative observed residual ‖P_Ω(XY − M)‖_F / ‖P_Ω(M)‖_F falls below this, or
  // when it changes by less than tolerance·(residual) between two iterations.
  double tolerance = 1e-4;
  // Penalties of the constraints X = U and Y = V. A positive value fixes them; 0 (default) makes
  // them adaptive: α_k = penalty_scale · tr(Y_k Y_kᵀ)/q and β_k = penalty_scale · tr(X_kᵀ X_k)/q,
  // a fixed fraction of the Gram matrices they are added to (see the .cpp).
  double alpha = 0, beta = 0;
  double penalty_scale = 0.1;
  // Dual step length, γ ∈ (0, (1+√5)/2) (Xu et al. 2011, Theorem; Huo 2015, Appendix A).
  double gamma = 1.618;
  // Divide every column by the RMS of its observed entries before the ADM and multiply Y back
  // after (false: one global scale). Columns of lighting-matrix slices span many orders of
  // magnitude; see the .cpp.
  bool scale_columns = true;
};

struct NmfResult {
  // Nonnegative factors (the ADM's projected variables U, V, returned as X, Y). Double precision:
  // the values of a lighting matrix span many orders of magnitude and float products of a few
  // huge entries would overflow. X is rows × q', Y is q' × cols, with q' ≤ min(rank, rows, cols)
  // (see min_oversampling), except when every entry was observed (see `complete`).
  Eigen::MatrixXd X, Y;
  // ‖P_Ω(XY − M)‖_F / ‖P_Ω(M)‖_F (0 when M_Ω = 0), on M's own scale.
  double observed_residual = 0;
  int iterations = 0;
  // Every entry of M was observed: no factorisation was run, and the result reproduces M exactly
  // (X = M, Y = I when cols ≤ rows, else X = I, Y = M), so that X·(Y·1) are M's exact row sums.
  bool complete = false;
};

// Completes a rows × cols nonnegative matrix from `observed`. Repeated entries are averaged;
// negative or non-finite values are treated as 0 (a lighting matrix has neither). Deterministic
// in (inputs, seed): the random initial factors are drawn from a generator seeded by `seed`.
// Never returns NaN/Inf; always terminates within options.max_iterations iterations.
// Throws std::invalid_argument for an entry outside the matrix or invalid options.
NmfResult CompleteNonnegative(int rows, int cols, std::span<const MatrixEntry> observed,
                              const NmfOptions& options, uint64_t seed);

// Row sums of X·Y without forming the product: X·(Y·1) (Huo 2015, Sec. 3, step 5).
Eigen::VectorXd FactoredRowSums(const NmfResult& result);

}  // namespace lightfarm
