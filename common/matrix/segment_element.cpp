// Elements of eye-segment rows: light j → camera-ray segment inside a medium (Huo 2016, Eq. 4
// for VPLs; the same integral for area VPLs, point, directional and medium VPLs):
//   A = β ∫_0^ℓ T_seg(0→t) σ_s(y_t) p_g(cos θ_t) T(y_t→L) V(y_t, L) I_L(y_t) G(y_t, L) dt
// with β the camera weight up to the segment start. `segment_samples` samples per element
// (media_sampling.h): for a point-like light a fraction `density_fraction` (MatrixOptions; in
// grid media) where the segment
// scatters (t ∝ σ_s·T_seg, its MediumTrack) and the rest equi-angular towards the light (Kulla &
// Fajardo 2012), by the balance heuristic; for a directional light, whose geometry term is
// constant, all of them where the segment scatters. T_seg and σ_s are the track's exact values;
// the connection to the light is ratio-tracked. A virtual light's geometry term is clamped as on
// surfaces: along the segment its 1/d² integrates to ~1/h, unbounded for a VPL beside the
// segment's end on a wall.
#include <embree3/rtcore.h>

#include <array>
#include <cmath>

#include "common/matrix/lighting_matrix.h"
#include "common/matrix/media_sampling.h"
#include "common/scene/phase.h"

namespace lightfarm {

RGB LightingMatrix::SegmentElement(uint32_t si, uint32_t col, MatrixCounters* counters) const {
  const EyeSegment& row = receivers_.segments[si];
  const VirtualLight& L = lights_.lights[col];
  if (L.IsRay()) return VrlSegmentElement(si, col, counters);  // Huo 2016, Eq. 3
  // The emitters' single scattering is the camera side's (ReceiverOptions::media_direct_samples).
  if (!segment_emitter_columns_ &&
      (L.kind == VirtualLightKind::kPoint || L.kind == VirtualLightKind::kDirectional || L.kind == VirtualLightKind::kAreaVPL))
    return RGB(0.f);
  if (int(L.depth) + int(row.depth) > max_depth_) return RGB(0.f);
  constexpr int kMaxSamples = 64, kRealLightSamples = 16;
  const bool directional = L.IsDirectional();
  // A real light (point, spot, directional) is one column among thousands of virtual ones and
  // carries the direct light: it gets kRealLightSamples × the samples, a small cost next to the
  // row's virtual lights. With one it would be the noisiest part of an eye segment's estimate
  // (scenes/cloud, 32², a distant light: rel_l1 0.155 with 4 samples, 0.052 with 32).
  const bool real = L.kind == VirtualLightKind::kPoint || directional;
  const int n = std::clamp(segment_samples_ * (real ? kRealLightSamples : 1), 1, kMaxSamples);
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 1, si, col}));
  // With coverage each sample integrates along one of the row's pieces (vrl_element.cpp).
  const uint32_t first_piece = FirstPieceDraw(row, rng);
  MediumTrack scratch;
  alignas(16) std::array<RTCRay, kMaxSamples> rays;
  std::array<RGB, kMaxSamples> values;
  std::array<Vec3, kMaxSamples> origins, dirs;
  std::array<float, kMaxSamples> lengths;
  std::array<int16_t, kMaxSamples> media;
  size_t nrays = 0;
  SegmentRay piece{};  // the same for every sample without coverage
  for (int k = 0; k < n; ++k) {
    if (k == 0 || row.pieces > 1) piece = SegmentRayFor(si, first_piece + uint32_t(k), &scratch);
    const EyeSegment& seg = *piece.seg;
    const MediumTrack& track = *piece.track;
    if (seg.medium < 0 || !(seg.length > 0) || track.empty()) continue;
    const Medium& med = scene_.media()[seg.medium];
    const StrategyMix mix(n, directional ? 1.f : DensityFraction(seg.medium, -1));
    // Equi-angular towards the light's position (point-like lights only).
    const EquiAngular ea(seg.o, seg.d, seg.length, directional ? seg.o : L.p);
    float u, t, pdf_density;
    size_t where;
    if (mix.First(k, rng, &u)) {
      t = track.Sample(u, &pdf_density, &where);
    } else {
      if (!ea.Valid()) continue;
      t = ea.Sample(u);
      where = track.Locate(t);
      pdf_density = track.Pdf(t, where);
    }
    const float weight = mix.Weight(pdf_density, directional || !ea.Valid() ? 0.f : ea.Pdf(t));
    if (!(weight > 0)) continue;
    const MediumTrack::Point sp = track.At(t, where);
    if (sp.sigma_s.IsBlack()) continue;
    Vec3 y = seg.o + seg.d * t;
    Vec3 w, target;
    float geometry = 1.f;
    if (directional) {
      w = -L.n;
    } else {
      Vec3 d = L.p - y;
      float dist2 = LengthSquared(d);
      if (!(dist2 > 0)) continue;
      w = d / std::sqrt(dist2);
      geometry = 1.f / (L.IsClamped() ? std::max(dist2, clamp_distance2_) : dist2);
      target = (L.kind == VirtualLightKind::kPoint || L.kind == VirtualLightKind::kMediumVPL)
                   ? L.p
                   : OffsetRayOrigin(L.p, L.ng, -w);
    }
    RGB intensity = LightIntensityTowards(L, w, scene_.materials());
    if (intensity.IsBlack()) continue;
    // Light travelling along -w scatters into the camera ray's reverse direction -seg.d.
    float phase = HenyeyGreenstein(Dot(w, seg.d), med.g());
    RGB value = seg.throughput * sp.sigma_s * sp.tr * intensity * (phase * geometry * weight);
    if (value.IsBlack() || !value.IsFinite()) continue;
    Vec3 dir = directional ? w : target - y;
    float tfar = directional ? kInfinity : 1.f - 1e-4f;
    if (!IsFinite(y) || !IsFinite(dir)) continue;  // never hand Embree a NaN ray
    RTCRay& ray = rays[nrays];
    ray = RTCRay{};
    ray.org_x = y.x; ray.org_y = y.y; ray.org_z = y.z;
    ray.dir_x = dir.x; ray.dir_y = dir.y; ray.dir_z = dir.z;
    ray.tnear = 0.f;
    ray.tfar = tfar;
    ray.mask = kMaskOpaque;
    ray.id = uint32_t(nrays);
    float dlen = Length(dir);
    origins[nrays] = y;
    dirs[nrays] = dir / dlen;
    lengths[nrays] = directional ? kInfinity : dlen * tfar;
    values[nrays] = value;
    media[nrays] = seg.medium;
    ++nrays;
  }
  if (nrays == 0) return RGB(0.f);
  if (recorded_rays_) recorded_rays_->insert(recorded_rays_->end(), rays.begin(), rays.begin() + nrays);
  scene_.Occluded(rays.data(), nrays);
  counters->shadow_rays += nrays;
  RGBAccum sum;
  for (size_t r = 0; r < nrays; ++r) {
    if (!(rays[r].tfar >= 0.f)) continue;
    RGB T = scene_.TransmittanceAlong(origins[r], dirs[r], lengths[r], media[r], rng);
    ++counters->transmittance_evals;
    sum.Add(values[r] * T);
  }
  return sum.ToRGB();
}

}  // namespace lightfarm
