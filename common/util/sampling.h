// Warping functions from [0,1)^2 to common domains, and low-discrepancy pixel samples.
#pragma once

#include <cmath>
#include <cstdint>

#include "common/util/math.h"

namespace lightfarm {

inline Vec2 SampleUniformDiskConcentric(Vec2 u) {
  Vec2 o{2 * u.x - 1, 2 * u.y - 1};
  if (o.x == 0 && o.y == 0) return {0, 0};
  float r, theta;
  if (std::abs(o.x) > std::abs(o.y)) {
    r = o.x;
    theta = (kPi / 4) * (o.y / o.x);
  } else {
    r = o.y;
    theta = (kPi / 2) - (kPi / 4) * (o.x / o.y);
  }
  return {r * std::cos(theta), r * std::sin(theta)};
}

inline Vec3 SampleCosineHemisphere(Vec2 u) {
  Vec2 d = SampleUniformDiskConcentric(u);
  float z = SafeSqrt(1 - d.x * d.x - d.y * d.y);
  return {d.x, d.y, z};
}
inline float CosineHemispherePdf(float cos_theta) { return cos_theta * kInvPi; }

// Veach's power heuristic (β = 2): the MIS weight of a sample of density a when the other
// strategy would have drawn it with density b (one sample from each).
inline float PowerHeuristic(float a, float b) {
  const float a2 = a * a, b2 = b * b;
  if (std::isinf(a2)) return 1.f;
  return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.f;
}

inline Vec3 SampleUniformSphere(Vec2 u) {
  float z = 1 - 2 * u.x;
  float r = SafeSqrt(1 - z * z);
  float phi = 2 * kPi * u.y;
  return {r * std::cos(phi), r * std::sin(phi), z};
}
inline constexpr float kUniformSpherePdf = kInv4Pi;

// Uniform direction within a cone of half-angle acos(cos_max) around +z.
inline Vec3 SampleUniformCone(Vec2 u, float cos_max) {
  float cos_t = (1 - u.x) + u.x * cos_max;
  float sin_t = SafeSqrt(1 - cos_t * cos_t);
  float phi = u.y * 2 * kPi;
  return {std::cos(phi) * sin_t, std::sin(phi) * sin_t, cos_t};
}
inline float UniformConePdf(float cos_max) { return 1 / (2 * kPi * (1 - cos_max)); }

// Uniform barycentrics on a triangle (pbrt-v4 SampleUniformTriangle).
inline void SampleUniformTriangle(Vec2 u, float* b0, float* b1) {
  if (u.x < u.y) {
    *b0 = u.x / 2;
    *b1 = u.y - *b0;
  } else {
    *b1 = u.y / 2;
    *b0 = u.x - *b1;
  }
}

// Equal-area mapping between the unit square and the sphere (Clarberg 2008), used by pbrt-v4's
// image infinite lights (octahedral equal-area environment maps).
Vec3 EqualAreaSquareToSphere(Vec2 p);
Vec2 EqualAreaSphereToSquare(Vec3 d);

// First two dimensions of the Sobol sequence (a (0,2)-sequence: stratified for every power of
// two), with random-digit (XOR) scrambling per pixel.
inline float Sobol2DComponent(uint32_t index, int dim, uint32_t scramble) {
  uint32_t v;
  if (dim == 0) {
    v = index;  // radical inverse base 2: bit reversal
    v = (v << 16) | (v >> 16);
    v = ((v & 0x00ff00ffu) << 8) | ((v & 0xff00ff00u) >> 8);
    v = ((v & 0x0f0f0f0fu) << 4) | ((v & 0xf0f0f0f0u) >> 4);
    v = ((v & 0x33333333u) << 2) | ((v & 0xccccccccu) >> 2);
    v = ((v & 0x55555555u) << 1) | ((v & 0xaaaaaaaau) >> 1);
  } else {
    v = 0;
    for (uint32_t c = 1u << 31; index; index >>= 1, c ^= c >> 1)
      if (index & 1) v ^= c;
  }
  v ^= scramble;
  return std::min(float(v >> 8) * 0x1p-24f, 0x1.fffffep-1f);
}

}  // namespace lightfarm
