// Henyey–Greenstein phase function (Henyey & Greenstein 1941), the one pbrt-v4 media use.
//
// Convention: cos_theta is the cosine between the direction light travelled before the event
// and the direction it travels after (so g > 0 scatters forward, peaking at cos_theta = 1).
// pbrt-v4 writes p(wo, wi) with wo pointing back along the incoming ray, i.e. its
// cos = Dot(wo, wi) is -cos_theta here.
#pragma once

#include <cmath>

#include "common/util/math.h"

namespace lightfarm {

// p(θ) = (1 - g²) / (4π (1 + g² - 2g cosθ)^{3/2}). The denominator is written as
// (1 - g)² + 2g(1 - cosθ): no cancellation near the forward peak for |g| → 1.
inline float HenyeyGreenstein(float cos_theta, float g) {
  double c = Clamp(double(cos_theta), -1.0, 1.0), gd = double(g);
  double denom = (1 - gd) * (1 - gd) + 2 * gd * (1 - c);
  if (!(denom > 0)) return 0.f;  // |g| = 1 is a delta; callers clamp g to (-1, 1)
  return float((1 - gd * gd) / (4 * 3.14159265358979323846 * denom * std::sqrt(denom)));
}

// Inverse CDF of HG in cosθ (travel-direction convention), increasing in u (u = 0 → -1).
// Double inside: for small |g| the closed form subtracts nearly equal numbers; below 1e-4 the
// distribution is isotropic to within the float resolution of cosθ, so the isotropic inverse
// (same orientation, so the map is continuous in g) is used.
inline float SampleHenyeyGreensteinCos(float u, float g) {
  double ud = double(u), gd = double(g);
  double c;
  if (std::abs(gd) < 1e-4) {
    c = 2 * ud - 1;
  } else {
    double s = (1 - gd * gd) / (1 - gd + 2 * gd * ud);
    c = (1 + gd * gd - s * s) / (2 * gd);
  }
  return float(Clamp(c, -1.0, 1.0));
}

// Samples the direction after scattering given the unit travel direction w_in before it.
// Returns the new unit travel direction; the pdf equals HenyeyGreenstein(Dot(w_in, w), g).
inline Vec3 SampleHenyeyGreenstein(Vec3 w_in, float g, float u1, float u2, float* pdf) {
  float cos_t = SampleHenyeyGreensteinCos(u1, g);
  float sin_t = SafeSqrt(1 - cos_t * cos_t);
  float phi = 2 * kPi * u2;
  Frame f(w_in);
  Vec3 w = f.FromLocal({sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t});
  if (pdf) *pdf = HenyeyGreenstein(cos_t, g);
  return Normalize(w);
}

}  // namespace lightfarm
