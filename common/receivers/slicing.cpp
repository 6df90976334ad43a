// Row slicing: a kd-tree over 6-D receiver coordinates (position, and shading normal scaled by
// normal_weight × scene diagonal), split top-down at quantiles along the widest 6-D axis, as
// LightSlice (Ou & Pellacini 2011) and Huo et al. 2015 (Sec. 6) do.
//
// Instead of halving until a size threshold (which leaves slices anywhere in (r/2, r]), each
// node first decides how many slices it becomes, k = round(n / rows_per_slice), and splits its
// rows either at the middle of the widest axis (when both sides then average 0.7–1.4 ×
// rows_per_slice per slice: this keeps separate surfaces apart) or at the quantile k_left / k
// (nth_element, ties by row index). Either way slices stay within about [0.7, 1.4] ×
// rows_per_slice rows, and the split is deterministic and O(n) per level, O(n log n) overall.
// Slice ids are assigned from the leaf counts, so they do not depend on which thread built
// what.
#include "common/receivers/slicing.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <span>

namespace lightfarm {

namespace {

using Point6 = std::array<float, 6>;

constexpr size_t kParallelRows = 16384;  // subtrees with at least this many rows split in parallel

struct SliceRow {
  Point6 x;
  uint32_t row = 0;
};

class SliceBuilder {
 public:
  SliceBuilder(size_t rows_per_slice, std::vector<Slice>& slices)
      : rows_per_slice_(rows_per_slice), slices_(slices) {}

  static size_t SliceCount(size_t n, size_t rows_per_slice) {
    return std::max<size_t>(1, (n + rows_per_slice / 2) / rows_per_slice);
  }

  // Splits `rows` into `count` slices with ids [first_slice, first_slice + count).
  void Recurse(std::span<SliceRow> rows, size_t count, size_t first_slice) {
    if (count <= 1 || rows.size() <= 1) {
      Slice& s = slices_[first_slice];
      s.rows.reserve(rows.size());
      for (const SliceRow& r : rows) s.rows.push_back(r.row);
      std::sort(s.rows.begin(), s.rows.end());
      return;
    }
    // Widest axis of the 6-D bounds.
    Point6 lo, hi;
    lo.fill(kInfinity);
    hi.fill(-kInfinity);
    for (const SliceRow& r : rows)
      for (int a = 0; a < 6; ++a) {
        lo[size_t(a)] = std::min(lo[size_t(a)], r.x[size_t(a)]);
        hi[size_t(a)] = std::max(hi[size_t(a)], r.x[size_t(a)]);
      }
    size_t axis = 0;
    for (size_t a = 1; a < 6; ++a)
      if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
    // Split at the middle of the widest axis when both sides then hold slices of acceptable
    // size (clusters such as the walls of a room stay whole), else at the quantile that gives
    // the left part count/2 slices.
    const float mid = 0.5f * (lo[axis] + hi[axis]);
    size_t below = 0;
    for (const SliceRow& r : rows) below += r.x[axis] < mid;
    size_t left_count = 0, k = 0;
    if (below > 0 && below < rows.size()) {
      size_t kl = std::clamp<size_t>(
          size_t(std::llround(double(count) * double(below) / double(rows.size()))), 1, count - 1);
      auto acceptable = [&](size_t n, size_t slices) {
        double avg = double(n) / double(slices);
        return avg >= 0.7 * double(rows_per_slice_) && avg <= 1.4 * double(rows_per_slice_);
      };
      if (acceptable(below, kl) && acceptable(rows.size() - below, count - kl)) {
        std::partition(rows.begin(), rows.end(),
                       [&](const SliceRow& r) { return r.x[axis] < mid; });
        left_count = kl;
        k = below;
      }
    }
    if (k == 0) {
      left_count = count / 2;
      k = std::clamp<size_t>(rows.size() * left_count / count, 1, rows.size() - 1);
      std::nth_element(rows.begin(), rows.begin() + ptrdiff_t(k), rows.end(),
                       [axis](const SliceRow& a, const SliceRow& b) {
                         if (a.x[axis] != b.x[axis]) return a.x[axis] < b.x[axis];
                         return a.row < b.row;
                       });
    }
    auto left = [&] { Recurse(rows.subspan(0, k), left_count, first_slice); };
    auto right = [&] { Recurse(rows.subspan(k), count - left_count, first_slice + left_count); };
    if (rows.size() >= kParallelRows) {
      tbb::parallel_invoke(left, right);
    } else {
      left();
      right();
    }
  }

