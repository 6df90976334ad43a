// `lightcuts` (Walter et al. 2005): for every receiver, a cut through the light tree chosen by
// refining the node with the largest error bound until every bound is below `error` × the
// current total estimate (or the cut reaches `max_cut` nodes).
//
// - A node's estimate is its representative's matrix element scaled channel by channel by
//   intensity(node) / power(representative) (Walter 2005, Eq. 2: the cluster's lights share the
//   representative's material, geometry and visibility terms). A leaf's estimate is its matrix
//   element itself, so with error=0 the cut refines to every leaf that can contribute and the
//   sum equals brute force. A child that inherits its parent's representative reuses the
//   parent's element: each refinement costs one new element (one shadow ray).
// - A node's error bound is an upper bound of Σ_j A_ij over its lights with visibility bounded
//   by 1: throughput · (material bound) · (geometric bound) · (emission bound) · intensity. All
//   bounds come from the node's bounding box and normal cone through the cone of directions
//   from the receiver to the box (its bounding sphere) — see ReceiverBounds and NodeBound.
//   * geometric: 1/max(d², d_min²) for VPLs (the clamp, d = distance to the box), 1/d² for
//     point lights (unbounded when the receiver is inside the box: refine), 1 for directional.
//   * receiver material: diffuse lobes: albedo/π × the cosine bound over the box (per side:
//     reflection on the side of wo, diffuse transmission on the other); Trowbridge-Reitz
//     lobes (conductor, rough coat, rough dielectric reflection): f·cos = D F G / (4 cos_o)
//     with F, G ≤ 1 and D bounded at the half vector closest to the normal: the half vector's
//     angle to the normal is at least half the angle between wi and the mirror direction of wo
//     (the half-vector map contracts sphere distances by at most 2), so D is bounded from the
//     angle between the box cone and the mirror direction. Rough-dielectric transmission has
//     no bound here: nodes that can reach that side are refined to leaves.
//   * emission: area VPLs: the cosine bound between the node's normal cone and the directions
//     from the box to the receiver (1 for two-sided emitters); surface VPLs: the same cosine
//     bound times the largest diffuse albedo/π below the node, plus, for glossy VPLs, the same
//     half-vector bound of D as for receivers, against a cone bounding the VPLs' mirror
//     directions (with the largest 1 / (4 cos_in π ax ay) and alpha below the node); points and
//     directional lights: 1.
//   The per-node emission bounds need the VPLs' materials; they are computed once per tree
//   (bottom-up, cached in the method).
// - Coated diffuse base: f_base(wo, wi) = K h(wo) h(wi) with h(w) = (1 − E(w)) e^{−a/cos'},
//   h ≤ 1 and h largest near the normal, so f_base ≤ f(wo, n) / (1 − E(n)); E(n) is bounded
//   by F0 (smooth coat, exact) or 4 F0 + 0.02 (rough coat, with margin for the tabulated E).
//
// Bounds and totals are compared in luminance. Elements a receiver's path-depth budget excludes
// are zero; the bounds ignore that (they stay conservative) and the representative estimate
// stays unbiased over the representative choice.
//
// The dark floor: a relative bound is hardest to meet where a receiver gets little light (a floor
// in the shadow of a plate, the far wall a glossy reflection lands on): the total is small, the
// bounds assume every light visible, and the cut runs to max_cut for a value the image barely
// holds. Below a few percent of the image's brightness an error is a fraction of a fraction of
// what the eye or rel_l1 sees (luminance discrimination is relative only above a dark floor:
// Weber's law bends there, the threshold-versus-intensity curve flattens). So a row whose cut
// holds max_cut / 4 nodes also stops when every bound is below error × F, F = floor × L/r (a
// smaller cut answers to the relative bound only: kFloorFromCutShare), L the image's mean
// radiance per camera sample (the light its camera paths collect by themselves plus its rows),
// r the rows per sample. A sample's error then stays below error × max(its radiance, floor × L),
// roughly. L comes from a pilot stage before the gather: an image-wide stratified subset of
// about kPilotRows rows (every k-th row; rows are in pixel order) refines its cuts at a coarser
// bound, and Combine adds their mean to the samples' own radiance. The subset depends only on
// the receivers, so the floor, and every row's cut, are the same however the rows are sliced.
//
// Parameters: error (relative error bound, default 0.02), max_cut (default 1000; unlimited
// when error = 0, which then means "exact"), floor (default kDefaultFloor; 0: no pilot, the
// plain relative bound; ignored when error = 0).
// Stats: "cut_size" is the sum of the final cut sizes over the task's rows (stats / rows = mean
// cut size); "cut_capped" counts rows whose cut stopped at max_cut; "floored" rows whose cut
// stopped on the floor before its own total's bound; "pilot_rows" the pilot's rows.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <limits>
#include <memory>
#include <mutex>
#include <span>

