// Elements of eye-segment rows: light j → camera-ray segment inside a medium (Huo 2016, Eq. 4
// for VPLs; the same integral for area VPLs, point, directional and medium VPLs):
//   A = β ∫_0^ℓ T_seg(0→t) σ_s(y_t) p_g(cos θ_t) T(y_t→L) V(y_t, L) I_L(y_t) G(y_t, L) dt
// with β the camera weight up to the segment start.
#include <embree3/rtcore.h>

#include <array>
#include <cmath>

#include "common/matrix/lighting_matrix.h"
#include "common/scene/phase.h"

namespace lightfarm {

RGB LightingMatrix::SegmentElement(uint32_t si, uint32_t col, MatrixCounters* counters) const {
  const EyeSegment& seg = receivers_.segments[si];
  const VirtualLight& L = lights_.lights[col];
  if (L.IsRay()) return VrlSegmentElement(si, col, counters);  // Huo 2016, Eq. 3
  if (int(L.depth) + int(seg.depth) > max_depth_) return RGB(0.f);
  if (seg.medium < 0 || !(seg.length > 0)) return RGB(0.f);
  const Medium& med = scene_.media()[seg.medium];
  constexpr int kMaxSamples = 64;
  const int n = std::clamp(segment_samples_, 1, kMaxSamples);
  Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, 1, si, col}));
  const bool directional = L.IsDirectional();
  const float len = seg.length;
  const float st = med.sigma_t().Max();
  // Equi-angular parameters: the light's foot point on the segment's line and its distance.
  float delta = 0, dist = 0, theta_a = 0, theta_b = 0;
  if (!directional) {
    delta = Dot(L.p - seg.o, seg.d);
    dist = std::max(Length(L.p - (seg.o + seg.d * delta)), 1e-7f);
    theta_a = std::atan2(-delta, dist);
    theta_b = std::atan2(len - delta, dist);
    if (!(theta_b > theta_a)) return RGB(0.f);
  }
  alignas(16) std::array<RTCRay, kMaxSamples> rays;
  std::array<RGB, kMaxSamples> values;
  std::array<Vec3, kMaxSamples> origins, dirs;
  std::array<float, kMaxSamples> lengths;
  size_t nrays = 0;
  for (int k = 0; k < n; ++k) {
    float u = Clamp((float(k) + rng.Uniform()) / float(n), 0.f, 0x1.fffffep-1f);
    float t, pdf;
    RGB analog_weight(0.f);
    if (!directional) {
      // Kulla & Fajardo 2012: pdf ∝ 1/(D² + (t-Δ)²), i.e. uniform in the subtended angle.
      t = Clamp(delta + dist * std::tan(theta_a + u * (theta_b - theta_a)), 0.f, len);
      pdf = dist / ((theta_b - theta_a) * (dist * dist + Sqr(t - delta)));
    } else if (med.homogeneous() && st > 0) {
      // Directional light: sample ∝ the segment's transmittance, truncated to [0, ℓ].
      float norm = -std::expm1(-st * len);
      t = Clamp(-std::log1p(-u * norm) / st, 0.f, len);
      pdf = st * std::exp(-st * t) / norm;
    } else {
      // Heterogeneous medium, directional light: delta tracking samples t ∝ σ_t(t)·T(0→t),
      // which cancels those factors and leaves its weight σ_s/σ_t (a miss contributes 0).
      FreePathSample fp = med.SampleFreePath({seg.o, seg.d, len}, rng);
      ++counters->transmittance_evals;
      if (!fp.scattered) continue;
      t = fp.t;
      pdf = 0;  // marks the analog estimate below
      analog_weight = fp.weight;
    }
    if (pdf < 0 || !std::isfinite(pdf)) continue;
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
    RGB value;
    if (pdf == 0) {
      value = seg.throughput * analog_weight * intensity * (phase * geometry / float(n));
    } else {
      RGB sigma_s = med.sigma_s() * med.Density(y);
      if (sigma_s.IsBlack()) continue;
      RGB t_seg = med.Transmittance({seg.o, seg.d, t}, rng);
      if (!med.homogeneous()) ++counters->transmittance_evals;
      value = seg.throughput * sigma_s * t_seg * intensity * (phase * geometry / (pdf * float(n)));
    }
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
    ++nrays;
  }
  if (nrays == 0) return RGB(0.f);
  scene_.Occluded(rays.data(), nrays);
  counters->shadow_rays += nrays;
  RGBAccum sum;
  for (size_t r = 0; r < nrays; ++r) {
    if (!(rays[r].tfar >= 0.f)) continue;
    RGB T = scene_.TransmittanceAlong(origins[r], dirs[r], lengths[r], seg.medium, rng);
    ++counters->transmittance_evals;
    sum.Add(values[r] * T);
  }
  return sum.ToRGB();
}

}  // namespace lightfarm
