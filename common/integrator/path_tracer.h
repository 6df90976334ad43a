// A unidirectional volumetric path tracer (pbrt-v4's VolPathIntegrator, Mitsuba 3's volpath):
// the truth the many-light methods are measured against, and the sampling the renderer uses where
// virtual lights cannot carry the light.
//
// - Next-event estimation at every non-specular surface vertex and medium scattering, combined
//   with BSDF / phase sampling by multiple importance sampling (power heuristic, Veach 1997) on
//   the directional densities; delta lights by next-event estimation only, delta lobes by BSDF
//   sampling only.
// - Media: distances by delta tracking over the majorant grid (Medium::SampleFreePath: spectral
//   tracking with the "max" collision probabilities for chromatic media), shadow rays by ratio
//   tracking (Scene::Transmittance). Both are unbiased, so the MIS weights need only the
//   directional densities, which sum to one over the two strategies for every path.
// - Depth as pbrt-v4 counts it: every surface or medium scattering is one vertex, `maxdepth`
//   vertices at most; emission found by the ray leaving the last vertex still counts; surfaces
//   that only bound media do not count.
// - Russian roulette from the third vertex on, on the throughput times the squared relative IOR
//   of the refractions so far (pbrt-v4's etaScale), so glass does not end paths early.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "common/lights/emitters.h"
#include "common/scene/scene.h"
#include "common/util/rng.h"

namespace lightfarm {

// Which estimators a path tracer combines: both by MIS, or one of them alone (each alone is
// unbiased for the light it can reach, which the tests use to check the weights).
enum class PathStrategy { kMIS, kBSDF, kLight };

struct PathTracerOptions {
  int max_depth = 5;
  PathStrategy strategy = PathStrategy::kMIS;
};

struct PathCounters {
  uint64_t paths = 0;        // camera rays traced
  uint64_t vertices = 0;     // scattering events (surface and medium) over all paths
  uint64_t shadow_rays = 0;  // next-event estimation rays
  uint64_t escaped = 0;      // paths that left the scene
  uint64_t roulette = 0;     // paths ended by Russian roulette
  void Add(const PathCounters& o) {
    paths += o.paths;
    vertices += o.vertices;
    shadow_rays += o.shadow_rays;
    escaped += o.escaped;
    roulette += o.roulette;
  }
};

// Weights on what a path gathers at its first scattering vertex, by where the light arrives
// from: the clamp compensation (clamp_compensation.cpp) traces, from a receiver, only the share
// of each first-vertex direction that the element bound removed. The first surface's emission is
// weighted by `emission`, light arriving there along a non-delta direction wi (local shading
// frame, wo towards the path's origin) by arrival(wo, wi), light leaving it by a delta (or sharp)
// lobe by `specular`, and a first vertex in a medium by `other`.
//
// With a `window` c > 0 the first vertex is forced within distance c of the ray's origin and
// everything it gathers is further weighted by (1 − d²/c²), d its distance from the origin: the
// share of a light path that the geometry clamp removed from an eye segment's elements
// (clamp_compensation.cpp). Inside a medium the vertex is a scattering point, drawn from the
// majorant's exponential truncated to the stretch before the next surface (or c), or that
// surface, chosen as delta tracking would choose; the path then goes on as usual.
struct FirstVertexWeight {
  float emission = 1, other = 1, specular = 1;
  std::function<float(Vec3 wo, Vec3 wi)> arrival;
  float window = 0;
};

class PathTracer {
 public:
  PathTracer(const Scene& scene, const PathTracerOptions& options);
  // Radiance arriving at the camera along `ray` (starting in the camera's medium). Draws every
  // random number from rng, so a path is a deterministic function of its generator.
  RGB Li(Ray ray, Rng& rng, PathCounters* counters) const;
  // Radiance arriving at ray.o along -ray.d, for a ray that starts in `medium` and may scatter at
  // most `max_depth` times (the clamp compensation traces from a receiver with its remaining depth).
  RGB Li(Ray ray, int medium, int max_depth, Rng& rng, PathCounters* counters,
         const FirstVertexWeight* first = nullptr) const;

  // Appends every ray traced from now on (closest-hit rays, shadow rays as handed to Embree) to
  // these vectors (nullptr: stop): the micro-benchmark replays them through Embree alone.
  // Single-threaded use only.
  void RecordRays(std::vector<Ray>* closest, std::vector<RTCRay>* shadow) {
    record_closest_ = closest;
    record_shadow_ = shadow;
  }

 private:
  // Next-event estimation from a surface vertex (local BSDF frame) or a medium point.
  // `first`: weight the sample by its direction (FirstVertexWeight::arrival).
  RGB LightAtSurface(const SurfaceHit& hit, const Material& m, const Frame& frame, Vec3 wo_local,
                     int medium, Rng& rng, PathCounters* counters,
                     const FirstVertexWeight* first = nullptr) const;
  RGB LightInMedium(Vec3 p, Vec3 d_in, int medium, Rng& rng, PathCounters* counters) const;
  // Transmittance × visibility of the shadow ray from o towards the sample (0 when occluded).
  RGB ShadowRay(Vec3 o, const LightSample& ls, int medium, Rng& rng, PathCounters* counters) const;
  // MIS weight of a light found by BSDF / phase sampling, given both densities.
  float HitWeight(float pdf_scatter, float pdf_light) const;

  const Scene& scene_;
  PathTracerOptions options_;
  EmitterSampler lights_;
  std::vector<Ray>* record_closest_ = nullptr;
  std::vector<RTCRay>* record_shadow_ = nullptr;
};

}  // namespace lightfarm