#include "common/gather/methods.h"
#include "common/lights/light_bounds.h"
#include "common/scene/bsdf.h"
#include "common/util/check.h"
#include "common/util/payload_bytes.h"

namespace lightfarm {

namespace {

// The pilot: about this many rows, refined at a bound of at least kPilotError and at most
// kPilotMaxCut nodes (it only needs the image's mean to a few percent).
constexpr size_t kPilotRows = 1024;
constexpr double kPilotError = 0.1;
constexpr size_t kPilotMaxCut = 256;
constexpr size_t kPilotRowsPerTask = 256;
// The floor's default, a fraction of the image's mean radiance per row: chosen by the sweep in
// docs/methods/lightcuts-floor.md (scripts/report-lightcuts-floor.sh).
constexpr double kDefaultFloor = 0.1;
// The floor only stops cuts of at least max_cut / 4 nodes (256 at the default cap): a dark row
// still gets that many before the floor ends it. Stopped earlier, whole dark regions came out as
// single-pixel specks (a few clusters whose representatives were all occluded); the floor's gain
// is the rows that would otherwise run to the cap.
constexpr size_t kFloorFromCutShare = 4;

// ---------------------------------------------------------------------------------------
// One receiver's view of the tree

struct ReceiverBounds {
  Vec3 p;
  Vec3 n_front;  // shading normal on the side of wo
  Vec3 mirror;   // wo reflected about the shading normal (world space)
  RGB throughput;
  LobeBound lobe;
};

// Upper bound of the receiver's f·|cos| over the cone of directions `c` (RGB).
RGB ReceiverMaterialBound(const ReceiverBounds& r, const DirectionCone& c, const Bounds3* box) {
  float cos_front = CosBound(r.n_front, c, r.p, box);
  float cos_back = CosBound(-r.n_front, c, r.p, box);
  RGB bound = r.lobe.diffuse_front * cos_front + r.lobe.diffuse_back * cos_back;
  if (r.lobe.glossy && cos_front > 0) {
    float cos2_h = HalfVectorCos2Bound(c.axis, c.spread, r.mirror, HalfAngle::FromCos(1.f));
    bound += RGB(MicrofacetDBound(r.lobe.alpha_x, r.lobe.alpha_y, cos2_h) * r.lobe.glossy_scale);
  }
  if (r.lobe.back_unbounded && cos_back > 0) return RGB(kInfinity);
  return bound;
}

class LightcutsGather final : public GatherMethod {
 public:
  LightcutsGather(double error, size_t max_cut, double floor)
      : error_(error), max_cut_(max_cut), floor_(error > 0 ? floor : 0) {}

  std::string name() const override { return "lightcuts"; }
  bool needs_light_tree() const override { return true; }
  int stage_count() const override { return floor_ > 0 ? 2 : 1; }
  std::string stage_name(int stage) const override {
    return stage + 1 == stage_count() ? "gather" : "pilot";
  }

