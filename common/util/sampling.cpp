#include "common/util/sampling.h"

namespace lightfarm {

Vec3 EqualAreaSquareToSphere(Vec2 p) {
  // Transform p to [-1,1]^2 and compute absolute values.
  float u = 2 * p.x - 1, v = 2 * p.y - 1;
  float up = std::abs(u), vp = std::abs(v);
  // Signed distance from the diagonal; r is the radius of the point on the octahedron.
  float signed_distance = 1 - (up + vp);
  float d = std::abs(signed_distance);
  float r = 1 - d;
  float phi = (r == 0 ? 1 : (vp - up) / r + 1) * kPi / 4;
  float z = std::copysign(1 - r * r, signed_distance);
  float cos_phi = std::copysign(std::cos(phi), u);
  float sin_phi = std::copysign(std::sin(phi), v);
  float s = r * SafeSqrt(2 - r * r);
  return {cos_phi * s, sin_phi * s, z};
}

Vec2 EqualAreaSphereToSquare(Vec3 d) {
  float x = std::abs(d.x), y = std::abs(d.y), z = std::abs(d.z);
  float r = SafeSqrt(1 - z);
  float a = std::max(x, y), b = std::min(x, y);
  b = a == 0 ? 0 : b / a;
  float phi = std::atan(b) * 2 / kPi;
  if (x < y) phi = 1 - phi;
  float v = phi * r;
  float u = r - v;
  if (d.z < 0) {
    std::swap(u, v);
    u = 1 - u;
    v = 1 - v;
  }
  u = std::copysign(u, d.x);
  v = std::copysign(v, d.y);
  return {0.5f * (u + 1), 0.5f * (v + 1)};
}

}  // namespace lightfarm
