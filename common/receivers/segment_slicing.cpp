// Eye-segment slicing (Huo 2016, Sec. 4): similarity graph, METIS K-way partition, boundary
// refinement, slice neighbours. See segment_slicing.h for the equations and deviations.
#include "common/receivers/segment_slicing.h"

#include <metis.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/receivers/svm_boundary.h"
#include "common/scene/phase.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

// A small 3-D kd-tree for k-nearest-neighbour queries over points (implicit, balanced: the node
// of a range is its middle element after nth_element on the widest axis). Ties by point id, so
// queries are deterministic.
class PointKdTree {
 public:
  explicit PointKdTree(std::vector<Vec3> points) : points_(std::move(points)) {
    order_.resize(points_.size());
    for (uint32_t i = 0; i < order_.size(); ++i) order_[i] = i;
    axis_.assign(points_.size(), 0);
    Build(0, order_.size());
  }

  // The k nearest points to q as (squared distance, id), nearest first.
  std::vector<std::pair<float, uint32_t>> Nearest(Vec3 q, size_t k) const {
    std::vector<std::pair<float, uint32_t>> heap;  // max-heap of the best k so far
    if (k == 0) return heap;
    heap.reserve(k + 1);
    Search(0, order_.size(), q, k, &heap);
    std::sort_heap(heap.begin(), heap.end());
    return heap;
  }

 private:
  void Build(size_t lo, size_t hi) {
    if (hi - lo <= 1) return;
    Vec3 bmin(kInfinity, kInfinity, kInfinity), bmax(-kInfinity, -kInfinity, -kInfinity);
    for (size_t i = lo; i < hi; ++i)
      for (int a = 0; a < 3; ++a) {
        bmin[a] = std::min(bmin[a], points_[order_[i]][a]);
        bmax[a] = std::max(bmax[a], points_[order_[i]][a]);
      }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (bmax[a] - bmin[a] > bmax[axis] - bmin[axis]) axis = a;
    const size_t mid = lo + (hi - lo) / 2;
    std::nth_element(order_.begin() + ptrdiff_t(lo), order_.begin() + ptrdiff_t(mid),
                     order_.begin() + ptrdiff_t(hi), [&](uint32_t a, uint32_t b) {
                       const float pa = points_[a][axis], pb = points_[b][axis];
                       return pa != pb ? pa < pb : a < b;
                     });
    axis_[mid] = uint8_t(axis);
    Build(lo, mid);
    Build(mid + 1, hi);
  }

  void Search(size_t lo, size_t hi, Vec3 q, size_t k,
              std::vector<std::pair<float, uint32_t>>* heap) const {
    if (lo >= hi) return;
    const size_t mid = lo + (hi - lo) / 2;
    const uint32_t id = order_[mid];
    const std::pair<float, uint32_t> cand(LengthSquared(points_[id] - q), id);
    if (heap->size() < k) {
      heap->push_back(cand);
      std::push_heap(heap->begin(), heap->end());
    } else if (cand < heap->front()) {
      std::pop_heap(heap->begin(), heap->end());
      heap->back() = cand;
      std::push_heap(heap->begin(), heap->end());
    }
    if (hi - lo == 1) return;
    const int axis = axis_[mid];
    const float diff = q[axis] - points_[id][axis];
    const bool left_first = diff < 0;
    // Near side first; the far side only if the splitting plane is within the k-th distance
    // (<= keeps equal-distance points with smaller ids reachable).
    if (left_first) Search(lo, mid, q, k, heap); else Search(mid + 1, hi, q, k, heap);
    if (heap->size() < k || diff * diff <= heap->front().first) {
      if (left_first) Search(mid + 1, hi, q, k, heap); else Search(lo, mid, q, k, heap);
    }
  }

  std::vector<Vec3> points_;
  std::vector<uint32_t> order_;
  std::vector<uint8_t> axis_;
};

// The direction where an HG phase function of a segment travelling along d is largest, when it
// has one (g = 0: isotropic, every direction).
Vec3 PhaseMaximumDirection(const SegmentFeatures& s) { return s.g >= 0 ? s.d : -s.d; }

