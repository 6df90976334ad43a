// Light tree invariants (Walter 2005, Sec. 4): a partition of the lights, sums and bounds that
// hold up the tree, representatives drawn ∝ intensity, determinism, and build speed.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <vector>

#include "common/lights/light_tree.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_light_tree {

Vec3 RandomUnit(Rng& rng) {
  float z = 1 - 2 * rng.Uniform(), phi = 2 * kPi * rng.Uniform();
  float r = SafeSqrt(1 - z * z);
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// A mixed light set: every kind, zero-power lights, two-sided emitters and duplicated
// positions.
LightSet MixedLights(size_t n, uint64_t seed) {
  Rng rng(seed);
  LightSet set;
  for (size_t i = 0; i < n; ++i) {
    VirtualLight l;
    uint32_t k = rng.UniformInt(10);
    l.kind = k < 4 ? VirtualLightKind::kSurfaceVPL
             : k < 7 ? VirtualLightKind::kAreaVPL
             : k < 9 ? VirtualLightKind::kPoint
                     : VirtualLightKind::kDirectional;
    l.p = {rng.Uniform() * 10 - 5, rng.Uniform() * 2, rng.Uniform() * 10 - 5};
    if (i % 17 == 3 && i > 0) l.p = set.lights[i - 1].p;  // identical positions
    l.n = RandomUnit(rng);
    l.ng = l.n;
    l.wi = RandomUnit(rng);
    l.power = RGB(rng.Uniform(), rng.Uniform(), rng.Uniform()) * 10.f;
    if (i % 13 == 0) l.power = RGB(0.f);  // zero power
    l.two_sided = l.kind == VirtualLightKind::kAreaVPL && i % 5 == 0;
    set.lights.push_back(l);
  }
  return set;
}

Vec3 ConeNormal(const VirtualLight& l) {
  return l.kind == VirtualLightKind::kSurfaceVPL ? FaceForward(l.n, l.wi) : l.n;
}

bool Contains(const Bounds3& outer, const Bounds3& inner) {
  return outer.lo.x <= inner.lo.x && outer.lo.y <= inner.lo.y && outer.lo.z <= inner.lo.z &&
         outer.hi.x >= inner.hi.x && outer.hi.y >= inner.hi.y && outer.hi.z >= inner.hi.z;
}

void ExpectRGBNear(RGB a, RGB b) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-5f * (1 + std::abs(b[c])));
}

