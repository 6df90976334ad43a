// `sparse-completion` (Huo, Wang, Liu, Bao 2015, "Sparse sampling and completion for light
// transport in VPL-based rendering"). Per slice (one task = one slice of the plan):
//
//  1. Global lightcut (Sec. 3, step 1): starting from the light tree's roots, the cut node with the
//     largest intensity (the cluster's error bound with material, geometry and visibility bounded
//     by constants, i.e. visibility overestimated: conservative) is split until the cut has
//     `global_cut` nodes. It depends on the tree only, so every task recomputes the same cut (a
//     few milliseconds) instead of shipping it through a coordinator stage.
//  2. The slice is the task's rows (the plan's slices: Ou & Pellacini 2011 6-D clustering).
//  3. Coarsening (Sec. 4): for sibling cut nodes a, b with parent f, whose representative f shares
//     with a, ε(f) = ‖V_b − V_a·I_b/I_a‖_∞ over sampled rows ζ_f, cost(f) = ε(f) + cost(b)
//     (Eq. 1, cost 0 on the global cut). Pairs whose cost is below merge_error · R are merged into
//     f, where R is the slice's mean radiance (max channel) measured on `reference_rows` fully
//     evaluated rows (the paper leaves the bound's scale open; relative to the slice's radiance
//     it means the same for any scene). |ζ_f| ∝ I_f (`coarsen_samples` rows for a pair of average
//     intensity, at least 2), uniform in the slice; merged children pass their rows on,
//     ζ_f = ζ_a ∪ ζ_b, topped up with fresh rows when the union is below the target. Sibling
//     pairs are disjoint, so all pairs of one level are tested together in one batch of shadow
//     rays (as the paper's GPU version tests all pairs in parallel); the merges repeat upwards
//     until no pair passes. Values of a node are its representative's element scaled per channel
//     by intensity / representative power (as in lightcuts.cpp), so V_f = V_a·I_f/I_a exactly
//     when f inherits a's representative. merge_error=0 disables coarsening.
//  4. Sampling (Sec. 5): the reduced matrix M (slice rows × coarse cut nodes) already holds the
//     entries computed in 3 (and the reference rows). More entries are drawn until rate·|M| are
//     known: a column with probability ∝ g(j) = max(C_j) − min(C_j) of its observed luminances
//     (f(i) = 1), then an unobserved row uniformly. Deviation: 10% of the new entries are spread
//     uniformly over columns (g(j) + 0.1·mean g) so that a column seen only as zero (occluded on
//     its few rows) can still reveal light elsewhere in the slice. rate ≥ 1 observes every entry.
//  5. Completion: M ≈ X·Y, X, Y ≥ 0 of rank `rank`, by the ADM of Xu et al. 2011
//     (common/matrix/nmf_completion.h), once per RGB channel on the same Ω (the paper does not
//     say; a channel has the rank of the geometry, stacking channels would add the colours to
//     it). The solver lowers the rank until |Ω| ≥ 2 q(m + n − q) (its min_oversampling): with
//     ~10-25 observed entries per row, q = 16 fits Ω and extrapolates noise elsewhere
//     (docs/methods/sparse-completion.md). When every entry is observed the solver returns M
//     itself (no factorisation), so with rate=1, merge_error=0 and global_cut ≥ number of lights
//     (every column a single light, scale 1) the result equals brute force up to the order of
//     the double sums.
//  6. Row sums = X·(Y·1) per channel (Sec. 3, step 5), without forming M.
//
// Parameters (--param): global_cut (850), merge_error (0.005), rate (0.1), rank (16),
// coarsen_samples (8), reference_rows (8; 0 disables coarsening), iterations (100, the paper's
// cap), tolerance (1e-4).
// merge_error: docs/methods/sparse-completion.md has the measurements that chose it.
// Stats (summed over slices, so mean = stat / slices): observed_residual (per slice, the relative
// observed-entry residual ‖P_Ω(XY − M)‖_F / ‖P_Ω(M)‖_F over the three channels), global_cut_nodes,
// coarse_cut_nodes, observed_entries, reduced_entries (|M|), nmf_iterations (the three
// channels' sum), complete_slices (slices whose M was fully observed).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <map>
#include <queue>
#include <set>
#include <stdexcept>
#include <unordered_map>