// Eq. 11's d(x_i, x_j): the larger relative difference of the two phase functions at the
// directions where either is largest. Normalised by the larger of the two values (symmetric, in
// [0, 1]); the paper divides by p_i, which is unbounded when p_j ≫ p_i.
float PhaseDifference(const SegmentFeatures& a, const SegmentFeatures& b) {
  float worst = 0;
  for (const Vec3 w : {PhaseMaximumDirection(a), PhaseMaximumDirection(b)}) {
    const float pa = HenyeyGreenstein(Dot(w, a.d), a.g);
    const float pb = HenyeyGreenstein(Dot(w, b.d), b.g);
    const float denom = std::max(pa, pb);
    if (denom > 0) worst = std::max(worst, std::abs(pa - pb) / denom);
  }
  return std::clamp(worst, 0.f, 1.f);
}

// The features of a piece of a segment split at fraction `at` of its length (piece 0 before it).
SegmentFeatures PieceFeatures(const SegmentFeatures& s, int piece, float at, float tau) {
  SegmentFeatures h = s;
  const Vec3 cut = s.x0 + (s.x1 - s.x0) * at;
  if (piece == 0) h.x1 = cut; else h.x0 = cut;
  h.tau = tau;
  return h;
}

SegmentFeatures HalfFeatures(const SegmentFeatures& s, int half, float tau) {
  return PieceFeatures(s, half, 0.5f, tau);
}

