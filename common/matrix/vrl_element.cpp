// Elements of virtual ray light (VRL) columns (Novák et al. 2012; Huo 2016, Sec. 3.1). A VRL is
// a particle's free flight y_s = b + s·ψ, s ∈ [0, ℓ], carrying the flux Φ that entered it; its
// light leaves y_s with density Φ · Tr(b→y_s) · σ_s(y_s) · p_g(ψ, ·) per unit length.
//
// VRL → surface point (Huo 2016, Eq. 5):
//   A = β ∫_0^ℓ Φ Tr(b→y_s) σ_s(y_s) p_g(ψ·ω_s) V̂(y_s, x) f_r(x) |cos θ_x| G(x, y_s) ds
// VRL → eye segment (Huo 2016, Eq. 3):
//   A = β ∫_0^ℓe ∫_0^ℓ Tr(a→x_t) σ_s(x_t) p_g(x_t) V̂(x_t, y_s) G(x_t, y_s)
//                      Φ Tr(b→y_s) σ_s(y_s) p_g(y_s) ds dt
// with ω_s the unit direction y_s → receiver, V̂ = visibility × transmittance (generalized
// visibility) and G = 1/max(d², d_min²) clamped like every virtual light.
//
// Sampling: equi-angular in s towards the surface point (Kulla & Fajardo 2012); for segments,
// s ∝ 1/(distance from y_s to the eye ray's line) and then t equi-angular towards y_s
// (Novák 2012, Sec. 4). Each element casts its `segment_samples` shadow rays as one batch.
#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "common/matrix/lighting_matrix.h"
#include "common/scene/phase.h"

