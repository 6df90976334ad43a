// `lightslice`: matrix slice sampling (Ou & Pellacini 2011, "LightSlice: matrix slice sampling
// for the many-lights problem"). The plan's slices (6-D clusters of position and normal,
// slicing.h) are the row clusters; one sampled row per slice reveals the global structure of the
// lights, and each slice then refines that clustering with the rows of its nearest slices to find
// the lights that matter locally. The image of a slice is the sum of its clusters' scaled
// representative columns, evaluated on the slice's rows only.
//
// Stages (a job graph, DESIGN.md):
//   0 "rows"     workers, one task per slice: `slice_rows` rows of the slice picked by a hash of
//                (seed, slice), evaluated against every light; the payload is each row reduced
//                (RGB → 2-norm, as MRCS) as a non-zero bitmap plus floats.
//   Combine(0)   coordinator ("cluster"): the reduced matrix R (one row per slice) clustered
//                globally with the MRCS clustering (mrcs_clustering.h: random projection to
//                `projection` dimensions, α sampling, top-down splitting) into `global_clusters`
//                clusters; columns dark on every row of R keep their own power-sampled clusters.
//   1 "slices"   workers, final, one task per slice: the R rows of the slice and of its
//                `neighbors` nearest slices are the local rows; the global clusters are split
//                where the local columns disagree until the slice has `local_clusters` clusters
//                (LightSliceRefine, lightslice.h); per cluster a representative ∝ its local norm,
//                weighted s_k/‖ρ_rep‖ (scaled to the cluster's total, as MRCS Sec. 3.3), evaluated
//                on every row of the slice.
//
// Artifact (what every stage-1 task receives; on the farm a blob fetched once per worker): the
// global cluster of every light (4 bytes per light) and R itself, each row as a non-zero bitmap
// plus one 16-bit code per non-zero: log2 of the value relative to the row's maximum, 2048 codes
// per octave (relative error below 0.02%, 32 octaves; smaller non-zeros are clipped to the last
// code, zeros stay exact). At 10^5 lights and 80 slices that is at most 0.4 + 80·(12.5 + 200) KB
// ≈ 17 MB (less with occlusion zeros) instead of ~100 MB for dense float RGB rows. Re-evaluating
// the neighbours' rows in each stage-1 task instead would cost (1 + neighbors)·n extra elements
// per slice — at 10^5 lights more than the slice's representative columns — so R travels.
// `lightslice.artifact_bytes` in the stats reports its size. The coordinator's Combine holds R
// densely for the clustering (rows × lit lights floats: 32 MB at 80 × 10^5; heavy at 10^6).
//
// Parameters (--param KEY=VALUE):
//   global_clusters=200  C_global: clusters of the global step.
//   local_clusters=300   C_local: clusters (= representative columns, ≈ shadow rays per pixel)
//                        per slice. Huo et al. 2015 report LightSlice at 256–425 rays per pixel
//                        at 1.8–3.3% error; local_clusters >= number of lights renders every light
//                        with weight 1 (= brute force).
//   neighbors=8          nearest slices whose sampled rows join the slice's own in the local
//                        refinement (capped by the plan's neighbour list, 8 by default).
//   slice_rows=1         rows sampled per slice (the paper: one). With few slices the refinement
//                        sees few rows (docs/methods/lightslice.md).
//   projection=50        random projection of R's columns for the global clustering (0: none;
//                        skipped when R has no more rows than this).
//   dark_share=auto      share of C_local for the lights dark on every local row (at least one
//                        cluster when there are any); auto: their share of all lights, as mrcs.
//
// Randomness: sampled rows from (seed, kRowSample, slice); global clustering from the job seed
// (as mrcs); refinement and representatives from (seed, stage 1, slice). Blocks have fixed sizes
// and sums run in fixed orders, so the same seed gives the same bits for any thread count and
// any task order.
#include "common/gather/lightslice.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>

#include "common/gather/methods.h"
#include "common/util/payload_bytes.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

constexpr size_t kColumnBlock = 1024;  // lights per block when evaluating a full row
constexpr size_t kRowBlock = 256;      // receivers per block in the slice stage
constexpr double kCodesPerOctave = 2048;
constexpr uint32_t kRowsMagic = 0x30534c52;      // "RLS0"
constexpr uint32_t kArtifactMagic = 0x31534c41;  // "ALS1"

struct LightSliceSettings {
  size_t slice_rows = 1;
  size_t global_clusters = 200;
  size_t neighbors = 8;
  int projection = 50;
  LightSliceLocalOptions local;
};


