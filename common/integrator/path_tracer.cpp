#include "common/integrator/path_tracer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>

#include "common/scene/phase.h"
#include "common/util/sampling.h"

namespace lightfarm {

namespace {

constexpr int kMaxPassthrough = 64;  // interface crossings without scattering before giving up

// The first vertex of a windowed path (FirstVertexWeight::window) in `med` along `ray`, whose
// next surface (if `found`) is at ray.tmax. Tentative collisions at the medium's majorant σ̄
// choose between the medium and the surface as delta tracking does (the medium with probability
// P = 1 − e^{−σ̄·tmax}; always when no surface is in the window), but a medium vertex is drawn
// from the exponential truncated to the window and weighted by σ_s(y)·Tr(o, y) / (P·pdf), the
// surface by Tr(o, surface) / (1 − P): every sample lands in the window, and in a homogeneous
// medium the weights are the albedo and 1, as delta tracking's.
FreePathSample ForcedFreePath(const Medium& med, const MediumRay& ray, bool found, Rng& rng) {
  FreePathSample fp;
  fp.t = ray.tmax;
  const float majorant = med.sigma_t().Max() * med.MaxDensity();
  const float tau = majorant * ray.tmax;
  const float p_collide = -std::expm1(-tau);
  const float p_medium = found ? p_collide : 1.f;
  if (!(p_medium > 0) || !(ray.tmax > 0)) {  // nothing scatters here (an empty medium)
    fp.weight = found ? med.Transmittance(ray, rng) : RGB(0.f);
    return fp;
  }
  if (rng.Uniform() < p_medium) {
    fp.scattered = true;
    const float u = rng.Uniform();
    float pdf = 1.f / ray.tmax;  // the truncated exponential's limit as σ̄·tmax → 0
    fp.t = u * ray.tmax;
    if (tau > 1e-4f) {
      fp.t = std::min(-std::log1p(-u * p_collide) / majorant, ray.tmax);
      pdf = majorant * std::exp(-majorant * fp.t) / p_collide;
    }
    const RGB sigma_s = med.sigma_s() * med.Density(ray.o + ray.d * fp.t);
    if (sigma_s.IsBlack() || !(pdf > 0)) {
      fp.weight = RGB(0.f);
      return fp;
    }
    fp.weight = sigma_s * med.Transmittance({ray.o, ray.d, fp.t}, rng) / (p_medium * pdf);
  } else {
    fp.weight = med.Transmittance(ray, rng) / (1.f - p_medium);
  }
  return fp;
}

}  // namespace

PathTracer::PathTracer(const Scene& scene, const PathTracerOptions& options)
    : scene_(scene), options_(options), lights_(scene) {}

float PathTracer::HitWeight(float pdf_scatter, float pdf_light) const {
  switch (options_.strategy) {
    case PathStrategy::kBSDF: return 1.f;
    case PathStrategy::kLight: return 0.f;
    case PathStrategy::kMIS: break;
  }
  return PowerHeuristic(pdf_scatter, pdf_light);
}

RGB PathTracer::ShadowRay(Vec3 o, const LightSample& ls, int medium, Rng& rng,
                          PathCounters* counters) const {
  ++counters->shadow_rays;
  return LightSampleVisibility(scene_, o, ls, medium, rng, record_shadow_);
}

RGB PathTracer::LightAtSurface(const SurfaceHit& hit, const Material& m, const Frame& frame,
                               Vec3 wo_local, int medium, Rng& rng, PathCounters* counters,
                               const FirstVertexWeight* first) const {
  const float u_pick = rng.Uniform();
  const Vec2 u{rng.Uniform(), rng.Uniform()};
  const std::optional<LightSample> ls = lights_.Sample(hit.p, u_pick, u);
  if (!ls) return RGB(0.f);
  const Vec3 wi_local = frame.ToLocal(ls->wi);
  RGB f = EvalBSDF(m, wo_local, wi_local, TransportMode::kRadiance) * std::abs(wi_local.z);
  if (first) f *= first->arrival(wo_local, wi_local);
  if (f.IsBlack()) return RGB(0.f);
  const int start = scene_.MediumAfter(hit, ls->wi, medium);
  const RGB tr = ShadowRay(OffsetRayOrigin(hit.p, hit.ng, ls->wi), *ls, start, rng, counters);
  if (tr.IsBlack()) return RGB(0.f);
  float w = 1.f;
  if (!ls->delta && options_.strategy == PathStrategy::kMIS)
    w = PowerHeuristic(ls->pdf, PdfBSDF(m, wo_local, wi_local, TransportMode::kRadiance));
  return f * ls->L * tr * (w / ls->pdf);
}

RGB PathTracer::LightInMedium(Vec3 p, Vec3 d_in, int medium, Rng& rng, PathCounters* counters) const {
  const float u_pick = rng.Uniform();
  const Vec2 u{rng.Uniform(), rng.Uniform()};
  const std::optional<LightSample> ls = lights_.Sample(p, u_pick, u);
  if (!ls) return RGB(0.f);
  // Travel-direction convention (phase.h): cos between the incoming and the outgoing direction.
  const float phase = HenyeyGreenstein(Dot(d_in, ls->wi), scene_.media()[medium].g());
  if (!(phase > 0)) return RGB(0.f);
  const RGB tr = ShadowRay(p, *ls, medium, rng, counters);
  if (tr.IsBlack()) return RGB(0.f);
  float w = 1.f;
  if (!ls->delta && options_.strategy == PathStrategy::kMIS) w = PowerHeuristic(ls->pdf, phase);
  return ls->L * tr * (phase * w / ls->pdf);
}

RGB PathTracer::Li(Ray ray, Rng& rng, PathCounters* counters) const {
  return Li(ray, scene_.camera_medium(), options_.max_depth, rng, counters);
}

RGB PathTracer::Li(Ray ray, int medium, int max_depth, Rng& rng, PathCounters* counters,
                   const FirstVertexWeight* first) const {
  ++counters->paths;
  RGB L(0.f), beta(1.f);
  float eta_scale = 1.f;
  int depth = 0, passthrough = 0;
  // The last scattering vertex and the density its direction was sampled with, for the MIS
  // weight of an emitter the ray finds; `specular`: that density was a delta (or the camera's).
  bool specular = true;
  Vec3 prev_p = ray.o;
  float prev_pdf = 0;
  const bool use_lights = options_.strategy != PathStrategy::kBSDF && !lights_.empty();
  // A windowed first vertex (FirstVertexWeight::window): the distance travelled towards it so far
  // (interfaces crossed) and its weight at distance d.
  const float window = first ? first->window : 0.f;
  float travelled = 0;
  const auto window_weight = [&](float d) { return std::max(0.f, 1.f - Sqr(d / window)); };
  for (;;) {
    const bool windowed = window > 0 && depth == 0;
    if (windowed) ray.tmax = window - travelled;
    SurfaceHit hit;
    if (record_closest_) record_closest_->push_back(ray);
    const bool found = scene_.Intersect(ray, &hit);
    bool scattered = false;
    if (medium >= 0) {
      const Medium& med = scene_.media()[medium];
      const FreePathSample fp =
          windowed ? ForcedFreePath(med, {ray.o, ray.d, found ? hit.t : ray.tmax}, found, rng)
                   : med.SampleFreePath({ray.o, ray.d, found ? hit.t : kInfinity}, rng);
      beta *= fp.weight;
      if (beta.IsBlack() || !beta.IsFinite()) break;
      if (fp.scattered) {
        if (windowed) beta *= window_weight(travelled + fp.t);
        if (first && depth == 0) beta *= first->other;
        if (depth++ >= max_depth) break;
        ++counters->vertices;
        passthrough = 0;
        const Vec3 p = ray.o + ray.d * fp.t;
        if (use_lights) L += beta * LightInMedium(p, ray.d, medium, rng, counters);
        float pdf = 0;
        const Vec3 wi = SampleHenyeyGreenstein(ray.d, med.g(), rng.Uniform(), rng.Uniform(), &pdf);
        // HG is sampled exactly: phase / pdf = 1, beta is unchanged.
        scattered = true;
        specular = false;
        prev_p = p;
        prev_pdf = pdf;
        ray = {p, wi, kInfinity};
      }
    }
    if (!scattered) {
      // The ray reached its surface (or escaped) without scattering in a medium.
      if (!found && windowed) break;  // nothing within the window
      if (!found) {
        ++counters->escaped;
        for (uint32_t i = 0; i < scene_.infinite_emitters().size(); ++i) {
          const RGB Le = scene_.infinite_emitters()[i].Le(ray.d);
          if (Le.IsBlack()) continue;
          const float w = specular ? 1.f : HitWeight(prev_pdf, lights_.PdfInfinite(i, ray.d));
          L += beta * Le * w;
        }
        break;
      }
      const Vec3 wo = -ray.d;
      const Shape& shape = scene_.shapes()[hit.shape];
      // The first vertex of a weighted path (FirstVertexWeight): the next surface that scatters.
      const FirstVertexWeight* at_first = depth == 0 ? first : nullptr;
      const Material& m = scene_.materials()[shape.material];
      const uint32_t flags = MaterialFlags(m);
      const float in_window = windowed ? window_weight(travelled + hit.t) : 1.f;
      if (shape.area_emitter >= 0) {
        const RGB Le = scene_.EmittedRadiance(hit, wo);
        if (!Le.IsBlack()) {
          float w = specular ? 1.f
                             : HitWeight(prev_pdf, lights_.PdfArea(uint32_t(shape.area_emitter), prev_p, hit));
          if (at_first) w *= at_first->emission * in_window;
          L += beta * Le * w;
        }
      }
      if (flags == 0) {  // a surface that only bounds a medium: cross it, no vertex
        if (++passthrough > kMaxPassthrough) break;
        if (windowed) travelled += hit.t;
        medium = scene_.MediumAfter(hit, ray.d, medium);
        ray.o = OffsetRayOrigin(hit.p, hit.ng, ray.d);
        ray.tmax = kInfinity;
        continue;
      }
      beta *= in_window;
      if (depth++ >= max_depth) break;
      ++counters->vertices;
      passthrough = 0;
      const Frame frame(hit.ns);
      const Vec3 wo_local = frame.ToLocal(wo);
      if (use_lights && !IsPurelySpecular(flags))
        L += beta * LightAtSurface(hit, m, frame, wo_local, medium, rng, counters, at_first);
      const float uc = rng.Uniform();
      const Vec2 u{rng.Uniform(), rng.Uniform()};
      const std::optional<BSDFSample> bs = SampleBSDF(m, wo_local, uc, u, TransportMode::kRadiance);
      if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) break;
      const Vec3 wi = frame.FromLocal(bs->wi);
      beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
      if (at_first) beta *= bs->IsSpecular() ? at_first->specular : at_first->arrival(wo_local, bs->wi);
      if (bs->flags & kBxDFTransmission) eta_scale *= bs->eta * bs->eta;
      specular = bs->IsSpecular();
      prev_p = hit.p;
      prev_pdf = bs->pdf;
      medium = scene_.MediumAfter(hit, wi, medium);
      ray = {OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity};
    }
    if (beta.IsBlack() || !beta.IsFinite()) break;
    // Russian roulette (pbrt-v4): survive with the throughput's largest channel, after two vertices.
    const float rr = (beta * eta_scale).Max();
    if (rr < 1.f && depth > 1) {
      const float q = std::max(0.f, 1.f - rr);
      if (rng.Uniform() < q) {
        ++counters->roulette;
        break;
      }
      beta = beta / (1.f - q);
    }
  }
  return L;
}

}  // namespace lightfarm
