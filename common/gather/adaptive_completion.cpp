// `adaptive-completion` (Huo, Wang, Hu, Hua, Bao 2016, "Adaptive matrix column sampling and
// completion for rendering participating media", Sec. 5, Algorithms 1 and 2). One task = one slice
// of the plan; the method only asks the LightingMatrix for entries and walks the LightTree, so it
// works on whatever element types the matrix holds (surface points and eye segments; VPLs, medium
// VPLs and the other light kinds).
//
// Per slice (m rows; a column is the 3m-vector of its rows' RGB values, see column_completion.h):
//  1. Column completion (Sec. 5.1.1, Algorithm 2): Ω holds ⌊ρm⌋ uniformly drawn rows (their three
//     entries). A column to sample is evaluated on Ω and projected onto U_Ω by least squares
//     (Eq. 13, rank-revealing, common/matrix/column_completion.h). When the energy-loss test of
//     Eq. 16 fails, the column is evaluated on every row (reusing Ω's entries), added to U by
//     re-orthogonalised Gram–Schmidt, its coefficients are Uᵀl (exact), and Ω is redrawn.
//     Deviations: (a) Eq. 16 weighs the loss by the column's observed energy instead of ‖e‖₁
//     (see FailsEnergyTest); its total is the current cut's energy Σ_i(U e_all)_i, plus the
//     columns already completed for the nodes being evaluated (so the first columns, with
//     e_all = 0, build the basis). (b) Ω never has fewer than omega_per_basis·k rows: with
//     |Ω| ≤ k the least squares interpolates any l_Ω, the test can never fail and the
//     reconstruction is arbitrary. (c) A light's completed coefficients are kept for the slice:
//     sampled again (in a child, or twice in one node) it costs nothing. (d) The projection keeps
//     only the directions of U_Ω whose pivots (column-pivoted QR) exceed rank_tolerance = 0.1 of
//     the largest; the others get coefficient 0. U is orthonormal, so a direction that is weak on
//     a uniform Ω is one concentrated on rows Ω missed (a VPL's highlight in a corner); fitting it
//     from Ω extrapolates noise over the rows it lives on. docs/methods/adaptive-completion.md has
//     the measurements behind the choice.
//  2. Node estimate (Sec. 5.1.2, Eq. 14): a node with more than K lights draws K columns with
//     probability ∝ luminance of their power; e(node) = (1/K) Σ e_k / pdf_k in U's coordinates.
//     A node with at most K lights evaluates each of them once (e(node) = Σ e_j, error 0):
//     sampling K of them with replacement would cost as much and stay noisy.
//  3. Traversal (Algorithm 1): the roots (one tree per light kind) are evaluated, then the cut
//     node with the largest error is split and its two children evaluated, while
//     r(node) > β‖e_all‖ (Eq. 17), e_all = Σ e(node) over the current cut. Eq. 17 compares a
//     squared quantity with a linear one; here r(node) is the root mean square of
//     ‖e(node) − e_k/pdf_k‖₂, the spread of the single-column estimates, and ‖e_all‖₂ = ‖U e_all‖₂
//     is the slice estimate's norm (U orthonormal), so both are radiances. β = 0 means exact: every
//     node is split until it has at most K lights.
//  4. Row sums s = U·e_all (Eq. 15), three entries per row; a channel sum the low-rank
//     reconstruction makes negative is set to 0 (counted in `negative_channels`).
//  5. Near lights (not in the paper). A light close to a slice's receivers has a spiky column
//     (1/d² down to the clamp distance on a few rows) that no low-rank basis observed on a uniform Ω
//     represents: Ω misses the spike, the projection loses it, and Eq. 16 lets it pass because one
//     column's loss is small next to the whole cut's energy. Summed over hundreds of such columns
//     the loss is a large negative bias. So the
//     lights closer than near_distance × the slice's bounding-box diagonal to one of its receivers
//     are taken out of the tree sampling (power 0 in the sampling prefix, skipped in exact nodes)
//     and their columns are evaluated on every row and summed exactly. On eye-segment slices every
//     non-directional light can be near; on surface slices only media lights, medium VPLs and VRLs
//     (an oriented VPL lying on a receiving surface is damped by the cosines; counting those made
//     cornell-box evaluate 60% of its elements). A VRL's distance is the segment's (it is near
//     wherever it passes close, not only at its start). Scenes without media are unchanged. The
//     price: near columns are most of the evaluated elements, and their number grows linearly
//     with the lights; docs/methods/adaptive-completion.md has the measurements, and the
//     cheaper splits measured and rejected. near_samples = K > 0 samples them instead: each row
//     draws K near lights by systematic sampling ∝ NearBound (power, distance, phase functions)
//     and adds A_ij / (K q_ij) per draw, unbiased, with K entries per row whatever the number of
//     near lights; it trades the near columns' exactness for noise (measured in the same doc).
//  6. Eye-segment slices take σ = 0.02 and β = 0.05 unless sigma / beta are given. Their rows hold
//     only the light the particle paths carry (the emitters' single scattering is the camera
//     side's, docs/rendering.md), so the slice's energy that Eq. 16 and 17 compare against is a
//     fraction of what it is with the emitters' columns; with the surface defaults the cut and
//     the basis grew ten- to twenty-fold on the cloud for an error that the looser thresholds
//     match (docs/methods/media-elements.md).
//
// Exact limit: with rho=1 (Ω = every row), sigma=0 (a column that loses anything on Ω is sampled
// fully) and beta=0 (every node refined to ≤ K lights, each evaluated once), every light's column
// is either in span(U) to rounding or added to U and projected exactly, so the row sums equal
// brute force's up to rounding (tests/unit/test_adaptive_completion.cpp).
//
// Parameters (--param): columns (K, 10), rho (0.1), sigma (0.005; 0.02 on eye-segment slices, see
// 6), beta (0.01; 0.05 there), omega_per_basis
// (2; see 1b), rank_tolerance (0.1; see 1d), near_distance (0.1; 0 turns it off; see 5),
// near_samples (0: near columns exact; see 5). Randomness: Ω from (seed, stage, task, kRowSample,
// draw number), a node's columns from (seed, stage, task, kColumnSample, node index), a row's near
// draws from (seed, stage, task, kNearSample, row); the slice
// is processed in one deterministic order and entries are evaluated in fixed chunks, so the bits
// do not depend on threads or on which worker runs the slice.
// Stats (summed over slices): columns_full (sampled on every row), columns_dropped (of those, not
// added to U: dependent to drop tolerance), columns_completed (from Ω), basis_size, nodes_split,
// cut_nodes, omega_redraws, speculative_entries (entries evaluated on an Ω redrawn before they
// were used), negative_channels, observed_residual (per slice, Σ‖l_Ω − U_Ω e‖₁ / Σ‖l_Ω‖₁ over
// the completed columns), near_columns (near lights, summed over slices, see 5), near_entries
// (their entries drawn per row, with near_samples).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <queue>
#include <stdexcept>
#include <unordered_map>

