#include "common/lights/emitters.h"

#include <algorithm>
#include <cmath>

#include "common/util/sampling.h"

namespace lightfarm {

std::vector<EmitterRef> CollectEmitters(const Scene& scene, float scene_radius) {
  std::vector<EmitterRef> out;
  for (uint32_t i = 0; i < scene.area_emitters().size(); ++i)
    out.push_back({EmitterRef::kArea, i, scene.area_emitters()[i].Power()});
  for (uint32_t i = 0; i < scene.point_emitters().size(); ++i) {
    const PointEmitter& e = scene.point_emitters()[i];
    float solid_angle = e.spot ? 2 * kPi * (1 - 0.5f * (e.cos_falloff_start + e.cos_falloff_end))
                               : 4 * kPi;
    out.push_back({EmitterRef::kPoint, i, e.intensity * solid_angle});
  }
  float disk = kPi * scene_radius * scene_radius;
  for (uint32_t i = 0; i < scene.distant_emitters().size(); ++i)
    out.push_back({EmitterRef::kDistant, i, scene.distant_emitters()[i].L * disk});
  for (uint32_t i = 0; i < scene.infinite_emitters().size(); ++i)
    out.push_back({EmitterRef::kInfinite, i,
                   scene.infinite_emitters()[i].AverageRadiance() * (4 * kPi * disk)});
  return out;
}

PowerPicker::PowerPicker(const std::vector<EmitterRef>& emitters) {
  for (const EmitterRef& e : emitters) {
    total_ += double(std::max(e.power.Luminance(), 0.f));
    cdf_.push_back(float(total_));
  }
}

size_t PowerPicker::Pick(float u, float* probability) const {
  const float x = u * float(total_);
  const size_t i = std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), x) - cdf_.begin(), cdf_.size() - 1);
  const float lo = i == 0 ? 0.f : cdf_[i - 1];
  *probability = (cdf_[i] - lo) / float(total_);
  return i;
}

EmitterSampler::EmitterSampler(const Scene& scene) : scene_(scene) {
  const Bounds3& b = scene.bounds();
  const float radius = b.Empty() ? 1.f : std::max(b.Radius(), 1e-3f);
  area_slot_.assign(scene.area_emitters().size(), -1);
  infinite_slot_.assign(scene.infinite_emitters().size(), -1);
  double total = 0;
  std::vector<double> weights;
  for (const EmitterRef& e : CollectEmitters(scene, radius)) {
    const float w = e.power.Luminance();
    if (!(w > 0) || !std::isfinite(w)) continue;  // emits nothing: never chosen, never hit with weight
    if (e.kind == EmitterRef::kArea) area_slot_[e.index] = int(emitters_.size());
    if (e.kind == EmitterRef::kInfinite) infinite_slot_[e.index] = int(emitters_.size());
    emitters_.push_back(e);
    weights.push_back(w);
    total += double(w);
  }
  double running = 0;
  for (double w : weights) {
    running += w;
    cdf_.push_back(running / total);
  }
  if (!cdf_.empty()) cdf_.back() = 1.0;
}

float EmitterSampler::SelectProbability(size_t slot) const {
  return float(cdf_[slot] - (slot == 0 ? 0.0 : cdf_[slot - 1]));
}