#include "common/gather/methods.h"
#include "common/matrix/nmf_completion.h"
#include "common/util/check.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

struct SparseCompletionSettings {
  size_t global_cut = 850;
  double merge_error = 0.005;
  double rate = 0.1;
  int rank = 16;
  int coarsen_samples = 8;
  int reference_rows = 8;
  int iterations = 100;
  double tolerance = 1e-4;
};

// Share of the importance-sampled entries spread uniformly over the columns (see step 4).
constexpr double kUniformColumnShare = 0.1;
// Entries per parallel evaluation chunk (several of Embree's 256-ray batches).
constexpr size_t kEvaluationChunk = 1024;

// ---------------------------------------------------------------------------------------
// Global lightcut

struct GlobalCut {
  std::vector<uint32_t> nodes;                   // cut nodes, ascending node index
  std::unordered_map<uint32_t, uint32_t> parent;  // parent of every node below a split
};

GlobalCut ComputeGlobalCut(const LightTree& tree, size_t target) {
  GlobalCut cut;
  // Max-heap on intensity; ties split the lower node index first (deterministic).
  auto lower_priority = [&](uint32_t a, uint32_t b) {
    const float ia = tree.node(a).intensity_lum, ib = tree.node(b).intensity_lum;
    return ia != ib ? ia < ib : a > b;
  };
  std::priority_queue<uint32_t, std::vector<uint32_t>, decltype(lower_priority)> heap(
      lower_priority);
  std::vector<uint32_t> leaves;  // cut nodes that cannot be split
  for (uint32_t root : tree.roots()) {
    if (tree.node(root).IsLeaf()) leaves.push_back(root);
    else heap.push(root);
  }
  while (!heap.empty() && leaves.size() + heap.size() < target) {
    const uint32_t n = heap.top();
    heap.pop();
    for (int32_t child : {tree.node(n).left, tree.node(n).right}) {
      cut.parent[uint32_t(child)] = n;
      if (tree.node(uint32_t(child)).IsLeaf()) leaves.push_back(uint32_t(child));
      else heap.push(uint32_t(child));
    }
  }
  cut.nodes = std::move(leaves);
  for (; !heap.empty(); heap.pop()) cut.nodes.push_back(heap.top());
  std::sort(cut.nodes.begin(), cut.nodes.end());
  return cut;
}

// ---------------------------------------------------------------------------------------
// Elements of the slice, evaluated once each

// The elements A(row, light) computed so far for one slice; rows are slice-local indices.
class ElementCache {
 public:
  ElementCache(const LightingMatrix& matrix, const std::vector<uint32_t>& rows)
      : matrix_(matrix), rows_(rows) {}

  static uint64_t Key(uint32_t light, uint32_t local_row) {
    return (uint64_t(light) << 32) | local_row;
  }

  // Evaluates every requested (light, local row) not yet known, in parallel chunks.
  void Evaluate(std::vector<uint64_t> requests, MatrixCounters* counters) {
    std::sort(requests.begin(), requests.end());
    requests.erase(std::unique(requests.begin(), requests.end()), requests.end());
    std::erase_if(requests, [&](uint64_t k) { return values_.count(k) != 0; });
    if (requests.empty()) return;
    std::vector<RGB> out(requests.size());
    const size_t nchunks = (requests.size() + kEvaluationChunk - 1) / kEvaluationChunk;
    std::vector<MatrixCounters> chunk_counters(nchunks);
    tbb::parallel_for(size_t(0), nchunks, [&](size_t c) {
      const size_t begin = c * kEvaluationChunk;
      const size_t end = std::min(requests.size(), begin + kEvaluationChunk);
      std::vector<uint32_t> rows(end - begin), cols(end - begin);
      for (size_t k = begin; k < end; ++k) {
        cols[k - begin] = uint32_t(requests[k] >> 32);
        rows[k - begin] = rows_[uint32_t(requests[k])];
      }
      matrix_.EvaluateEntries(rows, cols, std::span<RGB>(out.data() + begin, end - begin),
                              &chunk_counters[c]);
    });
    for (const MatrixCounters& c : chunk_counters) counters->Add(c);
    for (size_t k = 0; k < requests.size(); ++k) values_.emplace(requests[k], out[k]);
  }

  RGB Get(uint32_t light, uint32_t local_row) const {
    return values_.at(Key(light, local_row));
  }
  const std::unordered_map<uint64_t, RGB>& values() const { return values_; }

