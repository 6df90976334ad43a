// The column clustering of matrix row-column sampling (Hašan, Pellacini, Bala 2007, Sec. 3.3–3.5
// and 4), in its own file (mrcs_clustering.cpp), apart from the stages in mrcs.cpp, so that tests can
// check it on small matrices of their own.
//
// Notation (the paper's Table 1): R is the r × n matrix of sampled rows with RGB reduced to
// 2-norms, ρ_j its columns ("reduced columns"), ρ̄ = ρ/‖ρ‖. The clustering works on "points"
// x_j: the reduced columns, or their random projections to r' dimensions (Sec. 4). With
// w_j = ‖x_j‖ and u_j = x̄_j (u_j = 0 when w_j = 0), the objective (Sec. 3.4) is
//
//   Objective = Σ_k Σ_{i,j ∈ C_k} w_i w_j ‖u_i − u_j‖²        (ordered pairs)
//
// which is twice the expected squared error of the reduced estimator X_R (Appendix A).
// Expanding ‖u_i − u_j‖² = ‖u_i‖² + ‖u_j‖² − 2 u_i·u_j and summing over a set gives closed forms
// that replace the O(n²) pair sums:
//
//   α_i  = Σ_j w_i w_j ‖u_i − u_j‖² = w_i·( ‖u_i‖²·W + Q − 2 u_i·S )
//   cost(C) = Σ_{i,j∈C} w_i w_j ‖u_i − u_j‖² = 2·( W_C·Q_C − ‖S_C‖² )
//
// with W = Σ_j w_j, Q = Σ_j w_j ‖u_j‖², S = Σ_j w_j u_j = Σ_j x_j (over all points for α, over C
// for the cost). For unit u (every w > 0) Q = W, so cost(C) = 2(W_C² − ‖S_C‖²).
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace lightfarm {

// α_i for every column of `points` (d × n) in O(n·d) via the identity above, in double.
std::vector<double> MrcsAlpha(const Eigen::MatrixXf& points);

// The objective of a partition of (some of) the columns of `points` (indices into its columns).
double MrcsObjective(const Eigen::MatrixXf& points,
                     const std::vector<std::vector<uint32_t>>& clusters);

// Partitions the columns of `points` into min(count, n) non-empty clusters (fewer only when
// n < count): clustering by sampling to 2/3·count centres (probability ∝ α, multiset weights
// 1/p, nearest weighted centre), then top-down splitting of the most costly cluster along a
// random line at the best cut (Sec. 3.5, "combining the algorithms"). Deterministic in `seed`,
// whatever the thread count. Each cluster's indices are increasing.
std::vector<std::vector<uint32_t>> MrcsClusterPoints(const Eigen::MatrixXf& points, size_t count,
                                                     uint64_t seed);

// Top-down splitting alone (Sec. 3.5): starting from `clusters` (indices into the columns of
// `points`), splits the most costly cluster along a random line at the best cut until there are
// `count` clusters or none has two members. Only ever splits, so the objective never increases;
// the splits for a larger count extend those for a smaller one (same seed). Used by LightSlice's
// per-slice refinement of the global clusters. Deterministic in `seed`.
std::vector<std::vector<uint32_t>> MrcsSplitClusters(const Eigen::MatrixXf& points,
                                                     std::vector<std::vector<uint32_t>> clusters,
                                                     size_t count, uint64_t seed);

// Gaussian random projection (dims × rows, entries N(0, 1/dims)) for Sec. 4's speed-up.
Eigen::MatrixXf MrcsProjectionMatrix(int dims, int rows, uint64_t seed);

struct MrcsClusterOptions {
  size_t clusters = 600;     // c: representative columns (at least one per non-empty set below)
  int projection = 50;       // r': random projection dimension; 0 or >= r: none
  // Share of c given to the columns with ‖ρ‖ = 0 (at least 1 if any); < 0: their share n₀/n.
  double zero_share = -1;
};

struct MrcsCluster {
  std::vector<uint32_t> lights;  // the columns (light indices), increasing
  std::vector<double> pmf;       // probability of picking each as the representative; sums to 1
  bool zero_norm = false;        // columns with ‖ρ‖ = 0, sampled ∝ luminance of light power
};

// The cluster of the columns ids[p], p ∈ group, whose representative is picked ∝ weight[ids[p]]
// (Hašan 2007, Sec. 3.3); a single column is picked with probability 1.
MrcsCluster MrcsWeightedCluster(std::span<const uint32_t> group, std::span<const uint32_t> ids,
                                std::span<const double> weight);

struct MrcsClustering {
  std::vector<MrcsCluster> clusters;  // the ‖ρ‖ > 0 clusters first, then the zero-norm ones
  double objective = 0;               // of the ‖ρ‖ > 0 clusters, on the clustered points
  size_t zero_norm_columns = 0, zero_norm_clusters = 0;
};

// Every column lands in exactly one cluster, and every column that can contribute (‖ρ‖ > 0, or
// ‖ρ‖ = 0 with non-black power) has pmf > 0, so Σ_k φ_rep(k) / pmf(rep(k)) is unbiased.
//   points       d × n₊ clustering points of the columns with ‖ρ‖ > 0 (point_lights[p] = light)
//   norms        ‖ρ_j‖ for every light (unprojected), size n
//   power        luminance of every light's power, size n (the zero-norm columns' pmf)
//   zero_order   optional key per light: zero-norm columns are cut into contiguous runs of equal
//                power in (key, index) order (pass a spatial key); empty = index order
// When clusters >= n every column is its own cluster (pmf 1, weight exactly 1).
MrcsClustering MrcsBuildClusters(const Eigen::MatrixXf& points,
                                 std::span<const uint32_t> point_lights,
                                 std::span<const double> norms, std::span<const float> power,
                                 std::span<const uint64_t> zero_order,
                                 const MrcsClusterOptions& options, uint64_t seed);

// The whole clustering from a dense reduced matrix (r × n, entries ≥ 0): norms, projection,
// MrcsBuildClusters. The method streams its rows instead; this is the same computation for tests.
MrcsClustering MrcsClusterColumns(const Eigen::MatrixXf& reduced, std::span<const float> power,
                                  const MrcsClusterOptions& options, uint64_t seed);

struct MrcsRepresentative {
  uint32_t light = 0;
  size_t member = 0;   // index in the cluster
  double weight = 1;   // 1 / pmf = s_k / ‖ρ_rep‖ (Sec. 3.3)
};

// Picks a cluster's representative from its pmf with the generator of (seed, cluster index).
MrcsRepresentative MrcsChooseRepresentative(const MrcsCluster& cluster, uint64_t seed,
                                            uint32_t cluster_index);

}  // namespace lightfarm