#include "common/gather/methods.h"
#include "common/matrix/column_completion.h"
#include "common/util/check.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

struct AdaptiveCompletionSettings {
  int columns_per_node = 10;    // K, Huo 2016 Sec. 5.1.2
  double rho = 0.1;             // |Ω| = ⌊ρm⌋ rows, Sec. 5.1.1
  double sigma = 0.005;         // Eq. 16, Sec. 6.2
  double beta = 0.01;           // Eq. 17
  // On eye-segment slices (see 6): the defaults when sigma / beta are not given.
  double segment_sigma = 0.02, segment_beta = 0.05;
  double omega_per_basis = 2;   // |Ω| ≥ this · k rows (deviation 1b)
  double rank_tolerance = 0.1;  // of U_Ω, relative to its largest pivot (see 1d)
  double near_distance = 0.1;   // near lights: within this × the slice's diagonal (see 5)
  int near_samples = 0;         // near lights sampled per row (0: every near column exact; see 5)
};

// Entries per parallel evaluation chunk (several of Embree's 256-ray batches).
constexpr size_t kEvaluationChunk = 1024;
// Most columns evaluated on Ω in one batch.
constexpr size_t kMaxBatch = 64;

// out[k] = A(rows[k], cols[k]) in fixed chunks, counters summed in chunk order.
void EvaluateInChunks(const LightingMatrix& matrix, const std::vector<uint32_t>& rows,
                      const std::vector<uint32_t>& cols, std::vector<RGB>* out,
                      MatrixCounters* counters) {
  out->assign(rows.size(), RGB());
  const size_t nchunks = (rows.size() + kEvaluationChunk - 1) / kEvaluationChunk;
  std::vector<MatrixCounters> chunk_counters(nchunks);
  tbb::parallel_for(size_t(0), nchunks, [&](size_t c) {
    const size_t begin = c * kEvaluationChunk;
    const size_t n = std::min(rows.size(), begin + kEvaluationChunk) - begin;
    matrix.EvaluateEntries(std::span<const uint32_t>(rows.data() + begin, n),
                           std::span<const uint32_t>(cols.data() + begin, n),
                           std::span<RGB>(out->data() + begin, n), &chunk_counters[c]);
  });
  for (const MatrixCounters& c : chunk_counters) counters->Add(c);
}

// acc += scale·v, growing acc with zeros when v was computed with a larger basis (and v padded
// when it is shorter: coefficients computed before U grew).
void AddScaled(Eigen::VectorXd* acc, const Eigen::VectorXd& v, double scale) {
  if (v.size() > acc->size()) {
    const Eigen::Index old = acc->size();
    acc->conservativeResize(v.size());
    acc->tail(v.size() - old).setZero();
  }
  acc->head(v.size()) += scale * v;
}

// The closest points a + s·da, s ∈ [0, la] and b + t·db, t ∈ [0, lb] of two segments (unit
// directions; a length of 0 is a point): the closest pair of the two lines, each parameter
// clamped to its segment and the other re-projected (exact for segments). Returns (s, t).
std::pair<float, float> SegmentClosest(Vec3 a, Vec3 da, float la, Vec3 b, Vec3 db, float lb) {
  const Vec3 r = a - b;
  const float e = Dot(da, db), f = Dot(da, r), g = Dot(db, r);
  const float denom = 1.f - e * e;  // |da × db|² for unit directions
  float s = 0;
  if (la > 0 && lb > 0 && denom > 1e-6f) s = std::clamp((e * g - f) / denom, 0.f, la);
  float t = lb > 0 ? g + e * s : 0.f;  // closest t to a + s·da
  if (t < 0 || t > lb) {
    t = std::clamp(t, 0.f, lb);
    s = la > 0 ? std::clamp(Dot(b + db * t - a, da), 0.f, la) : 0.f;
  } else if (la > 0 && !(lb > 0 && denom > 1e-6f)) {
    s = std::clamp(Dot(b + db * t - a, da), 0.f, la);
  }
  return {s, t};
}