std::vector<uint32_t> SortedUnique(std::vector<uint32_t> v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// Symmetric adjacency (CSR) of the k-nearest-segment graph.
struct SegmentGraph {
  std::vector<idx_t> xadj, adjncy, adjwgt;
};

SegmentGraph BuildGraph(const std::vector<SegmentFeatures>& f, const SegmentSimilarityParams& sp,
                        size_t k) {
  const size_t n = f.size();
  std::vector<Vec3> endpoints(2 * n);
  for (size_t s = 0; s < n; ++s) {
    endpoints[2 * s] = f[s].x0;
    endpoints[2 * s + 1] = f[s].x1;
  }
  const PointKdTree tree(std::move(endpoints));
  // Each segment's k nearest other segments by the nearer of their endpoints to either of its
  // own (Sec. 4.2.1: "nearest start or end points of segments in a point KD-tree").
  std::vector<std::vector<uint32_t>> near(n);
  tbb::parallel_for(size_t(0), n, [&](size_t s) {
    std::vector<std::pair<float, uint32_t>> cand;
    for (const Vec3 q : {f[s].x0, f[s].x1})
      for (const auto& [d2, id] : tree.Nearest(q, 2 * k + 4))
        if (id / 2 != s) cand.emplace_back(d2, id / 2);
    std::sort(cand.begin(), cand.end());
    std::vector<uint32_t>& out = near[s];
    for (const auto& [d2, t] : cand) {
      if (std::find(out.begin(), out.end(), t) != out.end()) continue;
      out.push_back(t);
      if (out.size() == k) break;
    }
  });
  // Symmetrise: an edge when either end chose the other.
  std::vector<std::vector<uint32_t>> adj(n);
  for (size_t s = 0; s < n; ++s)
    for (uint32_t t : near[s]) {
      adj[s].push_back(t);
      adj[t].push_back(uint32_t(s));
    }
  SegmentGraph g;
  g.xadj.assign(n + 1, 0);
  for (size_t s = 0; s < n; ++s) {
    adj[s] = SortedUnique(std::move(adj[s]));
    g.xadj[s + 1] = g.xadj[s] + idx_t(adj[s].size());
  }
  g.adjncy.resize(size_t(g.xadj[n]));
  g.adjwgt.resize(size_t(g.xadj[n]));
  tbb::parallel_for(size_t(0), n, [&](size_t s) {
    size_t e = size_t(g.xadj[s]);
    for (uint32_t t : adj[s]) {
      // METIS takes integer weights: Eq. 8's similarity ∈ [0, 4] in thousandths, at least 1 so
      // that every edge still ties its ends a little.
      const float w = SegmentSimilarity(f[s], f[t], sp).Sum();
      g.adjncy[e] = idx_t(t);
      g.adjwgt[e] = idx_t(1 + std::lround(1000.f * w));
      ++e;
    }
  });
  return g;
}

SegmentSimilarityParams SimilarityParams(float scene_diagonal, const SegmentSlicingOptions& o) {
  SegmentSimilarityParams p;
  p.B = std::max(o.boundary_fraction * scene_diagonal, 1e-6f);
  p.kappa = o.kappa;
  p.pixel_sigma = o.pixel_sigma;
  return p;
}

// Whether a segment on a partition boundary is split in two, and where its halves go: each half
// joins the part (its own or a graph neighbour's) whose segments it is most similar to on
// average (Eq. 8); a segment inside one part, or whose halves agree, is kept whole.
struct SegmentSplit {
  bool split = false;
  float at = 0.5f;  // where, as a fraction of the length
  uint32_t part[2] = {0, 0};
  RGB first_half_transmittance;
  float tau[2] = {1, 1};
};

SegmentSplit DecideSplit(const Scene& scene, const EyeSegment& seg, size_t s,
                         const std::vector<SegmentFeatures>& f, const std::vector<uint32_t>& p,
                         const SegmentGraph& g, const SegmentSimilarityParams& sp, uint64_t seed) {
  const idx_t begin = g.xadj[s], end = g.xadj[s + 1];
  bool boundary = false;
  for (idx_t e = begin; e < end; ++e) boundary |= p[size_t(g.adjncy[size_t(e)])] != p[s];
  if (!boundary || seg.medium < 0 || !(seg.length > 0)) return {};
  const Medium& med = scene.media()[size_t(seg.medium)];
  Rng rng(HashSeed({seed, uint64_t(RngStream::kSlicing), 3, s}));
  const float half = 0.5f * seg.length;
  const RGB t0 = med.Transmittance({seg.o, seg.d, half}, rng);
  const RGB t1 = med.Transmittance({seg.o + seg.d * half, seg.d, half}, rng);
  const SegmentFeatures halves[2] = {HalfFeatures(f[s], 0, t0.Average()),
                                     HalfFeatures(f[s], 1, t1.Average())};
  // The segment's part and those of its graph neighbours
  std::vector<uint32_t> candidates{p[s]};
  for (idx_t e = begin; e < end; ++e) candidates.push_back(p[size_t(g.adjncy[size_t(e)])]);
  candidates = SortedUnique(std::move(candidates));
  uint32_t best[2] = {p[s], p[s]};
  for (int h = 0; h < 2; ++h) {
    float best_affinity = -1;
    for (uint32_t c : candidates) {
      // Mean similarity of the half to the segment's neighbours in part c
      float sum = 0;
      int count = 0;
      for (idx_t e = begin; e < end; ++e) {
        const size_t t = size_t(g.adjncy[size_t(e)]);
        if (p[t] != c) continue;
        sum += SegmentSimilarity(halves[h], f[t], sp).Sum();
        ++count;
      }
      if (count == 0) continue;
      const float affinity = sum / float(count);
      // Ties keep the segment's own part (candidates are sorted, so compare explicitly)
      if (affinity > best_affinity || (affinity == best_affinity && c == p[s])) {
        best_affinity = affinity;
        best[h] = c;
      }
    }
  }
  SegmentSplit out;
  out.part[0] = best[0];
  out.part[1] = best[1];
  out.split = best[0] != best[1];
  out.first_half_transmittance = t0;
  out.tau[0] = halves[0].tau;
  out.tau[1] = halves[1].tau;
  return out;
}

// The RBF-SVM boundaries of every pair of neighbouring parts (a < b, decision > 0 on a's side),
// each trained on the start and end points of a's segments with a graph neighbour in b and of b's
// with one in a (at most kMaxSvmPoints per side, evenly strided: training is superlinear).
constexpr size_t kMaxSvmPoints = 600;
using BoundaryMap = std::map<std::pair<uint32_t, uint32_t>, std::unique_ptr<SvmBoundary>>;

BoundaryMap TrainBoundaries(const std::vector<SegmentFeatures>& f, const std::vector<uint32_t>& p,
                            const SegmentGraph& g) {
  std::map<std::pair<uint32_t, uint32_t>, std::array<std::vector<Vec3>, 2>> points;
  for (size_t s = 0; s < f.size(); ++s) {
    std::vector<uint32_t> others;
    for (idx_t e = g.xadj[s]; e < g.xadj[s + 1]; ++e)
      if (p[size_t(g.adjncy[size_t(e)])] != p[s]) others.push_back(p[size_t(g.adjncy[size_t(e)])]);
    for (uint32_t o : SortedUnique(std::move(others))) {
      const bool first = p[s] < o;
      auto& side = points[{std::min(p[s], o), std::max(p[s], o)}][first ? 0 : 1];
      side.push_back(f[s].x0);
      side.push_back(f[s].x1);
    }
  }
  std::vector<std::pair<std::pair<uint32_t, uint32_t>, std::array<std::vector<Vec3>, 2>>> jobs(points.begin(),
                                                                                             points.end());
  std::vector<std::unique_ptr<SvmBoundary>> trained(jobs.size());
  tbb::parallel_for(size_t(0), jobs.size(), [&](size_t i) {
    std::array<std::vector<Vec3>, 2>& sides = jobs[i].second;
    Bounds3 box;
    for (auto& side : sides) {
      if (side.size() > kMaxSvmPoints) {
        std::vector<Vec3> kept;
        const double stride = double(side.size()) / double(kMaxSvmPoints);
        for (size_t k = 0; k < kMaxSvmPoints; ++k) kept.push_back(side[size_t(double(k) * stride)]);
        side = std::move(kept);
      }
      for (const Vec3& v : side) box.Extend(v);
    }
    // γ = 0.5 (the paper) relative to the boundary region's extent
    const float scale = std::max(Length(box.Diagonal()), 1e-6f);
    trained[i] = std::make_unique<SvmBoundary>(sides[0], sides[1], (box.lo + box.hi) * 0.5f, scale);
  });
  BoundaryMap out;
  for (size_t i = 0; i < jobs.size(); ++i) out.emplace(jobs[i].first, std::move(trained[i]));
  return out;
}

// Huo 2016, Sec. 4.2.3: where the segment crosses the boundary between its part and the
// neighbouring part it has most graph edges to (ties: the lower part). The decision is sampled
// at 8 points along the segment and the first sign change refined by bisection; a crossing in
// the first or last 2% of the segment is no split.
SegmentSplit DecideSplitSvm(const Scene& scene, const EyeSegment& seg, size_t s,
                            const std::vector<SegmentFeatures>& f, const std::vector<uint32_t>& p,
                            const SegmentGraph& g, const BoundaryMap& boundaries, uint64_t seed) {
  if (seg.medium < 0 || !(seg.length > 0)) return {};
  std::map<uint32_t, int> edges;
  for (idx_t e = g.xadj[s]; e < g.xadj[s + 1]; ++e) {
    const uint32_t o = p[size_t(g.adjncy[size_t(e)])];
    if (o != p[s]) ++edges[o];
  }
  if (edges.empty()) return {};
  uint32_t other = edges.begin()->first;
  for (const auto& [part, count] : edges)
    if (count > edges[other]) other = part;
  const auto it = boundaries.find({std::min(p[s], other), std::max(p[s], other)});
  if (it == boundaries.end() || !it->second->valid()) return {};
  const SvmBoundary& svm = *it->second;
  const double own = p[s] < other ? 1.0 : -1.0;  // the sign of the segment's own side
  const auto side = [&](float u) { return own * svm.Decision(f[s].x0 + (f[s].x1 - f[s].x0) * u) > 0; };
  constexpr int kSamples = 8;
  const bool start = side(0.f);
  float lo = 0, hi = -1;
  for (int k = 1; k <= kSamples; ++k) {
    const float u = float(k) / float(kSamples);
    if (side(u) != start) {
      lo = float(k - 1) / float(kSamples);
      hi = u;
      break;
    }
  }
  if (hi < 0) return {};
  for (int iter = 0; iter < 12; ++iter) {
    const float mid = 0.5f * (lo + hi);
    (side(mid) == start ? lo : hi) = mid;
  }
  const float at = 0.5f * (lo + hi);
  if (at < 0.02f || at > 0.98f) return {};
  const Medium& med = scene.media()[size_t(seg.medium)];
  Rng rng(HashSeed({seed, uint64_t(RngStream::kSlicing), 3, s}));
  const float first = at * seg.length;
  const RGB t0 = med.Transmittance({seg.o, seg.d, first}, rng);
  const RGB t1 = med.Transmittance({seg.o + seg.d * first, seg.d, seg.length - first}, rng);
  SegmentSplit out;
  out.split = true;
  out.at = at;
  out.part[0] = start ? p[s] : other;
  out.part[1] = start ? other : p[s];
  out.first_half_transmittance = t0;
  out.tau[0] = t0.Average();
  out.tau[1] = t1.Average();
  return out;
}

// Each sample's segments stay contiguous and in order: their ranges after a rebuild.
void RecomputeSampleRanges(ReceiverSet* receivers) {
  for (CameraSample& cs : receivers->samples) {
    cs.first_segment = -1;
    cs.segment_count = 0;
  }
  for (size_t s = 0; s < receivers->segments.size(); ++s) {
    CameraSample& cs = receivers->samples[receivers->segments[s].sample];
    if (cs.segment_count == 0) cs.first_segment = int32_t(s);
    ++cs.segment_count;
  }
}

}  // namespace