std::optional<LightSample> EmitterSampler::Sample(Vec3 p, float u_pick, Vec2 u) const {
  if (cdf_.empty()) return std::nullopt;
  const size_t slot = std::min<size_t>(
      std::upper_bound(cdf_.begin(), cdf_.end(), double(u_pick)) - cdf_.begin(), cdf_.size() - 1);
  const float select = SelectProbability(slot);
  const EmitterRef& e = emitters_[slot];
  LightSample s;
  switch (e.kind) {
    case EmitterRef::kArea: {
      const AreaEmitter& a = scene_.area_emitters()[e.index];
      scene_.SampleAreaEmitter(a, u, &s.p_light, &s.n_light);
      const Vec3 d = s.p_light - p;
      const float dist2 = LengthSquared(d);
      if (!(dist2 > 0)) return std::nullopt;
      s.wi = d / std::sqrt(dist2);
      const float cos_light = Dot(s.n_light, -s.wi);
      if (cos_light == 0.f || (!a.two_sided && cos_light < 0)) return std::nullopt;
      // Uniform by area (1/A) turned into solid angle at p: d² / (|cos θ_light| A).
      s.pdf = select * dist2 / (std::abs(cos_light) * a.area);
      s.L = a.L;
      s.area = true;
      break;
    }
    case EmitterRef::kPoint: {
      const PointEmitter& pe = scene_.point_emitters()[e.index];
      const Vec3 d = pe.position - p;
      const float dist2 = LengthSquared(d);
      if (!(dist2 > 0)) return std::nullopt;
      s.wi = d / std::sqrt(dist2);
      s.p_light = pe.position;
      s.L = pe.intensity * (pe.Falloff(-s.wi) / dist2);
      s.delta = true;
      s.pdf = select;
      break;
    }
    case EmitterRef::kDistant: {
      const DistantEmitter& de = scene_.distant_emitters()[e.index];
      s.wi = -de.direction;
      s.L = de.L;
      s.delta = true;
      s.infinite_distance = true;
      s.pdf = select;
      break;
    }
    case EmitterRef::kInfinite: {
      const InfiniteEmitter& ie = scene_.infinite_emitters()[e.index];
      float pdf = 0;
      s.wi = ie.SampleDirection(u, &pdf);
      if (!(pdf > 0)) return std::nullopt;
      s.L = ie.Le(s.wi);
      s.infinite_distance = true;
      s.pdf = select * pdf;
      break;
    }
  }
  if (!(s.pdf > 0) || s.L.IsBlack() || !s.L.IsFinite()) return std::nullopt;
  return s;
}

float EmitterSampler::PdfArea(uint32_t emitter, Vec3 p, const SurfaceHit& hit) const {
  if (emitter >= area_slot_.size() || area_slot_[emitter] < 0) return 0.f;
  const AreaEmitter& a = scene_.area_emitters()[emitter];
  const Vec3 d = hit.p - p;
  const float dist2 = LengthSquared(d);
  const float cos_light = std::abs(Dot(hit.ng, d)) / std::sqrt(dist2);
  if (!(cos_light > 0) || !(a.area > 0)) return 0.f;
  return SelectProbability(size_t(area_slot_[emitter])) * dist2 / (cos_light * a.area);
}

float EmitterSampler::PdfInfinite(uint32_t emitter, Vec3 w) const {
  if (emitter >= infinite_slot_.size() || infinite_slot_[emitter] < 0) return 0.f;
  return SelectProbability(size_t(infinite_slot_[emitter])) * scene_.infinite_emitters()[emitter].Pdf(w);
}

EmittedRay SampleEmittedRay(const Scene& scene, const EmitterRef& e, Vec3 center, float radius,
                          Rng& rng) {
  EmissionSample u;
  u.u1 = {rng.Uniform(), rng.Uniform()};
  u.u2 = {rng.Uniform(), rng.Uniform()};
  // Drawn after the two points, and only for a two-sided area light.
  if (e.kind == EmitterRef::kArea && scene.area_emitters()[e.index].two_sided) u.side = rng.Uniform();
  return SampleEmittedRay(scene, e, center, radius, u);
}

