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
constexpr size_t kRowBlock = 256;      // receivers per block in the column stage (one ray batch)

uint64_t Stream(RngStream s) { return static_cast<uint64_t>(s); }

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

// The row stage's payload (one per task): its reduced rows and, for colour averaging, the
// per-channel Σ_i A_ij² of its rows. EncodeRowPayload and DecodeRowPayload are each other's
// inverse (the decoder checks what the encoder wrote).
struct RowPayload {
  uint64_t seed = 0;
  uint64_t lights = 0;
  std::vector<ReducedRow> rows;
  bool color = false;
  std::vector<float> squares;  // 3 per light when `color`
};

std::vector<uint8_t> EncodeRowPayload(const RowPayload& p) {
  PayloadWriter out;
  out.Put(kRowsMagic);
  out.Put(p.seed);
  out.Put(p.lights);
  out.Put(uint64_t(p.rows.size()));
  out.Put(uint8_t(p.color ? 1 : 0));
  for (const ReducedRow& row : p.rows) {
    out.Put(row.row);
    out.PutSparse(row.mask, row.values);
  }
  if (p.color) out.PutArray(p.squares);
  return out.Take();
}

RowPayload DecodeRowPayload(const std::vector<uint8_t>& bytes, size_t lights) {
  PayloadReader in(bytes, "mrcs", "row-stage payload");
  RowPayload p;
  if (in.Get<uint32_t>() != kRowsMagic)
    throw std::runtime_error("mrcs: the row stage returned a payload of another method");
  p.seed = in.Get<uint64_t>();
  p.lights = in.Get<uint64_t>();
  if (p.lights != lights) throw std::runtime_error("mrcs: row-stage payload was computed for another light set");
  const size_t words = (lights + 63) / 64;
  const uint64_t count = in.Get<uint64_t>();
  p.color = in.Get<uint8_t>() != 0;
  for (uint64_t k = 0; k < count; ++k) {
    ReducedRow row;
    row.row = in.Get<uint32_t>();
    in.GetSparse(words, &row.mask, &row.values);
    p.rows.push_back(std::move(row));
  }
  if (p.color) in.GetArray(&p.squares, 3 * lights);
  if (!in.AtEnd()) throw std::runtime_error("mrcs: trailing bytes in a row-stage payload");
  return p;
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
  RowPayload payload;
  payload.seed = task.seed;
  payload.lights = n;
  payload.rows = std::move(rows);
  payload.color = color;
  if (color) {
    // Per-channel Σ_i A_ij² over this task's rows, for the colour-averaged weights.
    payload.squares.resize(3 * n);
    tbb::parallel_for(size_t(0), (n + kColumnBlock - 1) / kColumnBlock, [&](size_t b) {
      for (size_t j = b * kColumnBlock; j < std::min(n, (b + 1) * kColumnBlock); ++j)
        for (int c = 0; c < 3; ++c) {
          double sum = 0;
          for (size_t k = 0; k < nrows; ++k) sum += double(full[k][j][c]) * double(full[k][j][c]);
          payload.squares[3 * j + size_t(c)] = float(sum);
        }
    });
  }
  result.payload = EncodeRowPayload(payload);
  return result;
}

StageArtifact MatrixRowColumnSampling::Combine(int stage, const GatherContext& ctx,
                                               const std::vector<TaskOutput>& outputs) const {
  if (stage != 0) return {};
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols(), words = (n + 63) / 64;
  const size_t blocks = (n + kColumnBlock - 1) / kColumnBlock;
  // The reduced rows, in task order.
  uint64_t seed = 0;
  std::vector<ReducedRow> rows;
  std::vector<double> channel_squares;  // 3 per light, when colour averaging
  for (size_t t = 0; t < outputs.size(); ++t) {
    RowPayload payload = DecodeRowPayload(outputs[t].payload, n);
    if (t == 0) seed = payload.seed;
    if (payload.seed != seed) throw std::runtime_error("mrcs: row-stage tasks disagree on the seed");
    for (ReducedRow& row : payload.rows) rows.push_back(std::move(row));
    if (payload.color) {
      channel_squares.resize(3 * n, 0.0);
      for (size_t i = 0; i < 3 * n; ++i) channel_squares[i] += double(payload.squares[i]);
    }
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
  return m;
}

}  // namespace lightfarm
