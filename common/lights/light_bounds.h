// Bounds of lights and lobes over cones of directions, for a light tree's nodes: the half-angle
// and direction-cone arithmetic, bounds of a material's f·|cos| seen from a fixed direction
// (diffuse, coated, Trowbridge-Reitz lobes), and each node's emission bound (the largest diffuse
// albedo and glossy peak below it, with a cone of mirror directions). Lightcuts (Walter et al.
// 2005) refines its cuts with them; common/gather/lightcuts.cpp's header derives each bound.
// Kept beside the light tree as pbrt-v4 keeps LightBounds beside its light sampler.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/lights/light_tree.h"
#include "common/lights/virtual_light.h"
#include "common/scene/bsdf.h"
#include "common/util/math.h"

namespace lightfarm {

// ---------------------------------------------------------------------------------------
// Cones of directions

// Angles are kept as (cos, sin) pairs: the bounds below are evaluated for every cut node, and
// acos/cos dominated their cost. Rounding is covered by a margin of kAngleMargin (~1e-4 rad).
inline constexpr float kAngleMargin = 1e-4f;

// A half-angle θ ∈ [0, π] as (cos θ, sin θ).
struct HalfAngle {
  float cos = -1, sin = 0;  // default: π, every direction
  bool All() const { return cos <= -1.f; }
  static HalfAngle FromCos(float c) {
    HalfAngle a;
    a.cos = Clamp(c, -1.f, 1.f);
    a.sin = SafeSqrt(1 - a.cos * a.cos);
    return a;
  }
  // θ1 + θ2, saturating at π.
  friend HalfAngle operator+(HalfAngle a, HalfAngle b) {
    if (a.All() || b.All()) return HalfAngle();
    HalfAngle s;
    s.cos = a.cos * b.cos - a.sin * b.sin;
    s.sin = a.sin * b.cos + a.cos * b.sin;
    if (s.sin < 0 || s.cos <= -1.f) return HalfAngle();  // θ1 + θ2 ≥ π
    return s;
  }
};

// Largest cos(angle(n, w)) over unit w within half-angle `spread` of `axis`, where
// `cos_na` = n·axis: cos(max(0, angle(n, axis) − spread)), 0 when that angle reaches 90°.
inline float ConeMaxCos(float cos_na, HalfAngle spread) {
  if (spread.All() || cos_na >= spread.cos) return 1.f;
  // cos(a − s) = cos a cos s + sin a sin s, for a > s
  float v = cos_na * spread.cos + SafeSqrt(1 - cos_na * cos_na) * spread.sin;
  if (v < -kAngleMargin) return 0.f;
  return std::min(1.f, std::max(0.f, v) + kAngleMargin);
}

// The directions from a receiver to a node: a cone (axis, half-angle) around the node's
// bounding sphere, and the squared distance to its box.
struct DirectionCone {
  Vec3 axis{0, 0, 1};
  HalfAngle spread;  // default: every direction
  float dist2 = 0;   // squared distance from the receiver to the box (0 inside)
};

inline DirectionCone ConeToBox(Vec3 p, const Bounds3& b) {
  DirectionCone c;
  Vec3 lo_gap = b.lo - p, hi_gap = p - b.hi;
  Vec3 gap = Max(Max(lo_gap, hi_gap), Vec3(0, 0, 0));
  c.dist2 = LengthSquared(gap);
  Vec3 to_center = b.Center() - p;
  float d = Length(to_center);
  float r = b.Radius();
  // Widen slightly so rounding never excludes a corner direction.
  r = r * (1 + 1e-5f) + 1e-7f * (d + std::abs(p.x) + std::abs(p.y) + std::abs(p.z));
  if (d > r) {
    c.axis = to_center / d;
    float sin_s = std::min(1.f, r / d);
    c.spread.sin = sin_s;
    c.spread.cos = SafeSqrt(1 - sin_s * sin_s);
  }
  return c;
}

// Upper bound of max(0, n·w) for w in the cone, also using the box itself: n·(x − p) is
// linear in x, so its maximum over the box is at a corner, and |x − p| ≥ the box distance.
inline float CosBound(Vec3 n, const DirectionCone& c, Vec3 p, const Bounds3* box) {
  float bound = ConeMaxCos(Dot(n, c.axis), c.spread);
  if (box && bound > 0) {
    float max_dot = 0;
    for (int i = 0; i < 3; ++i)
      max_dot += std::max(n[i] * (box->lo[i] - p[i]), n[i] * (box->hi[i] - p[i]));
    if (max_dot <= 0) return 0.f;
    if (c.dist2 > 0) bound = std::min(bound, max_dot / std::sqrt(c.dist2));
  }
  return bound;
}

// ---------------------------------------------------------------------------------------
// BSDF bounds

// Trowbridge-Reitz D over microfacet normals at least θ_min from the normal, given
// cos²θ_min: D = 1 / (π ax ay (cos²θ + sin²θ (cos²φ/ax² + sin²φ/ay²))²) ≤ 1 / (π ax ay s²)
// with s = cos²θ + sin²θ / a_max², minimal at θ_min (a_max ≤ 1) or at θ = 90° (a_max > 1).
// The lower bound of s, given a_max (the largest alpha) and an upper bound of cos²θ.
inline float MicrofacetSBound(float amax, float cos2_theta_min) {
  float inv_a2 = 1.f / Sqr(amax);
  if (amax > 1.f) return inv_a2;
  float c2 = Clamp(cos2_theta_min, 0.f, 1.f);
  return c2 + (1 - c2) * inv_a2;
}
// 1 / (π ax ay): D at its peak for a_max ≤ 1; alphas clamped as TrowbridgeReitz does.
inline float MicrofacetPeakScale(float alpha_x, float alpha_y) {
  return 1.f / (kPi * std::max(alpha_x, 1e-4f) * std::max(alpha_y, 1e-4f));
}
inline float MicrofacetDBound(float alpha_x, float alpha_y, float cos2_theta_min) {
  float amax = std::max(std::max(alpha_x, alpha_y), 1e-4f);
  return MicrofacetPeakScale(alpha_x, alpha_y) / Sqr(MicrofacetSBound(amax, cos2_theta_min));
}

// Upper bound of cos² of the half-vector angle for directions w within `spread` of `axis`,
// against a lobe whose mirror directions lie within `mirror_spread` of `mirror`: the half
// vector's angle to the normal is at least half the angle between w and the mirror direction.
inline float HalfVectorCos2Bound(Vec3 axis, HalfAngle spread, Vec3 mirror, HalfAngle mirror_spread) {
  // Δ = angle(axis, mirror) − both spreads; cos²θ_h ≤ cos²(Δ/2) = (1 + cos Δ) / 2.
  HalfAngle total = spread + mirror_spread;
  const float cos_am = Dot(axis, mirror);
  if (total.All() || cos_am >= total.cos) return 1.f;
  float cos_delta = cos_am * total.cos + SafeSqrt(1 - cos_am * cos_am) * total.sin;
  return std::min(1.f, 0.5f * (1 + cos_delta) + kAngleMargin);
}

// What bounds f(wo, wi)·|cos θi| of one material seen from a fixed wo (local frame, z = n).
struct LobeBound {
  RGB diffuse_front;  // bound of f on the side of wo (multiplied by the cosine bound)
  RGB diffuse_back;   // on the other side
  bool glossy = false;  // a Trowbridge-Reitz reflection lobe on the side of wo
  float alpha_x = 0, alpha_y = 0;
  float glossy_scale = 0;     // 1 / (4 |cos_o|): f·cos ≤ D · glossy_scale
  bool back_unbounded = false;  // rough dielectric transmission
};

inline bool IsSmoothMaterial(const Material& m) {
  return std::max(m.alpha_x, m.alpha_y) < kEffectivelySmoothAlpha;
}

LobeBound MaterialLobeBound(const Material& m, Vec3 wo, TransportMode mode);

// ---------------------------------------------------------------------------------------
// Per-node emission bounds of VPL clusters (max over the node's lights)

struct EmissionBound {
  float diffuse_front = 0;  // × cosine bound of the normal cone
  float diffuse_back = 0;   // × cosine bound of the reversed cone
  // Glossy lobes (reflection side): f·cos ≤ glossy_peak / s², s from glossy_alpha and the
  // half-vector bound against the cone of mirror directions.
  float glossy_peak = 0;   // max of 1 / (4 cos_in π ax ay)
  float glossy_alpha = 0;  // max a_max
  Vec3 mirror_axis{0, 0, 1};
  float mirror_cos = 1;
  bool back_unbounded = false;
  void Max(const EmissionBound& o) {
    diffuse_front = std::max(diffuse_front, o.diffuse_front);
    diffuse_back = std::max(diffuse_back, o.diffuse_back);
    if (o.glossy_peak > 0) {
      if (glossy_peak > 0) {
        UnionCones(mirror_axis, mirror_cos, o.mirror_axis, o.mirror_cos, &mirror_axis, &mirror_cos);
      } else {
        mirror_axis = o.mirror_axis;
        mirror_cos = o.mirror_cos;
      }
      glossy_peak = std::max(glossy_peak, o.glossy_peak);
      glossy_alpha = std::max(glossy_alpha, o.glossy_alpha);
    }
    back_unbounded = back_unbounded || o.back_unbounded;
  }
  // Bound of the glossy lobes' f·cos towards directions within `spread` of `axis`.
  float Glossy(Vec3 axis, HalfAngle spread) const {
    if (glossy_peak <= 0) return 0.f;
    float cos2 = HalfVectorCos2Bound(axis, spread, mirror_axis, HalfAngle::FromCos(mirror_cos));
    return glossy_peak / Sqr(MicrofacetSBound(glossy_alpha, cos2));
  }
};

// A light's own emission bound (a leaf's).
EmissionBound LightEmissionBound(const VirtualLight& l, const std::vector<Material>& materials);

// Every node's emission bound, bottom-up over the tree (the leaves' lights need their materials).
std::vector<EmissionBound> ComputeEmissionBounds(const LightTree& tree, const LightSet& lights,
                                                 const std::vector<Material>& materials);

}  // namespace lightfarm
