#include "common/gather/mrcs_clustering.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <queue>

#include <tbb/parallel_for.h>

#include "common/util/rng.h"

namespace lightfarm {

namespace {

// Points per block when assigning them to centres: fixed, so it never depends on the thread count.
constexpr size_t kPointBlock = 1024;

uint64_t Stream(RngStream s) { return static_cast<uint64_t>(s); }

// A standard normal deviate (Box–Muller, one of the pair).
double Gaussian(Rng& rng) {
  double u1 = 1.0 - rng.UniformDouble();  // (0, 1]
  double u2 = rng.UniformDouble();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
}

// Σ_{i,j∈C} w_i w_j ‖u_i − u_j‖² = 2(W² − ‖S‖²) for unit u (points with w = 0 add nothing).
double ClusterCost(double W, double S2) { return std::max(0.0, 2.0 * (W * W - S2)); }

double ClusterCost(const Eigen::MatrixXf& points, const std::vector<double>& w,
                   const std::vector<uint32_t>& members) {
  Eigen::VectorXd S = Eigen::VectorXd::Zero(points.rows());
  double W = 0;
  for (uint32_t i : members) {
    S += points.col(i).cast<double>();
    W += w[i];
  }
  return ClusterCost(W, S.squaredNorm());
}

std::vector<double> ColumnNorms(const Eigen::MatrixXf& points) {
  std::vector<double> w(size_t(points.cols()));
  for (Eigen::Index j = 0; j < points.cols(); ++j) w[size_t(j)] = points.col(j).cast<double>().norm();
  return w;
}

// --- Clustering by sampling (Sec. 3.5) --------------------------------------------------------

std::vector<std::vector<uint32_t>> ClusterBySampling(const Eigen::MatrixXf& points,
                                                     const std::vector<double>& w, size_t centres,
                                                     uint64_t seed) {
  const size_t n = size_t(points.cols());
  std::vector<uint32_t> all(n);
  std::iota(all.begin(), all.end(), 0u);
  const std::vector<double> alpha = MrcsAlpha(points);
  // Pick centres with probability p_i ∝ α_i; a repeated pick adds 1/p_i to the centre's weight.
  std::vector<double> cdf(n);
  double total = 0;
  size_t positive = 0, last_positive = 0;
  for (size_t i = 0; i < n; ++i) {
    total += alpha[i];
    cdf[i] = total;
    if (alpha[i] > 0) {
      ++positive;
      last_positive = i;
    }
  }
  centres = std::min(centres, positive);
  if (!(total > 0) || centres <= 1) return {all};  // all directions equal: no cost to reduce
  std::map<uint32_t, double> multiset;  // ordered by point: deterministic centre order
  Rng rng(HashSeed({seed, Stream(RngStream::kClustering), 1}));
  // A very skewed α can make the last distinct centres rare; the splitting fills any shortfall.
  const size_t max_draws = 64 * centres + 1024;
  for (size_t draw = 0; multiset.size() < centres && draw < max_draws; ++draw) {
    double u = rng.UniformDouble() * total;
    // The first i with cdf[i] > u has α_i > 0; u rounded up to the total takes the last one.
    size_t i = size_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
    if (i >= n) i = last_positive;
    multiset[uint32_t(i)] += total / alpha[i];
  }
  const size_t k = multiset.size();
  Eigen::MatrixXf K(points.rows(), Eigen::Index(k));
  std::vector<double> scale(k), knorm(k);
  {
    size_t c = 0;
    for (const auto& [i, weight] : multiset) {
      K.col(Eigen::Index(c)) = points.col(i);
      scale[c] = weight;
      knorm[c] = w[i];
      ++c;
    }
  }
  // Nearest centre, the centres scaled by their multiset weights: d(x, λy) = λ(‖x‖‖y‖ − x·y)
  // (Sec. 4). One GEMM K^T·X per fixed block of points; ties go to the lower centre.
  std::vector<uint32_t> assign(n);
  const size_t blocks = (n + kPointBlock - 1) / kPointBlock;
  tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
    const size_t begin = b * kPointBlock, len = std::min(kPointBlock, n - begin);
    Eigen::MatrixXf dots = K.transpose() * points.middleCols(Eigen::Index(begin), Eigen::Index(len));
    for (size_t p = 0; p < len; ++p) {
      const double wp = w[begin + p];
      double best = std::numeric_limits<double>::infinity();
      uint32_t best_c = 0;
      for (size_t c = 0; c < k; ++c) {
        double dist = scale[c] * (knorm[c] * wp - double(dots(Eigen::Index(c), Eigen::Index(p))));
        if (dist < best) {
          best = dist;
          best_c = uint32_t(c);
        }
      }
      assign[begin + p] = best_c;
    }
  });
  std::vector<std::vector<uint32_t>> clusters(k);
  for (size_t i = 0; i < n; ++i) clusters[assign[i]].push_back(uint32_t(i));
  std::erase_if(clusters, [](const std::vector<uint32_t>& c) { return c.empty(); });
  return clusters;
}

