// The runtime scene: world-space geometry in an Embree BVH, materials, emitters, camera and the
// rendering hints the file gives (path depth, resolution, pixel filter). Built once from a
// SceneDescription; immutable and thread-safe to query afterwards (Embree's lifecycle: new →
// set buffers → commit geometry → attach → commit scene, then only queries).
#pragma once

#include <embree3/rtcore.h>

#include <memory>
#include <string>
#include <vector>

#include "common/scene/bsdf.h"
#include "common/scene/camera.h"
#include "common/scene/medium.h"
#include "common/scene/scene_description.h"
#include "common/util/math.h"
#include "common/util/rng.h"

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

// A diffuse area light: emission L on the front side (both sides if two_sided) of a shape.
struct AreaEmitter {
  uint32_t shape = 0;
  RGB L;  // radiance, already multiplied by "scale"
  bool two_sided = false;
  float area = 0;                    // total surface area
  std::vector<float> triangle_cdf;   // cumulative triangle areas (meshes), normalised
  // Emitted power Φ = π · A · L (· 2 when two-sided).
  RGB Power() const { return L * (kPi * area * (two_sided ? 2.f : 1.f)); }
};

// Point, spot, distant and infinite lights as the file gives them.
struct PointEmitter {
  Vec3 position;
  RGB intensity;                // I · scale
  bool spot = false;
  int medium = -1;              // the medium the light sits in (index into Scene::media())
  Vec3 axis{0, 0, 1};           // spot direction (world)
  float cos_falloff_start = 1, cos_falloff_end = -1;  // spot cone (smoothstep between)
  // pbrt-v4 spot falloff: smoothstep(cosFalloffEnd, cosFalloffStart, cos θ).
  float Falloff(Vec3 w_from_light) const;
};
struct DistantEmitter {
  int medium = -1;  // the medium its particles start in (the light's MediumInterface)
  Vec3 direction;  // direction the light travels (from "from" to "to")
  RGB L;           // irradiance scale: radiance arriving along -direction integrated = L·scale
};
struct InfiniteEmitter {
  int medium = -1;  // the medium its particles start in (the light's MediumInterface)
  RGB L{0.f};      // uniform radiance (when no image)
  Transform world_from_light, light_from_world;
  int width = 0, height = 0;  // equal-area octahedral image (pbrt-v4), empty for uniform
  std::vector<RGB> image;
  std::vector<float> pixel_cdf;  // luminance-proportional sampling over pixels
  float luminance_sum = 0;
  RGB scale{1.f};
  RGB Le(Vec3 w_world) const;  // radiance arriving from direction w (w points away from scene)
  // Samples a direction (pointing away from the scene) ∝ luminance; returns pdf (solid angle).
  Vec3 SampleDirection(Vec2 u, float* pdf) const;
  float Pdf(Vec3 w_world) const;
  RGB AverageRadiance() const;
};

// The rendering hints a scene gives (Integrator, Sampler, Film, PixelFilter), interpreted.
struct RenderHints {
  int max_depth = 5;        // Integrator "maxdepth"
  int width = 1280, height = 720;  // Film resolution
  int pixel_samples = 16;   // Sampler "pixelsamples" (a path-tracing budget; informative)
  std::string filter_type = "gaussian";
  float filter_xradius = 1.5f, filter_yradius = 1.5f;
  float filter_sigma = 0.5f, filter_B = 1.f / 3.f, filter_C = 1.f / 3.f, filter_tau = 3.f;
};

struct SceneBuildOptions {
  int width = 0, height = 0;  // 0: use the Film's resolution
  // Overrides the scene's PixelFilter with that filter's defaults (e.g. "box" to compare a
  // reduced-resolution render with an area-averaged reference). Empty: the scene's filter.
  std::string filter;
};

// Embree geometry masks (Debian's Embree is built with ray masks on): opaque surfaces and
// interface (null) surfaces that only change the medium. Shadow rays test kMaskOpaque only, so
// media boundaries never occlude; medium walks test kMaskInterface only.
inline constexpr uint32_t kMaskOpaque = 1u, kMaskInterface = 2u, kMaskAll = 0xFFFFFFFFu;

// A piece of a segment p0→p1 lying in one medium (parameter t ∈ [0, 1] along p1 - p0).
struct MediumSegment {
  float t0 = 0, t1 = 0;
  int medium = -1;
};

class Scene {
 public:
  // Loads and builds; every problem is a SceneError naming file:line.
  static std::unique_ptr<Scene> Build(const SceneDescription& desc, const SceneBuildOptions& opt);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // Closest hit along ray within (0, ray.tmax). The ray must be finite (validated by caller).
  // mask selects the geometry (kMaskAll: every surface, interfaces included).
  bool Intersect(const Ray& ray, SurfaceHit* hit, uint32_t mask = kMaskAll) const;
  // Occlusion for a batch of prepared Embree rays (tfar set to -inf where occluded). Every ray's
  // mask is set to kMaskOpaque here: interface surfaces never occlude.
  void Occluded(RTCRay* rays, size_t count) const;

