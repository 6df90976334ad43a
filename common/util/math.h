// Small fixed-size vector math for the renderer: float 3-vectors, RGB triples, orthonormal
// frames. Float stays float (as in pbrt-v4 / Mitsuba with -Wdouble-promotion); double is
// chosen explicitly where sums need it (see accum.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace lightfarm {

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;
inline constexpr float kInfinity = std::numeric_limits<float>::infinity();

template <typename T>
constexpr T Clamp(T v, T lo, T hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}
inline float Sqr(float x) { return x * x; }
inline float SafeSqrt(float x) { return std::sqrt(std::max(0.f, x)); }
inline float SafeAcos(float x) { return std::acos(Clamp(x, -1.f, 1.f)); }
inline float Lerp(float t, float a, float b) { return (1 - t) * a + t * b; }
inline float Radians(float deg) { return deg * (kPi / 180.f); }

struct Vec2 {
  float x = 0, y = 0;
  constexpr Vec2() = default;
  constexpr Vec2(float x_, float y_) : x(x_), y(y_) {}
  float operator[](int i) const { return i == 0 ? x : y; }
  Vec2 operator+(Vec2 o) const { return {x + o.x, y + o.y}; }
  Vec2 operator-(Vec2 o) const { return {x - o.x, y - o.y}; }
  Vec2 operator*(float s) const { return {x * s, y * s}; }
};

