// 4x4 affine/projective transforms (pbrt-v4 semantics: points are column vectors, M * p).
// Stored in double so long transform chains and far-from-origin scenes keep precision; the
// renderer applies them once when building world-space geometry.
#pragma once

#include <array>
#include <optional>

#include "common/util/math.h"

namespace lightfarm {

class Transform {
 public:
  using Matrix = std::array<std::array<double, 4>, 4>;

  Transform();  // identity
  explicit Transform(const Matrix& m);

  static Transform Translate(Vec3 d);
  static Transform Scale(float x, float y, float z);
  static Transform Rotate(float angle_deg, Vec3 axis);
  // World-from-camera inverse: pbrt's LookAt returns camera-from-world.
  static std::optional<Transform> LookAt(Vec3 eye, Vec3 look, Vec3 up);
  static Transform Perspective(float fov_deg, float near, float far);

  // nullopt when singular (an error the caller reports with the directive's location).
  std::optional<Transform> Inverse() const;
  Transform operator*(const Transform& o) const;

  Vec3 ApplyPoint(Vec3 p) const;
  Vec3 ApplyVector(Vec3 v) const;
  // Normals transform by the inverse transpose; the caller passes the inverse.
  Vec3 ApplyNormal(Vec3 n, const Transform& inverse) const;

  const Matrix& m() const { return m_; }
  bool IsIdentity() const;
  // True when the linear part flips orientation (negative determinant).
  bool SwapsHandedness() const;
  // Uniform scale factor if the linear part is a rotation times a uniform scale, else nullopt.
  std::optional<float> UniformScale(double tolerance = 1e-5) const;

 private:
  Matrix m_;
};

}  // namespace lightfarm
