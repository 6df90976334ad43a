// Path-traced compensation of the clamp (docs/rendering.md, "The clamp").
//
// The clamped estimate replaces G = cos θ_x cos θ_y / d² by G · min(1, d²/c²), c the clamp
// distance, so it misses (Kollig & Keller 2004)
//   ΔL(x) = ∫_A f(x) L_o(y→x) G(x, y) V(x, y) (1 − d²/c²)₊ dA(y)
//         = ∫_Ω f(x, ω) L_i(x, ω) |cos θ| (1 − d(ω)²/c²)₊ dω,
// d(ω) the distance to the first opaque surface along ω. One estimate per sample: ω from the
// receiver's BSDF (non-delta lobes: the matrix holds only those), the first surface y within c,
// and L_i(x, ω) path traced (Engelhardt et al. 2012) with the receiver's remaining depth. Area
// VPLs are clamped too, so L_i includes y's emission. Only the light within c is traced: the
// directions that find nothing there cost one short ray.
//
// Rows in a medium are skipped: there the clamp also bounds medium VPLs and VRLs, whose residual
// is not this surface integral.
#include "common/matrix/lighting_matrix.h"

namespace lightfarm {

RGBAccum LightingMatrix::ClampCompensation(uint32_t row, MatrixCounters* counters) const {
  RGBAccum sum;
  if (!compensates() || row >= rows_.size()) return sum;
  const RowData& r = rows_[row];
  const Material& m = scene_.materials()[r.material];
  PathCounters pc;
  const float inv_n = 1.f / float(compensation_samples_);
  for (int s = 0; s < compensation_samples_; ++s) {
    Rng rng(HashSeed({seed_, uint64_t(RngStream::kCompensation), row, uint64_t(s)}));
    const float uc = rng.Uniform();
    const Vec2 u{rng.Uniform(), rng.Uniform()};
    const std::optional<BSDFSample> bs = SampleBSDF(m, r.wo_local, uc, u, TransportMode::kRadiance);
    if (!bs || bs->IsSpecular() || !(bs->pdf > 0) || bs->f.IsBlack()) continue;
    const Vec3 wi = r.frame.FromLocal(bs->wi);
    const int medium = Dot(wi, r.ng) > 0 ? r.medium_out : r.medium_in;
    if (medium >= 0) continue;
    const Vec3 o = OffsetRayOrigin(r.p, r.ng, wi);
    // The offset grows with the coordinates' magnitude (far from the origin it can exceed c):
    // search c past the receiver itself, not past the offset origin.
    SurfaceHit hit;
    if (!scene_.Intersect({o, wi, clamp_distance_ + Length(o - r.p)}, &hit, kMaskOpaque)) continue;
    const float d2 = LengthSquared(hit.p - r.p);
    const float w = 1.f - d2 / clamp_distance2_;
    if (!(w > 0)) continue;
    ++counters->compensation_paths;
    const RGB Li = compensation_tracer_->Li({o, wi, kInfinity}, medium, r.light_depth_budget, rng, &pc);
    const RGB c = r.throughput * bs->f * Li * (std::abs(bs->wi.z) * w / bs->pdf * inv_n);
    if (c.IsFinite()) sum.Add(c);
  }
  counters->clamp_compensated += 0.2126 * sum.r + 0.7152 * sum.g + 0.0722 * sum.b;
  counters->shadow_rays += pc.shadow_rays;
  return sum;
}

}  // namespace lightfarm