// One reduced row of R: which lights are non-zero, and their values in light order.
struct SampledRow {
  uint32_t slice = 0, row = 0;
  std::vector<uint64_t> mask;
  std::vector<float> values;
};

template <typename Fn>
void ForEachNonZero(const SampledRow& row, Fn&& fn) {
  size_t v = 0;
  for (size_t wd = 0; wd < row.mask.size(); ++wd)
    for (uint64_t bits = row.mask[wd]; bits; bits &= bits - 1)
      fn(wd * 64 + size_t(std::countr_zero(bits)), row.values[v++]);
}

uint16_t EncodeRelative(float v, float scale) {
  const double octaves = std::max(0.0, -std::log2(double(v) / double(scale)));
  return uint16_t(std::min<double>(65535.0, 1.0 + std::round(octaves * kCodesPerOctave)));
}

float DecodeRelative(uint16_t code, float scale) {
  return float(double(scale) * std::exp2(-double(code - 1) / kCodesPerOctave));
}

std::vector<float> PowerLuminance(const LightSet& lights) {
  std::vector<float> power(lights.size());
  for (size_t j = 0; j < lights.size(); ++j) power[j] = lights.lights[j].power.Luminance();
  return power;
}

// The artifact, decoded for one slice: only the R rows it asks for.
struct GlobalClusters {
  uint64_t seed = 0, sampled_rows = 0, clusters = 0, zero_norm_clusters = 0;
  double objective = 0;
  std::vector<uint32_t> cluster_of;  // per light
  std::vector<SampledRow> rows;      // the requested slices' rows, in artifact order
};

class LightSliceGather final : public GatherMethod {
 public:
  explicit LightSliceGather(const LightSliceSettings& s) : s_(s) {}

  std::string name() const override { return "lightslice"; }
  // One uniformly drawn row per slice decides the slice's clusters; a coverage point covering a
  // sixteenth of a pixel at an edge is drawn as often as a whole pixel's, and the clusters then fit
  // the wrong surface (measured on cornell-box at 32², 5000 lights: rel_l2 against brute force up
  // to 0.18 with coverage 16 over four seeds, 0.013–0.028 with one path per sample).
  bool takes_coverage_rows() const override { return false; }
  int stage_count() const override { return 2; }
  std::string stage_name(int stage) const override { return stage == 0 ? "rows" : "slices"; }

  std::vector<SubMatrixTask> PlanStage(int stage, const GatherContext& ctx,
                                       const std::vector<SubMatrixTask>& tiles,
                                       const StageArtifact& previous) const override {
    if (stage == 1) return GatherMethod::PlanStage(stage, ctx, tiles, previous);
    return PlanRowTasks(tiles);
  }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact& previous) const override {
    return task.stage == 0 ? RunRowTask(ctx, task) : RunSliceTask(ctx, task, previous);
  }

  StageArtifact Combine(int stage, const GatherContext& ctx,
                        const std::vector<TaskOutput>& outputs) const override;

 private:
  std::vector<SubMatrixTask> PlanRowTasks(const std::vector<SubMatrixTask>& tiles) const;
  TaskOutput RunRowTask(const GatherContext& ctx, const SubMatrixTask& task) const;
  TaskOutput RunSliceTask(const GatherContext& ctx, const SubMatrixTask& task,
                          const StageArtifact& previous) const;
  GlobalClusters DecodeArtifact(const StageArtifact& bytes, size_t lights,
                                const std::set<uint32_t>& slices) const;

  LightSliceSettings s_;
};

// Stage 0: one task per slice (task id = the slice's tile id), holding its sampled rows.
std::vector<SubMatrixTask> LightSliceGather::PlanRowTasks(
    const std::vector<SubMatrixTask>& tiles) const {
  std::vector<SubMatrixTask> tasks;
  for (const SubMatrixTask& tile : tiles) {
    SubMatrixTask task;
    task.stage = 0;
    task.task_id = tile.task_id;
    task.seed = tile.seed;
    // `slice_rows` distinct rows, uniformly (partial Fisher–Yates on the slice's rows).
    std::vector<uint32_t> pool = tile.rows;
    const size_t k = std::min(s_.slice_rows, pool.size());
    Rng rng(HashSeed({tile.seed, uint64_t(RngStream::kRowSample), tile.task_id}));
    for (size_t i = 0; i < k; ++i)
      std::swap(pool[i], pool[i + rng.UniformInt(uint32_t(pool.size() - i))]);
    task.rows.assign(pool.begin(), pool.begin() + ptrdiff_t(k));
    std::sort(task.rows.begin(), task.rows.end());
    tasks.push_back(std::move(task));
  }
  if (tasks.empty()) tasks.emplace_back();  // Combine learns the seed from a payload
  return tasks;
}