float SegmentDistance2(Vec3 a, Vec3 da, float la, Vec3 b, Vec3 db, float lb) {
  const auto [s, t] = SegmentClosest(a, da, la, b, db, lb);
  return LengthSquared(a + da * s - (b + db * t));
}

// Squared distance between a row's receiver (a shading point, or an eye segment) and a light
// (a point, or a VRL's segment).
float RowLightDistance2(const LightingMatrix& matrix, uint32_t row, const VirtualLight& L) {
  const float vrl_length = L.IsRay() ? L.length : 0.f;
  const size_t npoints = matrix.point_rows();
  if (row < npoints) return SegmentDistance2(L.p, L.n, vrl_length, matrix.receivers().points[row].p, L.n, 0.f);
  const EyeSegment& seg = matrix.receivers().segments[row - npoints];
  return SegmentDistance2(L.p, L.n, vrl_length, seg.o, seg.d, seg.length);
}

// The sampling weight of a near light for a row (near_samples, see 5): the light's power times
// an unoccluded estimate of its geometry and phase functions, at the receiver's point closest to
// it x (the shading point, or on an eye segment). A point light at distance d: 1/d² (d floored
// at the clamp distance). A VRL p + t·n, t ∈ [0, ℓ], whose closest point to x is at t₀ and
// distance d: its power per length times ∫₀^ℓ ρ(t) dt / (d² + (t − t₀)²), ρ the product of the
// VRL's phase function and, for an eye segment, the segment's (towards the camera). With
// t = t₀ + d tan φ the integral is (1/d) ∫ ρ dφ over [atan(−t₀/d), atan((ℓ − t₀)/d)] (the whole
// angle the VRL subtends, so a long VRL passing close outweighs a short one), estimated at four
// midpoints in φ.
double NearBound(const LightingMatrix& matrix, uint32_t row, const VirtualLight& L, float floor_distance) {
  const double power = std::max(0.0, double(L.power.Luminance()));
  if (!(power > 0)) return 0;
  const size_t npoints = matrix.point_rows();
  Vec3 x;
  if (row < npoints) {
    x = matrix.receivers().points[row].p;
  } else {
    const EyeSegment& seg = matrix.receivers().segments[row - npoints];
    x = seg.o + seg.d * SegmentClosest(L.p, L.n, L.IsRay() ? L.length : 0.f, seg.o, seg.d, seg.length).second;
  }
  if (!L.IsRay() || !(L.length > 0)) {
    const double d2 = std::max(double(LengthSquared(x - L.p)), double(floor_distance) * double(floor_distance));
    return power / d2;
  }
  const double t0 = double(Dot(x - L.p, L.n));
  const Vec3 to_x = x - (L.p + L.n * float(t0));
  const double d = std::max(double(Length(to_x)), double(floor_distance));
  const double l = double(L.length);
  // φ from φ0 = atan(a) to φ1 = atan(b); their difference and the midpoints' sines and cosines
  // by the addition formulas (one atan2, one sine and one cosine per pair instead of two atans and
  // eight sines and cosines: this runs for every row and near light).
  const double a = -t0 / d, b = (l - t0) / d;
  const double span = std::atan2(b - a, 1 + a * b);  // φ1 − φ0 ∈ [0, π]
  // The light travels from the VRL point at φ to x along cos φ·e − sin φ·n (e: the unit vector
  // from the closest point to x): the VRL's phase function sees cos θ = −sin φ against n, an
  // eye segment's that direction against −d, the way to the camera.
  const Vec3 e = Length(to_x) > 0 ? to_x / Length(to_x) : Vec3{0, 0, 0};
  const double g = double(L.g);
  auto hg = [g](double c) {
    if (g == 0) return 1 / (4 * double(kPi));
    const double k = 1 + g * g - 2 * g * c;
    return (1 - g * g) / (4 * double(kPi) * k * std::sqrt(k));
  };
  const bool segment = row >= npoints;
  const EyeSegment* seg = segment ? &matrix.receivers().segments[row - npoints] : nullptr;
  const Vec3 back = segment ? -seg->d : Vec3{0, 0, 0};
  const double be = double(Dot(e, back)), bn = double(Dot(L.n, back));
  constexpr int kN = 4;
  const double step = span / kN;
  const double c0 = 1 / std::sqrt(1 + a * a), s0 = a * c0;  // cos φ0, sin φ0
  const double ch = std::cos(0.5 * step), sh = std::sin(0.5 * step);
  const double cs = 1 - 2 * sh * sh, ss = 2 * sh * ch;  // cos, sin of the step
  double sin_phi = s0 * ch + c0 * sh, cos_phi = c0 * ch - s0 * sh;  // the first midpoint
  double sum = 0;
  for (int i = 0; i < kN; ++i) {
    double w = hg(-sin_phi);
    if (segment) w *= hg(cos_phi * be - sin_phi * bn);
    sum += w;
    const double next_sin = sin_phi * cs + cos_phi * ss;
    cos_phi = cos_phi * cs - sin_phi * ss;
    sin_phi = next_sin;
  }
  return power / l * sum * step / d;
}

