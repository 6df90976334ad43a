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
// visibility) and G = 1/max(d², d_min²) clamped like every virtual light. An unclamped VRL
// element is ~1/h for a VRL passing at h from a point, and for two nearly parallel lines at h
// (a distant light's first flights beside an orthographic camera's rays), unbounded; the clamp
// keeps every element bounded at the price of the light of pairs closer than d_min
// (docs/methods/media-elements.md measures it).
//
// Sampling (media_sampling.h), `segment_samples` samples per element mixed by the balance
// heuristic: a fraction `density_fraction` (MatrixOptions; in grid media) where the media scatter (s ∝ σ_s·Tr along the VRL, t ∝
// σ_s·Tr along the eye segment, from their MediumTracks, so no sample lands in empty space), the
// rest where the geometry term peaks (VRL → point: s equi-angular towards the point, Kulla &
// Fajardo 2012; VRL → segment: s ∝ 1/(distance to the eye ray's line), then t equi-angular
// towards y_s, Novák 2012). Tr(b→y_s) and Tr(a→x_t) are the tracks' exact values; the
// connection's transmittance is ratio-tracked. Each element casts its shadow rays as one batch.
#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "common/matrix/lighting_matrix.h"
#include "common/matrix/media_sampling.h"
#include "common/scene/phase.h"

namespace lightfarm {

namespace {

constexpr int kMaxVrlSamples = 64;

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
  MediumTrack light_scratch;
  const MediumTrack& light = LightTrack(col, &light_scratch);
  if (light.empty()) return RGB(0.f);
  const StrategyMix mix(std::clamp(segment_samples_, 1, kMaxVrlSamples), DensityFraction(L.medium, -1));
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 2, ri, col}));
  const EquiAngular ea(L.p, L.n, L.length, row.p);
  const std::vector<Material>& materials = scene_.materials();
  alignas(16) std::array<RTCRay, kMaxVrlSamples> rays;
  std::array<PendingSample, kMaxVrlSamples> pending;
  size_t nrays = 0;
  for (int k = 0; k < mix.n; ++k) {
    // s where the VRL scatters, or equi-angular towards the point (the 1/d² peak).
    float u;
    float s, pdf_density;
    size_t where;
    if (mix.First(k, rng, &u)) {
      s = light.Sample(u, &pdf_density, &where);
    } else {
      if (!ea.Valid()) continue;
      s = ea.Sample(u);
      where = light.Locate(s);
      pdf_density = light.Pdf(s, where);
    }
    const float weight = mix.Weight(pdf_density, ea.Valid() ? ea.Pdf(s) : 0.f);
    if (!(weight > 0)) continue;
    const MediumTrack::Point lp = light.At(s, where);
    if (lp.sigma_s.IsBlack()) continue;
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
    // Light travelling along ψ scatters towards the receiver (-w).
    float phase = HenyeyGreenstein(-Dot(L.n, w), L.g);
    float geometry = 1.f / std::max(dist2, clamp_distance2_);
    RGB value = row.throughput * f * L.power * lp.sigma_s * lp.tr *
                (phase * std::abs(wi_local.z) * geometry * weight);
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
  const EyeSegment& row = receivers_.segments[si];
  const VirtualLight& L = lights_.lights[col];
  if (int(L.depth) + int(row.depth) > max_depth_) return RGB(0.f);
  if (L.medium < 0 || !(L.length > 0)) return RGB(0.f);
  MediumTrack eye_scratch, light_scratch;
  const MediumTrack& light = LightTrack(col, &light_scratch);
  if (light.empty()) return RGB(0.f);
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 3, si, col}));
  // With coverage each sample integrates along one of the row's pieces (SegmentRayFor). Its
  // piece is uniform whatever its strategy and stratum (the first piece is random), and the
  // piece's probability cancels in the balance heuristic's weight, so the element is unbiased
  // for the mean over the pieces with the strategies' counts and strata as without coverage.
  const uint32_t first_piece = FirstPieceDraw(row, rng);
  const int n = std::clamp(segment_samples_, 1, kMaxVrlSamples);
  alignas(16) std::array<RTCRay, kMaxVrlSamples> rays;
  std::array<PendingSample, kMaxVrlSamples> pending;
  size_t nrays = 0;
  SegmentRay ray{};  // the same for every sample without coverage
  for (int k = 0; k < n; ++k) {
    if (k == 0 || row.pieces > 1) ray = SegmentRayFor(si, first_piece + uint32_t(k), &eye_scratch);
    const EyeSegment& seg = *ray.seg;
    const MediumTrack& eye = *ray.track;
    if (seg.medium < 0 || !(seg.length > 0) || eye.empty()) continue;
    const Medium& eye_med = scene_.media()[seg.medium];
    const StrategyMix mix(n, DensityFraction(L.medium, seg.medium));
    // The floor on the lines' distance: far below the clamp distance and the segments' scale.
    const float h_floor = 1e-4f * std::max({L.length, seg.length, clamp_distance_});
    const InverseDistance vrl_sampler(L.p, L.n, L.length, seg.o, seg.d, h_floor);
    // Strategy 1: s and t where the VRL and the eye segment scatter. Strategy 2 (Novák 2012):
    // s ∝ 1/(distance to the eye ray's line), then t equi-angular towards y_s.
    float u;
    const bool density = mix.First(k, rng, &u);
    const float u2 = rng.Uniform();
    float s, t = 0, pdf_s_density = 0, pdf_t_density = 0;
    size_t s_where, t_where = MediumTrack::kOutside;
    if (density) {
      s = light.Sample(u, &pdf_s_density, &s_where);
      t = eye.Sample(u2, &pdf_t_density, &t_where);
    } else {
      s = vrl_sampler.Sample(u);
      s_where = light.Locate(s);
      pdf_s_density = light.Pdf(s, s_where);
    }
    const Vec3 y = L.p + L.n * s;
    const EquiAngular ea(seg.o, seg.d, seg.length, y);
    if (!density) {
      if (!ea.Valid()) continue;
      t = ea.Sample(u2);
      t_where = eye.Locate(t);
      pdf_t_density = eye.Pdf(t, t_where);
    }
    const float weight = mix.Weight(pdf_s_density * pdf_t_density,
                                    ea.Valid() ? vrl_sampler.Pdf(s) * ea.Pdf(t) : 0.f);
    if (!(weight > 0)) continue;
    const MediumTrack::Point lp = light.At(s, s_where), ep = eye.At(t, t_where);
    if (lp.sigma_s.IsBlack() || ep.sigma_s.IsBlack()) continue;
    const Vec3 x = seg.o + seg.d * t;
    Vec3 d = y - x;
    float dist2 = LengthSquared(d);
    if (!(dist2 > 0)) continue;
    float dist = std::sqrt(dist2);
    Vec3 w = d / dist;  // eye point → VRL point
    // Light travels ψ, scatters at y_s towards x (-w), then at x towards the camera (-seg.d).
    float phase = HenyeyGreenstein(-Dot(L.n, w), L.g) * HenyeyGreenstein(Dot(w, seg.d), eye_med.g());
    float geometry = 1.f / std::max(dist2, clamp_distance2_);
    RGB value = seg.throughput * L.power * ep.sigma_s * ep.tr * lp.sigma_s * lp.tr * (phase * geometry * weight);
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