TaskOutput LightSliceGather::RunRowTask(const GatherContext& ctx, const SubMatrixTask& task) const {
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols(), words = (n + 63) / 64;
  const size_t blocks = (n + kColumnBlock - 1) / kColumnBlock;
  TaskOutput result;
  PayloadWriter out;
  out.Put(kRowsMagic);
  out.Put(task.seed);
  out.Put(uint64_t(n));
  out.Put(task.task_id);
  out.Put(uint64_t(task.rows.size()));
  for (uint32_t row : task.rows) {
    // The full row in fixed blocks of lights (a slice's task holds one row: parallel over lights).
    std::vector<RGB> values(n);
    std::vector<MatrixCounters> counters(blocks);
    tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
      const size_t begin = b * kColumnBlock, len = std::min(kColumnBlock, n - begin);
      std::vector<uint32_t> rows(len, row), cols(len);
      std::iota(cols.begin(), cols.end(), uint32_t(begin));
      matrix.EvaluateEntries(rows, cols, std::span<RGB>(values.data() + begin, len), &counters[b]);
    });
    for (const MatrixCounters& c : counters) result.counters.Add(c);
    std::vector<uint64_t> mask(words, 0);
    std::vector<float> nonzero;
    for (size_t j = 0; j < n; ++j) {
      const float v = values[j].Norm();  // Hašan 2007, Sec. 3.2: RGB → 2-norm
      if (v > 0 && std::isfinite(v)) {
        mask[j / 64] |= uint64_t(1) << (j % 64);
        nonzero.push_back(v);
      }
    }
    out.Put(row);
    out.PutSparse(mask, nonzero);
  }
  result.payload = out.Take();
  result.stats["lightslice.row_payload_bytes"] = double(result.payload.size());
  return result;
}

StageArtifact LightSliceGather::Combine(int stage, const GatherContext& ctx,
                                        const std::vector<TaskOutput>& outputs) const {
  if (stage != 0) return {};
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols(), words = (n + 63) / 64;
  // Decode R, in task (= slice) order.
  uint64_t seed = 0;
  std::vector<SampledRow> rows;
  for (size_t t = 0; t < outputs.size(); ++t) {
    PayloadReader in(outputs[t].payload, "lightslice", "row-stage payload");
    if (in.Get<uint32_t>() != kRowsMagic)
      throw std::runtime_error("lightslice: the row stage returned a payload of another method");
    const uint64_t task_seed = in.Get<uint64_t>();
    if (t == 0) seed = task_seed;
    if (task_seed != seed) throw std::runtime_error("lightslice: row tasks disagree on the seed");
    if (in.Get<uint64_t>() != n)
      throw std::runtime_error("lightslice: row payload was computed for another light set");
    const uint32_t slice = in.Get<uint32_t>();
    const uint64_t count = in.Get<uint64_t>();
    for (uint64_t k = 0; k < count; ++k) {
      SampledRow row;
      row.slice = slice;
      row.row = in.Get<uint32_t>();
      in.GetSparse(words, &row.mask, &row.values);
      rows.push_back(std::move(row));
    }
    if (!in.AtEnd()) throw std::runtime_error("lightslice: trailing bytes in a row payload");
  }
  const size_t r = rows.size();

  // Global clustering of R's columns (Ou & Pellacini 2011: the MRCS clustering on the reduced
  // matrix of one row per slice).
  std::vector<double> norms(n, 0.0);
  for (const SampledRow& row : rows)
    ForEachNonZero(row, [&](size_t j, float v) { norms[j] += double(v) * double(v); });
  for (double& x : norms) x = std::sqrt(x);
  std::vector<uint32_t> point_lights, point_of(n, UINT32_MAX);
  for (size_t j = 0; j < n; ++j)
    if (norms[j] > 0) {
      point_of[j] = uint32_t(point_lights.size());
      point_lights.push_back(uint32_t(j));
    }
  Eigen::MatrixXf reduced = Eigen::MatrixXf::Zero(Eigen::Index(r), Eigen::Index(point_lights.size()));
  for (size_t i = 0; i < r; ++i)
    ForEachNonZero(rows[i], [&](size_t j, float v) { reduced(Eigen::Index(i), point_of[j]) = v; });
  Eigen::MatrixXf points;
  if (s_.projection > 0 && size_t(s_.projection) < r)
    points = MrcsProjectionMatrix(s_.projection, int(r), seed) * reduced;
  else
    points = std::move(reduced);
  MrcsClusterOptions options;
  options.clusters = s_.global_clusters;
  options.projection = 0;  // already applied
  const std::vector<float> power = PowerLuminance(matrix.lights());
  const MrcsClustering global =
      MrcsBuildClusters(points, point_lights, norms, power, {}, options, seed);
  std::vector<uint32_t> cluster_of(n, 0);
  for (size_t k = 0; k < global.clusters.size(); ++k)
    for (uint32_t j : global.clusters[k].lights) cluster_of[j] = uint32_t(k);

  // Artifact: the clustering and R, 16-bit log-encoded (see the top of this file).
  PayloadWriter out;
  out.Put(kArtifactMagic);
  out.Put(seed);
  out.Put(uint64_t(n));
  out.Put(uint64_t(r));
  out.Put(uint64_t(global.clusters.size()));
  out.Put(uint64_t(global.zero_norm_clusters));
  out.Put(global.objective);
  out.PutArray(cluster_of);
  for (const SampledRow& row : rows) {
    float scale = 0;
    for (float v : row.values) scale = std::max(scale, v);
    std::vector<uint16_t> codes(row.values.size());
    for (size_t k = 0; k < codes.size(); ++k) codes[k] = EncodeRelative(row.values[k], scale);
    out.Put(row.slice);
    out.Put(row.row);
    out.Put(scale);
    out.Put(uint64_t(codes.size()));
    out.PutArray(row.mask);
    out.PutArray(codes);
  }
  return out.Take();
}