EmittedRay SampleEmittedRay(const Scene& scene, const EmitterRef& e, Vec3 center, float radius,
                            const EmissionSample& u) {
  const Vec2 u1 = u.u1, u2 = u.u2;
  EmittedRay out;
  switch (e.kind) {
    case EmitterRef::kArea: {
      const AreaEmitter& a = scene.area_emitters()[e.index];
      Vec3 p, n;
      scene.SampleAreaEmitter(a, u1, &p, &n);
      Vec3 local = SampleCosineHemisphere(u2);
      float side = 1.f;
      if (a.two_sided && u.side < 0.5f) side = -1.f;
      Frame f(n * side);
      Vec3 d = f.FromLocal(local);
      if (local.z <= 0) return out;
      // Φ-weighted: pdf = 1/A · cos/π (· 1/2 two-sided); L·cos/pdf = L·A·π (·2).
      out.beta = a.L * (a.area * kPi * (a.two_sided ? 2.f : 1.f));
      out.ray = {OffsetRayOrigin(p, n, d), d, kInfinity};
      out.ng = n;
      const Shape& sh = scene.shapes()[a.shape];
      out.medium = sh.medium_transition ? (Dot(d, n) > 0 ? sh.outside_medium : sh.inside_medium)
                                        : sh.outside_medium;
      break;
    }
    case EmitterRef::kPoint: {
      const PointEmitter& pe = scene.point_emitters()[e.index];
      Vec3 d;
      float pdf;
      if (pe.spot) {
        Frame f(pe.axis);
        d = f.FromLocal(SampleUniformCone(u1, pe.cos_falloff_end));
        pdf = UniformConePdf(pe.cos_falloff_end);
      } else {
        d = SampleUniformSphere(u1);
        pdf = kUniformSpherePdf;
      }
      out.beta = pe.intensity * (pe.Falloff(d) / pdf);
      out.ray = {pe.position, d, kInfinity};
      out.medium = pe.medium;
      break;
    }
    case EmitterRef::kDistant: {
      const DistantEmitter& de = scene.distant_emitters()[e.index];
      Frame f(de.direction);
      Vec2 pd = SampleUniformDiskConcentric(u1) * radius;
      Vec3 o = center - de.direction * radius + f.s * pd.x + f.t * pd.y;
      out.beta = de.L * (kPi * radius * radius);
      out.ray = {o, de.direction, kInfinity};
      out.medium = de.medium;
      break;
    }
    case EmitterRef::kInfinite: {
      const InfiniteEmitter& ie = scene.infinite_emitters()[e.index];
      float pdf;
      Vec3 w = ie.SampleDirection(u1, &pdf);  // towards the environment
      if (!(pdf > 0)) return out;
      Frame f(-w);
      Vec2 pd = SampleUniformDiskConcentric(u2) * radius;
      Vec3 o = center + w * radius + f.s * pd.x + f.t * pd.y;
      out.beta = ie.Le(w) * (kPi * radius * radius / pdf);
      out.ray = {o, -w, kInfinity};
      out.medium = ie.medium;
      break;
    }
  }
  out.valid = out.beta.IsFinite() && !out.beta.IsBlack() && IsFinite(out.ray.o) &&
              IsFinite(out.ray.d);
  return out;
}

RGB LightSampleVisibility(const Scene& scene, Vec3 o, const LightSample& ls, int medium, Rng& rng,
                          std::vector<RTCRay>* recorded) {
  Vec3 dir = ls.wi;
  float tfar = kInfinity;
  if (!ls.infinite_distance) {
    const Vec3 target = ls.area ? OffsetRayOrigin(ls.p_light, ls.n_light, -ls.wi) : ls.p_light;
    dir = target - o;
    tfar = 1.f - 1e-4f;
  }
  if (!IsFinite(o) || !IsFinite(dir)) return RGB(0.f);
  RTCRay ray{};
  ray.org_x = o.x; ray.org_y = o.y; ray.org_z = o.z;
  ray.dir_x = dir.x; ray.dir_y = dir.y; ray.dir_z = dir.z;
  ray.tnear = 0.f;
  ray.tfar = tfar;
  ray.mask = kMaskOpaque;
  if (recorded) recorded->push_back(ray);
  scene.Occluded(&ray, 1);
  if (!(ray.tfar >= 0.f)) return RGB(0.f);  // Embree sets tfar = -inf when occluded
  if (!scene.has_media()) return RGB(1.f);
  // Ratio tracking through every medium the segment crosses (interfaces do not occlude).
  return ls.infinite_distance ? scene.TransmittanceAlong(o, ls.wi, kInfinity, medium, rng)
                              : scene.Transmittance(o, o + dir * tfar, medium, rng);
}

}  // namespace lightfarm