  // --- Participating media ---
  const std::vector<Medium>& media() const { return media_; }
  int camera_medium() const { return camera_medium_; }
  // The medium a ray leaving (or passing) surface `hit` along w is in, when it arrived in
  // `current`: a medium-transition shape decides by side (Dot(w, ng) > 0: outside), any other
  // surface keeps `current`.
  int MediumAfter(const SurfaceHit& hit, Vec3 w, int current) const;
  // The media along o + t·d, t ∈ [0, tmax] (d unit), starting in `medium` and crossing only
  // interface surfaces (opaque ones are the caller's visibility test). Appends pieces in order
  // (t in world units here); vacuum pieces have medium -1.
  void MediumSegments(Vec3 o, Vec3 d, float tmax, int medium, std::vector<MediumSegment>* out) const;
  // Transmittance of p0→p1 (or of o + t·d up to tmax) starting in `medium`: product over the
  // medium pieces (closed form in homogeneous media, ratio tracking otherwise). Validates the
  // rays it traces; a non-finite query returns 0.
  RGB Transmittance(Vec3 p0, Vec3 p1, int medium, Rng& rng) const;
  RGB TransmittanceAlong(Vec3 o, Vec3 d, float tmax, int medium, Rng& rng) const;

  const std::vector<Shape>& shapes() const { return shapes_; }
  const std::vector<Material>& materials() const { return materials_; }
  // The many-light split of every material's lobes (Material::sharp_alpha): set once by the
  // plan, before receivers or lights are generated, and identically on every worker.
  void SetSharpAlpha(float alpha) {
    for (Material& m : materials_) m.sharp_alpha = alpha;
  }
  const std::vector<AreaEmitter>& area_emitters() const { return area_emitters_; }
  const std::vector<PointEmitter>& point_emitters() const { return point_emitters_; }
  const std::vector<DistantEmitter>& distant_emitters() const { return distant_emitters_; }
  const std::vector<InfiniteEmitter>& infinite_emitters() const { return infinite_emitters_; }
  const Camera& camera() const { return camera_; }
  const RenderHints& hints() const { return hints_; }
  const Bounds3& bounds() const { return bounds_; }
  // True when the camera, a shape or a light uses a medium (a defined but unused medium is
  // not reachable by any path).
  bool has_media() const { return has_media_; }
  // The Embree device, for acceleration structures of other primitives (caustic photons).
  RTCDevice device() const { return device_; }

  // Emitted radiance of an area emitter leaving the surface at hit towards direction w.
  RGB EmittedRadiance(const SurfaceHit& hit, Vec3 w) const;
  // Radiance from the infinite lights along a ray that escaped in direction d.
  RGB EnvironmentRadiance(Vec3 d) const;

  // Samples a point on an area emitter uniformly by area: u.x picks the triangle through the
  // area CDF and is then reused within it, so a stratified u stays stratified over the surface.
  // Returns the position and the emitting-side (oriented geometric) normal.
  void SampleAreaEmitter(const AreaEmitter& e, Vec2 u, Vec3* p, Vec3* n) const;

 private:
  Scene() = default;
  RTCDevice device_ = nullptr;
  RTCScene rtc_scene_ = nullptr;
  std::vector<Shape> shapes_;
  std::vector<Material> materials_;
  std::vector<AreaEmitter> area_emitters_;
  std::vector<PointEmitter> point_emitters_;
  std::vector<DistantEmitter> distant_emitters_;
  std::vector<InfiniteEmitter> infinite_emitters_;
  Camera camera_;
  RenderHints hints_;
  Bounds3 bounds_;
  bool has_media_ = false;
  std::vector<Medium> media_;
  int camera_medium_ = -1;

  friend class SceneBuilder;
};

// Offsets a ray origin off a surface so that the new ray does not re-hit it: along the geometric
// normal, towards the side of w, by a bound proportional to the coordinates' magnitude (a fixed
// epsilon fails far from the origin; DESIGN.md pitfalls).
inline Vec3 OffsetRayOrigin(Vec3 p, Vec3 ng, Vec3 w) {
  float mag = MaxComponent(Abs(p));
  float eps = 0x1p-18f * (1.f + mag);  // ~64 float ulps at the point's magnitude
  Vec3 offset = ng * eps;
  if (Dot(w, ng) < 0) offset = -offset;
  return p + offset;
}

}  // namespace lightfarm