GlobalClusters LightSliceGather::DecodeArtifact(const StageArtifact& bytes, size_t lights,
                                                const std::set<uint32_t>& slices) const {
  PayloadReader in(bytes, "lightslice", "cluster artifact");
  if (in.Get<uint32_t>() != kArtifactMagic)
    throw std::runtime_error("lightslice: the slice stage received an artifact of another method");
  GlobalClusters g;
  g.seed = in.Get<uint64_t>();
  if (in.Get<uint64_t>() != lights)
    throw std::runtime_error("lightslice: artifact was computed for another light set");
  const size_t words = (lights + 63) / 64;
  g.sampled_rows = in.Get<uint64_t>();
  g.clusters = in.Get<uint64_t>();
  g.zero_norm_clusters = in.Get<uint64_t>();
  g.objective = in.Get<double>();
  in.GetArray(&g.cluster_of, lights);
  for (uint32_t k : g.cluster_of)
    if (k >= g.clusters) throw std::runtime_error("lightslice: artifact names a cluster out of range");
  for (uint64_t i = 0; i < g.sampled_rows; ++i) {
    SampledRow row;
    row.slice = in.Get<uint32_t>();
    row.row = in.Get<uint32_t>();
    const float scale = in.Get<float>();
    const uint64_t nnz = in.Get<uint64_t>();
    if (!slices.count(row.slice)) {  // another slice's row: not needed here
      if (nnz > lights) throw std::runtime_error("lightslice: corrupt artifact");
      in.Skip(words * sizeof(uint64_t) + nnz * sizeof(uint16_t));
      continue;
    }
    std::vector<uint16_t> codes;
    in.GetArray(&row.mask, words);
    in.GetArray(&codes, nnz);
    size_t bits = 0;
    for (uint64_t word : row.mask) bits += size_t(std::popcount(word));
    if (bits != nnz) throw std::runtime_error("lightslice: corrupt artifact");
    row.values.resize(nnz);
    for (size_t k = 0; k < nnz; ++k) row.values[k] = DecodeRelative(codes[k], scale);
    g.rows.push_back(std::move(row));
  }
  if (!in.AtEnd()) throw std::runtime_error("lightslice: trailing bytes in the artifact");
  return g;
}

