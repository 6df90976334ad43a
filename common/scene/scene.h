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
#include "common/scene/lights.h"
#include "common/scene/medium.h"
#include "common/scene/scene_description.h"
#include "common/scene/shapes.h"
#include "common/util/math.h"
#include "common/util/rng.h"

namespace lightfarm {

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
  // With near_max_alpha > 0 it also adds the near-field sharp twins: for each material whose
  // microfacet lobe stays rough under alpha but is no rougher than near_max_alpha, a copy whose
  // lobe is sharp, appended after the scene's own materials. Receiver paths use a twin at a
  // vertex whose reflection lands close by (docs/rendering.md, "Sharp lobes", *Near field*); the
  // lights never do. Replaces the twins of an earlier call.
  void SetSharpAlpha(float alpha, float near_max_alpha = 0);
  // How many near-field sharp twins the last SetSharpAlpha added.
  size_t near_sharp_twins() const { return near_twins_.empty() ? 0 : materials_.size() - own_materials_; }
  // The material's near-field sharp twin, -1 if it has none.
  int near_sharp_twin(int material) const {
    return material >= 0 && size_t(material) < near_twins_.size() ? near_twins_[size_t(material)] : -1;
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
  size_t own_materials_ = 0;       // materials_ beyond this are near-field sharp twins
  std::vector<int> near_twins_;    // per own material: its twin's index, or -1
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
