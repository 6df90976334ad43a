// The columns of the lighting matrix: real emitters turned into point/directional lights, and
// virtual point lights (VPLs) left by particle paths (Keller 1997, instant radiosity).
#pragma once

#include <cstdint>
#include <vector>

#include "common/util/math.h"

namespace lightfarm {

enum class VirtualLightKind : uint8_t {
  // A point on an area emitter: a cosine-weighted (Lambertian) emitter of intensity
  // power · cos θ (power = L · A / N, the sample's share of radiance × area).
  kAreaVPL,
  // A particle-path vertex on a surface: re-emits the arriving flux `power` through the
  // surface's BSDF, I(ω) = power · f(wi, ω) · |cos θ|, with wi the stored arrival direction.
  kSurfaceVPL,
  // A real point or spot light: intensity `power` (· spot falloff).
  kPoint,
  // Light from a direction (distant lights, importance samples of infinite lights):
  // irradiance `power` on a surface facing it; `n` is the direction the light travels.
  kDirectional,
  // A particle-path scattering event inside a medium (a VPL in a medium): re-emits `power`
  // through the Henyey–Greenstein phase function, I(ω) = power · p_g(-wi · ω), with wi the unit
  // direction towards where the light came from. Generated only for gather methods that handle
  // media rows, with `--param media_lights=vpl` (see render_job.cpp).
  kMediumVPL,
  // A virtual ray light (Novák et al. 2012): a particle's free flight through one medium, from
  // p along the unit direction n for `length` (to the next surface or medium boundary). The
  // flux `power` entering it scatters out at every point x_s = p + s·n with density
  // σ_s(x_s)·Tr(p→x_s) per unit length, through the HG phase function of g. Generated for gather
  // methods that handle media rows with `--param media_lights=vrl` (the default).
  kVRL,
};

struct VirtualLight {
  Vec3 p;    // position (unused for directional)
  Vec3 n;    // surface normal (shading) for VPLs; travel direction for directional; spot axis
  Vec3 ng;   // geometric normal (VPLs), for shadow-ray offsets
  Vec3 wi;   // surface VPL: unit direction towards where the light came from
  RGB power;
  uint32_t material = 0;  // surface VPL: material index in the scene
  VirtualLightKind kind = VirtualLightKind::kAreaVPL;
  uint8_t depth = 0;      // scattering events on the light path before this vertex
  bool two_sided = false; // area VPL of a two-sided emitter
  bool caustic = false;   // surface VPL whose light path went through a specular interaction
  float cos_falloff_start = 1, cos_falloff_end = -1;  // spot cone (kPoint with spot)
  bool spot = false;
  float g = 0;            // medium VPL, VRL: HG asymmetry of its medium
  int16_t medium = -1;    // medium VPL, VRL: the medium it sits in
  float length = 0;       // VRL: length of the segment p + s·n, s ∈ [0, length]

  bool IsDirectional() const { return kind == VirtualLightKind::kDirectional; }
  bool IsRay() const { return kind == VirtualLightKind::kVRL; }
  Vec3 End() const { return p + n * length; }  // VRL: the far end point
  // Subject to the geometry-term clamp (virtual lights only; real point lights are exact).
  bool IsClamped() const {
    return kind == VirtualLightKind::kAreaVPL || kind == VirtualLightKind::kSurfaceVPL ||
           kind == VirtualLightKind::kMediumVPL || kind == VirtualLightKind::kVRL;
  }
};

struct LightSetStats {
  size_t area_vpls = 0, surface_vpls = 0, point_lights = 0, directional_lights = 0;
  size_t particle_paths = 0;
  size_t caustic_vpls = 0;  // surface VPLs whose path went through a specular interaction
  size_t glossy_vpls = 0;   // surface VPLs on materials with a glossy lobe
  size_t medium_vpls = 0;   // particle scattering events in media (kMediumVPL)
  size_t vrls = 0;          // VRL columns (kVRL): pieces of the flights below
  size_t vrl_flights = 0;   // particle free flights through media that scatter light (AppendVrlPieces)
};

struct LightSet {
  std::vector<VirtualLight> lights;
  LightSetStats stats;
  size_t size() const { return lights.size(); }
};

}  // namespace lightfarm
