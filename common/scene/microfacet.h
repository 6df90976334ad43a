// Anisotropic Trowbridge-Reitz (GGX) microfacet distribution in the local shading frame
// (z = macro normal): normal distribution D, Smith masking Lambda / G1 and height-correlated
// masking-shadowing G, and sampling of the distribution of visible normals (Heitz 2018).
#pragma once

#include "common/util/math.h"

namespace lightfarm {

class TrowbridgeReitz {
 public:
  // Rough lobes clamp alpha to >= 1e-4 (as pbrt-v4) so D stays finite in float.
  TrowbridgeReitz(float alpha_x, float alpha_y)
      : alpha_x_(std::max(alpha_x, 1e-4f)), alpha_y_(std::max(alpha_y, 1e-4f)) {}

  // D(wm) for a unit microfacet normal; the stretched form
  //   D = 1 / (pi ax ay (x^2/ax^2 + y^2/ay^2 + z^2)^2)
  // equals the usual tan^2 form and has no singularity at wm.z = 0.
  float D(Vec3 wm) const {
    float e = Sqr(wm.x / alpha_x_) + Sqr(wm.y / alpha_y_) + Sqr(wm.z);
    float denom = kPi * alpha_x_ * alpha_y_ * Sqr(e);
    return denom > 0 ? 1 / denom : 0.f;
  }

  // Smith's auxiliary function: Lambda(w) = (sqrt(1 + alpha^2 tan^2) - 1) / 2 (Heitz 2014).
  float Lambda(Vec3 w) const {
    float z2 = Sqr(w.z);
    if (z2 == 0) return kInfinity;
    float alpha2_tan2 = (Sqr(alpha_x_ * w.x) + Sqr(alpha_y_ * w.y)) / z2;
    if (!std::isfinite(alpha2_tan2)) return kInfinity;
    return 0.5f * (std::sqrt(1 + alpha2_tan2) - 1);
  }
  float G1(Vec3 w) const { return 1 / (1 + Lambda(w)); }
  // Height-correlated masking-shadowing (Heitz 2014, Eq. 99).
  float G(Vec3 wo, Vec3 wi) const { return 1 / (1 + Lambda(wo) + Lambda(wi)); }

  // Density of normals visible from w: D_w(wm) = G1(w) max(0, w.wm) D(wm) / cos(w) (Heitz 2014,
  // Eq. 38), with |w.wm| so that it also serves w below the surface. Integrates to 1 over wm.
  float VisibleD(Vec3 w, Vec3 wm) const {
    float cos_w = std::abs(w.z);
    if (cos_w == 0) return 0.f;
    return G1(w) / cos_w * D(wm) * AbsDot(w, wm);
  }

  // Samples a microfacet normal (upper hemisphere) from the visible normal distribution of w
  // (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"). w below the surface is
  // mirrored, so the normals are those visible from -w.
  Vec3 SampleVisibleNormal(Vec3 w, Vec2 u) const {
    // Stretch w to the configuration of a unit-roughness hemisphere
    Vec3 wh = Normalize(Vec3(alpha_x_ * w.x, alpha_y_ * w.y, w.z));
    if (wh.z < 0) wh = -wh;
    // Orthonormal basis around wh
    Vec3 t1 = wh.z < 0.99999f ? Normalize(Cross(Vec3(0, 0, 1), wh)) : Vec3(1, 0, 0);
    Vec3 t2 = Cross(wh, t1);
    // Uniform point on the disk, warped onto the visible part of the projected hemisphere
    float r = std::sqrt(u.x);
    float phi = 2 * kPi * u.y;
    float p1 = r * std::cos(phi), p2 = r * std::sin(phi);
    float s = 0.5f * (1 + wh.z);
    p2 = Lerp(s, SafeSqrt(1 - Sqr(p1)), p2);
    // Reproject onto the hemisphere and unstretch
    float p3 = SafeSqrt(1 - Sqr(p1) - Sqr(p2));
    Vec3 nh = t1 * p1 + t2 * p2 + wh * p3;
    return Normalize(Vec3(alpha_x_ * nh.x, alpha_y_ * nh.y, std::max(1e-6f, nh.z)));
  }

  float alpha_x() const { return alpha_x_; }
  float alpha_y() const { return alpha_y_; }

 private:
  float alpha_x_, alpha_y_;
};

}  // namespace lightfarm