double& Channel(RGBAccum* a, int c) { return c == 0 ? a->r : (c == 1 ? a->g : a->b); }

// A node of the cut with its estimate (Eq. 14) and error (Eq. 17).
struct NodeEstimate {
  uint32_t node = 0;
  Eigen::VectorXd e;   // e(node), coordinates in U
  double error = 0;    // r(node)
  bool exact = false;  // every light of the node evaluated
};

// The columns a node asks for: each distinct light with its weight in e(node).
struct NodeColumns {
  uint32_t node = 0;
  bool exact = false;
  std::vector<uint32_t> draws;  // sampled lights, with repeats (sampled nodes)
  std::vector<double> inv_pdf;  // 1/pdf per draw
  std::vector<std::pair<uint32_t, double>> weighted;  // distinct lights, weight in e(node)
};

// One slice's traversal and completion state.
class SliceSolver {
 public:
  SliceSolver(const LightingMatrix& matrix, const LightTree& tree,
              const std::vector<double>& prefix, const std::vector<uint8_t>& near,
              const SubMatrixTask& task, const AdaptiveCompletionSettings& s, TaskOutput* out)
      : matrix_(matrix),
        tree_(tree),
        prefix_(prefix),
        near_(near),
        task_(task),
        s_(s),
        out_(out),
        m_(uint32_t(task.rows.size())),
        completion_(3 * size_t(m_), ColumnCompletionOptions{.rank_tolerance = s.rank_tolerance}) {}

  void Run() {
    EvaluateNearLights();
    RedrawOmega();
    // The roots, then the worst node split while Eq. 17 asks for it
    std::vector<NodeEstimate> roots = Evaluate(tree_.roots());
    auto lower_priority = [&](uint32_t a, uint32_t b) {
      const NodeEstimate& na = cut_[a];
      const NodeEstimate& nb = cut_[b];
      return na.error != nb.error ? na.error < nb.error : na.node > nb.node;
    };
    std::priority_queue<uint32_t, std::vector<uint32_t>, decltype(lower_priority)> queue(
        lower_priority);
    auto enter = [&](NodeEstimate&& est) {
      AddScaled(&e_all_, est.e, 1.0);
      cut_energy_ += completion_.ReconstructedSum(est.e);
      cut_.push_back(std::move(est));
      if (!cut_.back().exact) queue.push(uint32_t(cut_.size() - 1));
    };
    for (NodeEstimate& r : roots) enter(std::move(r));
    size_t in_cut = cut_.size();
    while (!queue.empty()) {
      const uint32_t worst = queue.top();
      // Huo 2016, Eq. 17: stop when the worst node's error is within β‖e_all‖
      if (s_.beta > 0 && cut_[worst].error <= s_.beta * e_all_.norm()) break;
      queue.pop();
      const LightTreeNode& node = tree_.node(cut_[worst].node);
      const uint32_t children[2] = {uint32_t(node.left), uint32_t(node.right)};
      std::vector<NodeEstimate> est = Evaluate(children);
      AddScaled(&e_all_, cut_[worst].e, -1.0);
      cut_energy_ -= completion_.ReconstructedSum(cut_[worst].e);
      for (NodeEstimate& c : est) enter(std::move(c));
      ++nodes_split_;
      ++in_cut;
    }

    // Eq. 15: s = U·Σ e(node)
    if (!sampled_near_.empty()) SampleNearLights(sampled_near_);
    const Eigen::VectorXd sums = completion_.Reconstruct(e_all_);
    out_->row_sums.assign(m_, RGBAccum());
    uint64_t negative = 0;
    for (uint32_t i = 0; i < m_; ++i)
      for (int c = 0; c < 3; ++c) {
        double v = sums(3 * Eigen::Index(i) + c) + near_sums_(3 * Eigen::Index(i) + c);
        if (!(v >= 0)) {
          ++negative;
          v = 0;
        }
        Channel(&out_->row_sums[i], c) = v;
      }

    auto& st = out_->stats;
    st["columns_full"] = double(columns_full_);
    st["columns_dropped"] = double(columns_dropped_);
    st["columns_completed"] = double(columns_completed_);
    st["basis_size"] = double(completion_.size());
    st["nodes_split"] = double(nodes_split_);
    st["cut_nodes"] = double(in_cut);
    st["omega_redraws"] = double(omega_redraws_);
    st["near_columns"] = double(near_columns_);
    st["near_entries"] = double(near_samples_);
    st["speculative_entries"] = double(speculative_entries_);
    st["negative_channels"] = double(negative);
    st["observed_residual"] =
        completed_observed_l1_ > 0 ? completed_residual_l1_ / completed_observed_l1_ : 0.0;
  }

 private:
  uint64_t SeedFor(RngStream stream, uint64_t index) const {
    return HashSeed({task_.seed, task_.stage, task_.task_id, uint64_t(stream), index});
  }