SegmentSimilarityTerms SegmentSimilarity(const SegmentFeatures& a, const SegmentFeatures& b,
                                         const SegmentSimilarityParams& params) {
  SegmentSimilarityTerms t;
  // Eq. 10
  const float B = params.B;
  t.spatial = std::max(0.f, B - Distance(a.x0, b.x0) - Distance(a.x1, b.x1)) / B;
  // Eq. 11 (direction and medium are constant along a segment, so d(x0i, x0j) = d(x1i, x1j))
  if (a.medium == b.medium) t.directional = params.kappa * 2.f * (1.f - PhaseDifference(a, b));
  // Eq. 12
  t.transmittance = 1.f - std::min(1.f, std::abs(a.tau - b.tau));
  // Pixel term (Gaussian in image space, see the header)
  const float r2 = Sqr(a.px - b.px) + Sqr(a.py - b.py);
  t.pixel = std::exp(-r2 / (2.f * std::max(params.pixel_sigma, 1e-6f)));
  return t;
}

std::vector<SegmentFeatures> ComputeSegmentFeatures(const Scene& scene, const ReceiverSet& receivers,
                                                    uint64_t seed) {
  std::vector<SegmentFeatures> f(receivers.segments.size());
  const int width = std::max(1, receivers.width);
  tbb::parallel_for(size_t(0), f.size(), [&](size_t s) {
    const EyeSegment& seg = receivers.segments[s];
    SegmentFeatures& out = f[s];
    out.x0 = seg.o;
    out.x1 = seg.o + seg.d * seg.length;
    out.d = seg.d;
    out.medium = seg.medium;
    const uint32_t pixel = receivers.samples[seg.sample].pixel;
    out.px = float(pixel % uint32_t(width));
    out.py = float(pixel / uint32_t(width));
    if (seg.medium >= 0) {
      const Medium& med = scene.media()[size_t(seg.medium)];
      out.g = med.g();
      Rng rng(HashSeed({seed, uint64_t(RngStream::kSlicing), 1, s}));
      out.tau = med.Transmittance({seg.o, seg.d, seg.length}, rng).Average();
    }
  });
  return f;
}