// --- Top-down splitting (Sec. 3.5) ------------------------------------------------------------

struct SplitResult {
  std::vector<uint32_t> left, right;
  double left_cost = 0, right_cost = 0;
};

// Projects the cluster's unit directions onto a random line, sorts, and takes the cut with the
// lowest summed cost (prefix and suffix sums: O(|C|·d)). Near-ties go to the most balanced cut,
// which also splits sensibly a cluster whose points all point the same way (cost 0).
SplitResult SplitAlongRandomLine(const Eigen::MatrixXf& points, const std::vector<double>& w,
                                 const std::vector<uint32_t>& members, double parent_cost,
                                 uint64_t seed, uint64_t split_index) {
  const Eigen::Index d = points.rows();
  const size_t s = members.size();
  Rng rng(HashSeed({seed, Stream(RngStream::kClustering), 2, split_index}));
  Eigen::VectorXd line(d);
  for (Eigen::Index k = 0; k < d; ++k) line[k] = Gaussian(rng);
  std::vector<std::pair<double, uint32_t>> order(s);
  for (size_t k = 0; k < s; ++k) {
    uint32_t i = members[k];
    double t = w[i] > 0 ? points.col(i).cast<double>().dot(line) / w[i] : 0.0;
    order[k] = {t, i};
  }
  std::sort(order.begin(), order.end());
  // cost_left[t]: the first t points; cost_right[t]: the points from t on.
  std::vector<double> cost_left(s + 1, 0.0), cost_right(s + 1, 0.0);
  Eigen::VectorXd S = Eigen::VectorXd::Zero(d);
  double W = 0;
  for (size_t t = 1; t <= s; ++t) {
    S += points.col(order[t - 1].second).cast<double>();
    W += w[order[t - 1].second];
    cost_left[t] = ClusterCost(W, S.squaredNorm());
  }
  S.setZero();
  W = 0;
  for (size_t t = s; t-- > 0;) {
    S += points.col(order[t].second).cast<double>();
    W += w[order[t].second];
    cost_right[t] = ClusterCost(W, S.squaredNorm());
  }
  double best = std::numeric_limits<double>::infinity();
  for (size_t t = 1; t < s; ++t) best = std::min(best, cost_left[t] + cost_right[t]);
  const double tolerance = 1e-9 * std::max(parent_cost, best);
  size_t cut = 1;
  double cut_balance = std::numeric_limits<double>::infinity();
  for (size_t t = 1; t < s; ++t) {
    if (cost_left[t] + cost_right[t] > best + tolerance) continue;
    double balance = std::abs(double(t) - 0.5 * double(s));
    if (balance < cut_balance) {
      cut_balance = balance;
      cut = t;
    }
  }
  SplitResult r;
  for (size_t t = 0; t < s; ++t) (t < cut ? r.left : r.right).push_back(order[t].second);
  std::sort(r.left.begin(), r.left.end());
  std::sort(r.right.begin(), r.right.end());
  r.left_cost = cost_left[cut];
  r.right_cost = cost_right[cut];
  return r;
}

