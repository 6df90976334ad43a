// `mrcs`: matrix row-column sampling (Hašan, Pellacini, Bala 2007). A few hundred full rows of
// the lighting matrix reveal which lights (columns) behave alike; the lights are clustered on
// those reduced columns, one representative per cluster is picked with probability ∝ its reduced
// norm and scaled by 1/probability, and the image is the sum of the c scaled representative
// columns — an unbiased estimate of the sum of all n columns (Sec. 3.3).
//
// Stages (a job graph, DESIGN.md):
//   0 "rows"     workers: r rows stratified over the image (the receivers ordered along a Morton
//                curve of their pixels, cut into r runs of equal size, one uniform pick per run;
//                Sec. 4 "row analysis"). Each task evaluates a chunk of them in full and returns
//                the reduced rows (RGB → 2-norm per element, Sec. 3.2) as a non-zero bitmap plus
//                the non-zero floats.
//   Combine(0)   coordinator ("cluster"): the reduced columns ρ_j, optionally randomly projected to
//                r' dimensions, clustered by sampling + top-down splitting (mrcs_clustering.h).
//                Columns with ‖ρ_j‖ = 0 (dark in every sampled row, not necessarily in the image)
//                are kept in their own clusters sampled ∝ power luminance, so nothing is dropped.
//                Artifact: one (light, RGB weight) per cluster.
//   1 "columns"  workers, final, over the plan's tiles: row_sum[i] = Σ_k weight_k ⊙ A(i, rep_k).
//
// Parameters (--param KEY=VALUE):
//   rows=300           r: sampled rows (capped at the number of receivers).
//   columns=2·rows     c: clusters = representative columns, 600 by default (the paper's 1:2).
//                      c >= number of lights renders every light with weight 1 (= brute force).
//                      At least one cluster goes to each non-empty set (‖ρ‖ > 0, ‖ρ‖ = 0).
//   projection=50      r': random projection of the reduced columns before clustering (Sec. 4);
//                      0 disables it, and it is skipped when r' >= r.
//   zero_share=auto    share of c given to the ‖ρ‖ = 0 columns: round(zero_share·c), at least 1
//                      when such columns exist, at most their number; budget the other set cannot
//                      use moves over. Default: their share of all columns (n₀/n), as if they
//                      were average lights — the rows say nothing about them. (cornell-box
//                      64², 20000 lights, 87 such columns: a fixed 0.05 spent 30 clusters on them
//                      and had mean rel_l2 0.019 over 8 seeds; n₀/n spends 3 and had 0.014.)
//                      They are cut into runs of equal power along a Morton curve of the light
//                      positions (directions for directional lights).
//   color_average=false  scale the representative per channel to the cluster's total colour,
//                      (Σ_j ‖ρ_j^c‖)/‖ρ_rep^c‖ (Sec. 4). Off by default: with a representative
//                      chosen ∝ the scalar norm this is biased whenever a cluster mixes colours;
//                      the default weight s_k/‖ρ_rep‖ (the same for all channels) is unbiased.
//
// Randomness: rows from (seed, kRowSample, stratum); clustering from (seed, kClustering, …);
// representatives from (seed, kColumnSample, cluster). Blocks of work have fixed sizes and every
// sum runs in a fixed order, so the same seed gives the same bits for any thread count.
#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <numeric>
#include <queue>
#include <stdexcept>

#include "common/gather/methods.h"
#include "common/gather/mrcs_clustering.h"
#include "common/util/payload_bytes.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

// Fixed block sizes: they decide summation order, so they never depend on the thread count.
constexpr size_t kRowsPerTask = 32;    // sampled rows per stage-0 task
constexpr size_t kColumnBlock = 1024;  // lights per block when decoding rows (multiple of 64)
constexpr size_t kPointBlock = 1024;   // points per block when assigning them to centres
constexpr size_t kRowBlock = 256;      // receivers per block in the column stage (one ray batch)

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


constexpr uint32_t kRowsMagic = 0x3052434d;      // "MCR0"
constexpr uint32_t kArtifactMagic = 0x3141434d;  // "MCA1"