TaskOutput LightSliceGather::RunSliceTask(const GatherContext& ctx, const SubMatrixTask& task,
                                          const StageArtifact& previous) const {
  const LightingMatrix& matrix = ctx.matrix;
  const size_t n = matrix.cols();
  TaskOutput result;
  const size_t nrows = task.rows.size();
  result.row_sums.resize(nrows);
  // Local rows: the slice's own sampled rows and its nearest slices'.
  std::set<uint32_t> local_slices = {task.task_id};
  for (size_t k = 0; k < std::min(s_.neighbors, task.neighbors.size()); ++k)
    local_slices.insert(task.neighbors[k]);
  const GlobalClusters global = DecodeArtifact(previous, n, local_slices);
  if (task.task_id == 0) {  // once per job: the numbers are summed over tasks
    result.stats["lightslice.artifact_bytes"] = double(previous.size());
    result.stats["lightslice.sampled_rows"] = double(global.sampled_rows);
    result.stats["lightslice.global_clusters"] = double(global.clusters);
    result.stats["lightslice.global_zero_norm_clusters"] = double(global.zero_norm_clusters);
    result.stats["lightslice.global_objective"] = global.objective;
  }
  if (nrows == 0 || n == 0) return result;
  Eigen::MatrixXf local = Eigen::MatrixXf::Zero(Eigen::Index(global.rows.size()), Eigen::Index(n));
  for (size_t i = 0; i < global.rows.size(); ++i)
    ForEachNonZero(global.rows[i],
                   [&](size_t j, float v) { local(Eigen::Index(i), Eigen::Index(j)) = v; });
  const std::vector<float> power = PowerLuminance(matrix.lights());
  const uint64_t slice_seed = HashSeed({task.seed, task.stage, task.task_id});
  const LightSliceLocalClustering refined =
      LightSliceRefine(local, global.cluster_of, power, s_.local, slice_seed);
  const std::vector<MrcsCluster>& clusters = refined.clustering.clusters;
  std::vector<std::pair<uint32_t, double>> reps(clusters.size());
  for (size_t k = 0; k < clusters.size(); ++k) {
    MrcsRepresentative rep = MrcsChooseRepresentative(clusters[k], slice_seed, uint32_t(k));
    reps[k] = {rep.light, rep.weight};
  }
  // Each block of receivers walks the representatives in cluster order: a fixed sum order.
  const size_t blocks = (nrows + kRowBlock - 1) / kRowBlock;
  std::vector<MatrixCounters> counters(blocks);
  tbb::parallel_for(size_t(0), blocks, [&](size_t b) {
    const size_t begin = b * kRowBlock, len = std::min(kRowBlock, nrows - begin);
    std::span<const uint32_t> rows(task.rows.data() + begin, len);
    std::vector<RGB> column(len);
    for (const auto& [light, weight] : reps) {
      matrix.Column(light, rows, column, &counters[b]);
      for (size_t i = 0; i < len; ++i) {
        RGBAccum& acc = result.row_sums[begin + i];
        acc.r += weight * double(column[i].r);
        acc.g += weight * double(column[i].g);
        acc.b += weight * double(column[i].b);
      }
    }
  });
  for (const MatrixCounters& c : counters) result.counters.Add(c);
  result.stats["lightslice.local_rows"] = double(global.rows.size());
  result.stats["lightslice.local_clusters"] = double(clusters.size());
  result.stats["lightslice.local_dark_lights"] = double(refined.clustering.zero_norm_columns);
  result.stats["lightslice.local_dark_clusters"] = double(refined.clustering.zero_norm_clusters);
  result.stats["lightslice.local_objective"] = refined.clustering.objective;
  result.stats["lightslice.local_objective_unrefined"] = refined.global_objective;
  return result;
}

}  // namespace

// --- lightslice.h ------------------------------------------------------------------------------