 private:
  const LightingMatrix& matrix_;
  const std::vector<uint32_t>& rows_;
  std::unordered_map<uint64_t, RGB> values_;
};

// Per-channel factor turning the representative's element into the node's estimate:
// intensity(node) / power(representative) (0 in a channel the representative does not emit).
RGB NodeScale(const LightTree& tree, const LightSet& lights, uint32_t node) {
  const LightTreeNode& n = tree.node(node);
  const RGB power = lights.lights[n.representative].power;
  RGB s;
  for (int c = 0; c < 3; ++c) s[c] = power[c] > 0 ? n.intensity[c] / power[c] : 0.f;
  return s;
}

double& Channel(RGBAccum* a, int c) { return c == 0 ? a->r : (c == 1 ? a->g : a->b); }

// k distinct values from [0, n) not in `taken` (sorted), uniformly; `taken` gains them.
void DrawDistinctRows(uint32_t n, size_t k, Rng& rng, std::vector<uint32_t>* taken) {
  k = std::min(k, size_t(n) - std::min(size_t(n), taken->size()));
  if (k == 0) return;
  std::vector<uint32_t> pool;
  pool.reserve(n - taken->size());
  for (uint32_t r = 0, t = 0; r < n; ++r) {
    while (t < taken->size() && (*taken)[t] < r) ++t;
    if (t < taken->size() && (*taken)[t] == r) continue;
    pool.push_back(r);
  }
  for (size_t i = 0; i < k; ++i) {
    const size_t j = i + rng.UniformInt(uint32_t(pool.size() - i));
    std::swap(pool[i], pool[j]);
  }
  taken->insert(taken->end(), pool.begin(), pool.begin() + ptrdiff_t(k));
  std::sort(taken->begin(), taken->end());
}