 private:
  size_t rows_per_slice_;
  std::vector<Slice>& slices_;
};

}  // namespace

std::vector<Slice> SliceReceivers(const ReceiverSet& receivers, float scene_diagonal,
                                  const SlicingOptions& options) {
  const size_t n = receivers.points.size();
  if (n == 0) return {};
  const size_t rows_per_slice = std::max<size_t>(1, options.rows_per_slice);
  const float w = options.normal_weight * std::max(scene_diagonal, 0.f);

  // 6-D coordinates of every row.
  std::vector<SliceRow> rows(n);
  for (size_t i = 0; i < n; ++i) {
    const ShadingPoint& sp = receivers.points[i];
    rows[i].x = {sp.p.x, sp.p.y, sp.p.z, sp.ns.x * w, sp.ns.y * w, sp.ns.z * w};
    rows[i].row = uint32_t(i);
  }
  // Never more slices than rows.
  const size_t count = std::min(n, SliceBuilder::SliceCount(n, rows_per_slice));
  std::vector<Slice> slices(count);
  SliceBuilder(rows_per_slice, slices).Recurse(rows, count, 0);

  // Centroids: mean position, mean normal (6-D centroid kept for the neighbour search).
  std::vector<Point6> centroid(count);
  tbb::parallel_for(size_t(0), count, [&](size_t s) {
    Slice& slice = slices[s];
    std::array<double, 6> sum{};
    for (uint32_t r : slice.rows) {
      const ShadingPoint& sp = receivers.points[r];
      sum[0] += double(sp.p.x); sum[1] += double(sp.p.y); sum[2] += double(sp.p.z);
      sum[3] += double(sp.ns.x); sum[4] += double(sp.ns.y); sum[5] += double(sp.ns.z);
    }
    const double inv = 1.0 / double(std::max<size_t>(1, slice.rows.size()));
    slice.center = Vec3(float(sum[0] * inv), float(sum[1] * inv), float(sum[2] * inv));
    Vec3 mean_n(float(sum[3] * inv), float(sum[4] * inv), float(sum[5] * inv));
    float len = Length(mean_n);
    slice.normal = len > 1e-6f ? mean_n / len : Vec3(0, 0, 0);
    centroid[s] = {slice.center.x, slice.center.y, slice.center.z,
                   mean_n.x * w, mean_n.y * w, mean_n.z * w};
  });

  // k nearest slices by 6-D centroid distance (ties by id). O(S²) over slices: S = rows / 800
  // stays in the low thousands for the images this renders, where this takes milliseconds.
  const size_t k = std::min(options.neighbors, count - 1);
  if (k > 0) {
    tbb::parallel_for(size_t(0), count, [&](size_t s) {
      std::vector<std::pair<float, uint32_t>> dist;
      dist.reserve(count - 1);
      for (size_t t = 0; t < count; ++t) {
        if (t == s) continue;
        float d2 = 0;
        for (size_t a = 0; a < 6; ++a) d2 += Sqr(centroid[s][a] - centroid[t][a]);
        dist.emplace_back(d2, uint32_t(t));
      }
      std::partial_sort(dist.begin(), dist.begin() + ptrdiff_t(k), dist.end());
      std::vector<uint32_t>& out = slices[s].neighbors;
      out.resize(k);
      for (size_t j = 0; j < k; ++j) out[j] = dist[j].second;
    });
  }
  return slices;
}

}  // namespace lightfarm