  // Near lights (see 5): their columns on every row, summed apart from the completion.
  void EvaluateNearLights() {
    near_sums_ = Eigen::VectorXd::Zero(3 * Eigen::Index(m_));
    std::vector<uint32_t> lights;
    for (uint32_t j = 0; j < near_.size(); ++j)
      if (near_[j]) lights.push_back(j);
    near_columns_ = lights.size();
    if (s_.near_samples > 0 && lights.size() > size_t(s_.near_samples)) {
      sampled_near_ = std::move(lights);  // after the traversal, on the final U (see Run)
      return;
    }
    // In groups of columns so that the entry lists stay small, each group in tiles of
    // kNearTile rows × kNearTile lights: an evaluation chunk then reads the media tracks of a few
    // rows and lights many times (each of a row's coverage pieces, and each VRL's track), instead
    // of those of every row of the slice once.
    constexpr uint32_t kNearTile = 32;
    const size_t group = std::max<size_t>(kNearTile, (1u << 16) / std::max<uint32_t>(1, m_));
    for (size_t first = 0; first < lights.size(); first += group) {
      const size_t last = std::min(lights.size(), first + group);
      std::vector<uint32_t> rows, cols, local;
      for (uint32_t r0 = 0; r0 < m_; r0 += kNearTile)
        for (size_t j0 = first; j0 < last; j0 += kNearTile)
          for (size_t j = j0; j < std::min(last, j0 + kNearTile); ++j)
            for (uint32_t r = r0; r < std::min(m_, r0 + kNearTile); ++r) {
              rows.push_back(task_.rows[r]);
              cols.push_back(lights[j]);
              local.push_back(r);
            }
      std::vector<RGB> values;
      EvaluateInChunks(matrix_, rows, cols, &values, &out_->counters);
      for (size_t k = 0; k < values.size(); ++k) {
        const Eigen::Index r = Eigen::Index(local[k]);
        for (int c = 0; c < 3; ++c)
          if (std::isfinite(values[k][c])) near_sums_(3 * r + c) += double(values[k][c]);
      }
    }
  }

  // Near lights sampled per row instead (near_samples = K): row i draws K lights by systematic
  // sampling of q_ij ∝ NearBound(i, j) and adds Σ A_ij · n_ij / (K q_ij), n_ij the draws of j:
  // unbiased for Σ_j A_ij, and every light with K q_ij ≥ 1 is drawn at least once. The cost is
  // K entries per row, whatever the number of near lights.
  void SampleNearLights(const std::vector<uint32_t>& lights) {
    const LightSet& set = matrix_.lights();
    const size_t k = size_t(s_.near_samples);
    const float floor_distance = std::max(matrix_.clamp_distance(), 1e-6f);
    std::vector<std::vector<std::pair<uint32_t, double>>> draws(m_);
    tbb::parallel_for(uint32_t(0), m_, [&](uint32_t r) {
      std::vector<double> cdf(lights.size() + 1, 0.0);
      for (size_t j = 0; j < lights.size(); ++j)
        cdf[j + 1] = cdf[j] + NearBound(matrix_, task_.rows[r], set.lights[lights[j]], floor_distance);
      const double total = cdf.back();
      if (!(total > 0)) return;
      Rng rng(SeedFor(RngStream::kNearSample, r));
      const double u0 = rng.UniformDouble();
      size_t j = 0;
      for (size_t d = 0; d < k; ++d) {
        const double target = (double(d) + u0) / double(k) * total;
        while (j + 1 < lights.size() && !(cdf[j + 1] > target)) ++j;
        const double p = (cdf[j + 1] - cdf[j]) / total;
        if (!(p > 0)) continue;
        const double w = 1.0 / (double(k) * p);
        if (!draws[r].empty() && draws[r].back().first == lights[j])
          draws[r].back().second += w;
        else
          draws[r].emplace_back(lights[j], w);
      }
    });
    std::vector<uint32_t> rows, cols, local;
    std::vector<double> weights;
    for (uint32_t r = 0; r < m_; ++r)
      for (const auto& [light, w] : draws[r]) {
        rows.push_back(task_.rows[r]);
        cols.push_back(light);
        local.push_back(r);
        weights.push_back(w);
      }
    std::vector<RGB> values;
    EvaluateInChunks(matrix_, rows, cols, &values, &out_->counters);
    for (size_t e = 0; e < values.size(); ++e)
      for (int c = 0; c < 3; ++c)
        if (std::isfinite(values[e][c])) near_sums_(3 * Eigen::Index(local[e]) + c) += weights[e] * double(values[e][c]);
    near_samples_ = values.size();
  }

  // Ω: distinct uniform rows (Algorithm 2, DrawRowIndices), never fewer than omega_per_basis·k.
  void RedrawOmega() {
    const size_t by_ratio = size_t(std::floor(s_.rho * double(m_)));
    const size_t by_basis = size_t(std::ceil(s_.omega_per_basis * double(completion_.size())));
    const size_t count = std::min<size_t>(m_, std::max({by_ratio, by_basis, size_t(1)}));
    std::vector<uint32_t> pool(m_);
    for (uint32_t r = 0; r < m_; ++r) pool[r] = r;
    Rng rng(SeedFor(RngStream::kRowSample, omega_redraws_++));
    for (size_t i = 0; i < count && count < m_; ++i)
      std::swap(pool[i], pool[i + rng.UniformInt(uint32_t(m_ - i))]);
    pool.resize(count);
    std::sort(pool.begin(), pool.end());
    omega_rows_ = std::move(pool);
    std::vector<uint32_t> entries;
    entries.reserve(3 * omega_rows_.size());
    for (uint32_t r : omega_rows_)
      for (uint32_t c = 0; c < 3; ++c) entries.push_back(3 * r + c);
    completion_.SetObserved(std::move(entries));
  }

