#include "common/util/transform.h"

#include <cmath>

namespace lightfarm {

Transform::Transform() {
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m_[i][j] = i == j ? 1.0 : 0.0;
}

Transform::Transform(const Matrix& m) : m_(m) {}

Transform Transform::Translate(Vec3 d) {
  Transform t;
  t.m_[0][3] = d.x;
  t.m_[1][3] = d.y;
  t.m_[2][3] = d.z;
  return t;
}

Transform Transform::Scale(float x, float y, float z) {
  Transform t;
  t.m_[0][0] = x;
  t.m_[1][1] = y;
  t.m_[2][2] = z;
  return t;
}

Transform Transform::Rotate(float angle_deg, Vec3 axis_in) {
  const double x = axis_in.x, y = axis_in.y, z = axis_in.z;
  double len = std::sqrt(x * x + y * y + z * z);
  Transform t;
  if (len == 0.0) return t;
  double ax = x / len, ay = y / len, az = z / len;
  double theta = double(angle_deg) * M_PI / 180.0;
  double s = std::sin(theta), c = std::cos(theta);
  // Rodrigues' rotation formula, as pbrt-v4's Rotate().
  t.m_[0][0] = ax * ax + (1 - ax * ax) * c;
  t.m_[0][1] = ax * ay * (1 - c) - az * s;
  t.m_[0][2] = ax * az * (1 - c) + ay * s;
  t.m_[1][0] = ax * ay * (1 - c) + az * s;
  t.m_[1][1] = ay * ay + (1 - ay * ay) * c;
  t.m_[1][2] = ay * az * (1 - c) - ax * s;
  t.m_[2][0] = ax * az * (1 - c) - ay * s;
  t.m_[2][1] = ay * az * (1 - c) + ax * s;
  t.m_[2][2] = az * az + (1 - az * az) * c;
  return t;
}

std::optional<Transform> Transform::LookAt(Vec3 eye, Vec3 look, Vec3 up) {
  // Build world-from-camera, then invert: pbrt's LookAt yields camera-from-world.
  Vec3 dir = look - eye;
  if (LengthSquared(dir) == 0.f) return std::nullopt;
  dir = Normalize(dir);
  if (LengthSquared(up) == 0.f) return std::nullopt;
  Vec3 right = Cross(Normalize(up), dir);
  if (Length(right) < 1e-6f) return std::nullopt;
  right = Normalize(right);
  Vec3 new_up = Cross(dir, right);
  Matrix w{};
  for (int i = 0; i < 3; ++i) {
    w[i][0] = right[i];
    w[i][1] = new_up[i];
    w[i][2] = dir[i];
    w[i][3] = eye[i];
  }
  w[3] = {0, 0, 0, 1};
  return Transform(w).Inverse();
}

Transform Transform::Perspective(float fov_deg, float n, float f) {
  Matrix persp{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, f / (f - n), -f * n / (f - n)}, {0, 0, 1, 0}}};
  double inv_tan = 1.0 / std::tan(double(fov_deg) * M_PI / 360.0);
  return Transform::Scale(float(inv_tan), float(inv_tan), 1) * Transform(persp);
}

std::optional<Transform> Transform::Inverse() const {
  // Gauss-Jordan elimination with full pivoting (numerically stable for 4x4).
  int indxc[4], indxr[4];
  int ipiv[4] = {0, 0, 0, 0};
  Matrix minv = m_;
  for (int i = 0; i < 4; i++) {
    int irow = 0, icol = 0;
    double big = 0.0;
    for (int j = 0; j < 4; j++) {
      if (ipiv[j] != 1) {
        for (int k = 0; k < 4; k++) {
          if (ipiv[k] == 0) {
            if (std::abs(minv[j][k]) >= big) {
              big = std::abs(minv[j][k]);
              irow = j;
              icol = k;
            }
          } else if (ipiv[k] > 1) {
            return std::nullopt;
          }
        }
      }
    }
    ++ipiv[icol];
    if (irow != icol)
      for (int k = 0; k < 4; ++k) std::swap(minv[irow][k], minv[icol][k]);
    indxr[i] = irow;
    indxc[i] = icol;
    if (minv[icol][icol] == 0.0) return std::nullopt;
    double pivinv = 1.0 / minv[icol][icol];
    minv[icol][icol] = 1.0;
    for (int j = 0; j < 4; j++) minv[icol][j] *= pivinv;
    for (int j = 0; j < 4; j++) {
      if (j != icol) {
        double save = minv[j][icol];
        minv[j][icol] = 0;
        for (int k = 0; k < 4; k++) minv[j][k] -= minv[icol][k] * save;
      }
    }
  }
  for (int j = 3; j >= 0; j--) {
    if (indxr[j] != indxc[j]) {
      for (int k = 0; k < 4; k++) std::swap(minv[k][indxr[j]], minv[k][indxc[j]]);
    }
  }
  for (const auto& row : minv)
    for (double v : row)
      if (!std::isfinite(v)) return std::nullopt;
  return Transform(minv);
}