void CheckInvariants(const LightSet& lights, const LightTree& tree) {
  const auto& nodes = tree.nodes();
  const auto& order = tree.order();
  ASSERT_EQ(order.size(), lights.size());
  // Every light in exactly one leaf.
  std::vector<int> seen(lights.size(), 0);
  size_t leaves = 0;
  for (const LightTreeNode& n : nodes) {
    if (!n.IsLeaf()) continue;
    ++leaves;
    ASSERT_EQ(n.count, 1u);
    ASSERT_LT(n.representative, lights.size());
    EXPECT_EQ(order[n.first], n.representative);
    ++seen[n.representative];
  }
  EXPECT_EQ(leaves, lights.size());
  for (size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "light " << i;

  // One root per kind present, roots cover all lights.
  std::vector<bool> kind_present(4, false);
  for (const VirtualLight& l : lights.lights) kind_present[size_t(l.kind)] = true;
  size_t kinds = 0;
  for (bool b : kind_present) kinds += b;
  EXPECT_EQ(tree.roots().size(), kinds);
  size_t covered = 0;
  for (uint32_t r : tree.roots()) covered += nodes[r].count;
  EXPECT_EQ(covered, lights.size());
  EXPECT_EQ(nodes.size(), 2 * lights.size() - kinds);

  for (size_t i = 0; i < nodes.size(); ++i) {
    const LightTreeNode& n = nodes[i];
    // Lights below the node: kind, position inside the bounds, normal inside the cone.
    for (uint32_t k = n.first; k < n.first + n.count; ++k) {
      const VirtualLight& l = lights.lights[order[k]];
      EXPECT_EQ(l.kind, n.kind);
      Vec3 p = l.IsDirectional() ? l.n : l.p;
      EXPECT_TRUE(p.x >= n.bounds.lo.x && p.x <= n.bounds.hi.x && p.y >= n.bounds.lo.y &&
                  p.y <= n.bounds.hi.y && p.z >= n.bounds.lo.z && p.z <= n.bounds.hi.z);
      if (n.cone_cos > -1.f && l.kind != VirtualLightKind::kPoint) {
        EXPECT_GE(Dot(ConeNormal(l), n.cone_axis), n.cone_cos - 1e-4f) << "node " << i;
      }
    }
    // The representative is one of the node's lights.
    bool rep_below = false;
    for (uint32_t k = n.first; k < n.first + n.count; ++k) rep_below |= order[k] == n.representative;
    EXPECT_TRUE(rep_below) << "node " << i;
    if (n.IsLeaf()) {
      ExpectRGBNear(n.intensity, lights.lights[n.representative].power);
      continue;
    }
    const LightTreeNode& a = nodes[size_t(n.left)];
    const LightTreeNode& b = nodes[size_t(n.right)];
    EXPECT_GT(size_t(n.left), i);
    EXPECT_GT(size_t(n.right), i);
    EXPECT_EQ(a.count + b.count, n.count);
    EXPECT_EQ(a.first, n.first);
    EXPECT_EQ(b.first, n.first + a.count);
    ExpectRGBNear(n.intensity, a.intensity + b.intensity);
    EXPECT_NEAR(n.intensity_lum, a.intensity_lum + b.intensity_lum, 1e-4f * (1 + n.intensity_lum));
    EXPECT_TRUE(Contains(n.bounds, a.bounds));
    EXPECT_TRUE(Contains(n.bounds, b.bounds));
    // A child with an unbounded cone forces an unbounded parent.
    if (a.cone_cos <= -1.f || b.cone_cos <= -1.f) {
      EXPECT_LE(n.cone_cos, -1.f);
    }
  }
}

TEST(LightTree, InvariantsOnMixedLights) {
  LightSet lights = MixedLights(3000, 7);
  LightTree tree = LightTree::Build(lights, 42);
  CheckInvariants(lights, tree);
  // Two-sided area lights make their leaves' cones unbounded.
  for (const LightTreeNode& n : tree.nodes()) {
    if (n.IsLeaf() && lights.lights[n.representative].two_sided) {
      EXPECT_LE(n.cone_cos, -1.f);
    }
  }
}

TEST(LightTree, DegenerateSets) {
  LightSet empty;
  LightTree t0 = LightTree::Build(empty, 1);
  EXPECT_TRUE(t0.nodes().empty());
  EXPECT_TRUE(t0.roots().empty());

  LightSet one = MixedLights(1, 3);
  one.lights[0].power = RGB(1, 2, 3);
  LightTree t1 = LightTree::Build(one, 1);
  ASSERT_EQ(t1.nodes().size(), 1u);
  EXPECT_TRUE(t1.nodes()[0].IsLeaf());
  EXPECT_EQ(t1.nodes()[0].representative, 0u);

  // 5000 lights at one point, with one normal, all without power: still a valid tree of
  // logarithmic depth.
  LightSet same;
  for (int i = 0; i < 5000; ++i) {
    VirtualLight l;
    l.kind = VirtualLightKind::kAreaVPL;
    l.p = {1, 2, 3};
    l.n = {0, 1, 0};
    same.lights.push_back(l);
  }
  LightTree ts = LightTree::Build(same, 9);
  CheckInvariants(same, ts);
  int depth = 0;
  for (uint32_t node = ts.roots()[0]; !ts.node(node).IsLeaf(); node = uint32_t(ts.node(node).left))
    ++depth;
  EXPECT_LE(depth, 20);
  EXPECT_GE(ts.node(ts.roots()[0]).cone_cos, 0.999f);

  // Geometrically spaced positions defeat binned splits; depth must stay bounded.
  LightSet spaced;
  for (int i = 0; i < 4000; ++i) {
    VirtualLight l;
    l.kind = VirtualLightKind::kPoint;
    l.p = {std::ldexp(1.f, i % 120 - 60), 0, 0};
    l.power = RGB(1.f);
    spaced.lights.push_back(l);
  }
  LightTree tsp = LightTree::Build(spaced, 9);
  CheckInvariants(spaced, tsp);
}

// P(light j is the root's representative) = intensity_lum(j) / intensity_lum(root).
TEST(LightTree, RepresentativeProportionalToIntensity) {
  LightSet set;
  const float powers[] = {1, 2, 3, 4, 0};
  for (int i = 0; i < 5; ++i) {
    VirtualLight l;
    l.kind = VirtualLightKind::kPoint;
    l.p = {float(i), float(i * i % 3), 0};
    l.power = RGB(powers[i]);
    set.lights.push_back(l);
  }
  const int trials = 20000;
  std::vector<int> count(5, 0);
  for (int s = 0; s < trials; ++s) {
    LightTree t = LightTree::Build(set, uint64_t(s));
    ++count[t.node(t.roots()[0]).representative];
  }
  EXPECT_EQ(count[4], 0);  // no power: never chosen
  for (int i = 0; i < 4; ++i) {
    double p = double(powers[i]) / 10.0;
    double sigma = std::sqrt(trials * p * (1 - p));
    EXPECT_NEAR(count[i], trials * p, 5 * sigma) << "light " << i;
  }
}

TEST(LightTree, DeterministicAcrossThreadCounts) {
  LightSet lights = MixedLights(20000, 11);
  LightTree a = LightTree::Build(lights, 5);
  LightTree b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = LightTree::Build(lights, 5);
  }
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  EXPECT_EQ(a.order(), b.order());
  EXPECT_EQ(a.roots(), b.roots());
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    const LightTreeNode &x = a.nodes()[i], &y = b.nodes()[i];
    EXPECT_EQ(x.representative, y.representative);
    EXPECT_EQ(x.left, y.left);
    EXPECT_EQ(x.intensity, y.intensity);
    EXPECT_EQ(x.cone_cos, y.cone_cos);
  }
  // A different seed changes some representatives, never the structure.
  LightTree c = LightTree::Build(lights, 6);
  EXPECT_EQ(a.order(), c.order());
  size_t differ = 0;
  for (size_t i = 0; i < a.nodes().size(); ++i)
    differ += a.nodes()[i].representative != c.nodes()[i].representative;
  EXPECT_GT(differ, 0u);
}