namespace lightfarm {

namespace {

constexpr int kMaxVrlSamples = 64;

// Equi-angular sampling of a parameter on [0, len] of the line o + s·d (d unit) towards the
// point c: pdf ∝ 1/(D² + (s − Δ)²), uniform in the angle the line subtends at c.
struct EquiAngular {
  float delta = 0, dist = 0, theta_a = 0, theta_b = 0;
  EquiAngular(Vec3 o, Vec3 d, float len, Vec3 c) {
    delta = Dot(c - o, d);
    dist = std::max(Length(c - (o + d * delta)), 1e-7f);
    theta_a = std::atan2(-delta, dist);
    theta_b = std::atan2(len - delta, dist);
  }
  bool Valid() const { return theta_b > theta_a; }
  float Sample(float u, float len) const {
    return Clamp(delta + dist * std::tan(theta_a + u * (theta_b - theta_a)), 0.f, len);
  }
  float Pdf(float s) const {
    return dist / ((theta_b - theta_a) * (dist * dist + Sqr(s - delta)));
  }
};

// Novák 2012's VRL sampling: s on [0, len] of the VRL b + s·ψ with pdf ∝ 1/h(s), h(s) the
// distance from y_s to the (infinite) eye-ray line a + t·ω:
//   h(s)² = h0² + sin²θ (s − s0)²   (θ the angle between the lines, s0 the closest point),
// whose CDF is an asinh. h0 is floored so the pdf stays finite for intersecting lines (still a
// normalised pdf, just not exactly ∝ 1/h); near-parallel lines sample s uniformly.
struct InverseDistance {
  float s0 = 0, h0 = 0, sin_t = 0, a = 0, b = 0, len = 0;
  bool uniform = false;
  InverseDistance(Vec3 vrl_o, Vec3 vrl_d, float vrl_len, Vec3 eye_o, Vec3 eye_d, float h_floor) {
    len = vrl_len;
    auto perp = [&](Vec3 v) { return v - eye_d * Dot(v, eye_d); };
    Vec3 pw = perp(vrl_o - eye_o), pd = perp(vrl_d);
    float sin2 = LengthSquared(pd);
    if (!(sin2 > 1e-6f)) {
      uniform = true;
      return;
    }
    sin_t = std::sqrt(sin2);
    s0 = -Dot(pw, pd) / sin2;
    h0 = std::max(SafeSqrt(LengthSquared(pw) - Sqr(Dot(pw, pd)) / sin2), h_floor);
    a = std::asinh((0 - s0) * sin_t / h0);
    b = std::asinh((len - s0) * sin_t / h0);
    if (!(b > a)) uniform = true;
  }
  float Sample(float u) const {
    if (uniform) return u * len;
    return Clamp(s0 + h0 / sin_t * std::sinh(a + u * (b - a)), 0.f, len);
  }
  float Pdf(float s) const {
    if (uniform) return 1.f / len;
    return sin_t / ((b - a) * std::sqrt(h0 * h0 + Sqr(sin_t * (s - s0))));
  }
};

// A shadow ray from `from` to `to` (unnormalised direction, tfar just short of 1).
void SetShadowRay(RTCRay* ray, Vec3 from, Vec3 to, uint32_t id) {
  Vec3 dir = to - from;
  *ray = RTCRay{};
  ray->org_x = from.x; ray->org_y = from.y; ray->org_z = from.z;
  ray->dir_x = dir.x; ray->dir_y = dir.y; ray->dir_z = dir.z;
  ray->tnear = 0.f;
  ray->tfar = 1.f - 1e-4f;
  ray->mask = kMaskOpaque;
  ray->id = id;
}

// Per-sample data waiting for its shadow ray.
struct PendingSample {
  RGB value;
  Vec3 origin, dir;  // transmittance walk: origin + t·dir, dir unit, t ∈ [0, length]
  float length = 0;
  float unclamped_scale = 1;
  int16_t medium = -1;
};

// Casts an element's sample shadow rays as one batch and sums the visible samples, each times
// the transmittance of its connection (generalized visibility, Huo 2016 Sec. 3), keeping the
// clamp counters. Shared by both VRL element types.
RGB SumVisibleSamples(const Scene& scene, RTCRay* rays, const PendingSample* pending, size_t nrays,
                      Rng& rng, std::vector<RTCRay>* recorded, MatrixCounters* counters) {
  if (nrays == 0) return RGB(0.f);
  if (recorded) recorded->insert(recorded->end(), rays, rays + nrays);
  scene.Occluded(rays, nrays);
  counters->shadow_rays += nrays;
  RGBAccum sum;
  for (size_t r = 0; r < nrays; ++r) {
    if (!(rays[r].tfar >= 0.f)) continue;  // occluded
    const PendingSample& ps = pending[r];
    RGB v = ps.value * scene.TransmittanceAlong(ps.origin, ps.dir, ps.length, ps.medium, rng);
    ++counters->transmittance_evals;
    if (ps.unclamped_scale != 1.f) {
      double lum = double(v.Luminance());
      counters->clamp_lost += lum * double(ps.unclamped_scale - 1.f);
      counters->clamp_kept += lum;
    }
    sum.Add(v);
  }
  return sum.ToRGB();
}

}  // namespace

RGB LightingMatrix::VrlPointElement(uint32_t ri, uint32_t col, MatrixCounters* counters) const {
  const RowData& row = rows_[ri];
  const VirtualLight& L = lights_.lights[col];
  if (L.depth > row.light_depth_budget) return RGB(0.f);
  if (L.medium < 0 || !(L.length > 0)) return RGB(0.f);
  const Medium& med = scene_.media()[L.medium];
  const int n = std::clamp(segment_samples_, 1, kMaxVrlSamples);
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 2, ri, col}));
  const EquiAngular ea(L.p, L.n, L.length, row.p);
  if (!ea.Valid()) return RGB(0.f);
  const std::vector<Material>& materials = scene_.materials();
  alignas(16) std::array<RTCRay, kMaxVrlSamples> rays;
  std::array<PendingSample, kMaxVrlSamples> pending;
  size_t nrays = 0;
  for (int k = 0; k < n; ++k) {
    float u = Clamp((float(k) + rng.Uniform()) / float(n), 0.f, 0x1.fffffep-1f);
    float s = ea.Sample(u, L.length);
    float pdf = ea.Pdf(s);
    if (!(pdf > 0) || !std::isfinite(pdf)) continue;
    Vec3 y = L.p + L.n * s;
    Vec3 d = y - row.p;
    float dist2 = LengthSquared(d);
    if (!(dist2 > 0)) continue;
    float dist = std::sqrt(dist2);
    Vec3 w = d / dist;  // receiver → VRL point
    Vec3 wi_local = row.frame.ToLocal(w);
    // The geometric and shading normals must agree on the side, or light would leak.
    if (Dot(row.ng, w) * wi_local.z <= 0) continue;
    RGB f = EvalBSDF(materials[row.material], row.wo_local, wi_local, TransportMode::kRadiance);
    if (f.IsBlack()) continue;
    RGB sigma_s = med.sigma_s() * med.Density(y);
    if (sigma_s.IsBlack()) continue;
    // Light travelling along ψ scatters towards the receiver (-w).
    float phase = HenyeyGreenstein(-Dot(L.n, w), L.g);
    RGB tr_light = med.Transmittance({L.p, L.n, s}, rng);
    if (!med.homogeneous()) ++counters->transmittance_evals;
    float geometry = 1.f / std::max(dist2, clamp_distance2_);
    RGB value = row.throughput * f * L.power * sigma_s * tr_light *
                (phase * std::abs(wi_local.z) * geometry / (pdf * float(n)));
    if (value.IsBlack() || !value.IsFinite()) continue;
    Vec3 o = OffsetRayOrigin(row.p, row.ng, w);
    if (!IsFinite(o) || !IsFinite(y)) continue;  // never hand Embree a NaN ray
    SetShadowRay(&rays[nrays], o, y, uint32_t(nrays));
    PendingSample& ps = pending[nrays];
    ps.value = value;
    ps.origin = o;
    Vec3 od = y - o;
    float olen = Length(od);
    ps.dir = od / olen;
    ps.length = olen * (1.f - 1e-4f);
    ps.unclamped_scale = dist2 < clamp_distance2_ ? clamp_distance2_ / dist2 : 1.f;
    ps.medium = Dot(w, row.ng) > 0 ? row.medium_out : row.medium_in;
    ++nrays;
  }
  return SumVisibleSamples(scene_, rays.data(), pending.data(), nrays, rng, recorded_rays_, counters);
}