// One reduced row: which of the n elements are non-zero, and their values in light order.
struct ReducedRow {
  uint32_t row = 0;
  std::vector<uint64_t> mask;
  std::vector<float> values;
  std::vector<uint32_t> block_offset;  // values before each kColumnBlock block (decoding only)
};

struct ClusterArtifact {
  uint64_t sampled_rows = 0, zero_norm_columns = 0, zero_norm_clusters = 0;
  double objective = 0;
  std::vector<uint32_t> lights;
  std::vector<RGB> weights;
};

StageArtifact EncodeArtifact(const ClusterArtifact& a) {
  PayloadWriter out;
  out.Put(kArtifactMagic);
  out.Put(a.sampled_rows);
  out.Put(a.zero_norm_columns);
  out.Put(a.zero_norm_clusters);
  out.Put(a.objective);
  out.Put(uint64_t(a.lights.size()));
  out.PutArray(a.lights);
  out.PutArray(a.weights);
  return out.Take();
}

ClusterArtifact DecodeArtifact(const StageArtifact& bytes, size_t lights) {
  PayloadReader in(bytes, "mrcs", "cluster artifact");
  ClusterArtifact a;
  if (in.Get<uint32_t>() != kArtifactMagic)
    throw std::runtime_error("mrcs: the column stage received an artifact of another method");
  a.sampled_rows = in.Get<uint64_t>();
  a.zero_norm_columns = in.Get<uint64_t>();
  a.zero_norm_clusters = in.Get<uint64_t>();
  a.objective = in.Get<double>();
  const uint64_t count = in.Get<uint64_t>();
  in.GetArray(&a.lights, count);
  in.GetArray(&a.weights, count);
  for (uint32_t l : a.lights)
    if (l >= lights) throw std::runtime_error("mrcs: artifact names a light out of range");
  return a;
}

// Interleaves the low 16 bits of x and y (Morton order of pixels).
uint32_t Morton2(uint32_t x, uint32_t y) {
  auto spread = [](uint32_t v) {
    v &= 0xffff;
    v = (v | (v << 8)) & 0x00ff00ffu;
    v = (v | (v << 4)) & 0x0f0f0f0fu;
    v = (v | (v << 2)) & 0x33333333u;
    v = (v | (v << 1)) & 0x55555555u;
    return v;
  };
  return spread(x) | (spread(y) << 1);
}

// Interleaves the low 20 bits of x, y, z.
uint64_t Morton3(uint32_t x, uint32_t y, uint32_t z) {
  auto spread = [](uint64_t v) {
    v &= 0xfffff;
    v = (v | (v << 32)) & 0x1f00000000ffffULL;
    v = (v | (v << 16)) & 0x1f0000ff0000ffULL;
    v = (v | (v << 8)) & 0x100f00f00f00f00fULL;
    v = (v | (v << 4)) & 0x10c30c30c30c30c3ULL;
    v = (v | (v << 2)) & 0x1249249249249249ULL;
    return v;
  };
  return spread(x) | (spread(y) << 1) | (spread(z) << 2);
}

// Kind, then a Morton code of the position in the lights' bounds (of the direction for
// directional lights): the order in which zero-norm columns are cut into clusters.
std::vector<uint64_t> SpatialKeys(const LightSet& set) {
  Bounds3 bounds;
  for (const VirtualLight& l : set.lights)
    if (!l.IsDirectional()) bounds.Extend(l.p);
  std::vector<uint64_t> keys(set.size());
  for (size_t j = 0; j < set.size(); ++j) {
    const VirtualLight& l = set.lights[j];
    Vec3 lo = bounds.lo, extent = bounds.Diagonal(), p = l.p;
    if (l.IsDirectional()) {
      lo = Vec3(-1, -1, -1);
      extent = Vec3(2, 2, 2);
      p = l.n;
    }
    uint32_t q[3];
    for (int a = 0; a < 3; ++a) {
      float t = extent[a] > 0 ? (p[a] - lo[a]) / extent[a] : 0.f;
      q[a] = uint32_t(Clamp(t, 0.f, 1.f) * float((1u << 20) - 1));
    }
    keys[j] = (uint64_t(l.kind) << 60) | Morton3(q[0], q[1], q[2]);
  }
  return keys;
}