  std::vector<SubMatrixTask> PlanStage(int stage, const GatherContext& ctx,
                                       const std::vector<SubMatrixTask>& tiles,
                                       const StageArtifact& previous) const override {
    if (stage + 1 == stage_count()) return GatherMethod::PlanStage(stage, ctx, tiles, previous);
    // Every k-th row of the image, in row order, whichever tile holds it.
    const size_t k = std::max<size_t>(1, ctx.matrix.receivers().points.size() / kPilotRows);
    std::vector<uint32_t> pilot;
    for (const SubMatrixTask& tile : tiles)
      for (uint32_t row : tile.rows)
        if (row % k == 0) pilot.push_back(row);
    std::sort(pilot.begin(), pilot.end());
    // At least one task, so that Combine runs even without receivers.
    std::vector<SubMatrixTask> tasks;
    for (size_t begin = 0; begin < pilot.size() || tasks.empty(); begin += kPilotRowsPerTask) {
      SubMatrixTask task;
      task.stage = uint32_t(stage);
      task.task_id = uint32_t(tasks.size());
      task.seed = tiles.empty() ? 0 : tiles.front().seed;
      const size_t end = std::min(pilot.size(), begin + kPilotRowsPerTask);
      if (begin < end) task.rows.assign(pilot.begin() + ptrdiff_t(begin), pilot.begin() + ptrdiff_t(end));
      tasks.push_back(std::move(task));
    }
    return tasks;
  }

  // The pilot's payloads (row count, summed luminance) → the artifact: the floor F.
  StageArtifact Combine(int, const GatherContext& ctx, const std::vector<TaskOutput>& outputs) const override {
    double rows = 0, sum = 0;
    for (const TaskOutput& o : outputs) {
      PayloadReader in(o.payload, "lightcuts", "pilot payload");
      rows += double(in.Get<uint64_t>());
      sum += in.Get<double>();
      if (!in.AtEnd()) throw std::runtime_error("lightcuts: trailing bytes in a pilot payload");
    }
    const ReceiverSet& receivers = ctx.matrix.receivers();
    double emitted = 0;
    for (const CameraSample& s : receivers.samples) emitted += double(std::max(0.f, s.emitted.Luminance()));
    float floor = 0;
    if (rows > 0 && !receivers.points.empty()) {
      // L / r = (emitted per sample + row mean × r) / r, r = rows per sample.
      const double per_sample = double(receivers.points.size()) / double(receivers.samples.size());
      floor = float(floor_ * (emitted / double(receivers.samples.size()) / per_sample + sum / rows));
    }
    PayloadWriter out;
    out.Put(floor);
    return out.Take();
  }

  // Its bounds know surface elements only (material × geometry × cone); media rows need their own.
  bool gathers_media() const override { return false; }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact& previous) const override {
    CHECK(ctx.tree != nullptr);  // the plan builds the tree for methods that need one
    std::shared_ptr<const std::vector<EmissionBound>> emission = Emission(ctx);
    const bool pilot = int(task.stage) + 1 < stage_count();
    Criterion criterion{float(error_), max_cut_, 0.f};
    if (pilot) {
      criterion = Criterion{float(std::max(error_, kPilotError)), std::min(max_cut_, kPilotMaxCut), 0.f};
    } else if (floor_ > 0) {
      PayloadReader in(previous, "lightcuts", "pilot artifact");
      criterion.floor = in.Get<float>();
      if (!in.AtEnd() || !(criterion.floor >= 0) || !std::isfinite(criterion.floor))
        throw std::runtime_error("lightcuts: corrupt pilot artifact");
    }
    TaskOutput result;
    result.row_sums.resize(task.rows.size());
    // Chunks of rows refine their cuts in lockstep so that their new elements are evaluated
    // in one batch (Embree traces batches of shadow rays much faster than single rays). Each
    // row's cut depends only on its own elements, so the result does not depend on the chunks
    // or on how they are spread over threads.
    constexpr size_t kRowsPerChunk = 64;
    const size_t nchunks = (task.rows.size() + kRowsPerChunk - 1) / kRowsPerChunk;
    std::vector<ChunkStats> chunks(nchunks);
    tbb::parallel_for(size_t(0), nchunks, [&](size_t c) {
      size_t begin = c * kRowsPerChunk, end = std::min(task.rows.size(), begin + kRowsPerChunk);
      GatherRows(ctx.matrix, *ctx.tree, *emission, criterion,
                 std::span<const uint32_t>(task.rows).subspan(begin, end - begin),
                 std::span<RGBAccum>(result.row_sums).subspan(begin, end - begin), &chunks[c]);
    });
    double cut_size = 0, capped = 0, floored = 0;
    for (const ChunkStats& c : chunks) {
      result.counters.Add(c.counters);
      cut_size += c.cut_size;
      capped += c.capped;
      floored += c.floored;
    }
    if (pilot) {
      // The mean of the pilot rows' luminance, summed in row order: the same bits on any threads.
      double sum = 0;
      for (const RGBAccum& r : result.row_sums) sum += double(std::max(0.f, r.ToRGB().Luminance()));
      PayloadWriter out;
      out.Put(uint64_t(task.rows.size()));
      out.Put(sum);
      result.payload = out.Take();
      result.row_sums.clear();
      result.stats["pilot_rows"] = double(task.rows.size());
      return result;
    }
    result.stats["cut_size"] = cut_size;
    result.stats["cut_capped"] = capped;
    result.stats["floored"] = floored;
    return result;
  }

