// A Lightcuts-style binary light tree (Walter et al. 2005, Sec. 4): leaves are the virtual
// lights, inner nodes cluster lights of one kind by position (and orientation), each node keeps
// its bounds, total intensity and a representative light chosen with probability ∝ intensity.
// Separate trees per light kind (area/surface VPLs are oriented, points and medium VPLs are not,
// directional lights cluster by direction, VRLs by midpoint and direction with bounds covering
// both end points); `roots()` lists them. Used by lightcuts, lightslice,
// sparse-completion (the global cut) and adaptive-completion.
#pragma once

#include <cstdint>
#include <vector>

#include "common/lights/virtual_light.h"

namespace lightfarm {

// The smallest cone containing the cones (axis_a, cos_a) and (axis_b, cos_b), half-angles as
// cosines (-1: every direction), pbrt-v4's DirectionCone::Union construction: the light tree's
// emission cones and lightcuts' glossy mirror cones both use it.
void UnionCones(Vec3 axis_a, float cos_a, Vec3 axis_b, float cos_b, Vec3* axis, float* cos_out);

struct LightTreeNode {
  Bounds3 bounds;        // positions (directional lights: their unit directions; VRLs: both ends)
  Vec3 cone_axis{0, 0, 1};
  float cone_cos = -1;   // normals lie within acos(cone_cos) of cone_axis; -1: unbounded
  RGB intensity;         // Σ power of the lights below (the cluster's total power)
  float intensity_lum = 0;  // luminance of `intensity`, the scalar used for choices
  uint32_t representative = 0;  // index into LightSet::lights
  int32_t left = -1, right = -1;  // child node indices, -1 for a leaf
  uint32_t first = 0, count = 0;  // range in order() of the lights below this node
  VirtualLightKind kind = VirtualLightKind::kAreaVPL;
  bool IsLeaf() const { return left < 0; }
};

class LightTree {
 public:
  // Deterministic for a given light set and seed (representatives are drawn from hashed
  // generators), whatever the thread count.
  static LightTree Build(const LightSet& lights, uint64_t seed);

  const std::vector<LightTreeNode>& nodes() const { return nodes_; }
  const std::vector<uint32_t>& roots() const { return roots_; }  // one per light kind present
  const std::vector<uint32_t>& order() const { return order_; }  // light indices in leaf order
  const LightTreeNode& node(uint32_t i) const { return nodes_[i]; }

 private:
  std::vector<LightTreeNode> nodes_;
  std::vector<uint32_t> roots_;
  std::vector<uint32_t> order_;
};

}  // namespace lightfarm