std::vector<std::vector<uint32_t>> SplitUntil(const Eigen::MatrixXf& points,
                                              const std::vector<double>& w,
                                              std::vector<std::vector<uint32_t>> clusters,
                                              size_t count, uint64_t seed) {
  struct Entry {
    double cost;
    size_t size, id;
    // Highest cost first, then largest, then oldest: a total order, so runs are reproducible.
    bool operator<(const Entry& o) const {
      if (cost != o.cost) return cost < o.cost;
      if (size != o.size) return size < o.size;
      return id > o.id;
    }
  };
  std::vector<std::vector<uint32_t>> nodes = std::move(clusters);
  std::vector<double> costs(nodes.size());
  std::priority_queue<Entry> queue;
  for (size_t i = 0; i < nodes.size(); ++i) {
    costs[i] = ClusterCost(points, w, nodes[i]);
    queue.push({costs[i], nodes[i].size(), i});
  }
  std::vector<std::vector<uint32_t>> done;
  uint64_t splits = 0;
  while (!queue.empty() && done.size() + queue.size() < count) {
    Entry top = queue.top();
    queue.pop();
    if (nodes[top.id].size() < 2) {
      done.push_back(std::move(nodes[top.id]));
      continue;
    }
    SplitResult r = SplitAlongRandomLine(points, w, nodes[top.id], top.cost, seed, splits++);
    nodes[top.id].clear();
    nodes.push_back(std::move(r.left));
    queue.push({r.left_cost, nodes.back().size(), nodes.size() - 1});
    nodes.push_back(std::move(r.right));
    queue.push({r.right_cost, nodes.back().size(), nodes.size() - 1});
  }
  while (!queue.empty()) {
    done.push_back(std::move(nodes[queue.top().id]));
    queue.pop();
  }
  std::sort(done.begin(), done.end(),
            [](const auto& a, const auto& b) { return a.front() < b.front(); });
  return done;
}

}  // namespace

std::vector<double> MrcsAlpha(const Eigen::MatrixXf& points) {
  const size_t n = size_t(points.cols());
  const std::vector<double> w = ColumnNorms(points);
  // W = Σ w_j, Q = Σ w_j ‖u_j‖² (= W over the non-zero points), S = Σ w_j u_j = Σ x_j.
  Eigen::VectorXd S = Eigen::VectorXd::Zero(points.rows());
  double W = 0, Q = 0;
  for (size_t j = 0; j < n; ++j) {
    if (!(w[j] > 0)) continue;
    S += points.col(Eigen::Index(j)).cast<double>();
    W += w[j];
    Q += w[j];  // ‖u_j‖² = 1
  }
  // α_i = w_i(‖u_i‖² W + Q − 2 u_i·S) = w_i(W + Q) − 2 x_i·S for w_i > 0, else 0.
  std::vector<double> alpha(n, 0.0);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    if (!(w[i] > 0)) return;
    double xs = points.col(Eigen::Index(i)).cast<double>().dot(S);
    alpha[i] = std::max(0.0, w[i] * (W + Q) - 2.0 * xs);
  });
  return alpha;
}

double MrcsObjective(const Eigen::MatrixXf& points,
                     const std::vector<std::vector<uint32_t>>& clusters) {
  const std::vector<double> w = ColumnNorms(points);
  double total = 0;
  for (const std::vector<uint32_t>& c : clusters) total += ClusterCost(points, w, c);
  return total;
}

std::vector<std::vector<uint32_t>> MrcsClusterPoints(const Eigen::MatrixXf& points, size_t count,
                                                     uint64_t seed) {
  const size_t n = size_t(points.cols());
  if (n == 0 || count == 0) return {};
  std::vector<std::vector<uint32_t>> clusters;
  if (count >= n) {
    for (uint32_t i = 0; i < n; ++i) clusters.push_back({i});
    return clusters;
  }
  const std::vector<double> w = ColumnNorms(points);
  // Sample 2/3 of the clusters, then split the most costly ones (Sec. 3.5, "combining").
  clusters = ClusterBySampling(points, w, std::max<size_t>(1, 2 * count / 3), seed);
  return SplitUntil(points, w, std::move(clusters), count, seed);
}

std::vector<std::vector<uint32_t>> MrcsSplitClusters(const Eigen::MatrixXf& points,
                                                     std::vector<std::vector<uint32_t>> clusters,
                                                     size_t count, uint64_t seed) {
  std::erase_if(clusters, [](const std::vector<uint32_t>& c) { return c.empty(); });
  if (clusters.empty()) return clusters;
  return SplitUntil(points, ColumnNorms(points), std::move(clusters), count, seed);
}