LightSliceLocalClustering LightSliceRefine(const Eigen::MatrixXf& local,
                                           std::span<const uint32_t> global_of,
                                           std::span<const float> power,
                                           const LightSliceLocalOptions& options, uint64_t seed) {
  const size_t n = size_t(local.cols());
  if (global_of.size() != n || power.size() != n)
    throw std::invalid_argument("LightSliceRefine: inconsistent sizes");
  LightSliceLocalClustering out;
  MrcsClustering& c = out.clustering;
  std::vector<double> w(n);
  std::vector<uint32_t> lit, dark;
  for (size_t j = 0; j < n; ++j) {
    w[j] = local.col(Eigen::Index(j)).cast<double>().norm();
    (w[j] > 0 ? lit : dark).push_back(uint32_t(j));
  }
  const size_t n_plus = lit.size(), n_zero = dark.size();
  c.zero_norm_columns = n_zero;
  // The lit lights' points (local columns) and their global groups, in global-cluster order.
  Eigen::MatrixXf points(local.rows(), Eigen::Index(n_plus));
  std::map<uint32_t, std::vector<uint32_t>> by_global;
  for (size_t p = 0; p < n_plus; ++p) {
    points.col(Eigen::Index(p)) = local.col(Eigen::Index(lit[p]));
    by_global[global_of[lit[p]]].push_back(uint32_t(p));
  }
  std::vector<std::vector<uint32_t>> groups;
  for (auto& [k, members] : by_global) groups.push_back(std::move(members));
  out.lit_global_groups = groups.size();
  if (n_plus > 0) out.global_objective = MrcsObjective(points, groups);

  const size_t budget = std::max<size_t>(options.clusters, 1);
  if (budget >= n) {  // every light its own cluster, weight exactly 1: the exact sum
    for (uint32_t j = 0; j < n; ++j) c.clusters.push_back({{j}, {1.0}, !(w[j] > 0)});
    c.zero_norm_clusters = n_zero;
    return out;
  }
  // Budget split as MrcsBuildClusters: round(share·C) for the dark lights (at least 1, at most
  // their number), the rest for the lit ones (at least 1); what one cannot use goes to the other.
  const double share = options.dark_share >= 0 ? options.dark_share : double(n_zero) / double(n);
  size_t c_zero = 0, c_plus = 0;
  if (n_zero > 0) c_zero = std::clamp<size_t>(size_t(std::llround(share * double(budget))), 1, n_zero);
  if (n_plus > 0) c_plus = std::clamp<size_t>(budget > c_zero ? budget - c_zero : 0, 1, n_plus);
  if (n_zero > 0) c_zero = std::clamp<size_t>(budget > c_plus ? budget - c_plus : 0, 1, n_zero);

  // Lit lights: split the global clusters where the local columns disagree; representative
  // ∝ local norm, weight s_k / ‖ρ_rep‖ (Hašan 2007, Sec. 3.3).
  if (n_plus > 0) {
    const std::vector<std::vector<uint32_t>> split =
        MrcsSplitClusters(points, std::move(groups), c_plus, seed);
    c.objective = MrcsObjective(points, split);
    for (const std::vector<uint32_t>& g : split) c.clusters.push_back(MrcsWeightedCluster(g, lit, w));
  }
  // Dark lights: the rows say nothing about them here, so runs of equal power in global-cluster
  // order, representative ∝ power (mrcs's zero-norm clusters, MrcsBuildClusters with no points).
  if (n_zero > 0) {
    std::vector<double> zeros(n_zero, 0.0);
    std::vector<float> dark_power(n_zero);
    std::vector<uint64_t> keys(n_zero);
    for (size_t t = 0; t < n_zero; ++t) {
      dark_power[t] = power[dark[t]];
      keys[t] = global_of[dark[t]];
    }
    MrcsClusterOptions zo;
    zo.clusters = c_zero;
    zo.projection = 0;
    const MrcsClustering runs = MrcsBuildClusters(Eigen::MatrixXf(local.rows(), 0), {}, zeros,
                                                  dark_power, keys, zo, seed);
    for (MrcsCluster run : runs.clusters) {
      for (uint32_t& j : run.lights) j = dark[j];
      run.zero_norm = true;
      c.clusters.push_back(std::move(run));
    }
    c.zero_norm_clusters = runs.clusters.size();
  }
  return out;
}

std::unique_ptr<GatherMethod> CreateLightSliceGather(const OptionMap& params) {
  LightSliceSettings s;
  s.global_clusters = size_t(params.GetInt("global_clusters", 200, 1, 1LL << 32));
  s.local.clusters = size_t(params.GetInt("local_clusters", 300, 1, 1LL << 32));
  s.neighbors = size_t(params.GetInt("neighbors", 8, 0, 1 << 16));
  s.slice_rows = size_t(params.GetInt("slice_rows", 1, 1, 1 << 16));
  s.projection = int(params.GetInt("projection", 50, 0, 1 << 16));
  if (params.GetString("dark_share", "auto") != "auto")
    s.local.dark_share = params.GetDouble("dark_share", 0.0, 0.0, 1.0);
  return std::make_unique<LightSliceGather>(s);
}

GatherMethodInfo LightSliceMethod() {
  GatherMethodInfo m;
  m.name = "lightslice";
  m.create = CreateLightSliceGather;
  // Ou & Pellacini 2011: global clusters and the per-slice refinement's clusters (2:3).
  m.sweep = "global_clusters=50,local_clusters=75;global_clusters=100,local_clusters=150;"
            "global_clusters=200,local_clusters=300;global_clusters=400,local_clusters=600;"
            "global_clusters=800,local_clusters=1200";
  return m;
}

}  // namespace lightfarm
