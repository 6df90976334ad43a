// Shapes in world space, as the scene holds them (pbrt-v4's shapes): triangle meshes and exact
// spheres, the surface hits rays report on them, and the tessellation of the pbrt shapes Embree
// has no primitive for.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/scene/scene_description.h"
#include "common/util/math.h"

namespace lightfarm {

// Where a ray hit a surface, in world space.
struct SurfaceHit {
  Vec3 p;
  Vec3 ng;  // geometric normal, unit, oriented as the shape's (reverse orientation applied)
  Vec3 ns;  // shading normal, unit, in the same hemisphere as ng
  Vec2 uv;
  float t = 0;
  uint32_t shape = 0;  // index into Scene::shapes()
  uint32_t prim = 0;
};

enum class ShapeKind : uint8_t { kTriangleMesh, kSphere };

// A shape after instancing and transformation, in world space.
struct Shape {
  ShapeKind kind = ShapeKind::kTriangleMesh;
  int material = 0;      // index into Scene::materials()
  int area_emitter = -1;  // index into Scene::area_emitters(), -1 if not emissive
  bool flip_normals = false;  // ReverseOrientation xor handedness swap
  std::string name;       // `Shape "plymesh"` at file:line, for messages
  // Triangle mesh data (world space).
  std::vector<Vec3> positions, normals;
  std::vector<Vec2> uvs;
  std::vector<uint32_t> indices;
  // Sphere data (world space).
  Vec3 center;
  float radius = 0;
  // MediumInterface: indices into Scene::media(), -1 for vacuum. Only a shape whose two media
  // differ changes the medium a ray is in (pbrt-v4: other shapes keep the ray's medium).
  int inside_medium = -1, outside_medium = -1;
  bool medium_transition = false;

  size_t PrimitiveCount() const { return kind == ShapeKind::kSphere ? 1 : indices.size() / 3; }
};

// Fills a Shape's triangle data from object-space arrays, transformed to world space; a
// non-finite position or normal, or arrays of mismatched sizes, are a SceneError naming the
// shape's file:line.
void SetMesh(Shape* shape, const ShapeDesc& sd, std::vector<Vec3> p, std::vector<Vec3> n,
             std::vector<Vec2> uv, const std::vector<int>& idx);
// Tessellates a (partial) sphere in object space: used when the transform is not a similarity
// or the sphere is cut (zmin/zmax/phimax), where Embree's exact sphere primitive cannot be used.
void TessellateSphere(float radius, float zmin, float zmax, float phimax, std::vector<Vec3>* p,
                      std::vector<Vec3>* n, std::vector<Vec2>* uv, std::vector<int>* idx);
// Tessellates a (partial, annular) disk at z = height in object space.
void TessellateDisk(float height, float radius, float inner, float phimax, std::vector<Vec3>* p,
                    std::vector<Vec3>* n, std::vector<Vec2>* uv, std::vector<int>* idx);

}  // namespace lightfarm