Eigen::MatrixXf MrcsProjectionMatrix(int dims, int rows, uint64_t seed) {
  Eigen::MatrixXf P(dims, rows);
  Rng rng(HashSeed({seed, Stream(RngStream::kClustering), 3}));
  const double scale = 1.0 / std::sqrt(double(std::max(dims, 1)));
  for (Eigen::Index c = 0; c < P.cols(); ++c)
    for (Eigen::Index r = 0; r < P.rows(); ++r) P(r, c) = float(scale * Gaussian(rng));
  return P;
}

MrcsCluster MrcsWeightedCluster(std::span<const uint32_t> group, std::span<const uint32_t> ids,
                                std::span<const double> weight) {
  MrcsCluster cluster;
  double s = 0;
  for (uint32_t p : group) s += weight[ids[p]];
  for (uint32_t p : group) {
    cluster.lights.push_back(ids[p]);
    cluster.pmf.push_back(group.size() == 1 ? 1.0 : weight[ids[p]] / s);
  }
  return cluster;
}

MrcsClustering MrcsBuildClusters(const Eigen::MatrixXf& points,
                                 std::span<const uint32_t> point_lights,
                                 std::span<const double> norms, std::span<const float> power,
                                 std::span<const uint64_t> zero_order,
                                 const MrcsClusterOptions& options, uint64_t seed) {
  const size_t n = norms.size();
  if (power.size() != n || (!zero_order.empty() && zero_order.size() != n) ||
      size_t(points.cols()) != point_lights.size())
    throw std::invalid_argument("MrcsBuildClusters: inconsistent sizes");
  MrcsClustering out;
  std::vector<uint32_t> zero;
  for (uint32_t j = 0; j < n; ++j)
    if (!(norms[j] > 0)) zero.push_back(j);
  const size_t n_zero = zero.size(), n_plus = n - n_zero;
  out.zero_norm_columns = n_zero;
  if (point_lights.size() != n_plus)
    throw std::invalid_argument("MrcsBuildClusters: one point per column with a non-zero norm");
  const size_t c = std::max<size_t>(options.clusters, 1);
  // Every column its own cluster: weight exactly 1, the brute-force sum.
  if (c >= n) {
    for (uint32_t j = 0; j < n; ++j) out.clusters.push_back({{j}, {1.0}, !(norms[j] > 0)});
    out.zero_norm_clusters = n_zero;
    return out;
  }
  // Split the budget: round(share·c) for the zero-norm columns (at least 1, at most their
  // number), the rest for the others (at least 1); what one set cannot use goes to the other.
  const double share =
      options.zero_share >= 0 ? options.zero_share : double(n_zero) / double(std::max<size_t>(n, 1));
  size_t c_zero = 0, c_plus = 0;
  if (n_zero > 0)
    c_zero = std::clamp<size_t>(size_t(std::llround(share * double(c))), 1, n_zero);
  if (n_plus > 0) c_plus = std::clamp<size_t>(c > c_zero ? c - c_zero : 0, 1, n_plus);
  if (n_zero > 0) c_zero = std::clamp<size_t>(c > c_plus ? c - c_plus : 0, 1, n_zero);

  // Columns with ‖ρ‖ > 0: cluster their points; representative ∝ ‖ρ_j‖ (Sec. 3.3).
  if (n_plus > 0) {
    std::vector<std::vector<uint32_t>> groups = MrcsClusterPoints(points, c_plus, seed);
    out.objective = MrcsObjective(points, groups);
    for (const std::vector<uint32_t>& g : groups)
      out.clusters.push_back(MrcsWeightedCluster(g, point_lights, norms));
  }
  // Columns with ‖ρ‖ = 0 (dark in every sampled row): no row information, so runs of equal
  // power along `zero_order`, representative ∝ power luminance (Sec. 3.3's unbiased remedy).
  if (n_zero > 0) {
    if (!zero_order.empty())
      std::stable_sort(zero.begin(), zero.end(),
                       [&](uint32_t a, uint32_t b) { return zero_order[a] < zero_order[b]; });
    std::vector<double> mass(n_zero);
    double total = 0;
    for (size_t t = 0; t < n_zero; ++t) total += double(std::max(power[zero[t]], 0.f));
    for (size_t t = 0; t < n_zero; ++t)
      mass[t] = total > 0 ? double(std::max(power[zero[t]], 0.f)) : 1.0;
    if (!(total > 0)) total = double(n_zero);
    // Advance to the next run when this one holds its share of the mass, or when each of the
    // remaining runs needs one of the remaining columns: exactly c_zero non-empty runs.
    std::vector<std::vector<uint32_t>> runs(1);
    double acc = 0;
    for (size_t t = 0; t < n_zero; ++t) {
      runs.back().push_back(zero[t]);
      acc += mass[t];
      const size_t run = runs.size() - 1, runs_left = c_zero - 1 - run;
      if (runs_left == 0) continue;
      if (n_zero - 1 - t == runs_left || acc >= total * double(run + 1) / double(c_zero))
        runs.emplace_back();
    }
    for (std::vector<uint32_t>& run : runs) {
      std::sort(run.begin(), run.end());
      MrcsCluster cluster;
      cluster.zero_norm = true;
      double s = 0;
      for (uint32_t j : run) s += double(std::max(power[j], 0.f));
      for (uint32_t j : run) {
        double p = s > 0 ? double(std::max(power[j], 0.f)) / s : 1.0 / double(run.size());
        cluster.pmf.push_back(run.size() == 1 ? 1.0 : p);
      }
      cluster.lights = std::move(run);
      out.clusters.push_back(std::move(cluster));
    }
    out.zero_norm_clusters = runs.size();
  }
  return out;
}