struct MrcsSettings {
  size_t rows = 300;
  MrcsClusterOptions clustering;
  bool color_average = false;
};

class MatrixRowColumnSampling final : public GatherMethod {
 public:
  explicit MatrixRowColumnSampling(const MrcsSettings& settings) : settings_(settings) {}

  std::string name() const override { return "mrcs"; }
  int stage_count() const override { return 2; }
  std::string stage_name(int stage) const override { return stage == 0 ? "rows" : "columns"; }

  std::vector<SubMatrixTask> PlanStage(int stage, const GatherContext& ctx,
                                       const std::vector<SubMatrixTask>& tiles,
                                       const StageArtifact& previous) const override {
    if (stage == 1) return GatherMethod::PlanStage(stage, ctx, tiles, previous);
    return PlanRowTasks(ctx, tiles);
  }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact& previous) const override {
    return task.stage == 0 ? RunRowTask(ctx, task) : RunColumnTask(ctx, task, previous);
  }

  StageArtifact Combine(int stage, const GatherContext& ctx,
                        const std::vector<TaskOutput>& outputs) const override;

 private:
  std::vector<SubMatrixTask> PlanRowTasks(const GatherContext& ctx,
                                          const std::vector<SubMatrixTask>& tiles) const;
  TaskOutput RunRowTask(const GatherContext& ctx, const SubMatrixTask& task) const;
  TaskOutput RunColumnTask(const GatherContext& ctx, const SubMatrixTask& task,
                           const StageArtifact& previous) const;

  MrcsSettings settings_;
};

std::vector<SubMatrixTask> MatrixRowColumnSampling::PlanRowTasks(
    const GatherContext& ctx, const std::vector<SubMatrixTask>& tiles) const {
  const uint64_t seed = tiles.empty() ? 0 : tiles.front().seed;
  const ReceiverSet& receivers = ctx.matrix.receivers();
  // Order the receivers along a Morton curve of their pixels, so that equal runs of the order
  // are compact blocks of the image (samples of one pixel stay together).
  std::vector<std::pair<uint64_t, uint32_t>> order;
  for (const SubMatrixTask& tile : tiles)
    for (uint32_t row : tile.rows) {
      // Rows after the shading points are eye segments (media).
      const uint32_t sample = row < receivers.points.size()
                                  ? receivers.points[row].sample
                                  : receivers.segments[row - receivers.points.size()].sample;
      uint32_t pixel = receivers.samples[sample].pixel;
      uint32_t x = pixel % uint32_t(std::max(receivers.width, 1));
      uint32_t y = pixel / uint32_t(std::max(receivers.width, 1));
      order.emplace_back(uint64_t(Morton2(x, y)), row);
    }
  std::sort(order.begin(), order.end());
  // One uniform pick in each of r equal runs (stratified sampling, Sec. 4).
  const size_t m = order.size(), r = std::min(settings_.rows, m);
  std::vector<uint32_t> sampled(r);
  for (size_t k = 0; k < r; ++k) {
    size_t begin = k * m / r, end = (k + 1) * m / r;
    Rng rng(HashSeed({seed, Stream(RngStream::kRowSample), k}));
    sampled[k] = order[begin + rng.UniformInt(uint32_t(end - begin))].second;
  }
  // At least one task, so that Combine learns the seed even without receivers.
  std::vector<SubMatrixTask> tasks;
  for (size_t begin = 0; begin < r || tasks.empty(); begin += kRowsPerTask) {
    SubMatrixTask task;
    task.stage = 0;
    task.task_id = uint32_t(tasks.size());
    task.seed = seed;
    for (size_t k = begin; k < std::min(r, begin + kRowsPerTask); ++k) task.rows.push_back(sampled[k]);
    tasks.push_back(std::move(task));
  }
  return tasks;
}