Transform Transform::operator*(const Transform& o) const {
  Matrix r{};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += m_[i][k] * o.m_[k][j];
      r[i][j] = s;
    }
  return Transform(r);
}

Vec3 Transform::ApplyPoint(Vec3 p) const {
  double x = p.x, y = p.y, z = p.z;
  double xp = m_[0][0] * x + m_[0][1] * y + m_[0][2] * z + m_[0][3];
  double yp = m_[1][0] * x + m_[1][1] * y + m_[1][2] * z + m_[1][3];
  double zp = m_[2][0] * x + m_[2][1] * y + m_[2][2] * z + m_[2][3];
  double wp = m_[3][0] * x + m_[3][1] * y + m_[3][2] * z + m_[3][3];
  if (wp == 1.0) return {float(xp), float(yp), float(zp)};
  return {float(xp / wp), float(yp / wp), float(zp / wp)};
}

Vec3 Transform::ApplyVector(Vec3 v) const {
  double x = v.x, y = v.y, z = v.z;
  return {float(m_[0][0] * x + m_[0][1] * y + m_[0][2] * z),
          float(m_[1][0] * x + m_[1][1] * y + m_[1][2] * z),
          float(m_[2][0] * x + m_[2][1] * y + m_[2][2] * z)};
}

Vec3 Transform::ApplyNormal(Vec3 n, const Transform& inverse) const {
  const Matrix& mi = inverse.m_;
  double x = n.x, y = n.y, z = n.z;
  return {float(mi[0][0] * x + mi[1][0] * y + mi[2][0] * z),
          float(mi[0][1] * x + mi[1][1] * y + mi[2][1] * z),
          float(mi[0][2] * x + mi[1][2] * y + mi[2][2] * z)};
}

bool Transform::IsIdentity() const {
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      if (m_[i][j] != (i == j ? 1.0 : 0.0)) return false;
  return true;
}

bool Transform::SwapsHandedness() const {
  double det = m_[0][0] * (m_[1][1] * m_[2][2] - m_[1][2] * m_[2][1]) -
               m_[0][1] * (m_[1][0] * m_[2][2] - m_[1][2] * m_[2][0]) +
               m_[0][2] * (m_[1][0] * m_[2][1] - m_[1][1] * m_[2][0]);
  return det < 0;
}

std::optional<float> Transform::UniformScale(double tolerance) const {
  // Columns of the linear part must be orthogonal and of equal length.
  double col[3][3];
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) col[j][i] = m_[i][j];
  if (m_[3][0] != 0 || m_[3][1] != 0 || m_[3][2] != 0 || m_[3][3] != 1) return std::nullopt;
  double len[3];
  for (int j = 0; j < 3; ++j)
    len[j] = std::sqrt(col[j][0] * col[j][0] + col[j][1] * col[j][1] + col[j][2] * col[j][2]);
  if (len[0] == 0) return std::nullopt;
  for (int j = 1; j < 3; ++j)
    if (std::abs(len[j] - len[0]) > tolerance * len[0]) return std::nullopt;
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b) {
      double d = col[a][0] * col[b][0] + col[a][1] * col[b][1] + col[a][2] * col[b][2];
      if (std::abs(d) > tolerance * len[0] * len[0]) return std::nullopt;
    }
  return float(len[0]);
}

}  // namespace lightfarm