 private:
  // When a row's cut stops: every bound below error × max(total, floor), or max_cut nodes. The
  // floor counts only from max_cut / kFloorFromCutShare nodes on.
  struct Criterion {
    float error;
    size_t max_cut;
    float floor;
    float Floor(size_t cut_size) const {
      return cut_size >= max_cut / kFloorFromCutShare ? floor : 0.f;
    }
  };

  struct ChunkStats {
    MatrixCounters counters;
    double cut_size = 0, capped = 0, floored = 0;
  };

  struct CutNode {
    float bound = 0;  // error bound (luminance); 0 for leaves and nodes that cannot contribute
    uint32_t node = 0;
    RGB estimate;
    RGB rep_value;  // the representative's element
    bool rep_known = false;
  };
  // The cut as a max-heap of small entries on the bound (ties by node index, so the cut is
  // deterministic) pointing into a pool of cut nodes.
  struct HeapEntry {
    float bound;
    uint32_t node;
    uint32_t slot;  // index into RowCut::pool
  };
  static bool HeapLess(const HeapEntry& a, const HeapEntry& b) {
    if (a.bound != b.bound) return a.bound < b.bound;
    return a.node > b.node;
  }

  struct RowCut {
    ReceiverBounds receiver;
    std::vector<CutNode> pool;  // every node that has been in the cut
    std::vector<HeapEntry> heap;  // the current cut
    RGB total;  // running sum of the cut's estimates
    bool done = false;
  };

  // Error bound (luminance of the RGB bound) of a node for a receiver; 0 when no light below
  // can reach it.
  static float NodeBound(const ReceiverBounds& r, const LightTreeNode& node,
                         const EmissionBound& e, float clamp2) {
    if (node.intensity.IsBlack()) return 0.f;
    RGB material;
    float light = 1, geometric = 1;
    if (node.kind == VirtualLightKind::kDirectional) {
      // Directions towards the lights: the travel directions reversed.
      DirectionCone c;
      c.axis = -node.cone_axis;
      c.spread = HalfAngle::FromCos(node.cone_cos);
      material = ReceiverMaterialBound(r, c, nullptr);
    } else {
      DirectionCone c = ConeToBox(r.p, node.bounds);
      material = ReceiverMaterialBound(r, c, &node.bounds);
      if (material.IsBlack()) return 0.f;
      if (node.kind == VirtualLightKind::kPoint) {
        geometric = c.dist2 > 0 ? 1.f / c.dist2 : kInfinity;
      } else {
        // The clamp bounds 1/d² by 1/d_min² (elements are clamped).
        geometric = 1.f / std::max(c.dist2, clamp2);
        // Emission: cosine between the node's normals and the directions box → receiver.
        float front = 1, back = 1;
        if (node.cone_cos > -1.f && !c.spread.All()) {
          HalfAngle spread = HalfAngle::FromCos(node.cone_cos) + c.spread;
          float cos_na = -Dot(node.cone_axis, c.axis);
          front = ConeMaxCos(cos_na, spread);
          back = ConeMaxCos(-cos_na, spread);
        }
        light = e.diffuse_front * front + e.diffuse_back * back +
                (front > 0 ? e.Glossy(-c.axis, c.spread) : 0.f);
        if (e.back_unbounded && back > 0) light = kInfinity;
      }
    }
    float lum = (r.throughput * node.intensity * material).Luminance() * light * geometric;
    if (std::isnan(lum)) return kInfinity;  // 0 · ∞: no bound, refine
    return lum;
  }