TaskOutput MatrixRowColumnSampling::RunRowTask(const GatherContext& ctx,
                                               const SubMatrixTask& task) const {
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols(), words = (n + 63) / 64, nrows = task.rows.size();
  const bool color = settings_.color_average;
  std::vector<ReducedRow> rows(nrows);
  std::vector<std::vector<RGB>> full(color ? nrows : 0);
  std::vector<MatrixCounters> counters(nrows);
  tbb::parallel_for(size_t(0), nrows, [&](size_t k) {
    std::vector<RGB> values(n);
    matrix.Row(task.rows[k], values, &counters[k]);
    ReducedRow& out = rows[k];
    out.row = task.rows[k];
    out.mask.assign(words, 0);
    for (size_t j = 0; j < n; ++j) {
      float v = values[j].Norm();  // Sec. 3.2: RGB → 2-norm
      if (v > 0 && std::isfinite(v)) {
        out.mask[j / 64] |= uint64_t(1) << (j % 64);
        out.values.push_back(v);
      }
    }
    if (color) full[k] = std::move(values);
  });
  TaskOutput result;
  for (const MatrixCounters& c : counters) result.counters.Add(c);
  PayloadWriter out;
  out.Put(kRowsMagic);
  out.Put(task.seed);
  out.Put(uint64_t(n));
  out.Put(uint64_t(nrows));
  out.Put(uint8_t(color ? 1 : 0));
  for (const ReducedRow& row : rows) {
    out.Put(row.row);
    out.Put(uint64_t(row.values.size()));
    out.PutArray(row.mask);
    out.PutArray(row.values);
  }
  if (color) {
    // Per-channel Σ_i A_ij² over this task's rows, for the colour-averaged weights.
    std::vector<float> squares(3 * n);
    tbb::parallel_for(size_t(0), (n + kColumnBlock - 1) / kColumnBlock, [&](size_t b) {
      for (size_t j = b * kColumnBlock; j < std::min(n, (b + 1) * kColumnBlock); ++j)
        for (int c = 0; c < 3; ++c) {
          double sum = 0;
          for (size_t k = 0; k < nrows; ++k) sum += double(full[k][j][c]) * double(full[k][j][c]);
          squares[3 * j + size_t(c)] = float(sum);
        }
    });
    out.PutArray(squares);
  }
  result.payload = out.Take();
  return result;
}

