// An independent, deliberately simple unidirectional volumetric path tracer, used ONLY to validate
// lightfarm's many-light transport (`lightfarm-volpath-check`, tests/oracle/volpath_check.cpp, and
// tests/scenes/test_transport_vs_path_tracer.cpp; it is not a gather method and is not installed). It shares lightfarm's scene parser, Embree scene, BSDFs and camera, but
// none of the transport code (receivers, particle tracing, matrix elements, clamping).
//
// Depth counting follows pbrt-v4's VolPathIntegrator: a surface with a real material counts as
// a scattering vertex (emission found there is added first, then the path stops if it already
// has max_depth vertices), a real collision in a medium counts too (the path stops there when
// it already has max_depth vertices, before any lighting), interface (null) surfaces never
// count. So max_depth 1 is direct lighting only.
//
// Estimator (no MIS, nothing counted twice):
//   - next-event estimation to the area emitters at every non-specular surface vertex and every
//     medium collision; shadow rays are blocked by every non-interface surface and attenuated by
//     exp(-σ_t·d) through the homogeneous media they cross;
//   - emission hit by BSDF/phase sampling is added only for the camera ray and after a specular
//     (delta) vertex, which next-event estimation cannot connect through;
//   - free paths by analog delta tracking in homogeneous media (real collisions at rate
//     max_c σ_t,c; absorption/scatter/null chosen by the channel-averaged coefficients with
//     per-channel weights, which is exact analog tracking for grey media);
//   - no Russian roulette (max_depth bounds the path).
// Pixels: box filter over the pixel footprint with uniformly jittered samples (compare with a
// `--filter box` lightfarm render or an area-averaged reference).
#pragma once

#include <cstdint>
#include <vector>

#include "common/image/image.h"
#include "common/scene/scene.h"
#include "common/util/rng.h"

namespace lightfarm {

struct VolpathCheckOptions {
  int max_depth = -1;  // -1: the scene's
  int spp = 256;
  uint64_t seed = 1;
  // Diagnostics: drop emission reached through specular vertices after a non-specular one,
  // i.e. every caustic path L S+ (D|M) ... E.
  bool no_emitted_after_specular = false;
  // Diagnostics: drop only the caustics seen directly, L S+ X S* E with X the camera path's one
  // non-specular vertex (surface or medium): the paths a VPL/VRL many-light renderer cannot form
  // (its receiver X cannot connect to a light through a specular chain).
  bool no_direct_caustics = false;
  // Diagnostics: scale each camera sample so its largest channel is at most this (pbrt-v4's
  // RGBFilm "maxcomponentvalue"; infinite by default, as there).
  float max_component = kInfinity;
};

class VolumetricPathTracer {
 public:
  // Throws std::runtime_error for what it does not handle: heterogeneous media, emitters other
  // than area lights.
  VolumetricPathTracer(const Scene& scene, const VolpathCheckOptions& opt);
  // Radiance along a camera ray (one sample of the path-space estimator).
  RGB Li(Ray ray, Rng& rng) const;
  int max_depth() const { return max_depth_; }

 private:
  bool SampleCollision(const Medium& med, float tmax, Rng& rng, float* t, RGB* beta) const;
  RGB SampleEmitter(Vec3 x, const SurfaceHit* hit, int medium, Rng& rng, Vec3* wl) const;
  RGB ShadowTransmittance(Vec3 o, Vec3 p, int medium) const;

  const Scene& scene_;
  VolpathCheckOptions opt_;
  int max_depth_;
  std::vector<double> emitter_cdf_;
};

// The scene's image (its Film resolution; build it with the box filter, which is what the
// jittered pixel samples integrate) and the variance of each pixel's mean.
struct PathTracedImage {
  Image mean, variance_of_mean;
  int max_depth = 0;  // the depth the tracer used (the option's, else the scene's)
};
PathTracedImage RenderPathTraced(const Scene& scene, const VolpathCheckOptions& opt);

}  // namespace lightfarm
