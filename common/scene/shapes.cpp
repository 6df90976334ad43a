#include "common/scene/shapes.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "common/util/error.h"

namespace lightfarm {
namespace {

void CheckFinite(const std::vector<Vec3>& v, const char* what, const ShapeDesc& sd) {
  for (size_t i = 0; i < v.size(); ++i)
    if (!IsFinite(v[i]))
      throw SceneError(sd.loc, std::string("Shape \"") + sd.type + "\": " + what + "[" +
                                   std::to_string(i) + "] is not finite");
}

}  // namespace

void SetMesh(Shape* shape, const ShapeDesc& sd, std::vector<Vec3> p, std::vector<Vec3> n,
             std::vector<Vec2> uv, const std::vector<int>& idx) {
  CheckFinite(p, "P", sd);
  CheckFinite(n, "N", sd);
  if (!n.empty() && n.size() != p.size())
    throw SceneError(sd.loc, "Shape \"" + sd.type + "\": \"N\" has " + std::to_string(n.size()) +
                                 " normals for " + std::to_string(p.size()) + " vertices");
  if (!uv.empty() && uv.size() != p.size())
    throw SceneError(sd.loc, "Shape \"" + sd.type + "\": \"uv\" has " +
                                 std::to_string(uv.size()) + " entries for " +
                                 std::to_string(p.size()) + " vertices");
  if (idx.size() % 3 != 0)
    throw SceneError(sd.loc, "Shape \"" + sd.type + "\": \"indices\" count " +
                                 std::to_string(idx.size()) + " is not a multiple of 3");
  auto inv = sd.world_from_object.Inverse();
  if (!inv) throw SceneError(sd.loc, "Shape \"" + sd.type + "\": transform is singular");
  for (Vec3& q : p) q = sd.world_from_object.ApplyPoint(q);
  for (Vec3& m : n) {
    m = sd.world_from_object.ApplyNormal(m, *inv);
    float len = Length(m);
    m = len > 0 ? m / len : Vec3{0, 0, 0};
  }
  CheckFinite(p, "P (after transform)", sd);
  shape->indices.clear();
  size_t degenerate = 0;
  for (size_t t = 0; t < idx.size(); t += 3) {
    for (int k = 0; k < 3; ++k)
      if (idx[t + k] < 0 || size_t(idx[t + k]) >= p.size())
        throw SceneError(sd.loc, "Shape \"" + sd.type + "\": index " + std::to_string(idx[t + k]) +
                                     " out of range (" + std::to_string(p.size()) + " vertices)");
    Vec3 e = Cross(p[idx[t]] - p[idx[t + 2]], p[idx[t + 1]] - p[idx[t + 2]]);
    // Finite vertices can still be too far apart for float: an infinite area (and NaN sampling
    // densities and normals downstream).
    if (!std::isfinite(LengthSquared(e)))
      throw SceneError(sd.loc, "Shape \"" + sd.type + "\": triangle " + std::to_string(t / 3) +
                                   " is too large for float (its area overflows)");
    if (!(LengthSquared(e) > 0.f)) {
      ++degenerate;  // zero-area: contributes nothing and has no normal; drop it
      continue;
    }
    for (int k = 0; k < 3; ++k) shape->indices.push_back(uint32_t(idx[t + k]));
  }
  if (degenerate > 0)
    spdlog::warn("{}: Shape \"{}\": dropped {} zero-area triangle(s)", sd.loc.ToString(), sd.type,
                 degenerate);
  shape->positions = std::move(p);
  shape->normals = std::move(n);
  shape->uvs = std::move(uv);
}

void TessellateSphere(float radius, float zmin, float zmax, float phimax, std::vector<Vec3>* p,
                      std::vector<Vec3>* n, std::vector<Vec2>* uv, std::vector<int>* idx) {
  const int nu = 128, nv = 64;
  float theta_min = std::acos(Clamp(std::min(zmin, zmax) / radius, -1.f, 1.f));
  float theta_max = std::acos(Clamp(std::max(zmin, zmax) / radius, -1.f, 1.f));
  for (int j = 0; j <= nv; ++j) {
    float v = float(j) / nv;
    float theta = Lerp(v, theta_min, theta_max);
    for (int i = 0; i <= nu; ++i) {
      float u = float(i) / nu;
      float phi = u * phimax;
      Vec3 d{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
      p->push_back(d * radius);
      n->push_back(d);
      uv->push_back({u, v});
    }
  }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      int a = j * (nu + 1) + i, b = a + 1, c = a + (nu + 1), d = c + 1;
      // Winding so that the cross-product normal points outwards (pbrt convention).
      idx->insert(idx->end(), {a, c, b, b, c, d});
    }
}

void TessellateDisk(float height, float radius, float inner, float phimax, std::vector<Vec3>* p,
                    std::vector<Vec3>* n, std::vector<Vec2>* uv, std::vector<int>* idx) {
  const int nu = 256;
  for (int i = 0; i <= nu; ++i) {
    float phi = float(i) / nu * phimax;
    float c = std::cos(phi), s = std::sin(phi);
    p->push_back({radius * c, radius * s, height});
    p->push_back({inner * c, inner * s, height});
    n->push_back({0, 0, 1});
    n->push_back({0, 0, 1});
    uv->push_back({float(i) / nu, 0});
    uv->push_back({float(i) / nu, 1});
  }
  for (int i = 0; i < nu; ++i) {
    int o0 = 2 * i, i0 = 2 * i + 1, o1 = 2 * i + 2, i1 = 2 * i + 3;
    idx->insert(idx->end(), {o0, o1, i0, i0, o1, i1});
  }
}

}  // namespace lightfarm