StageArtifact MatrixRowColumnSampling::Combine(int stage, const GatherContext& ctx,
                                               const std::vector<TaskOutput>& outputs) const {
  if (stage != 0) return {};
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols(), words = (n + 63) / 64;
  const size_t blocks = (n + kColumnBlock - 1) / kColumnBlock;
  // Decode the reduced rows, in task order.
  uint64_t seed = 0;
  std::vector<ReducedRow> rows;
  std::vector<double> channel_squares;  // 3 per light, when colour averaging
  for (size_t t = 0; t < outputs.size(); ++t) {
    PayloadReader in(outputs[t].payload, "mrcs", "row-stage payload");
    if (in.Get<uint32_t>() != kRowsMagic)
      throw std::runtime_error("mrcs: the row stage returned a payload of another method");
    uint64_t task_seed = in.Get<uint64_t>();
    if (t == 0) seed = task_seed;
    if (task_seed != seed) throw std::runtime_error("mrcs: row-stage tasks disagree on the seed");
    if (in.Get<uint64_t>() != n)
      throw std::runtime_error("mrcs: row-stage payload was computed for another light set");
    const uint64_t count = in.Get<uint64_t>();
    const bool color = in.Get<uint8_t>() != 0;
    for (uint64_t k = 0; k < count; ++k) {
      ReducedRow row;
      row.row = in.Get<uint32_t>();
      const uint64_t nnz = in.Get<uint64_t>();
      in.GetArray(&row.mask, words);
      in.GetArray(&row.values, nnz);
      size_t bits = 0;
      for (uint64_t word : row.mask) bits += size_t(std::popcount(word));
      if (bits != nnz) throw std::runtime_error("mrcs: corrupt row-stage payload");
      rows.push_back(std::move(row));
    }
    if (color) {
      std::vector<float> squares;
      in.GetArray(&squares, 3 * n);
      channel_squares.resize(3 * n, 0.0);
      for (size_t i = 0; i < 3 * n; ++i) channel_squares[i] += double(squares[i]);
    }
    if (!in.AtEnd()) throw std::runtime_error("mrcs: trailing bytes in a row-stage payload");
  }
  const size_t r = rows.size();
  tbb::parallel_for(size_t(0), r, [&](size_t i) {
    ReducedRow& row = rows[i];
    row.block_offset.resize(blocks);
    uint32_t offset = 0;
    for (size_t b = 0; b < blocks; ++b) {
      row.block_offset[b] = offset;
      for (size_t wd = b * kColumnBlock / 64; wd < std::min(words, (b + 1) * kColumnBlock / 64); ++wd)
        offset += uint32_t(std::popcount(row.mask[wd]));
    }
  });
  // Visits the non-zero elements of block b, row by row (a fixed order per column).
  auto for_each_in_block = [&](size_t b, auto&& fn) {
    for (size_t i = 0; i < r; ++i) {
      const ReducedRow& row = rows[i];
      uint32_t v = row.block_offset[b];
      for (size_t wd = b * kColumnBlock / 64; wd < std::min(words, (b + 1) * kColumnBlock / 64); ++wd)
        for (uint64_t bits = row.mask[wd]; bits; bits &= bits - 1)
          fn(i, wd * 64 + size_t(std::countr_zero(bits)), row.values[v++]);
    }
  };
  // ‖ρ_j‖ of every reduced column.
  std::vector<double> norms(n, 0.0);
  tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
    for_each_in_block(b, [&](size_t, size_t j, float v) { norms[j] += double(v) * double(v); });
  });
  for (double& x : norms) x = std::sqrt(x);
  // Clustering points: the columns with ‖ρ‖ > 0, randomly projected to r' dimensions (Sec. 4).
  std::vector<uint32_t> point_lights, point_of(n, UINT32_MAX);
  for (size_t j = 0; j < n; ++j)
    if (norms[j] > 0) {
      point_of[j] = uint32_t(point_lights.size());
      point_lights.push_back(uint32_t(j));
    }
  const int projection = settings_.clustering.projection;
  const bool project = projection > 0 && size_t(projection) < r;
  const Eigen::Index d = project ? Eigen::Index(projection) : Eigen::Index(r);
  Eigen::MatrixXf projector;
  if (project) projector = MrcsProjectionMatrix(projection, int(r), seed);
  Eigen::MatrixXf points = Eigen::MatrixXf::Zero(d, Eigen::Index(point_lights.size()));
  tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
    for_each_in_block(b, [&](size_t i, size_t j, float v) {
      Eigen::Index p = Eigen::Index(point_of[j]);
      if (project)
        points.col(p) += v * projector.col(Eigen::Index(i));
      else
        points(Eigen::Index(i), p) = v;
    });
  });
  std::vector<float> power(n);
  for (size_t j = 0; j < n; ++j) power[j] = matrix.lights().lights[j].power.Luminance();
  const std::vector<uint64_t> keys = SpatialKeys(matrix.lights());
  MrcsClustering clustering = MrcsBuildClusters(points, point_lights, norms, power, keys,
                                                settings_.clustering, seed);
  // One representative per cluster, scaled by 1/pmf (or to the cluster's total colour).
  ClusterArtifact artifact;
  artifact.sampled_rows = r;
  artifact.zero_norm_columns = clustering.zero_norm_columns;
  artifact.zero_norm_clusters = clustering.zero_norm_clusters;
  artifact.objective = clustering.objective;
  if (settings_.color_average && channel_squares.size() != 3 * n)
    throw std::runtime_error("mrcs: row-stage payloads lack the per-channel norms");
  std::vector<std::pair<uint32_t, RGB>> chosen;
  for (size_t k = 0; k < clustering.clusters.size(); ++k) {
    const MrcsCluster& cluster = clustering.clusters[k];
    MrcsRepresentative rep = MrcsChooseRepresentative(cluster, seed, uint32_t(k));
    RGB weight(float(rep.weight));
    if (settings_.color_average && !cluster.zero_norm && cluster.lights.size() > 1) {
      for (int c = 0; c < 3; ++c) {
        double total = 0;
        for (uint32_t j : cluster.lights) total += std::sqrt(channel_squares[3 * j + size_t(c)]);
        double own = std::sqrt(channel_squares[3 * rep.light + size_t(c)]);
        if (own > 0) weight[c] = float(total / own);
      }
    }
    chosen.emplace_back(rep.light, weight);
  }
  std::sort(chosen.begin(), chosen.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [light, weight] : chosen) {
    artifact.lights.push_back(light);
    artifact.weights.push_back(weight);
  }
  return EncodeArtifact(artifact);
}