MrcsClustering MrcsClusterColumns(const Eigen::MatrixXf& reduced, std::span<const float> power,
                                  const MrcsClusterOptions& options, uint64_t seed) {
  const size_t n = size_t(reduced.cols());
  const Eigen::Index r = reduced.rows();
  std::vector<double> norms = ColumnNorms(reduced);
  std::vector<uint32_t> point_lights;
  for (uint32_t j = 0; j < n; ++j)
    if (norms[j] > 0) point_lights.push_back(j);
  Eigen::MatrixXf nonzero(r, Eigen::Index(point_lights.size()));
  for (size_t p = 0; p < point_lights.size(); ++p)
    nonzero.col(Eigen::Index(p)) = reduced.col(Eigen::Index(point_lights[p]));
  Eigen::MatrixXf points;
  if (options.projection > 0 && options.projection < r)
    points = MrcsProjectionMatrix(options.projection, int(r), seed) * nonzero;
  else
    points = std::move(nonzero);
  return MrcsBuildClusters(points, point_lights, norms, power, {}, options, seed);
}

MrcsRepresentative MrcsChooseRepresentative(const MrcsCluster& cluster, uint64_t seed,
                                            uint32_t cluster_index) {
  if (cluster.lights.empty() || cluster.pmf.size() != cluster.lights.size())
    throw std::invalid_argument("MrcsChooseRepresentative: empty or inconsistent cluster");
  Rng rng(HashSeed({seed, Stream(RngStream::kColumnSample), cluster_index}));
  double total = 0;
  for (double p : cluster.pmf) total += p;
  const double u = rng.UniformDouble() * total;
  // Inverse CDF; a member with pmf 0 is never chosen (the sum does not pass u on it).
  size_t chosen = cluster.lights.size();
  double acc = 0;
  for (size_t k = 0; k < cluster.pmf.size(); ++k) {
    acc += cluster.pmf[k];
    if (u < acc) {
      chosen = k;
      break;
    }
  }
  if (chosen == cluster.lights.size())  // rounding at the top end: the last member with pmf > 0
    for (size_t k = cluster.pmf.size(); k-- > 0;)
      if (cluster.pmf[k] > 0) {
        chosen = k;
        break;
      }
  if (chosen == cluster.lights.size()) chosen = 0;  // all zero: nothing to estimate
  MrcsRepresentative rep;
  rep.light = cluster.lights[chosen];
  rep.member = chosen;
  rep.weight = cluster.pmf[chosen] > 0 ? 1.0 / cluster.pmf[chosen] : 0.0;
  return rep;
}

}  // namespace lightfarm