size_t SegmentSliceCount(size_t segments, size_t eye_rays, const SegmentSlicingOptions& options) {
  if (segments == 0) return 0;
  const size_t min_rows = std::max<size_t>(1, options.min_rows_per_slice);
  const size_t max_rows = std::max(min_rows, options.max_rows_per_slice);
  // Huo 2016, Sec. 4.3: K = 0.008 × eye rays, kept within [n / max_rows, n / min_rows]
  const size_t by_rays = size_t(std::llround(options.slices_per_eye_ray * double(eye_rays)));
  const size_t lo = (segments + max_rows - 1) / max_rows;
  const size_t hi = std::max<size_t>(1, segments / min_rows);
  return std::clamp(std::clamp(by_rays, lo, std::max(lo, hi)), size_t(1), segments);
}

std::vector<uint32_t> PartitionSegments(const std::vector<SegmentFeatures>& features, size_t parts,
                                        float scene_diagonal, const SegmentSlicingOptions& options) {
  const size_t n = features.size();
  std::vector<uint32_t> part(n, 0);
  if (n == 0 || parts <= 1) return part;
  parts = std::min(parts, n);
  SegmentGraph g = BuildGraph(features, SimilarityParams(scene_diagonal, options),
                              std::max<size_t>(1, options.graph_neighbors));
  idx_t nvtxs = idx_t(n), ncon = 1, nparts = idx_t(parts), objval = 0;
  idx_t metis_options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(metis_options);
  metis_options[METIS_OPTION_NUMBERING] = 0;
  // METIS's own generator, seeded from the job seed: the partition is a function of the graph
  // and the seed only (METIS 5 is serial)
  metis_options[METIS_OPTION_SEED] =
      idx_t(HashSeed({options.seed, uint64_t(RngStream::kSlicing), 2}) & 0x3fffffff);
  std::vector<idx_t> result(n, 0);
  const int status = METIS_PartGraphKway(&nvtxs, &ncon, g.xadj.data(), g.adjncy.data(), nullptr,
                                         nullptr, g.adjwgt.data(), &nparts, nullptr, nullptr,
                                         metis_options, &objval, result.data());
  if (status != METIS_OK)
    throw std::runtime_error("segment slicing: METIS_PartGraphKway failed (status " +
                             std::to_string(status) + ")");
  for (size_t s = 0; s < n; ++s) part[s] = uint32_t(result[s]);
  return part;
}