class SparseCompletionGather final : public GatherMethod {
 public:
  explicit SparseCompletionGather(const SparseCompletionSettings& s) : s_(s) {}
  std::string name() const override { return "sparse-completion"; }
  bool needs_light_tree() const override { return true; }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact&) const override {
    CHECK(ctx.tree != nullptr);  // the plan builds the tree for methods that need one
    const LightTree& tree = *ctx.tree;
    const LightingMatrix& matrix = ctx.matrix;
    const LightSet& lights = matrix.lights();
    TaskOutput result;
    const uint32_t m = uint32_t(task.rows.size());
    result.row_sums.resize(m);
    if (m == 0 || tree.roots().empty()) return result;
    auto seed_for = [&](RngStream stream, uint64_t index) {
      return HashSeed({task.seed, task.stage, task.task_id, uint64_t(stream), index});
    };

    // Step 1: the conservative global cut
    const GlobalCut global = ComputeGlobalCut(tree, s_.global_cut);
    ElementCache cache(matrix, task.rows);
    auto value = [&](uint32_t node, uint32_t row) {
      return cache.Get(tree.node(node).representative, row) * NodeScale(tree, lights, node);
    };

    // Reference rows: every global-cut node on a few rows, for the slice's radiance scale (the
    // merge bound) and as observed entries of every column
    std::vector<uint32_t> reference;
    {
      Rng rng(seed_for(RngStream::kRowSample, ~0ull));
      DrawDistinctRows(m, size_t(s_.reference_rows), rng, &reference);
      std::vector<uint64_t> requests;
      for (uint32_t node : global.nodes)
        for (uint32_t r : reference)
          requests.push_back(ElementCache::Key(tree.node(node).representative, r));
      cache.Evaluate(std::move(requests), &result.counters);
    }
    double slice_radiance = 0;
    for (uint32_t r : reference) {
      RGBAccum total;
      for (uint32_t node : global.nodes) total.Add(value(node, r));
      slice_radiance += std::max({total.r, total.g, total.b});
    }
    if (!reference.empty()) slice_radiance /= double(reference.size());

    // Step 3: coarsening
    const std::vector<uint32_t> coarse = Coarsen(tree, lights, global, m, slice_radiance,
                                                 seed_for, &cache, &result.counters);
    const uint32_t n = uint32_t(coarse.size());

    // Step 4: the reduced matrix's observed entries, then importance-sampled ones
    std::unordered_map<uint32_t, uint32_t> column_of_light;
    for (uint32_t j = 0; j < n; ++j) column_of_light[tree.node(coarse[j]).representative] = j;
    std::vector<std::vector<uint32_t>> observed_rows(n);
    for (const auto& [key, v] : cache.values()) {
      auto it = column_of_light.find(uint32_t(key >> 32));
      if (it != column_of_light.end()) observed_rows[it->second].push_back(uint32_t(key));
    }
    for (std::vector<uint32_t>& rows : observed_rows) std::sort(rows.begin(), rows.end());
    SampleEntries(tree, lights, coarse, m, seed_for, &observed_rows, &cache, &result.counters);

    // Step 5: completion per channel
    std::vector<MatrixEntry> entries[3];
    for (uint32_t j = 0; j < n; ++j)
      for (uint32_t r : observed_rows[j]) {
        const RGB v = value(coarse[j], r);
        for (int c = 0; c < 3; ++c) entries[c].push_back({r, j, v[c]});
      }
    NmfOptions options;
    options.rank = s_.rank;
    options.max_iterations = s_.iterations;
    options.tolerance = s_.tolerance;
    // One global scale, not per-column RMS scaling: the row sums need the bright columns fitted
    // best, which the unweighted least squares does. Measured (Cornell box 32², 5000 lights,
    // rate 0.3): rel. L1 0.096 with the global scale, 0.18 with per-column scaling (column RMS
    // span up to 1e4 per slice); on slices spanning 1e9 (tests/stability, bays) the two agree
    // (85% vs 83% of the bright bay's energy).
    options.scale_columns = false;
    NmfResult completed[3];
    tbb::parallel_for(0, 3, [&](int c) {
      completed[c] = CompleteNonnegative(int(m), int(n), entries[c], options,
                                         seed_for(RngStream::kCompletion, uint64_t(c)));
    });

    // Step 6: row sums X·(Y·1)
    double residual2 = 0, norm2 = 0;
    for (int c = 0; c < 3; ++c) {
      const Eigen::VectorXd sums = FactoredRowSums(completed[c]);
      for (uint32_t i = 0; i < m; ++i) Channel(&result.row_sums[i], c) = sums(i);
      double channel_norm2 = 0;
      for (const MatrixEntry& e : entries[c]) channel_norm2 += double(e.value) * double(e.value);
      residual2 += completed[c].observed_residual * completed[c].observed_residual * channel_norm2;
      norm2 += channel_norm2;
    }
    const size_t observed = entries[0].size();
    result.stats["observed_residual"] = norm2 > 0 ? std::sqrt(residual2 / norm2) : 0.0;
    result.stats["global_cut_nodes"] = double(global.nodes.size());
    result.stats["coarse_cut_nodes"] = double(n);
    result.stats["observed_entries"] = double(observed);
    result.stats["reduced_entries"] = double(m) * double(n);
    result.stats["nmf_iterations"] =
        double(completed[0].iterations + completed[1].iterations + completed[2].iterations);
    result.stats["complete_slices"] = completed[0].complete ? 1.0 : 0.0;
    return result;
  }

 private:
  template <typename SeedFn>
  std::vector<uint32_t> Coarsen(const LightTree& tree, const LightSet& lights,
                                const GlobalCut& global, uint32_t m, double slice_radiance,
                                const SeedFn& seed_for, ElementCache* cache,
                                MatrixCounters* counters) const {
    // Cut nodes with their accumulated cost and sampled rows (empty on the global cut)
    struct CutNode {
      double cost = 0;
      std::vector<uint32_t> rows;
    };
    std::map<uint32_t, CutNode> cut;
    for (uint32_t node : global.nodes) cut[node] = CutNode{};
    const double bound = s_.merge_error * slice_radiance;
    if (!(bound > 0) || cut.size() < 2) {
      std::vector<uint32_t> nodes;
      for (const auto& [node, state] : cut) nodes.push_back(node);
      return nodes;
    }
    double mean_intensity = 0;
    for (uint32_t node : global.nodes) mean_intensity += double(tree.node(node).intensity_lum);
    mean_intensity /= double(global.nodes.size());

    std::set<uint32_t> rejected;  // parents whose pair failed the bound (final: rows never change)
    for (;;) {
      // Candidate pairs: both children of a parent in the cut
      struct Pair {
        uint32_t parent, a, b;  // a shares the parent's representative
        std::vector<uint32_t> rows;
      };
      std::vector<Pair> pairs;
      for (const auto& [node, state] : cut) {
        auto p = global.parent.find(node);
        if (p == global.parent.end()) continue;
        const LightTreeNode& parent = tree.node(p->second);
        if (uint32_t(parent.left) != node) continue;  // visit each pair once, from its left child
        if (!cut.count(uint32_t(parent.right)) || rejected.count(p->second)) continue;
        Pair pair{p->second, uint32_t(parent.left), uint32_t(parent.right), {}};
        if (tree.node(pair.a).representative != parent.representative) std::swap(pair.a, pair.b);
        pairs.push_back(std::move(pair));
      }
      if (pairs.empty()) break;

      // Rows ζ_f: the children's rows, topped up to ∝ I_f with fresh uniform rows
      std::vector<uint64_t> requests;
      for (Pair& pair : pairs) {
        const CutNode& ca = cut[pair.a];
        const CutNode& cb = cut[pair.b];
        std::set_union(ca.rows.begin(), ca.rows.end(), cb.rows.begin(), cb.rows.end(),
                       std::back_inserter(pair.rows));
        const double share =
            mean_intensity > 0 ? double(tree.node(pair.parent).intensity_lum) / (2 * mean_intensity)
                               : 1.0;
        const size_t target = size_t(std::clamp(std::ceil(s_.coarsen_samples * share), 2.0,
                                                double(m)));
        if (pair.rows.size() < target) {
          Rng rng(seed_for(RngStream::kRowSample, pair.parent));
          DrawDistinctRows(m, target - pair.rows.size(), rng, &pair.rows);
        }
        for (uint32_t node : {pair.parent, pair.a, pair.b})
          for (uint32_t r : pair.rows)
            requests.push_back(ElementCache::Key(tree.node(node).representative, r));
      }
      cache->Evaluate(std::move(requests), counters);

      // ε(f) = ‖V_a + V_b − V_f‖_∞ (= ‖V_b − V_a·I_b/I_a‖_∞ with f's representative a's),
      // cost(f) = ε(f) + cost(b) (Huo 2015, Eq. 1); merge below the bound
      bool merged = false;
      for (Pair& pair : pairs) {
        const RGB sa = NodeScale(tree, lights, pair.a), sb = NodeScale(tree, lights, pair.b);
        const RGB sf = NodeScale(tree, lights, pair.parent);
        const uint32_t la = tree.node(pair.a).representative;
        const uint32_t lb = tree.node(pair.b).representative;
        const uint32_t lf = tree.node(pair.parent).representative;
        double eps = 0;
        for (uint32_t r : pair.rows) {
          const RGB d = cache->Get(la, r) * sa + cache->Get(lb, r) * sb - cache->Get(lf, r) * sf;
          eps = std::max(eps, double(std::max({std::abs(d.r), std::abs(d.g), std::abs(d.b)})));
        }
        const double cost = eps + cut[pair.b].cost;
        if (cost < bound) {
          cut.erase(pair.a);
          cut.erase(pair.b);
          cut[pair.parent] = CutNode{cost, std::move(pair.rows)};
          merged = true;
        } else {
          rejected.insert(pair.parent);
        }
      }
      if (!merged) break;
    }
    std::vector<uint32_t> nodes;
    for (const auto& [node, state] : cut) nodes.push_back(node);
    return nodes;
  }

  // Draws entries until rate·m·n are known: columns ∝ g(j) (+ a uniform share), rows uniform
  // among the column's unobserved ones; evaluates them into the cache.
  template <typename SeedFn>
  void SampleEntries(const LightTree& tree, const LightSet& lights,
                     const std::vector<uint32_t>& coarse, uint32_t m, const SeedFn& seed_for,
                     std::vector<std::vector<uint32_t>>* observed_rows, ElementCache* cache,
                     MatrixCounters* counters) const {
    const uint32_t n = uint32_t(coarse.size());
    std::vector<std::vector<uint32_t>>& rows = *observed_rows;
    size_t known = 0;
    for (const auto& r : rows) known += r.size();
    const double total = double(m) * double(n);
    const size_t target = s_.rate >= 1 ? size_t(total) : size_t(std::ceil(s_.rate * total));
    if (known >= target) return;
    size_t remaining = target - known;

    // g(j) = max − min of the column's observed luminances
    std::vector<double> g(n, 0.0);
    double mean_g = 0;
    for (uint32_t j = 0; j < n; ++j) {
      if (rows[j].empty()) continue;
      const RGB scale = NodeScale(tree, lights, coarse[j]);
      const uint32_t light = tree.node(coarse[j]).representative;
      float lo = kInfinity, hi = -kInfinity;
      for (uint32_t r : rows[j]) {
        const float v = (cache->Get(light, r) * scale).Luminance();
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
      g[j] = double(hi - lo);
      mean_g += g[j];
    }
    mean_g /= double(n);
    for (double& w : g) w += kUniformColumnShare * mean_g;

    // Multinomial allocation over columns with room left; excess draws on a full column are
    // redrawn among the others (terminates: each round fills a column or places every draw)
    std::vector<size_t> alloc(n, 0);
    Rng rng(seed_for(RngStream::kColumnSample, 0));
    if (s_.rate >= 1) {
      for (uint32_t j = 0; j < n; ++j) alloc[j] = m - rows[j].size();
      remaining = 0;
    }
    while (remaining > 0) {
      std::vector<double> cdf(n);
      double sum = 0;
      bool any_room = false;
      for (uint32_t j = 0; j < n; ++j) {
        const bool room = rows[j].size() + alloc[j] < m;
        any_room |= room;
        sum += room ? g[j] : 0.0;
        cdf[j] = sum;
      }
      if (!any_room) break;
      if (!(sum > 0)) {  // no signal in any column with room: uniform over them
        sum = 0;
        for (uint32_t j = 0; j < n; ++j) {
          sum += rows[j].size() + alloc[j] < m ? 1.0 : 0.0;
          cdf[j] = sum;
        }
      }
      const size_t draws = remaining;
      for (size_t d = 0; d < draws; ++d) {
        const double u = rng.UniformDouble() * sum;
        const uint32_t j = uint32_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
        if (j < n && rows[j].size() + alloc[j] < m) {
          ++alloc[j];
          --remaining;
        }
      }
    }

    // Rows per column, then one batch of evaluations
    std::vector<uint64_t> requests;
    for (uint32_t j = 0; j < n; ++j) {
      if (alloc[j] == 0) continue;
      Rng row_rng(seed_for(RngStream::kRowSample, uint64_t(1) << 40 | j));
      DrawDistinctRows(m, alloc[j], row_rng, &rows[j]);
      const uint32_t light = tree.node(coarse[j]).representative;
      for (uint32_t r : rows[j]) requests.push_back(ElementCache::Key(light, r));
    }
    cache->Evaluate(std::move(requests), counters);
  }

  SparseCompletionSettings s_;
};

}  // namespace

