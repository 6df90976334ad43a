// Caustic photons: what virtual lights cannot carry to a receiver (docs/rendering.md, "Caustics
// seen directly").
//
// Light reaches a receiver x (a surface point or an eye segment's scattering point) from the
// path's previous scattering event y. A many-light method connects x to y with a straight shadow
// ray, so it carries every path whose y is an emitter or a non-delta event (an area VPL, a VPL,
// a VRL). When y is a delta bounce (glass, a mirror, a water surface) no connection exists: the
// caustics L S+ D E and L S+ M E, and also light that a VPL sends through a specular surface,
// L ... D S+ D E (under water, the lit floor seen on the ceiling). So particle paths, traced as
// light generation traces them, store a photon at every non-delta event whose previous event was
// a delta bounce, and the photons are gathered where the camera path ends:
//  - on a surface receiver, a k-nearest-neighbour density estimate (Jensen 2001, Eq. 7.6):
//      L(x, ωo) ≈ Σ_p f(x, ωo, ωp) Φp / (π r²),  r the distance to the k-th photon (≤ r_max);
//  - along an eye segment, the beam radiance estimate (Jarosz et al. 2008) with a cylinder of
//    fixed radius r: L ≈ Σ_p Tr(o, x⊥p) p_g(ωp, −d) Φp / (π r²), x⊥p the photon's
//    projection on the segment, for photons whose projection falls inside it.
// Each path is counted once: the kind of x's previous event decides whether the columns or the
// photons carry it, and the matrix evaluates only non-delta lobes.
//
// Deterministic: path i draws from its own generator (job seed, path index), paths are
// consumed in index order, and the trees are built from the stored photons in that order.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/scene/scene.h"

namespace lightfarm {

struct CausticPhoton {
  Vec3 p;
  Vec3 n;       // surface photon: the geometric normal there; volume photon: unused
  Vec3 dir;     // unit direction of travel on arrival
  RGB power;    // flux (divided by the number of paths traced)
  uint8_t depth = 0;    // scattering events before it on the light path
  int16_t medium = -1;  // volume photon: the medium it scattered in
};

struct CausticPhotonOptions {
  size_t target_photons = 0;  // photons to store (surface + volume); 0: none traced
  int max_depth = 5;          // the scene's maxdepth
  uint64_t seed = 0;
  bool volume = false;        // store photons at scattering events in media (eye segments gather them)
  float volume_radius = 0;    // the beam radiance estimate's radius (world units)
};

class CausticPhotonMap {
 public:
  // Traces particle paths until target_photons are stored or a path budget (8× the target, at
  // least 2^20) is spent, so a scene whose specular objects catch little light stops in time.
  static std::unique_ptr<CausticPhotonMap> Trace(const Scene& scene, const CausticPhotonOptions& options);
  ~CausticPhotonMap();

  const std::vector<CausticPhoton>& surface() const { return surface_; }
  const std::vector<CausticPhoton>& volume() const { return volume_; }
  size_t paths() const { return paths_; }

  // The k nearest surface photons of p within max_radius, nearest first (ties by index); the
  // estimate's radius² is returned in *radius2 (the k-th distance², or max_radius² when fewer
  // were found).
  void NearestSurface(Vec3 p, size_t k, float max_radius, std::vector<uint32_t>* out, float* radius2) const;
  // Volume photons within volume_radius() of the segment o + t·d, t ∈ [0, length] (d unit),
  // whose projection t lies on it: (index, t) in order of t, then index.
  struct SegmentHit {
    uint32_t photon;
    float t;
  };
  void NearSegment(Vec3 o, Vec3 d, float length, std::vector<SegmentHit>* out) const;
  float volume_radius() const { return volume_radius_; }

 private:
  struct Tree;
  std::vector<CausticPhoton> surface_, volume_;
  std::unique_ptr<Tree> surface_tree_, volume_tree_;
  size_t paths_ = 0;
  float volume_radius_ = 0;
};

}  // namespace lightfarm
