// Row slicing: a partition of the rows into slices of about rows_per_slice rows that are
// compact in 6-D (position + scaled normal), with their nearest neighbouring slices.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <vector>

#include "common/render/render_job.h"
#include "common/receivers/slicing.h"
#include "common/util/rng.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_slicing {

// Receivers on the six faces of a unit box (normals pointing inwards), like a Cornell box.
ReceiverSet BoxReceivers(size_t n, uint64_t seed) {
  Rng rng(seed);
  ReceiverSet set;
  for (size_t i = 0; i < n; ++i) {
    ShadingPoint sp;
    int face = int(rng.UniformInt(6));
    int axis = face / 2;
    float side = face % 2 ? 1.f : 0.f;
    Vec3 p(rng.Uniform(), rng.Uniform(), rng.Uniform());
    p[axis] = side;
    Vec3 normal(0, 0, 0);
    normal[axis] = side > 0 ? -1.f : 1.f;
    sp.p = p;
    sp.ng = sp.ns = normal;
    set.points.push_back(sp);
  }
  return set;
}

using Point6 = std::array<double, 6>;

Point6 Centroid6(const ReceiverSet& set, const Slice& slice, float w) {
  Point6 c{};
  for (uint32_t r : slice.rows) {
    const ShadingPoint& sp = set.points[r];
    for (int a = 0; a < 3; ++a) {
      c[size_t(a)] += double(sp.p[a]);
      c[size_t(a) + 3] += double(sp.ns[a] * w);
    }
  }
  for (double& v : c) v /= double(slice.rows.size());
  return c;
}

double Distance2(const Point6& a, const Point6& b) {
  double d = 0;
  for (size_t i = 0; i < 6; ++i) d += (a[i] - b[i]) * (a[i] - b[i]);
  return d;
}

TEST(Slicing, PartitionsRowsIntoSlicesOfTheRequestedSize) {
  ReceiverSet set = BoxReceivers(20000, 1);
  SlicingOptions opt;
  opt.rows_per_slice = 800;
  std::vector<Slice> slices = SliceReceivers(set, std::sqrt(3.f), opt);
  ASSERT_EQ(slices.size(), 25u);  // round(20000 / 800)
  std::vector<int> seen(set.points.size(), 0);
  for (const Slice& s : slices) {
    EXPECT_TRUE(std::is_sorted(s.rows.begin(), s.rows.end()));
    EXPECT_GE(s.rows.size(), opt.rows_per_slice / 2);
    EXPECT_LE(s.rows.size(), opt.rows_per_slice * 2);
    for (uint32_t r : s.rows) ++seen[r];
  }
  for (size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "row " << i;

  // Small inputs: one slice; never more slices than rows.
  ReceiverSet few = BoxReceivers(10, 2);
  EXPECT_EQ(SliceReceivers(few, 1.f, opt).size(), 1u);
  opt.rows_per_slice = 1;
  EXPECT_EQ(SliceReceivers(few, 1.f, opt).size(), 10u);
  EXPECT_TRUE(SliceReceivers(ReceiverSet(), 1.f, opt).empty());
}

// With a strong normal weight every slice lies on one face of the box; its mean normal is that
// face's normal and its centre the mean position.
TEST(Slicing, SlicesAreCompactInPositionAndNormal) {
  ReceiverSet set = BoxReceivers(12000, 3);
  SlicingOptions opt;
  opt.rows_per_slice = 500;
  opt.normal_weight = 4.f;  // normals dominate the unit box's positions
  std::vector<Slice> slices = SliceReceivers(set, std::sqrt(3.f), opt);
  for (const Slice& s : slices) {
    Vec3 n0 = set.points[s.rows[0]].ns;
    Vec3 mean(0, 0, 0);
    for (uint32_t r : s.rows) {
      EXPECT_EQ(set.points[r].ns, n0);
      mean += set.points[r].p;
    }
    mean = mean / float(s.rows.size());
    EXPECT_NEAR(Dot(s.normal, n0), 1.f, 1e-5f);
    EXPECT_NEAR(Distance(s.center, mean), 0.f, 1e-4f);
  }
}

TEST(Slicing, NeighboursAreTheNearestSlices) {
  ReceiverSet set = BoxReceivers(30000, 4);
  SlicingOptions opt;
  opt.rows_per_slice = 600;
  opt.neighbors = 6;
  const float diagonal = std::sqrt(3.f);
  std::vector<Slice> slices = SliceReceivers(set, diagonal, opt);
  const float w = opt.normal_weight * diagonal;
  std::vector<Point6> centroid;
  for (const Slice& s : slices) centroid.push_back(Centroid6(set, s, w));
  size_t mutual = 0, total = 0;
  for (size_t i = 0; i < slices.size(); ++i) {
    const std::vector<uint32_t>& nb = slices[i].neighbors;
    ASSERT_EQ(nb.size(), opt.neighbors);
    EXPECT_EQ(std::set<uint32_t>(nb.begin(), nb.end()).size(), nb.size());
    // The k-th neighbour is no farther than any slice that is not a neighbour.
    double farthest = 0;
    for (uint32_t j : nb) {
      EXPECT_NE(j, i);
      farthest = std::max(farthest, Distance2(centroid[i], centroid[j]));
    }
    for (size_t j = 0; j < slices.size(); ++j) {
      if (j == i || std::find(nb.begin(), nb.end(), uint32_t(j)) != nb.end()) continue;
      EXPECT_GE(Distance2(centroid[i], centroid[j]), farthest * (1 - 1e-4));
    }
    for (uint32_t j : nb) {
      const std::vector<uint32_t>& back = slices[j].neighbors;
      mutual += std::find(back.begin(), back.end(), uint32_t(i)) != back.end();
      ++total;
    }
  }
  // Nearest-neighbour relations are mostly symmetric.
  EXPECT_GT(double(mutual) / double(total), 0.6);
}

TEST(Slicing, DeterministicAcrossThreadCounts) {
  ReceiverSet set = BoxReceivers(50000, 5);
  SlicingOptions opt;
  std::vector<Slice> a = SliceReceivers(set, 2.f, opt);
  std::vector<Slice> b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = SliceReceivers(set, 2.f, opt);
  }
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].rows, b[i].rows);
    EXPECT_EQ(a[i].neighbors, b[i].neighbors);
    EXPECT_EQ(a[i].center, b[i].center);
  }
}

// The plan's tasks are the slices; brute force does not depend on them.
TEST(Slicing, PlanUsesSlicesAndBruteForceIgnoresThem) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderSettings s;
  s.width = s.height = 16;
  s.lights = 500;
  s.params = {"rows_per_slice=40"};
  RenderOutput small = RenderScene(scene, s);
  s.params = {"rows_per_slice=800"};
  RenderOutput large = RenderScene(scene, s);
  const size_t rows = small.stats["receivers"]["points"].get<size_t>();
  EXPECT_EQ(small.stats["slices"].get<size_t>(), std::max<size_t>(1, (rows + 20) / 40));
  EXPECT_EQ(large.stats["slices"].get<size_t>(), 1u);
  ASSERT_EQ(small.image.pixels.size(), large.image.pixels.size());
  for (size_t i = 0; i < small.image.pixels.size(); ++i)
    ASSERT_EQ(small.image.pixels[i], large.image.pixels[i]) << "pixel " << i;
}

}  // namespace test_slicing
}  // namespace lightfarm