struct Vec3 {
  float x = 0, y = 0, z = 0;
  constexpr Vec3() = default;
  constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  Vec3 operator+(Vec3 o) const { return {x + o.x, y + o.y, z + o.z}; }
  Vec3 operator-(Vec3 o) const { return {x - o.x, y - o.y, z - o.z}; }
  Vec3 operator-() const { return {-x, -y, -z}; }
  Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
  Vec3 operator/(float s) const { return *this * (1.f / s); }
  Vec3& operator+=(Vec3 o) { x += o.x; y += o.y; z += o.z; return *this; }
  Vec3& operator-=(Vec3 o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
  Vec3& operator*=(float s) { x *= s; y *= s; z *= s; return *this; }
  bool operator==(const Vec3& o) const { return x == o.x && y == o.y && z == o.z; }
};
inline Vec3 operator*(float s, Vec3 v) { return v * s; }
inline float Dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline float AbsDot(Vec3 a, Vec3 b) { return std::abs(Dot(a, b)); }
inline Vec3 Cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float LengthSquared(Vec3 v) { return Dot(v, v); }
inline float Length(Vec3 v) { return std::sqrt(Dot(v, v)); }
inline Vec3 Normalize(Vec3 v) { return v / Length(v); }
inline Vec3 Min(Vec3 a, Vec3 b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
inline Vec3 Max(Vec3 a, Vec3 b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
inline Vec3 Abs(Vec3 v) { return {std::abs(v.x), std::abs(v.y), std::abs(v.z)}; }
inline float MaxComponent(Vec3 v) { return std::max(v.x, std::max(v.y, v.z)); }
inline float Distance(Vec3 a, Vec3 b) { return Length(a - b); }
inline float DistanceSquared(Vec3 a, Vec3 b) { return LengthSquared(a - b); }
inline bool IsFinite(Vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
// Flip v to lie in the same hemisphere as ref.
inline Vec3 FaceForward(Vec3 v, Vec3 ref) { return Dot(v, ref) < 0.f ? -v : v; }

// Builds two unit vectors orthogonal to the unit vector n (Duff et al. 2017, branchless).
inline void CoordinateSystem(Vec3 n, Vec3* s, Vec3* t) {
  float sign = std::copysign(1.f, n.z);
  float a = -1.f / (sign + n.z);
  float b = n.x * n.y * a;
  *s = {1.f + sign * n.x * n.x * a, sign * b, -sign * n.x};
  *t = {b, sign + n.y * n.y * a, -n.y};
}

// Orthonormal shading frame: local z is the shading normal.
struct Frame {
  Vec3 s{1, 0, 0}, t{0, 1, 0}, n{0, 0, 1};
  Frame() = default;
  explicit Frame(Vec3 normal) : n(normal) { CoordinateSystem(n, &s, &t); }
  Vec3 ToLocal(Vec3 v) const { return {Dot(v, s), Dot(v, t), Dot(v, n)}; }
  Vec3 FromLocal(Vec3 v) const { return s * v.x + t * v.y + n * v.z; }
};

struct Bounds3 {
  Vec3 lo{kInfinity, kInfinity, kInfinity};
  Vec3 hi{-kInfinity, -kInfinity, -kInfinity};
  void Extend(Vec3 p) { lo = Min(lo, p); hi = Max(hi, p); }
  void Extend(const Bounds3& b) { lo = Min(lo, b.lo); hi = Max(hi, b.hi); }
  bool Empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  Vec3 Center() const { return (lo + hi) * 0.5f; }
  Vec3 Diagonal() const { return hi - lo; }
  float Radius() const { return Empty() ? 0.f : 0.5f * Length(hi - lo); }
  int MaxAxis() const {
    Vec3 d = Diagonal();
    return d.x > d.y && d.x > d.z ? 0 : (d.y > d.z ? 1 : 2);
  }
};

// Linear RGB radiometric triple (the film's colour space, sRGB primaries).
struct RGB {
  float r = 0, g = 0, b = 0;
  constexpr RGB() = default;
  constexpr explicit RGB(float v) : r(v), g(v), b(v) {}
  constexpr RGB(float r_, float g_, float b_) : r(r_), g(g_), b(b_) {}
  float operator[](int i) const { return i == 0 ? r : (i == 1 ? g : b); }
  float& operator[](int i) { return i == 0 ? r : (i == 1 ? g : b); }
  RGB operator+(RGB o) const { return {r + o.r, g + o.g, b + o.b}; }
  RGB operator-(RGB o) const { return {r - o.r, g - o.g, b - o.b}; }
  RGB operator*(RGB o) const { return {r * o.r, g * o.g, b * o.b}; }
  RGB operator/(RGB o) const { return {r / o.r, g / o.g, b / o.b}; }
  RGB operator*(float s) const { return {r * s, g * s, b * s}; }
  RGB operator/(float s) const { return *this * (1.f / s); }
  RGB& operator+=(RGB o) { r += o.r; g += o.g; b += o.b; return *this; }
  RGB& operator*=(RGB o) { r *= o.r; g *= o.g; b *= o.b; return *this; }
  RGB& operator*=(float s) { r *= s; g *= s; b *= s; return *this; }
  bool operator==(const RGB& o) const { return r == o.r && g == o.g && b == o.b; }
  bool IsBlack() const { return r == 0.f && g == 0.f && b == 0.f; }
  float Max() const { return std::max(r, std::max(g, b)); }
  float Average() const { return (r + g + b) * (1.f / 3.f); }
  // Rec.709 luminance.
  float Luminance() const { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }
  bool IsFinite() const { return std::isfinite(r) && std::isfinite(g) && std::isfinite(b); }
  // RGB -> scalar as MRCS does (Hašan 2007, Sec. 3.2): the 2-norm of the triple.
  float Norm() const { return std::sqrt(r * r + g * g + b * b); }
};
inline RGB operator*(float s, RGB c) { return c * s; }
inline RGB Exp(RGB c) { return {std::exp(c.r), std::exp(c.g), std::exp(c.b)}; }
inline RGB Sqrt(RGB c) { return {SafeSqrt(c.r), SafeSqrt(c.g), SafeSqrt(c.b)}; }

// Double-precision RGB accumulator: row sums over up to 1e6+ lights of mixed magnitude.
struct RGBAccum {
  double r = 0, g = 0, b = 0;
  void Add(RGB c) { r += double(c.r); g += double(c.g); b += double(c.b); }
  void Add(const RGBAccum& o) { r += o.r; g += o.g; b += o.b; }
  RGB ToRGB() const { return {static_cast<float>(r), static_cast<float>(g), static_cast<float>(b)}; }
};

}  // namespace lightfarm