RGB LightingMatrix::VrlSegmentElement(uint32_t si, uint32_t col, MatrixCounters* counters) const {
  const EyeSegment& seg = receivers_.segments[si];
  const VirtualLight& L = lights_.lights[col];
  if (int(L.depth) + int(seg.depth) > max_depth_) return RGB(0.f);
  if (seg.medium < 0 || !(seg.length > 0) || L.medium < 0 || !(L.length > 0)) return RGB(0.f);
  const Medium& eye_med = scene_.media()[seg.medium];
  const Medium& light_med = scene_.media()[L.medium];
  const int n = std::clamp(segment_samples_, 1, kMaxVrlSamples);
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 3, si, col}));
  // The floor on the lines' distance: far below the clamp distance and the segments' scale.
  const float h_floor = 1e-4f * std::max({L.length, seg.length, clamp_distance_});
  const InverseDistance vrl_sampler(L.p, L.n, L.length, seg.o, seg.d, h_floor);
  // Latin-hypercube pairing of the strata of s and t: a shuffled stratum index for t.
  std::array<int, kMaxVrlSamples> t_stratum;
  for (int k = 0; k < n; ++k) t_stratum[size_t(k)] = k;
  for (int k = n - 1; k > 0; --k)
    std::swap(t_stratum[size_t(k)], t_stratum[size_t(rng.UniformInt(uint32_t(k + 1)))]);
  alignas(16) std::array<RTCRay, kMaxVrlSamples> rays;
  std::array<PendingSample, kMaxVrlSamples> pending;
  size_t nrays = 0;
  for (int k = 0; k < n; ++k) {
    float us = Clamp((float(k) + rng.Uniform()) / float(n), 0.f, 0x1.fffffep-1f);
    float ut = Clamp((float(t_stratum[size_t(k)]) + rng.Uniform()) / float(n), 0.f, 0x1.fffffep-1f);
    float s = vrl_sampler.Sample(us);
    float pdf_s = vrl_sampler.Pdf(s);
    Vec3 y = L.p + L.n * s;
    const EquiAngular ea(seg.o, seg.d, seg.length, y);
    if (!ea.Valid()) continue;
    float t = ea.Sample(ut, seg.length);
    float pdf_t = ea.Pdf(t);
    float pdf = pdf_s * pdf_t;
    if (!(pdf > 0) || !std::isfinite(pdf)) continue;
    Vec3 x = seg.o + seg.d * t;
    Vec3 d = y - x;
    float dist2 = LengthSquared(d);
    if (!(dist2 > 0)) continue;
    float dist = std::sqrt(dist2);
    Vec3 w = d / dist;  // eye point → VRL point
    RGB sigma_eye = eye_med.sigma_s() * eye_med.Density(x);
    RGB sigma_light = light_med.sigma_s() * light_med.Density(y);
    if (sigma_eye.IsBlack() || sigma_light.IsBlack()) continue;
    // Light travels ψ, scatters at y_s towards x (-w), then at x towards the camera (-seg.d).
    float phase = HenyeyGreenstein(-Dot(L.n, w), L.g) * HenyeyGreenstein(Dot(w, seg.d), eye_med.g());
    RGB tr = eye_med.Transmittance({seg.o, seg.d, t}, rng) * light_med.Transmittance({L.p, L.n, s}, rng);
    if (!eye_med.homogeneous()) ++counters->transmittance_evals;
    if (!light_med.homogeneous()) ++counters->transmittance_evals;
    float geometry = 1.f / std::max(dist2, clamp_distance2_);
    RGB value = seg.throughput * L.power * sigma_eye * sigma_light * tr *
                (phase * geometry / (pdf * float(n)));
    if (value.IsBlack() || !value.IsFinite()) continue;
    if (!IsFinite(x) || !IsFinite(y)) continue;  // never hand Embree a NaN ray
    SetShadowRay(&rays[nrays], x, y, uint32_t(nrays));
    PendingSample& ps = pending[nrays];
    ps.value = value;
    ps.origin = x;
    ps.dir = w;
    ps.length = dist * (1.f - 1e-4f);
    ps.unclamped_scale = dist2 < clamp_distance2_ ? clamp_distance2_ / dist2 : 1.f;
    ps.medium = seg.medium;
    ++nrays;
  }
  return SumVisibleSamples(scene_, rays.data(), pending.data(), nrays, rng, recorded_rays_, counters);
}

}  // namespace lightfarm