// Spatially coherent clusters: the tree separates two far-apart groups at the root.
TEST(LightTree, SeparatesDistantClusters) {
  LightSet set;
  Rng rng(3);
  for (int i = 0; i < 200; ++i) {
    VirtualLight l;
    l.kind = VirtualLightKind::kPoint;
    float offset = i % 2 ? 100.f : -100.f;
    l.p = {offset + rng.Uniform(), rng.Uniform(), rng.Uniform()};
    l.power = RGB(1.f);
    set.lights.push_back(l);
  }
  LightTree t = LightTree::Build(set, 1);
  const LightTreeNode& root = t.node(t.roots()[0]);
  const LightTreeNode& left = t.node(uint32_t(root.left));
  const LightTreeNode& right = t.node(uint32_t(root.right));
  EXPECT_EQ(left.count, 100u);
  EXPECT_EQ(right.count, 100u);
  EXPECT_LT(left.bounds.Diagonal().x, 2.f);
  EXPECT_LT(right.bounds.Diagonal().x, 2.f);
}

TEST(LightTree, BuildsHundredThousandLightsQuickly) {
  LightSet lights = MixedLights(100000, 21);
  auto start = std::chrono::steady_clock::now();
  LightTree tree = LightTree::Build(lights, 1);
  double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(tree.order().size(), lights.size());
  // ~0.1 s on the 2-core CI machine; generous for a loaded machine.
  EXPECT_LT(seconds, 3.0);
}

}  // namespace test_light_tree
}  // namespace lightfarm