std::unique_ptr<GatherMethod> CreateSparseCompletionGather(const OptionMap& params) {
  SparseCompletionSettings s;
  s.global_cut = size_t(params.GetInt("global_cut", 850, 1, 1LL << 32));
  s.merge_error = params.GetDouble("merge_error", 0.005, 0.0, 1e6);
  s.rate = params.GetDouble("rate", 0.1, 1e-6, 1.0);
  s.rank = int(params.GetInt("rank", 16, 1, 1024));
  s.coarsen_samples = int(params.GetInt("coarsen_samples", 8, 1, 1 << 20));
  s.reference_rows = int(params.GetInt("reference_rows", 8, 0, 1 << 20));
  s.iterations = int(params.GetInt("iterations", 100, 0, 1 << 20));
  s.tolerance = params.GetDouble("tolerance", 1e-4, 0.0, 1.0);
  return std::make_unique<SparseCompletionGather>(s);
}

GatherMethodInfo SparseCompletionMethod() {
  GatherMethodInfo m;
  m.name = "sparse-completion";
  m.create = CreateSparseCompletionGather;
  // Huo 2015: sampling rate 1-20% (10% default).
  m.sweep = "rate=0.01;rate=0.02;rate=0.05;rate=0.1;rate=0.2";
  // The sampling rate ∝ 1/target (0.002/target, within 1%..50%).
  m.params_for_target = [](double target) {
    std::ostringstream s;
    s << std::clamp(0.002 / target, 0.01, 0.5);
    return std::vector<std::string>{"rate=" + s.str()};
  };
  return m;
}

}  // namespace lightfarm
