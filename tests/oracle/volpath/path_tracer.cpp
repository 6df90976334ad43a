#include "tests/oracle/volpath/path_tracer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/scene/phase.h"
#include "common/util/sampling.h"

namespace lightfarm {

VolumetricPathTracer::VolumetricPathTracer(const Scene& scene, const VolpathCheckOptions& opt)
    : scene_(scene), opt_(opt),
      max_depth_(opt.max_depth >= 0 ? opt.max_depth : scene.hints().max_depth) {
  for (const Medium& m : scene.media())
    if (!m.homogeneous())
      throw std::runtime_error("volpath-check handles homogeneous media only (medium " +
                               m.name() + ")");
  if (!scene.point_emitters().empty() || !scene.distant_emitters().empty() ||
      !scene.infinite_emitters().empty())
    throw std::runtime_error("volpath-check handles area emitters only");
  double total = 0;
  for (const AreaEmitter& e : scene.area_emitters()) {
    total += double(e.Power().Luminance());
    emitter_cdf_.push_back(total);
  }
  for (double& c : emitter_cdf_) c /= total;
}

RGB VolumetricPathTracer::Li(Ray ray, Rng& rng) const {
  RGB L(0.f), beta(1.f);
  int depth = 0;
  bool emission_counts = true;  // camera ray, or previous vertex specular
  int nonspecular_vertices = 0;
  int medium = scene_.camera_medium();
  for (int guard = 0; guard < 10000; ++guard) {
    SurfaceHit hit;
    bool found = scene_.Intersect(ray, &hit);
    float tmax = found ? hit.t : kInfinity;
    if (medium >= 0) {
      const Medium& med = scene_.media()[medium];
      float t;
      bool scattered = SampleCollision(med, tmax, rng, &t, &beta);
      if (beta.IsBlack()) return L;
      if (scattered) {
        if (depth++ >= max_depth_) return L;
        Vec3 x = ray.o + ray.d * t;
        // Next-event estimation through the phase function (travel-direction cosine: light
        // arrives travelling -wl, leaves travelling -ray.d).
        Vec3 wl;
        RGB Ld = SampleEmitter(x, nullptr, medium, rng, &wl);
        if (!Ld.IsBlack())
          L += beta * Ld * HenyeyGreenstein(Dot(wl, ray.d), med.g());
        float pdf;
        Vec3 wn = SampleHenyeyGreenstein(ray.d, med.g(), rng.Uniform(), rng.Uniform(), &pdf);
        // f/pdf = 1 for sampling the phase function exactly.
        ray = {x, wn, kInfinity};
        emission_counts = false;
        ++nonspecular_vertices;
        continue;
      }
    }
    if (!found) {
      if (emission_counts) L += beta * scene_.EnvironmentRadiance(ray.d);
      return L;
    }
    Vec3 wo = -ray.d;
    const Shape& shape = scene_.shapes()[hit.shape];
    const Material& m = scene_.materials()[shape.material];
    uint32_t flags = MaterialFlags(m);
    if (flags == 0) {  // interface: not a vertex
      medium = scene_.MediumAfter(hit, ray.d, medium);
      ray = {OffsetRayOrigin(hit.p, hit.ng, ray.d), ray.d, kInfinity};
      continue;
    }
    if (emission_counts) L += beta * scene_.EmittedRadiance(hit, wo);
    if (depth++ == max_depth_) return L;
    Frame frame(hit.ns);
    Vec3 wo_local = frame.ToLocal(wo);
    if (!IsPurelySpecular(flags)) {
      Vec3 wl;
      RGB Ld = SampleEmitter(hit.p, &hit, medium, rng, &wl);
      if (!Ld.IsBlack()) {
        Vec3 wl_local = frame.ToLocal(wl);
        L += beta * Ld * EvalBSDF(m, wo_local, wl_local, TransportMode::kRadiance) *
             std::abs(wl_local.z);
      }
    }
    auto bs = SampleBSDF(m, wo_local, rng.Uniform(), {rng.Uniform(), rng.Uniform()},
                         TransportMode::kRadiance);
    if (!bs || !(bs->pdf > 0) || bs->f.IsBlack()) return L;
    Vec3 wi = frame.FromLocal(bs->wi);
    beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
    if (!beta.IsFinite() || beta.IsBlack()) return L;
    if (!bs->IsSpecular()) ++nonspecular_vertices;
    emission_counts = bs->IsSpecular() &&
                      !(opt_.no_emitted_after_specular && nonspecular_vertices > 0) &&
                      !(opt_.no_direct_caustics && nonspecular_vertices == 1);
    medium = scene_.MediumAfter(hit, wi, medium);
    ray = {OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity};
  }
  return L;
}

// Delta tracking in a homogeneous medium over (0, tmax), real collisions at the majorant
// max_c σ_t,c. True at a scattering collision at *t; false when the ray reaches tmax or is
// absorbed (then *beta is black). *beta takes the per-channel event weights (all 1 for grey
// media, where this is analog tracking).
bool VolumetricPathTracer::SampleCollision(const Medium& med, float tmax, Rng& rng, float* t,
                                         RGB* beta) const {
  const RGB st = med.sigma_t(), ss = med.sigma_s(), sa = med.sigma_a();
  const float smaj = st.Max();
  if (!(smaj > 0)) return false;
  const float ps = ss.Average() / smaj, pa = sa.Average() / smaj;
  const float pn = std::max(0.f, 1.f - ps - pa);
  float tt = 0;
  for (int guard = 0; guard < 1000000; ++guard) {
    tt += -std::log(1.f - rng.Uniform()) / smaj;
    if (!(tt < tmax)) return false;
    float u = rng.Uniform() * (ps + pa + pn);
    if (u < ps) {
      *t = tt;
      *beta *= ss / (smaj * ps);
      return true;
    }
    if (u < ps + pa) {
      *beta = RGB(0.f);
      return false;
    }
    *beta *= (RGB(smaj) - st) / (smaj * pn);
  }
  return false;
}

// Unbiased estimate of emitted radiance arriving at x from one sampled emitter point, divided
// by the sampling pdf (solid angle), times visibility and transmittance; *wl is the unit
// direction towards the light sample. `hit` non-null: x is on that surface (origin offset and
// the medium on the side of wl).
RGB VolumetricPathTracer::SampleEmitter(Vec3 x, const SurfaceHit* hit, int medium, Rng& rng,
                                       Vec3* wl) const {
  if (emitter_cdf_.empty()) return RGB(0.f);
  float u = rng.Uniform();
  size_t i = 0;
  while (i + 1 < emitter_cdf_.size() && double(u) >= emitter_cdf_[i]) ++i;
  double p_pick = emitter_cdf_[i] - (i == 0 ? 0.0 : emitter_cdf_[i - 1]);
  const AreaEmitter& e = scene_.area_emitters()[i];
  Vec3 p, n;
  scene_.SampleAreaEmitter(e, {rng.Uniform(), rng.Uniform()}, &p, &n);
  Vec3 d = p - x;
  float dist2 = LengthSquared(d);
  if (!(dist2 > 0)) return RGB(0.f);
  float dist = std::sqrt(dist2);
  Vec3 w = d / dist;
  float cos_l = -Dot(w, n);
  if (!e.two_sided && cos_l <= 0) return RGB(0.f);
  *wl = w;
  Vec3 o = x;
  int med = medium;
  if (hit) {
    o = OffsetRayOrigin(hit->p, hit->ng, w);
    med = scene_.MediumAfter(*hit, w, medium);
  }
  RGB tr = ShadowTransmittance(o, p, med);
  if (tr.IsBlack()) return RGB(0.f);
  // pdf_area = 1 / area; solid-angle conversion |cos_l| / dist².
  float g = std::abs(cos_l) / dist2;
  return e.L * tr * float(double(g) * double(e.area) / p_pick);
}

// Visibility and transmittance from o to p (p on an emitter): blocked by any surface with a
// material; interfaces switch the medium; homogeneous attenuation exp(-σ_t·length) per piece.
RGB VolumetricPathTracer::ShadowTransmittance(Vec3 o, Vec3 p, int medium) const {
  RGB T(1.f);
  Vec3 cur = o;
  for (int crossings = 0; crossings < 256; ++crossings) {
    Vec3 d = p - cur;
    float len = Length(d);
    if (!(len > 0)) return T;
    d = d / len;
    // Stop just short of the emitter so that it does not occlude itself.
    float tmax = len * (1.f - 1e-4f);
    SurfaceHit hit;
    bool found = scene_.Intersect({cur, d, tmax}, &hit);
    float seg = found ? hit.t : len;
    if (medium >= 0) T *= Exp(scene_.media()[medium].sigma_t() * -seg);
    if (!found) return T;
    if (MaterialFlags(scene_.materials()[scene_.shapes()[hit.shape].material]) != 0)
      return RGB(0.f);
    medium = scene_.MediumAfter(hit, d, medium);
    cur = OffsetRayOrigin(hit.p, hit.ng, d);
  }
  return RGB(0.f);
}

PathTracedImage RenderPathTraced(const Scene& scene, const VolpathCheckOptions& opt) {
  VolumetricPathTracer pt(scene, opt);
  const int w = scene.hints().width, h = scene.hints().height;
  PathTracedImage out{Image(w, h), Image(w, h), pt.max_depth()};
  Image& img = out.mean;
  Image& var = out.variance_of_mean;
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      Rng rng(HashSeed({opt.seed, uint64_t(RngStream::kCameraSample), uint64_t(y) * w + x}));
      RGBAccum sum, sum2;
      for (int s = 0; s < opt.spp; ++s) {
        Vec2 pf{float(x) + rng.Uniform(), float(y) + rng.Uniform()};
        Ray ray = scene.camera().GenerateRay(pf, {rng.Uniform(), rng.Uniform()});
        RGB L = pt.Li(ray, rng);
        if (!L.IsFinite()) L = RGB(0.f);
        if (L.Max() > opt.max_component) L *= opt.max_component / L.Max();
        sum.Add(L);
        sum2.Add(L * L);
      }
      double n = opt.spp;
      RGB mean(float(sum.r / n), float(sum.g / n), float(sum.b / n));
      img.at(x, y) = mean;
      // Variance of the pixel mean.
      var.at(x, y) = RGB(float((sum2.r / n - sum.r / n * sum.r / n) / n),
                         float((sum2.g / n - sum.g / n * sum.g / n) / n),
                         float((sum2.b / n - sum.b / n * sum.b / n) / n));
    }
  });
  return out;
}

}  // namespace lightfarm
