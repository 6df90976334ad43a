#include "common/lights/light_generation.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "common/lights/emitters.h"
#include "common/scene/medium_track.h"
#include "common/scene/phase.h"
#include "common/util/rng.h"
#include "common/util/sampling.h"

namespace lightfarm {

namespace {

// Distance along the (unit-direction) ray to where it leaves the scene's bounding sphere: the
// end of a VRL in a medium that no surface bounds.
float ExitDistance(const Ray& ray, Vec3 center, float radius) {
  Vec3 oc = ray.o - center;
  float b = Dot(oc, ray.d), c = LengthSquared(oc) - radius * radius;
  float disc = b * b - c;
  return disc > 0 ? std::max(0.f, -b + std::sqrt(disc)) : 0.f;
}

// Dimension `dim` (< kHaltonDims) of Halton point `index` (radical inverses in bases 2, 3, 5, 7,
// 11, 13), shifted by `shift` modulo 1.
constexpr int kHaltonDims = 6;
float ShiftedHalton(uint64_t index, int dim, float shift) {
  static constexpr uint32_t kBases[kHaltonDims] = {2, 3, 5, 7, 11, 13};
  const uint32_t base = kBases[dim];
  double inv = 1.0 / base, f = inv, v = 0;
  for (uint64_t i = index; i > 0; i /= base, f *= inv) v += double(i % base) * f;
  const float u = float(v) + shift;
  return std::min(u >= 1.f ? u - 1.f : u, 0x1.fffffep-1f);
}

// Traces one particle path and appends its surface VPLs (power not yet divided by #paths).
// Returns the lights it made towards the budget: a VRL counts once, however many pieces it has.
// `emission`: the emitted ray's sample points (quasi-random paths), or null to draw them from rng.
size_t TraceParticlePath(const Scene& scene, const EmitterRef& e, float p_select, Vec3 center,
                         float radius, int max_depth, MediumLights medium_lights, int vrl_pieces,
                         const EmissionSample* emission, Rng& rng, std::vector<VirtualLight>* out) {
  size_t made = 0;
  EmittedRay em = emission ? SampleEmittedRay(scene, e, center, radius, *emission)
                           : SampleEmittedRay(scene, e, center, radius, rng);
  if (!em.valid) return made;
  RGB beta = em.beta / p_select;
  const float beta0 = std::max(beta.Max(), 1e-30f);
  Ray ray = em.ray;
  int medium = em.medium;
  bool through_specular = false;
  int bounces = 0;      // scattering events so far
  int passthrough = 0;  // interface crossings (not scattering)
  while (bounces < max_depth - 1) {
    SurfaceHit hit;
    bool found = scene.Intersect(ray, &hit);
    if (medium >= 0) {
      // Delta tracking decides whether the particle scatters in the medium before the surface.
      const Medium& med = scene.media()[medium];
      if (medium_lights == MediumLights::kVRL && !med.sigma_s().IsBlack()) {
        // A "long" VRL (Jarosz et al. 2011's long beams): the whole free flight to the next
        // surface or medium boundary, with Tr along it evaluated by the elements. Ending it at
        // the sampled collision instead would attenuate twice (the collision's survival
        // probability is already Tr). The flux is the one entering the flight.
        float length = found ? hit.t : ExitDistance(ray, center, radius);
        if (length > 0 && std::isfinite(length)) {
          VirtualLight v;
          v.kind = VirtualLightKind::kVRL;
          v.p = ray.o;
          v.n = ray.d;
          v.ng = ray.d;
          v.wi = -ray.d;
          v.length = length;
          v.power = beta;
          v.g = med.g();
          v.medium = int16_t(medium);
          // The scattering event on the VRL counts as a bounce of the light path.
          v.depth = uint8_t(std::min(bounces + 1, 255));
          v.caustic = through_specular;
          made += AppendVrlPieces(med, v, vrl_pieces, out);
        }
      }
      MediumRay mray{ray.o, ray.d, found ? hit.t : kInfinity};
      FreePathSample fp = med.SampleFreePath(mray, rng);
      beta *= fp.weight;
      if (!beta.IsFinite() || beta.IsBlack()) return made;
      if (fp.scattered) {
        ++bounces;
        Vec3 x = ray.o + ray.d * fp.t;
        if (medium_lights == MediumLights::kVPL) {
          // Delta tracking's collision density σ_t·T cancels in the estimator; the weight
          // already holds σ_s/σ_t, so the event re-emits beta through the phase function.
          VirtualLight v;
          v.kind = VirtualLightKind::kMediumVPL;
          v.p = x;
          v.wi = -ray.d;
          v.n = ray.d;
          v.ng = ray.d;
          v.power = beta;
          v.g = med.g();
          v.medium = int16_t(medium);
          v.depth = uint8_t(std::min(bounces, 255));
          v.caustic = through_specular;
          if (IsFinite(x)) {
            out->push_back(v);
            ++made;
          }
        }
        if (bounces >= max_depth - 1) return made;
        // HG phase sampling: the weight f_p/pdf is 1.
        Vec3 wnew = SampleHenyeyGreenstein(ray.d, med.g(), rng.Uniform(), rng.Uniform(), nullptr);
        if (bounces > 2) {
          float q = std::min(1.f, beta.Max() / beta0);
          if (rng.Uniform() >= q) return made;
          beta = beta / q;
        }
        ray = {x, wnew, kInfinity};
        if (!IsFinite(ray.o) || !IsFinite(ray.d)) return made;
        continue;
      }
    }
    if (!found) return made;
    const Shape& shape = scene.shapes()[hit.shape];
    const Material& m = scene.materials()[shape.material];
    uint32_t flags = MaterialFlags(m);
    Vec3 wo = -ray.d;
    if (flags == 0) {  // interface: no surface, continue straight through into the next medium
      if (++passthrough > 64) return made;
      medium = scene.MediumAfter(hit, ray.d, medium);
      ray.o = OffsetRayOrigin(hit.p, hit.ng, ray.d);
      continue;
    }
    ++bounces;
    if (!IsPurelySpecular(flags)) {
      VirtualLight v;
      v.kind = VirtualLightKind::kSurfaceVPL;
      v.p = hit.p;
      v.n = hit.ns;
      v.ng = hit.ng;
      v.wi = wo;
      v.power = beta;
      v.material = uint32_t(shape.material);
      v.depth = uint8_t(std::min(bounces, 255));
      v.caustic = through_specular;
      out->push_back(v);
      ++made;
    }
    if (bounces >= max_depth - 1) return made;  // no later vertex could reach a receiver in budget
    const std::optional<ParticleBounce> bounce = ScatterParticle(m, hit, wo, rng, &beta);
    if (!bounce) return made;
    const Vec3 wi = bounce->wi;
    through_specular = through_specular || bounce->specular;
    medium = scene.MediumAfter(hit, wi, medium);
    // Russian roulette on throughput relative to the emitted flux.
    if (bounces > 2) {
      float q = std::min(1.f, beta.Max() / beta0);
      if (rng.Uniform() >= q) return made;
      beta = beta / q;
    }
    ray = {OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity};
  }
  return made;
}

}  // namespace

bool AppendVrlPieces(const Medium& med, const VirtualLight& vrl, int pieces, std::vector<VirtualLight>* out) {
  const MediumTrack track(med, {vrl.p, vrl.n, vrl.length});
  if (track.empty()) return false;
  const float crossing = track.TransmittanceToEnd().Average();
  const int n = std::clamp(int(std::ceil(float(pieces) * (1.f - crossing))), 1, std::max(pieces, 1));
  float s0 = track.Quantile(0.f);
  for (int k = 0; k < n; ++k) {
    const float s1 = k + 1 == n ? track.support_end() : track.Quantile(float(k + 1) / float(n));
    if (!(s1 > s0)) continue;
    VirtualLight piece = vrl;
    piece.p = vrl.p + vrl.n * s0;
    piece.length = s1 - s0;
    piece.power = vrl.power * track.At(s0).tr;
    out->push_back(piece);
    s0 = s1;
  }
  return true;
}

std::optional<ParticleBounce> ScatterParticle(const Material& m, const SurfaceHit& hit, Vec3 wo, Rng& rng,
                                              RGB* beta) {
  const Frame frame(hit.ns);
  const Vec3 wo_local = frame.ToLocal(wo);
  auto bs = SampleBSDF(m, wo_local, rng.Uniform(), {rng.Uniform(), rng.Uniform()},
                       TransportMode::kImportance);
  if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) return std::nullopt;
  const Vec3 wi = frame.FromLocal(bs->wi);
  // Shading-normal correction for importance transport (Veach 1997, Sec. 5.3).
  const float denom = AbsDot(wo, hit.ng) * std::abs(bs->wi.z);
  if (!(denom > 0)) return std::nullopt;
  const float correction = AbsDot(wo, hit.ns) * AbsDot(wi, hit.ng) / denom;
  *beta *= bs->f * (std::abs(bs->wi.z) * correction / bs->pdf);
  if (!beta->IsFinite() || beta->IsBlack()) return std::nullopt;
  // A direction on the wrong side of the true surface would leak through it.
  const bool same_side = Dot(wi, hit.ng) * Dot(wo, hit.ng) > 0;
  if (same_side != ((bs->flags & kBxDFReflection) != 0)) return std::nullopt;
  return ParticleBounce{wi, bs->IsSpecular()};
}

