// Turning a scene's emitters into the virtual light set (the matrix columns).
#pragma once

#include <cstdint>
#include <optional>

#include "common/lights/virtual_light.h"
#include "common/scene/scene.h"
#include "common/util/rng.h"

namespace lightfarm {

// What particle paths leave inside media (render_job.cpp: `--param media_lights`).
enum class MediumLights : uint8_t {
  kNone,  // nothing: particles still scatter and attenuate in media
  kVPL,   // a kMediumVPL at every scattering event
  kVRL,   // a kVRL per free flight through a medium (Novák 2012)
};

// Virtual lights a render makes when it is not told (--lights, a request without a count).
inline constexpr size_t kDefaultLights = 10000;

struct LightGenerationOptions {
  size_t target_lights = kDefaultLights;  // total virtual lights wanted (a target; see below)
  // Share of the budget spent on the emitters themselves (area lights, environment); the rest
  // goes to indirect VPLs from particle tracing. With maxdepth <= 1 everything is direct.
  float direct_fraction = 0.5f;
  int max_depth = 5;        // the scene's path depth (Integrator maxdepth)
  uint64_t seed = 0;
  // Lights left inside media (only for gather methods that evaluate media rows). VPLs and VRLs
  // are two estimates of the same light, so a path leaves one kind or the other, never both.
  MediumLights medium_lights = MediumLights::kNone;
  // VRLs are cut into up to this many pieces of equal in-scattering weight, each a column
  // (light_generation.cpp, AppendVrlPieces); a VRL counts once towards target_lights.
  int vrl_pieces = 1;
  // Particle paths start from quasi-random points (light_generation.cpp): the emitter, the
  // emitted ray's position and direction and a two-sided emitter's side from a randomly shifted
  // Halton sequence (--param light_paths=halton).
  bool quasi_random_paths = false;
};

// Deterministic for a given seed whatever the thread count: every path and every emitter sample
// draws from its own hashed generator, and paths are consumed in index order.
//
// Direct lights: area emitters get VPLs by stratified sampling ∝ emitted power; infinite lights
// become directional lights by importance sampling the map; point, spot and distant lights are
// one column each. Indirect: particle paths leave a VPL at every non-specular surface vertex up
// to maxdepth - 1 bounces (paths through specular vertices carry caustics; glossy VPLs keep their
// arrival direction), with Russian roulette. In media, a path leaves a medium VPL at each
// scattering event or a VRL for each free flight (opt.medium_lights). Paths are traced until the indirect budget is met;
// every VPL's power is divided by the number of paths started.
LightSet GenerateLights(const Scene& scene, const LightGenerationOptions& opt);

// Appends the columns of one VRL: pieces of equal in-scattering weight (MediumTrack), as many as
// `pieces` where light cannot cross the medium along it and fewer, max(1, ⌈pieces·(1 − Tr)⌉),
// where it can, each trimmed to where the density may scatter (Huo 2016, Sec. 3.2: VRL segments
// are the columns). A piece [s_a, s_b] is itself a VRL from b + s_a·ψ whose flux is Φ·Tr(b→s_a),
// so the pieces sum to the whole VRL. Returns false, appending nothing, when no light scatters
// out anywhere along it (a flight through empty space). Deterministic.
bool AppendVrlPieces(const Medium& med, const VirtualLight& vrl, int pieces, std::vector<VirtualLight>* out);

// One bounce of a particle path (importance transport) at a surface: samples the BSDF from
// wo (unit, back towards the light), multiplies beta by f·|cos|/pdf with the shading-normal
// correction (Veach 1997, Sec. 5.3), and rejects a direction on the wrong side of the true
// surface. nullopt when the path ends here.
struct ParticleBounce {
  Vec3 wi;        // the new direction of travel
  bool specular;  // sampled from a delta lobe
};
std::optional<ParticleBounce> ScatterParticle(const Material& m, const SurfaceHit& hit, Vec3 wo, Rng& rng,
                                              RGB* beta);

}  // namespace lightfarm