  // Which columns a node evaluates: all its lights (≤ K), or K draws ∝ luminance (Eq. 14).
  NodeColumns Columns(uint32_t index) const {
    const LightTreeNode& node = tree_.node(index);
    const std::vector<uint32_t>& order = tree_.order();
    NodeColumns nc;
    nc.node = index;
    const uint32_t k = uint32_t(s_.columns_per_node);
    const double lo = prefix_[node.first], hi = prefix_[node.first + node.count];
    const double total = hi - lo;
    // Near lights are summed exactly elsewhere (their power is 0 in prefix_); a node whose other
    // lights carry no power contributes nothing but is still listed exactly (cheap: black).
    if (node.count <= k || !(total > 0)) {
      nc.exact = true;
      for (uint32_t i = node.first; i < node.first + node.count; ++i)
        if (!near_[order[i]]) nc.weighted.emplace_back(order[i], 1.0);
      return nc;
    }
    Rng rng(SeedFor(RngStream::kColumnSample, index));
    for (uint32_t d = 0; d < k; ++d) {
      uint32_t pos;
      double pdf;
      {
        const double target = lo + rng.UniformDouble() * total;
        auto it = std::upper_bound(prefix_.begin() + node.first + 1,
                                   prefix_.begin() + node.first + node.count + 1, target);
        pos = uint32_t(std::min<ptrdiff_t>(it - prefix_.begin(), node.first + node.count) - 1);
        // Rounding may land on a light of zero weight (a near one): the nearest with weight
        while (pos > node.first && !(prefix_[pos + 1] > prefix_[pos])) --pos;
        while (pos + 1 < node.first + node.count && !(prefix_[pos + 1] > prefix_[pos])) ++pos;
        pdf = (prefix_[pos + 1] - prefix_[pos]) / total;
      }
      nc.draws.push_back(order[pos]);
      nc.inv_pdf.push_back(1.0 / pdf);
    }
    // Distinct lights with their total weight 1/(K·pdf) per draw
    std::vector<std::pair<uint32_t, double>> w;
    for (uint32_t d = 0; d < k; ++d) w.emplace_back(nc.draws[d], nc.inv_pdf[d] / k);
    std::sort(w.begin(), w.end());
    for (const auto& [light, weight] : w) {
      if (!nc.weighted.empty() && nc.weighted.back().first == light)
        nc.weighted.back().second += weight;
      else
        nc.weighted.emplace_back(light, weight);
    }
    return nc;
  }

  // SampleAndEvaluate (Algorithm 1) for a set of nodes, their columns completed together.
  template <typename Nodes>
  std::vector<NodeEstimate> Evaluate(const Nodes& nodes) {
    std::vector<NodeColumns> columns;
    std::vector<std::pair<uint32_t, double>> requests;
    for (uint32_t n : nodes) {
      columns.push_back(Columns(n));
      for (const auto& lw : columns.back().weighted) requests.push_back(lw);
    }
    Complete(requests);
    std::vector<NodeEstimate> out;
    for (const NodeColumns& nc : columns) {
      NodeEstimate est;
      est.node = nc.node;
      est.exact = nc.exact;
      est.e = Eigen::VectorXd::Zero(Eigen::Index(completion_.size()));
      if (nc.exact) {
        for (const auto& [light, w] : nc.weighted) AddScaled(&est.e, coefficients_.at(light), 1.0);
      } else {
        // Eq. 14: the mean of the single-column estimates e_k / pdf_k
        const double k = double(nc.draws.size());
        for (size_t d = 0; d < nc.draws.size(); ++d)
          AddScaled(&est.e, coefficients_.at(nc.draws[d]), nc.inv_pdf[d] / k);
        // Eq. 17 (root mean square form, see the header)
        double spread2 = 0;
        for (size_t d = 0; d < nc.draws.size(); ++d) {
          Eigen::VectorXd diff = est.e;
          AddScaled(&diff, coefficients_.at(nc.draws[d]), -nc.inv_pdf[d]);
          spread2 += diff.squaredNorm();
        }
        est.error = std::sqrt(spread2 / k);
      }
      out.push_back(std::move(est));
    }
    return out;
  }