LightSet GenerateLights(const Scene& scene, const LightGenerationOptions& opt) {
  LightSet set;
  const Bounds3& b = scene.bounds();
  Vec3 center = b.Empty() ? Vec3{0, 0, 0} : b.Center();
  float radius = std::max(b.Radius(), 1e-3f) * 1.01f;

  // --- Real point/spot and distant lights: one column each -------------------------------
  for (const PointEmitter& pe : scene.point_emitters()) {
    VirtualLight v;
    v.kind = VirtualLightKind::kPoint;
    v.p = pe.position;
    v.n = pe.axis;
    v.power = pe.intensity;
    v.spot = pe.spot;
    v.cos_falloff_start = pe.cos_falloff_start;
    v.cos_falloff_end = pe.cos_falloff_end;
    set.lights.push_back(v);
    ++set.stats.point_lights;
  }
  for (const DistantEmitter& de : scene.distant_emitters()) {
    VirtualLight v;
    v.kind = VirtualLightKind::kDirectional;
    v.n = de.direction;
    v.power = de.L;
    set.lights.push_back(v);
    ++set.stats.directional_lights;
  }

  // --- Area and infinite lights: the direct budget, split ∝ emitted power ------------------
  std::vector<EmitterRef> emitters = CollectEmitters(scene, radius);
  bool indirect = opt.max_depth > 1;
  size_t direct_budget = indirect ? size_t(std::llround(double(opt.target_lights) * double(opt.direct_fraction)))
                                  : opt.target_lights;
  double sampled_power = 0;
  for (const EmitterRef& e : emitters)
    if (e.kind == EmitterRef::kArea || e.kind == EmitterRef::kInfinite)
      sampled_power += double(e.power.Luminance());
  // A power that overflows float (radiance × area, or an environment × the scene's extent) would
  // turn the split below into NaN light counts (a huge allocation).
  for (const EmitterRef& e : emitters)
    if (!e.power.IsFinite())
      throw std::runtime_error("emitted power of a light overflows float (its radiance times its "
                               "area or the scene's extent is too large)");
  for (const EmitterRef& e : emitters) {
    if (e.kind != EmitterRef::kArea && e.kind != EmitterRef::kInfinite) continue;
    size_t n = std::max<size_t>(1, size_t(std::llround(double(direct_budget) * double(e.power.Luminance()) /
                                                      std::max(sampled_power, 1e-30))));
    uint32_t scramble0 = uint32_t(HashSeed({opt.seed, uint64_t(RngStream::kEmitterSample), e.index, e.kind, 0}));
    uint32_t scramble1 = uint32_t(HashSeed({opt.seed, uint64_t(RngStream::kEmitterSample), e.index, e.kind, 1}));
    for (size_t i = 0; i < n; ++i) {
      // Scrambled Sobol points: stratified over the emitter for any power-of-two prefix.
      Vec2 u{Sobol2DComponent(uint32_t(i), 0, scramble0), Sobol2DComponent(uint32_t(i), 1, scramble1)};
      VirtualLight v;
      if (e.kind == EmitterRef::kArea) {
        const AreaEmitter& a = scene.area_emitters()[e.index];
        scene.SampleAreaEmitter(a, u, &v.p, &v.n);
        v.ng = v.n;
        v.kind = VirtualLightKind::kAreaVPL;
        v.two_sided = a.two_sided;
        v.power = a.L * (a.area / float(n));
        ++set.stats.area_vpls;
      } else {
        const InfiniteEmitter& ie = scene.infinite_emitters()[e.index];
        float pdf;
        Vec3 w = ie.SampleDirection(u, &pdf);
        if (!(pdf > 0)) continue;
        v.kind = VirtualLightKind::kDirectional;
        v.n = -w;
        v.power = ie.Le(w) / (pdf * float(n));
        ++set.stats.directional_lights;
      }
      set.lights.push_back(v);
    }
  }

  // --- Indirect VPLs: particle paths until the budget is met -------------------------------
  size_t indirect_budget = opt.target_lights > set.lights.size() ? opt.target_lights - set.lights.size() : 0;
  if (!indirect || indirect_budget == 0 || emitters.empty()) return set;
  const PowerPicker picker(emitters);
  if (picker.empty()) return set;

  // Cranley–Patterson shifts of the quasi-random paths' Halton points, one per dimension.
  float halton_shift[kHaltonDims];
  for (int d = 0; d < kHaltonDims; ++d) {
    Rng shift_rng(HashSeed({opt.seed, uint64_t(RngStream::kParticlePath), ~uint64_t(0), uint64_t(d)}));
    halton_shift[d] = shift_rng.Uniform();
  }
  const size_t batch = 4096;
  // Give up if paths keep escaping: a scene that never bounces light yields no VPLs.
  const size_t max_paths = std::max<size_t>(indirect_budget * 64, 1 << 20);
  std::vector<std::vector<VirtualLight>> per_path(batch);
  std::vector<size_t> per_path_made(batch);
  size_t paths = 0, produced = 0;
  std::vector<VirtualLight> indirect_vpls;
  while (produced < indirect_budget && paths < max_paths) {
    tbb::parallel_for(size_t(0), batch, [&](size_t k) {
      per_path[k].clear();
      uint64_t index = paths + k;
      Rng rng(HashSeed({opt.seed, uint64_t(RngStream::kParticlePath), index}));
      float p_select = 0;
      float u_pick;
      EmissionSample emission;
      if (opt.quasi_random_paths) {
        // The path's first six dimensions (the emitter, the emitted ray's two points, a two-sided
        // emitter's side: a side drawn at random would thin the points at random) from a
        // randomly shifted Halton point (Keller 1997 drew instant radiosity's particles from
        // Halton points): the paths start evenly over the emitters' power, positions and
        // directions, and a light set's total varies less from seed to seed.
        float u[kHaltonDims];
        for (int d = 0; d < kHaltonDims; ++d) u[d] = ShiftedHalton(index + 1, d, halton_shift[d]);
        u_pick = u[0];
        emission = {{u[1], u[2]}, {u[3], u[4]}, u[5]};
      } else {
        u_pick = rng.Uniform();
      }
      const size_t ei = picker.Pick(u_pick, &p_select);
      per_path_made[k] = TraceParticlePath(scene, emitters[ei], p_select, center, radius, opt.max_depth,
                                           opt.medium_lights, opt.vrl_pieces,
                                           opt.quasi_random_paths ? &emission : nullptr, rng, &per_path[k]);
    });
    // Consume whole paths in index order so the result is independent of scheduling.
    for (size_t k = 0; k < batch && produced < indirect_budget; ++k) {
      ++paths;
      size_t points = 0;  // lights that are not VRL pieces: the rest of made are VRL flights
      for (VirtualLight& v : per_path[k]) {
        points += !v.IsRay();
        indirect_vpls.push_back(v);
      }
      produced += per_path_made[k];
      set.stats.vrl_flights += per_path_made[k] - points;
    }
  }
  set.stats.particle_paths = paths;
  const float inv_paths = 1.f / float(paths);
  for (VirtualLight& v : indirect_vpls) {
    v.power *= inv_paths;
    if (v.kind == VirtualLightKind::kMediumVPL || v.kind == VirtualLightKind::kVRL) {
      ++(v.kind == VirtualLightKind::kVRL ? set.stats.vrls : set.stats.medium_vpls);
      set.lights.push_back(v);
      continue;
    }
    if (v.caustic) ++set.stats.caustic_vpls;
    if (MaterialFlags(scene.materials()[v.material]) & kBxDFGlossy) ++set.stats.glossy_vpls;
    ++set.stats.surface_vpls;
    set.lights.push_back(v);
  }
  return set;
}

}  // namespace lightfarm