TaskOutput MatrixRowColumnSampling::RunColumnTask(const GatherContext& ctx,
                                                  const SubMatrixTask& task,
                                                  const StageArtifact& previous) const {
  const LightingMatrix& matrix = ctx.matrix;
  const ClusterArtifact artifact = DecodeArtifact(previous, matrix.cols());
  TaskOutput result;
  const size_t nrows = task.rows.size();
  std::vector<RGBAccum> sums(nrows);
  const size_t blocks = (nrows + kRowBlock - 1) / kRowBlock;
  std::vector<MatrixCounters> counters(blocks);
  // Each block of receivers walks the representatives in artifact order: a fixed sum order.
  tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
    const size_t begin = b * kRowBlock, len = std::min(kRowBlock, nrows - begin);
    std::span<const uint32_t> rows(task.rows.data() + begin, len);
    std::vector<RGB> column(len);
    for (size_t k = 0; k < artifact.lights.size(); ++k) {
      matrix.Column(artifact.lights[k], rows, column, &counters[b]);
      const RGB w = artifact.weights[k];
      for (size_t i = 0; i < len; ++i) {
        RGBAccum& acc = sums[begin + i];
        acc.r += double(w.r) * double(column[i].r);
        acc.g += double(w.g) * double(column[i].g);
        acc.b += double(w.b) * double(column[i].b);
      }
    }
  });
  for (const MatrixCounters& c : counters) result.counters.Add(c);
  result.row_sums = std::move(sums);
  if (task.task_id == 0) {  // once per job: the numbers are summed over tasks
    result.stats["mrcs.sampled_rows"] = double(artifact.sampled_rows);
    result.stats["mrcs.clusters"] = double(artifact.lights.size());
    result.stats["mrcs.zero_norm_columns"] = double(artifact.zero_norm_columns);
    result.stats["mrcs.zero_norm_clusters"] = double(artifact.zero_norm_clusters);
    result.stats["mrcs.reduced_objective"] = artifact.objective;
  }
  return result;
}

}  // namespace

// --- mrcs_clustering.h ------------------------------------------------------------------------

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

std::unique_ptr<GatherMethod> CreateMrcsGather(const OptionMap& params) {
  MrcsSettings s;
  s.rows = size_t(params.GetInt("rows", 300, 1, 1 << 20));
  s.clustering.clusters = size_t(params.GetInt("columns", 2 * (long long)s.rows, 1, 1LL << 32));
  s.clustering.projection = int(params.GetInt("projection", 50, 0, 1 << 16));
  if (params.GetString("zero_share", "auto") != "auto")
    s.clustering.zero_share = params.GetDouble("zero_share", 0.0, 0.0, 1.0);
  s.color_average = params.GetBool("color_average", false);
  return std::make_unique<MatrixRowColumnSampling>(s);
}

GatherMethodInfo MrcsMethod() {
  GatherMethodInfo m;
  m.name = "mrcs";
  m.create = CreateMrcsGather;
  // Hašan 2007 uses rows:columns of 1:2 and 1:3 (Fig. 6).
  m.sweep = "rows=25,columns=50;rows=50,columns=100;rows=50,columns=150;rows=100,columns=200;"
            "rows=100,columns=300;rows=200,columns=400;rows=300,columns=600;rows=300,columns=900";
  // Columns ∝ 1/target (12/target, within 50..5000), rows half of them.
  m.params_for_target = [](double target) {
    const long columns = std::clamp(std::lround(12.0 / target), 50L, 5000L);
    return std::vector<std::string>{"rows=" + std::to_string(columns / 2), "columns=" + std::to_string(columns)};
  };
  // auto: rel_l2 0.013 / 0.016 at 5000 / 20000 lights (auto_method.cpp has the protocol).
  m.auto_surface_rel_l2 = 0.016;
  m.auto_surface_rays_per_pixel = 1352.4;
  return m;
}

}  // namespace lightfarm