  // Algorithm 2 for every requested light not yet known. Columns are evaluated on Ω in batches
  // (one parallel evaluation each) and then tested in order; after a failure Ω changes, so the
  // batch's later columns are evaluated again on the new Ω (their first entries are counted as
  // speculative). The batch doubles after a batch without failure and restarts at one column
  // after a failure, which bounds that waste while the basis grows.
  void Complete(const std::vector<std::pair<uint32_t, double>>& requests) {
    std::vector<std::pair<uint32_t, double>> pending;
    for (const auto& lw : requests)
      if (!coefficients_.count(lw.first)) pending.push_back(lw);
    double running_energy = 0;  // energy of the columns completed in this call
    size_t next = 0;
    while (next < pending.size()) {
      // l_Ω of the batch's columns
      const size_t omega = omega_rows_.size();
      const size_t end = std::min(pending.size(), next + batch_);
      std::vector<uint32_t> rows, cols;
      rows.reserve((end - next) * omega);
      cols.reserve((end - next) * omega);
      for (size_t p = next; p < end; ++p)
        for (uint32_t r : omega_rows_) {
          rows.push_back(task_.rows[r]);
          cols.push_back(pending[p].first);
        }
      std::vector<RGB> values;
      EvaluateInChunks(matrix_, rows, cols, &values, &out_->counters);
      const double to_all_rows = double(m_) / double(omega);

      size_t p = next;
      bool failed = false;
      for (; p < end && !failed; ++p) {
        const auto [light, weight] = pending[p];
        const RGB* observed = values.data() + (p - next) * omega;
        Eigen::VectorXd l_omega(3 * Eigen::Index(omega));
        for (size_t i = 0; i < omega; ++i)
          for (int c = 0; c < 3; ++c) l_omega(3 * Eigen::Index(i) + c) = double(observed[i][c]);
        const ColumnProjection proj = completion_.Project(l_omega);
        const double column_energy = proj.observed_sum * to_all_rows * weight;
        if (!FailsEnergyTest(proj, column_energy, cut_energy_ + running_energy, s_.sigma)) {
          ++columns_completed_;
          completed_residual_l1_ += proj.residual_l1;
          completed_observed_l1_ += proj.observed_l1;
          running_energy += completion_.ReconstructedSum(proj.coefficients) * weight;
          coefficients_.emplace(light, proj.coefficients);
          continue;
        }
        // The energy test failed: sample the column on every row, add it to U, redraw Ω
        const Eigen::VectorXd full = FullColumn(light, observed);
        ++columns_full_;
        if (!completion_.Add(full)) ++columns_dropped_;
        Eigen::VectorXd e = completion_.ProjectFull(full);
        running_energy += completion_.ReconstructedSum(e) * weight;
        coefficients_.emplace(light, std::move(e));
        const std::vector<uint32_t> previous = omega_rows_;
        RedrawOmega();
        // Ω of every row is redrawn as itself: the batch's entries stay valid
        if (omega_rows_ != previous) {
          speculative_entries_ += (end - p - 1) * omega;
          failed = true;
        }
      }
      batch_ = failed ? 1 : std::min<size_t>(2 * batch_, kMaxBatch);
      next = p;
    }
  }

  // The column on every row of the slice, reusing its entries on Ω.
  Eigen::VectorXd FullColumn(uint32_t light, const RGB* on_omega) {
    std::vector<int32_t> omega_index(m_, -1);
    for (size_t i = 0; i < omega_rows_.size(); ++i) omega_index[omega_rows_[i]] = int32_t(i);
    std::vector<uint32_t> rows, cols, local;
    for (uint32_t r = 0; r < m_; ++r)
      if (omega_index[r] < 0) {
        rows.push_back(task_.rows[r]);
        cols.push_back(light);
        local.push_back(r);
      }
    std::vector<RGB> values;
    EvaluateInChunks(matrix_, rows, cols, &values, &out_->counters);
    Eigen::VectorXd full(3 * Eigen::Index(m_));
    for (uint32_t r = 0; r < m_; ++r)
      if (omega_index[r] >= 0)
        for (int c = 0; c < 3; ++c)
          full(3 * Eigen::Index(r) + c) = double(on_omega[omega_index[r]][c]);
    for (size_t i = 0; i < local.size(); ++i)
      for (int c = 0; c < 3; ++c) full(3 * Eigen::Index(local[i]) + c) = double(values[i][c]);
    return full;
  }

  const LightingMatrix& matrix_;
  const LightTree& tree_;
  const std::vector<double>& prefix_;
  const std::vector<uint8_t>& near_;  // per light: summed exactly, never sampled
  const SubMatrixTask& task_;
  const AdaptiveCompletionSettings& s_;
  TaskOutput* out_;
  const uint32_t m_;

  ColumnCompletion completion_;
  std::vector<uint32_t> omega_rows_;
  size_t batch_ = 1;  // columns evaluated on Ω together (see Complete)
  std::unordered_map<uint32_t, Eigen::VectorXd> coefficients_;  // per light, completed
  std::vector<NodeEstimate> cut_;  // every node evaluated (split ones stay, out of the sums)
  Eigen::VectorXd e_all_;          // Σ e(node) over the current cut
  double cut_energy_ = 0;          // Σ_i (U e_all)_i
  Eigen::VectorXd near_sums_;      // 3m: the near lights' columns summed
  uint64_t near_columns_ = 0;
  uint64_t near_samples_ = 0;  // entries evaluated for sampled near lights
  std::vector<uint32_t> sampled_near_;  // near lights sampled per row (near_samples)

  uint64_t columns_full_ = 0, columns_dropped_ = 0, columns_completed_ = 0;
  uint64_t nodes_split_ = 0, omega_redraws_ = 0, speculative_entries_ = 0;
  double completed_residual_l1_ = 0, completed_observed_l1_ = 0;
};

class AdaptiveCompletionGather final : public GatherMethod {
 public:
  explicit AdaptiveCompletionGather(const AdaptiveCompletionSettings& s) : s_(s) {}
  std::string name() const override { return "adaptive-completion"; }