size_t RefineSegmentSlices(const Scene& scene, ReceiverSet* receivers,
                           std::vector<SegmentFeatures>* features, std::vector<uint32_t>* part,
                           float scene_diagonal, const SegmentSlicingOptions& options,
                           size_t* merged_out) {
  size_t merged = 0;
  std::vector<SegmentFeatures>& f = *features;
  std::vector<uint32_t>& p = *part;
  const size_t n = f.size();
  if (n < 2) return 0;
  const SegmentSimilarityParams sp = SimilarityParams(scene_diagonal, options);
  const SegmentGraph g = BuildGraph(f, sp, std::max<size_t>(1, options.graph_neighbors));

  // Decisions read only the partition before refinement: independent per segment.
  std::vector<SegmentSplit> splits(n);
  if (options.boundary == SegmentBoundary::kSvm) {
    const BoundaryMap boundaries = TrainBoundaries(f, p, g);
    tbb::parallel_for(size_t(0), n, [&](size_t s) {
      splits[s] = DecideSplitSvm(scene, receivers->segments[s], s, f, p, g, boundaries, options.seed);
    });
  } else {
    tbb::parallel_for(size_t(0), n, [&](size_t s) {
      splits[s] = DecideSplit(scene, receivers->segments[s], s, f, p, g, sp, options.seed);
    });
  }

  // Rebuild the segment list in the same (sample) order, halves in place of split segments.
  const std::vector<EyeSegment> old_segments = std::move(receivers->segments);
  const std::vector<SegmentFeatures> old_features = std::move(f);
  const std::vector<uint32_t> old_part = std::move(p);
  std::vector<EyeSegment>& segs = receivers->segments;
  segs.clear();
  f.clear();
  p.clear();
  size_t split_count = 0;
  std::vector<uint8_t> created;  // per new segment: a half made by a split
  // Sec. 4.2.3's last step: a new piece joins the connecting piece of its ray (the one before
  // it, same sample, same medium) when both are in the same part and their Eq. 8 similarity is
  // above merge_threshold. The joined segment starts where the earlier one does, with its
  // throughput (the later one's is that times the earlier one's transmittance), so the ray's
  // in-scattering is unchanged; its τ is the product.
  auto append = [&](const EyeSegment& seg, const SegmentFeatures& feat, uint32_t part_of, bool is_new) {
    if (!segs.empty() && (is_new || created.back()) && options.merge_threshold > 0) {
      EyeSegment& last = segs.back();
      // Contiguous pieces only: a ray leaves a medium and re-enters it (an interface sphere of
      // vacuum inside fog) with the same medium and depth on both sides of the gap.
      const Vec3 end = last.o + last.d * last.length;
      if (last.sample == seg.sample && last.medium == seg.medium && last.depth == seg.depth &&
          Distance(end, seg.o) <= 1e-4f * (1.f + Length(end)) && p.back() == part_of &&
          SegmentSimilarity(f.back(), feat, sp).Sum() > options.merge_threshold) {
        last.length += seg.length;
        f.back().x1 = feat.x1;
        f.back().tau *= feat.tau;
        created.back() = 0;  // a whole segment again
        ++merged;
        return;
      }
    }
    segs.push_back(seg);
    f.push_back(feat);
    p.push_back(part_of);
    created.push_back(is_new ? 1 : 0);
  };
  for (size_t s = 0; s < n; ++s) {
    const SegmentSplit& sp_s = splits[s];
    if (!sp_s.split) {
      // Not split: the segment keeps its part (even when both halves prefer another one: moving
      // whole segments would unbalance the partition METIS chose)
      append(old_segments[s], old_features[s], old_part[s], false);
      continue;
    }
    ++split_count;
    const EyeSegment& seg = old_segments[s];
    EyeSegment a = seg, b = seg;
    a.length = sp_s.at * seg.length;
    b.length = seg.length - a.length;
    b.o = seg.o + seg.d * a.length;
    b.throughput = seg.throughput * sp_s.first_half_transmittance;  // unbiased estimate
    append(a, PieceFeatures(old_features[s], 0, sp_s.at, sp_s.tau[0]), sp_s.part[0], true);
    append(b, PieceFeatures(old_features[s], 1, sp_s.at, sp_s.tau[1]), sp_s.part[1], true);
  }
  RecomputeSampleRanges(receivers);
  if (merged_out) *merged_out = merged;
  return split_count;
}