  // The node's estimate from its representative's element (Walter 2005, Eq. 2), channel by
  // channel; a leaf's estimate is its element.
  static RGB Scale(const RGB& rep_value, const LightTreeNode& node, const VirtualLight& rep) {
    if (node.IsLeaf()) return rep_value;
    RGB e;
    for (int c = 0; c < 3; ++c)
      e[c] = rep.power[c] > 0 ? rep_value[c] * (node.intensity[c] / rep.power[c]) : 0.f;
    return e;
  }

  static bool WantsRefinement(const RowCut& cut, float error, float floor) {
    if (cut.heap.empty()) return false;
    const float bound = cut.heap.front().bound;
    return bound > 0 && bound > error * std::max(floor, cut.total.Luminance());
  }

  void GatherRows(const LightingMatrix& matrix, const LightTree& tree,
                  const std::vector<EmissionBound>& emission, const Criterion& criterion,
                  std::span<const uint32_t> rows,
                  std::span<RGBAccum> sums, ChunkStats* stats) const {
    const std::vector<Material>& materials = matrix.scene().materials();
    const LightSet& lights = matrix.lights();
    const float clamp2 = Sqr(matrix.clamp_distance());

    // Receiver data for the bounds
    std::vector<RowCut> cuts(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      const ShadingPoint& sp = matrix.receivers().points[rows[i]];
      ReceiverBounds& r = cuts[i].receiver;
      r.p = sp.p;
      r.throughput = sp.throughput;
      Vec3 wo_local = Frame(sp.ns).ToLocal(sp.wo);
      r.n_front = wo_local.z < 0 ? -sp.ns : sp.ns;
      r.mirror = sp.ns * (2 * Dot(sp.wo, sp.ns)) - sp.wo;
      r.lobe = MaterialLobeBound(materials[sp.material], wo_local, TransportMode::kRadiance);
    }

    // New cut nodes of this step; those that need their representative's element are listed
    // in (entry_rows, entry_cols) and filled after one batched evaluation.
    struct Pending {
      uint32_t cut;  // row within the chunk
      CutNode node;
      int32_t entry = -1;  // index into the batch, -1: value known (or not needed)
    };
    std::vector<Pending> pending;
    std::vector<uint32_t> entry_rows, entry_cols;
    std::vector<RGB> entry_values;
    auto add = [&](uint32_t cut, uint32_t index, const CutNode* parent) {
      const LightTreeNode& node = tree.node(index);
      Pending p;
      p.cut = cut;
      p.node.node = index;
      float bound = NodeBound(cuts[cut].receiver, node, emission[index], clamp2);
      if (bound > 0) {
        // Bound zero: nothing below reaches the receiver, the node is exactly zero.
        p.node.bound = node.IsLeaf() ? 0.f : bound;
        p.node.rep_known = true;
        if (parent && parent->rep_known &&
            tree.node(parent->node).representative == node.representative) {
          p.node.rep_value = parent->rep_value;
        } else {
          p.entry = int32_t(entry_rows.size());
          entry_rows.push_back(rows[cut]);
          entry_cols.push_back(node.representative);
        }
      }
      pending.push_back(p);
    };
    auto flush = [&] {
      entry_values.resize(entry_rows.size());
      matrix.EvaluateEntries(entry_rows, entry_cols, entry_values, &stats->counters);
      for (Pending& p : pending) {
        if (p.entry >= 0) p.node.rep_value = entry_values[size_t(p.entry)];
        if (p.node.rep_known) {
          const LightTreeNode& node = tree.node(p.node.node);
          p.node.estimate = Scale(p.node.rep_value, node, lights.lights[node.representative]);
        }
        RowCut& cut = cuts[p.cut];
        cut.total += p.node.estimate;
        cut.heap.push_back({p.node.bound, p.node.node, uint32_t(cut.pool.size())});
        cut.pool.push_back(p.node);
        std::push_heap(cut.heap.begin(), cut.heap.end(), HeapLess);
      }
      pending.clear();
      entry_rows.clear();
      entry_cols.clear();
    };

    // The cut starts at the roots.
    for (uint32_t c = 0; c < cuts.size(); ++c)
      for (uint32_t root : tree.roots()) add(c, root, nullptr);
    flush();
    // Each step refines every unfinished row's worst node: the one with the largest bound,
    // while it exceeds the relative error of the row's total (Walter 2005, Sec. 4.1).
    for (;;) {
      bool any = false;
      for (uint32_t c = 0; c < cuts.size(); ++c) {
        RowCut& cut = cuts[c];
        if (cut.done) continue;
        const size_t size = cut.heap.size();
        if (size >= criterion.max_cut || !WantsRefinement(cut, criterion.error, criterion.Floor(size))) {
          cut.done = true;
          continue;
        }
        std::pop_heap(cut.heap.begin(), cut.heap.end(), HeapLess);
        const CutNode parent = cut.pool[cut.heap.back().slot];
        cut.heap.pop_back();
        cut.total = cut.total - parent.estimate;
        const LightTreeNode& node = tree.node(parent.node);
        add(c, uint32_t(node.left), &parent);
        add(c, uint32_t(node.right), &parent);
        any = true;
      }
      if (!any) break;
      flush();
    }

    for (size_t i = 0; i < cuts.size(); ++i) {
      RowCut& cut = cuts[i];
      stats->cut_size += double(cut.heap.size());
      if (WantsRefinement(cut, criterion.error, criterion.Floor(cut.heap.size()))) stats->capped += 1;
      else if (WantsRefinement(cut, criterion.error, 0.f)) stats->floored += 1;
      // The running total drifts by rounding: sum the final cut in double, in node order so
      // the result does not depend on heap internals.
      std::sort(cut.heap.begin(), cut.heap.end(),
                [](const HeapEntry& a, const HeapEntry& b) { return a.node < b.node; });
      RGBAccum sum;
      for (const HeapEntry& e : cut.heap) sum.Add(cut.pool[e.slot].estimate);
      sums[i] = sum;
    }
  }