  // Lights closer than near_distance × the slice's bounding-box diagonal to one of its receivers
  // (a shading point, or the nearest point of an eye segment). Directional lights are never near.
  std::vector<uint8_t> NearLights(const LightingMatrix& matrix, const SubMatrixTask& task) const {
    const LightSet& lights = matrix.lights();
    std::vector<uint8_t> near(lights.size(), 0);
    if (!(s_.near_distance > 0) || task.rows.empty()) return near;
    const ReceiverSet& receivers = matrix.receivers();
    const size_t npoints = matrix.point_rows();
    Bounds3 b;
    for (uint32_t r : task.rows) {
      if (r < npoints) {
        b.Extend(receivers.points[r].p);
      } else {
        const EyeSegment& seg = receivers.segments[r - npoints];
        b.Extend(seg.o);
        b.Extend(seg.o + seg.d * seg.length);
      }
    }
    const bool segment_slice = task.rows.front() >= npoints;
    const float margin = float(s_.near_distance) * Length(b.Diagonal());
    const float margin2 = margin * margin;
    tbb::parallel_for(size_t(0), lights.size(), [&](size_t j) {
      const VirtualLight& L = lights.lights[j];
      // On surfaces, only medium VPLs (an oriented VPL lying on a receiving surface is damped by
      // the cosines on both sides; a medium VPL beside a surface or in an eye segment's path is not)
      if (L.IsDirectional() || (!segment_slice && L.kind != VirtualLightKind::kMediumVPL && !L.IsRay())) return;
      // A VRL is a segment: its bounding box against the slice's, then segment distances.
      const float vrl_length = L.IsRay() ? L.length : 0.f;
      const Vec3 end = L.p + L.n * vrl_length;
      const Vec3 lo = Min(L.p, end), hi = Max(L.p, end);
      const Vec3 outside = Max(Max(b.lo - hi, lo - b.hi), Vec3(0, 0, 0));
      if (LengthSquared(outside) > margin2) return;
      for (uint32_t r : task.rows) {
        if (RowLightDistance2(matrix, r, L) <= margin2) {
          near[j] = 1;
          return;
        }
      }
    });
    return near;
  }
  bool needs_light_tree() const override { return true; }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact&) const override {
    CHECK(ctx.tree != nullptr);  // the plan builds the tree for methods that need one
    TaskOutput result;
    result.row_sums.resize(task.rows.size());
    if (task.rows.empty() || ctx.tree->roots().empty()) return result;
    // Luminance of the lights' power in leaf order, prefix-summed: sampling ∝ intensity
    const LightTree& tree = *ctx.tree;
    const std::vector<uint32_t>& order = tree.order();
    const std::vector<uint8_t> near = NearLights(ctx.matrix, task);
    std::vector<double> prefix(order.size() + 1, 0.0);
    for (size_t i = 0; i < order.size(); ++i)
      prefix[i + 1] =
          prefix[i] + (near[order[i]] ? 0.0
                                      : std::max(0.0, double(ctx.matrix.lights().lights[order[i]]
                                                                 .power.Luminance())));
    AdaptiveCompletionSettings s = s_;
    if (task.rows.front() >= ctx.matrix.point_rows()) {
      s.sigma = s.segment_sigma;
      s.beta = s.segment_beta;
    }
    SliceSolver(ctx.matrix, tree, prefix, near, task, s, &result).Run();
    return result;
  }

 private:
  AdaptiveCompletionSettings s_;
};

}  // namespace

std::unique_ptr<GatherMethod> CreateAdaptiveCompletionGather(const OptionMap& params) {
  AdaptiveCompletionSettings s;
  s.columns_per_node = int(params.GetInt("columns", 10, 1, 1 << 20));
  s.rho = params.GetDouble("rho", 0.1, 1e-6, 1.0);
  s.sigma = params.GetDouble("sigma", 0.005, 0.0, 1e6);
  s.beta = params.GetDouble("beta", 0.01, 0.0, 1e6);
  // Given, sigma and beta hold for every slice; else eye-segment slices have their own (see 6).
  s.segment_sigma = params.Has("sigma") ? s.sigma : s.segment_sigma;
  s.segment_beta = params.Has("beta") ? s.beta : s.segment_beta;
  s.omega_per_basis = params.GetDouble("omega_per_basis", 2.0, 0.0, 1e6);
  s.rank_tolerance = params.GetDouble("rank_tolerance", 0.1, 0.0, 1.0);
  s.near_distance = params.GetDouble("near_distance", 0.1, 0.0, 1e6);
  s.near_samples = int(params.GetInt("near_samples", 0, 0, 1 << 20));
  return std::make_unique<AdaptiveCompletionGather>(s);
}

GatherMethodInfo AdaptiveCompletionMethod() {
  GatherMethodInfo m;
  m.name = "adaptive-completion";
  m.create = CreateAdaptiveCompletionGather;
  // Huo 2016: sampling ratio rho and the error threshold sigma.
  m.sweep = "rho=0.05,sigma=0.05;rho=0.1,sigma=0.02;rho=0.1,sigma=0.01;rho=0.1,sigma=0.005;rho=0.2,sigma=0.002";
  return m;
}

}  // namespace lightfarm