std::vector<Slice> SliceSegments(const Scene& scene, ReceiverSet* receivers,
                                 const SegmentSlicingOptions& options) {
  if (receivers->segments.empty()) return {};
  const float diagonal = Length(scene.bounds().Diagonal());
  size_t eye_rays = 0;
  for (const CameraSample& cs : receivers->samples) eye_rays += cs.segment_count > 0;
  std::vector<SegmentFeatures> features = ComputeSegmentFeatures(scene, *receivers, options.seed);
  const size_t parts = SegmentSliceCount(features.size(), eye_rays, options);
  std::vector<uint32_t> part = PartitionSegments(features, parts, diagonal, options);
  if (options.refine && parts > 1)
    RefineSegmentSlices(scene, receivers, &features, &part, diagonal, options);

  // Slices in part order, empty parts (METIS may leave some) dropped
  std::vector<Slice> by_part(parts);
  for (size_t s = 0; s < part.size(); ++s) by_part[part[s]].rows.push_back(uint32_t(s));
  std::vector<Slice> slices;
  for (Slice& sl : by_part)
    if (!sl.rows.empty()) slices.push_back(std::move(sl));
  const size_t count = slices.size();

  // Centroids in 6-D: mean midpoint, mean direction scaled as SliceReceivers scales normals
  const float w = 0.25f * diagonal;
  std::vector<std::array<float, 6>> centroid(count);
  tbb::parallel_for(size_t(0), count, [&](size_t c) {
    Slice& sl = slices[c];
    std::array<double, 6> sum{};
    for (uint32_t r : sl.rows) {
      const Vec3 m = (features[r].x0 + features[r].x1) * 0.5f;
      const Vec3 d = features[r].d;
      for (int a = 0; a < 3; ++a) {
        sum[size_t(a)] += double(m[a]);
        sum[size_t(a) + 3] += double(d[a]);
      }
    }
    const double inv = 1.0 / double(sl.rows.size());
    sl.center = Vec3(float(sum[0] * inv), float(sum[1] * inv), float(sum[2] * inv));
    const Vec3 mean_d(float(sum[3] * inv), float(sum[4] * inv), float(sum[5] * inv));
    const float len = Length(mean_d);
    sl.normal = len > 1e-6f ? mean_d / len : Vec3(0, 0, 0);
    centroid[c] = {sl.center.x, sl.center.y, sl.center.z, mean_d.x * w, mean_d.y * w, mean_d.z * w};
  });
  const size_t k = std::min(options.slice_neighbors, count - 1);
  if (k > 0) {
    tbb::parallel_for(size_t(0), count, [&](size_t c) {
      std::vector<std::pair<float, uint32_t>> dist;
      for (size_t t = 0; t < count; ++t) {
        if (t == c) continue;
        float d2 = 0;
        for (size_t a = 0; a < 6; ++a) d2 += Sqr(centroid[c][a] - centroid[t][a]);
        dist.emplace_back(d2, uint32_t(t));
      }
      std::partial_sort(dist.begin(), dist.begin() + ptrdiff_t(k), dist.end());
      for (size_t j = 0; j < k; ++j) slices[c].neighbors.push_back(dist[j].second);
    });
  }
  return slices;
}

}  // namespace lightfarm