  // Emission bounds of the tree's nodes, computed once per tree.
  std::shared_ptr<const std::vector<EmissionBound>> Emission(const GatherContext& ctx) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const LightTree* tree = ctx.tree;
    if (!cached_ || cached_tree_ != tree || cached_lights_ != &ctx.matrix.lights() ||
        cached_nodes_ != tree->nodes().size()) {
      cached_ = std::make_shared<const std::vector<EmissionBound>>(
          ComputeEmissionBounds(*tree, ctx.matrix.lights(), ctx.matrix.scene().materials()));
      cached_tree_ = tree;
      cached_lights_ = &ctx.matrix.lights();
      cached_nodes_ = tree->nodes().size();
    }
    return cached_;
  }

  double error_;
  size_t max_cut_;
  double floor_;
  mutable std::mutex mutex_;
  mutable std::shared_ptr<const std::vector<EmissionBound>> cached_;
  mutable const LightTree* cached_tree_ = nullptr;
  mutable const LightSet* cached_lights_ = nullptr;
  mutable size_t cached_nodes_ = 0;
};

}  // namespace

std::unique_ptr<GatherMethod> CreateLightcutsGather(const OptionMap& params) {
  double error = params.GetDouble("error", 0.02, 0.0, 1.0);
  // error = 0 asks for the exact sum: no cap unless one is given.
  const long long unlimited = std::numeric_limits<int32_t>::max();
  size_t max_cut = size_t(params.GetInt("max_cut", error > 0 ? 1000 : unlimited, 1, unlimited));
  double floor = params.GetDouble("floor", kDefaultFloor, 0.0, 1.0);
  return std::make_unique<LightcutsGather>(error, max_cut, floor);
}

GatherMethodInfo LightcutsMethod() {
  GatherMethodInfo m;
  m.name = "lightcuts";
  m.create = CreateLightcutsGather;
  // Walter 2005: the per-receiver relative error bound (2% in the paper).
  m.sweep = "error=0.2;error=0.1;error=0.05;error=0.02;error=0.01;error=0.005";
  // The bound is the target itself (at most 1).
  m.params_for_target = [](double target) {
    std::ostringstream s;
    s << std::min(target, 1.0);
    return std::vector<std::string>{"error=" + s.str()};
  };
  return m;
}

}  // namespace lightfarm
