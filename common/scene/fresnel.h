// Fresnel reflectance and the reflection / refraction of directions, in the local shading
// frame (z = normal). Conventions follow pbrt-v4 (Sec. 9.3 and 9.4): eta is the relative
// index of refraction eta_t / eta_i seen from the side the normal points to, so light arriving
// from below (cos < 0) sees 1 / eta.
#pragma once

#include "common/util/math.h"

namespace lightfarm {

// Mirror direction of wo about the unit vector n (both point away from the surface).
inline Vec3 Reflect(Vec3 wo, Vec3 n) { return -wo + n * (2 * Dot(wo, n)); }

// Refracts wi (pointing away from the surface) through the interface with normal n and
// relative IOR eta. Returns false on total internal reflection. *etap receives the relative
// IOR actually crossed (eta, or 1/eta when wi is on the side opposite to n).
inline bool Refract(Vec3 wi, Vec3 n, float eta, float* etap, Vec3* wt) {
  float cos_i = Dot(n, wi);
  // Light arriving from the inside: flip the interface
  if (cos_i < 0) {
    eta = 1 / eta;
    cos_i = -cos_i;
    n = -n;
  }
  // Snell's law: sin_t = sin_i / eta
  float sin2_i = std::max(0.f, 1 - Sqr(cos_i));
  float sin2_t = sin2_i / Sqr(eta);
  if (sin2_t >= 1) return false;
  float cos_t = SafeSqrt(1 - sin2_t);
  *wt = -wi / eta + n * (cos_i / eta - cos_t);
  if (etap) *etap = eta;
  return true;
}

// Unpolarised Fresnel reflectance of a dielectric interface; cos_i < 0 means the light
// arrives from the inside (relative IOR 1/eta). Returns 1 under total internal reflection.
inline float FrDielectric(float cos_i, float eta) {
  cos_i = Clamp(cos_i, -1.f, 1.f);
  if (cos_i < 0) {
    eta = 1 / eta;
    cos_i = -cos_i;
  }
  float sin2_t = (1 - Sqr(cos_i)) / Sqr(eta);
  if (sin2_t >= 1) return 1.f;
  float cos_t = SafeSqrt(1 - sin2_t);
  // Amplitude coefficients for parallel and perpendicular polarisation
  float r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  float r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5f * (Sqr(r_parallel) + Sqr(r_perpendicular));
}

// Minimal float complex arithmetic for FrComplex. std::complex<float> routes * and / through
// the C99 Annex G helpers (__mulsc3 / __divsc3) unless -ffast-math is on; the magnitudes in
// the Fresnel equations (|eta + ik| < ~1e3, cosines in [0, 1]) need none of their
// overflow / NaN recovery, and conductor lobes are evaluated for every matrix element.
struct ComplexF {
  float re = 0, im = 0;
  constexpr ComplexF(float r, float i = 0) : re(r), im(i) {}
  ComplexF operator+(ComplexF o) const { return {re + o.re, im + o.im}; }
  ComplexF operator-(ComplexF o) const { return {re - o.re, im - o.im}; }
  ComplexF operator*(ComplexF o) const { return {re * o.re - im * o.im, re * o.im + im * o.re}; }
  ComplexF operator/(ComplexF o) const {
    float inv = 1 / (o.re * o.re + o.im * o.im);
    return {(re * o.re + im * o.im) * inv, (im * o.re - re * o.im) * inv};
  }
  float Norm() const { return re * re + im * im; }  // |z|^2
};
// Principal square root (non-negative real part).
inline ComplexF Sqrt(ComplexF z) {
  float r = std::hypot(z.re, z.im);
  if (r == 0) return {0, 0};
  float a = std::sqrt(0.5f * (r + std::abs(z.re)));
  if (z.re >= 0) return {a, z.im / (2 * a)};
  return {std::abs(z.im) / (2 * a), std::copysign(a, z.im)};
}

// Unpolarised Fresnel reflectance of a conductor with complex IOR eta + i k (the same
// expressions as the dielectric case, evaluated in complex arithmetic).
inline float FrComplex(float cos_i, float eta, float k) {
  cos_i = Clamp(cos_i, 0.f, 1.f);
  ComplexF n(eta, k);
  ComplexF sin2_t = ComplexF(1 - Sqr(cos_i)) / (n * n);
  ComplexF cos_t = Sqrt(ComplexF(1) - sin2_t);
  ComplexF r_parallel = (n * cos_i - cos_t) / (n * cos_i + cos_t);
  ComplexF r_perpendicular = (ComplexF(cos_i) - n * cos_t) / (ComplexF(cos_i) + n * cos_t);
  float f = 0.5f * (r_parallel.Norm() + r_perpendicular.Norm());
  // At cos_i = 0 with eta + ik = 1 the ratios are 0/0: grazing reflection is total
  return std::isfinite(f) ? Clamp(f, 0.f, 1.f) : 1.f;
}

inline RGB FrComplex(float cos_i, RGB eta, RGB k) {
  return {FrComplex(cos_i, eta.r, k.r), FrComplex(cos_i, eta.g, k.g), FrComplex(cos_i, eta.b, k.b)};
}

}  // namespace lightfarm
