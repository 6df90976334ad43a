// The scene's emitters as light sources for sampling: which emitter (by power, the choice both
// particle tracing and next-event estimation make) and a point or direction on it as seen from a
// point in the scene (pbrt-v4's PowerLightSampler and Light::SampleLi / PDF_Li).
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <optional>
#include <vector>

#include "common/scene/scene.h"
#include "common/util/rng.h"

namespace lightfarm {

// One emitter as a source of light.
struct EmitterRef {
  enum Kind { kArea, kPoint, kDistant, kInfinite } kind;
  uint32_t index;  // into the scene's list of that kind
  RGB power;       // emitted power Φ (distant and infinite: through the scene's bounding disk)
};

// Every emitter of the scene with its power; scene_radius bounds the scene (distant and infinite
// lights deliver their power through a disk of that radius).
std::vector<EmitterRef> CollectEmitters(const Scene& scene, float scene_radius);

// A ray leaving an emitter with the flux it carries (divided by its sampling pdf): the start of
// a particle path (light generation, caustic photons).
struct EmittedRay {
  Ray ray;
  RGB beta;
  Vec3 ng;          // emitter surface normal (area lights), for the origin offset
  int medium = -1;  // the medium the ray starts in
  bool valid = false;
};
// Area lights: a point ∝ area and a cosine-weighted direction; point and spot lights: a
// direction in their cone; distant and infinite lights: a ray through the disk of `radius`
// around `center` that bounds the scene.
EmittedRay SampleEmittedRay(const Scene& scene, const EmitterRef& e, Vec3 center, float radius, Rng& rng);
// The same from given sample points: u1 the position (area lights, the disk of distant and
// infinite lights) or the direction (point lights, the infinite light's), u2 the area light's
// direction or the infinite light's disk, side a two-sided area light's side (< 0.5: the back).
struct EmissionSample {
  Vec2 u1, u2;
  float side = 1;
};
EmittedRay SampleEmittedRay(const Scene& scene, const EmitterRef& e, Vec3 center, float radius,
                            const EmissionSample& u);

// Picks emitters ∝ the luminance of their power (particle paths start so).
class PowerPicker {
 public:
  explicit PowerPicker(const std::vector<EmitterRef>& emitters);
  bool empty() const { return !(total_ > 0); }
  // The emitter's index in `emitters` for u ∈ [0, 1), and the probability it had.
  size_t Pick(float u, float* probability) const;

 private:
  std::vector<float> cdf_;
  double total_ = 0;
};

// Light arriving at a reference point from one sampled point or direction of an emitter.
struct LightSample {
  RGB L;              // radiance (area, infinite) or intensity / d² (point) or irradiance (distant)
  Vec3 wi;            // unit, from the reference point towards the light
  Vec3 p_light;       // the point on the light (unused when `infinite_distance`)
  Vec3 n_light;       // its emitting-side normal (area lights), for the shadow ray's end offset
  bool infinite_distance = false;  // distant and infinite lights: the shadow ray is unbounded
  bool delta = false;  // point, spot and distant lights: BSDF sampling can never hit them
  bool area = false;
  // Probability density of this sample: the emitter's selection probability times the solid-angle
  // density at the reference point (delta lights: the selection probability alone).
  float pdf = 0;
};

// The generalized visibility of light sample `ls` from `o` (a ray origin the caller offset off
// its surface): 0 when an opaque surface lies between them, else the transmittance through the
// media the segment crosses starting in `medium` (1 in a scene without media). The shadow ray
// ends just short of an area light's point, offset off its surface, so the emitter does not
// occlude itself; distant and infinite lights' is unbounded. `recorded` (benchmarks) receives
// the ray as it was handed to Embree. One ray; the caller counts it.
RGB LightSampleVisibility(const Scene& scene, Vec3 o, const LightSample& ls, int medium, Rng& rng,
                          std::vector<RTCRay>* recorded = nullptr);

class EmitterSampler {
 public:
  explicit EmitterSampler(const Scene& scene);
  bool empty() const { return cdf_.empty(); }
  // Picks an emitter ∝ the luminance of its power with u_pick and samples it as seen from p.
  // nullopt when the sample carries nothing (back of a one-sided emitter, zero pdf).
  std::optional<LightSample> Sample(Vec3 p, float u_pick, Vec2 u) const;
  // The density Sample(p, ...) has of reaching `hit`, a point on area emitter `emitter`, per
  // solid angle at p (selection included): for MIS weights of paths that hit the emitter.
  float PdfArea(uint32_t emitter, Vec3 p, const SurfaceHit& hit) const;
  // Same for infinite light `emitter` and the direction w (pointing away from the scene).
  float PdfInfinite(uint32_t emitter, Vec3 w) const;

 private:
  float SelectProbability(size_t slot) const;

  const Scene& scene_;
  std::vector<EmitterRef> emitters_;
  std::vector<double> cdf_;  // cumulative luminance of power, normalised
  std::vector<int> area_slot_, infinite_slot_;  // emitter index of that kind → slot in emitters_
};

}  // namespace lightfarm
