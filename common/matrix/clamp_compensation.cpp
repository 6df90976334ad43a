// Path-traced compensation of the clamp and the element bound (docs/rendering.md, "The clamp").
//
// The clamped estimate replaces G = cos θ_x cos θ_y / d² by G_c = G · min(1, d²/c²), c the clamp
// distance, and the element bound then scales an element whose kernel K (f_x·f_y·G_c for a
// surface VPL, f_x·G_c for an area VPL's emission, largest channel) exceeds its limit B down to
// B. Each light path x ← y ← ω' therefore misses the share
//   w(ω, ω') = (1 − d²/c²)₊ + min(1, d²/c²) · (1 − B/K(ω, ω'))₊
// of its contribution (Kollig & Keller 2004's residual, for both bounds), and the compensation is
//   ΔL(x) = ∫_Ω f(x, ω) |cos θ| ∫ w(ω, ω') dL_i(x, ω; ω'),
// the light arriving at x along ω split by the direction ω' it reached y from. One estimate per
// sample: ω from the receiver's BSDF (non-delta lobes: the matrix holds only those), y the first
// opaque surface along ω, and L_i(x, ω) path traced (Engelhardt et al. 2012) with the receiver's
// remaining depth, weighting what y gathers by w (PathTracer's FirstVertexWeight). Light that
// leaves y by a delta or sharp lobe gets none: no VPL carries it, so no element was clamped on it
// (the caustic photons carry it whole, and counting a share here counted it twice: a bright rim
// where a floor meets a glass). A purely specular y that does not emit is not traced. The bound's
// share of an emitter's own light (a glossy receiver seeing a small light) is also estimated by
// one emitter sample per sample, MIS-combined (power heuristic) with the BSDF samples that hit
// the emitter: found by BSDF sampling alone, a small light's share is mostly fireflies. (Scenes
// with media keep BSDF sampling alone: the emitter sample has no transmittance.) Where no
// material can reach the bound (a Lambertian scene) only the surfaces within c are traced: the
// directions that find nothing there cost one short ray. A sample whose y cannot reach the bound
// (a Lambertian y whose best case stays below it) and lies beyond c costs one ray and no path.
// A direction into a medium finds y as an eye segment's samples do (below): a scattering point
// or a surface within c, the clamp's share alone (the element bound's share of a glossy y seen
// through a medium is not traced).
//
// Eye-segment rows. An element of a segment row (segment_element.cpp, vrl_element.cpp) integrates
// over points x = o + t·d of the segment and points y of a virtual light (a VPL, a point on a
// VRL) with G = 1/max(d², c²), d = |x − y|. Written over the direction ω from x and the distance d
// to y, the true kernel is 1/d² times the volume (or area) measure d²·dω·dd, so the clamp keeps
// min(1, d²/c²) of every path x ← y and the residual is
//   ΔL(seg) = β ∫_0^ℓ σ_s(x) T_seg(0→t) ∫_{S²} p(ω) ∫_0^c (1 − d²/c²) T(x, y) L_y(y → x) dd dω dt,
// L_y being what y scatters towards x: σ_s(y)·L_s at a medium point (everything it in-scatters:
// every VRL and medium VPL carries light arriving there), a surface's reflected light at an opaque
// y (not what leaves it by a delta lobe, for the caustic photons carry that), and its emission
// only where area VPLs are segment columns (otherwise the camera side's emitter samples have the
// emitter → x light unclamped). One estimate per sample: t from the segment's track (σ_s·T_seg),
// ω from the phase function, then the path tracer with a windowed first vertex
// (FirstVertexWeight::window = c), which forces y within c and weights it by 1 − d²/c².
#include "common/matrix/lighting_matrix.h"

#include <embree3/rtcore.h>

#include <algorithm>

#include "common/scene/phase.h"
#include "common/util/sampling.h"

namespace lightfarm {

namespace {

// An eye segment takes this many times a surface row's samples: its residual's integrand,
// σ_s(y)·L_s(y) within c of the segment, changes voxel by voxel in a grid medium, and a segment's
// samples cost little next to its row of VRL elements (docs/methods/media-elements.md, "The clamp
// in media").
constexpr int kSegmentCompensationFactor = 16;

}  // namespace

bool LightingMatrix::BoundWeight(const RowData& r, const Material& m, const BSDFSample& bs,
                                 const SurfaceHit& hit, float d2, float w_clamp,
                                 FirstVertexWeight* weight) const {
  const Material& my = scene_.materials()[scene_.shapes()[hit.shape].material];
  const Vec3 wi = r.frame.FromLocal(bs.wi);
  // G_c without the receiver's BSDF, and the share of the true G it is (the samples measure G).
  const float g = std::abs(bs.wi.z) * std::abs(Dot(hit.ns, wi)) / std::max(d2, clamp_distance2_);
  const float kept = std::min(1.f, d2 / clamp_distance2_);
  const RGB fx = EvalBSDF(m, r.wo_local, bs.wi, TransportMode::kRadiance);
  const float area_kernel = fx.Max() * g;
  const int emitter = scene_.shapes()[hit.shape].area_emitter;
  const bool emits = emitter >= 0 && area_kernel > bound_area_ * 1.001f;
  // A Lambertian y reflects at most max(ρ)/π: below the limit there, nothing of y's was bound;
  // a purely specular y holds no VPLs.
  const bool reflects = my.type == MaterialType::kDiffuse
                            ? area_kernel * my.reflectance.Max() * kInvPi > bound_surface_ * 1.001f
                            : !IsPurelySpecular(MaterialFlags(my));
  if (!emits && !reflects) return false;
  // With emitter samples (BoundEmitterSample) the bound's share of the emission is MIS-weighted.
  const float mis = emits && compensation_emitters_
                        ? PowerHeuristic(PdfBSDF(m, r.wo_local, bs.wi, TransportMode::kRadiance),
                                         compensation_emitters_->PdfArea(uint32_t(emitter), r.p, hit))
                        : 1.f;
  weight->emission = w_clamp + (emits ? kept * (1.f - bound_area_ / area_kernel) * mis : 0.f);
  weight->other = w_clamp;
  weight->specular = 0.f;
  const float limit = bound_surface_;
  weight->arrival = [&my, fx, g, kept, limit, w_clamp](Vec3 wo, Vec3 wi_y) {
    // As the surface VPL at y evaluates it: arrival wi_y, leaving towards the receiver (wo).
    const float kernel = (fx * EvalBSDF(my, wi_y, wo, TransportMode::kImportance)).Max() * g;
    return kernel > limit * 1.001f ? w_clamp + kept * (1.f - limit / kernel) : w_clamp;
  };
  return true;
}

RGB LightingMatrix::BoundEmitterSample(const RowData& r, const Material& m, Rng& rng,
                                      PathCounters* counters) const {
  const float u_pick = rng.Uniform();
  const Vec2 u{rng.Uniform(), rng.Uniform()};
  const std::optional<LightSample> ls = compensation_emitters_->Sample(r.p, u_pick, u);
  if (!ls || !ls->area || !(ls->pdf > 0)) return RGB(0.f);
  const Vec3 wi_local = r.frame.ToLocal(ls->wi);
  // The directions the BSDF side skips are skipped here too (the wrong side, a medium).
  if (Dot(r.ng, ls->wi) * wi_local.z <= 0) return RGB(0.f);
  if ((Dot(ls->wi, r.ng) > 0 ? r.medium_out : r.medium_in) >= 0) return RGB(0.f);
  const RGB fx = EvalBSDF(m, r.wo_local, wi_local, TransportMode::kRadiance);
  const float d2 = LengthSquared(ls->p_light - r.p);
  const float kernel = fx.Max() * std::abs(wi_local.z) * std::abs(Dot(ls->n_light, ls->wi)) /
                       std::max(d2, clamp_distance2_);
  if (!(kernel > bound_area_ * 1.001f)) return RGB(0.f);
  const float share = std::min(1.f, d2 / clamp_distance2_) * (1.f - bound_area_ / kernel);
  // No media here (compensation_emitters_ exists only without them): visibility alone.
  ++counters->shadow_rays;
  const Vec3 o = OffsetRayOrigin(r.p, r.ng, ls->wi);
  if (LightSampleVisibility(scene_, o, *ls, -1, rng).IsBlack()) return RGB(0.f);
  const float mis = PowerHeuristic(ls->pdf, PdfBSDF(m, r.wo_local, wi_local, TransportMode::kRadiance));
  return r.throughput * fx * ls->L * (std::abs(wi_local.z) * share * mis / ls->pdf);
}

RGBAccum LightingMatrix::SegmentCompensation(uint32_t row, MatrixCounters* counters) const {
  RGBAccum sum;
  const uint32_t si = row - uint32_t(rows_.size());
  if (si >= receivers_.segments.size()) return sum;
  const EyeSegment& eye_row = receivers_.segments[si];
  const int budget = max_depth_ - int(eye_row.depth);
  if (budget <= 0) return sum;
  PathCounters pc;
  const int n = compensation_samples_ * kSegmentCompensationFactor;
  const float inv_n = 1.f / float(n);
  // With coverage, sample s takes piece (first + s) of the row (SegmentRayFor), first from its own
  // generator so that rows without pieces draw what they drew before.
  Rng piece_rng(HashSeed({seed_, uint64_t(RngStream::kCompensation), row, ~uint64_t(0)}));
  const uint32_t first_piece = FirstPieceDraw(eye_row, piece_rng);
  MediumTrack scratch;
  SegmentRay piece{};
  for (int s = 0; s < n; ++s) {
    if (s == 0 || eye_row.pieces > 1) piece = SegmentRayFor(si, first_piece + uint32_t(s), &scratch);
    const EyeSegment& seg = *piece.seg;
    const MediumTrack& track = *piece.track;
    if (seg.medium < 0 || !(seg.length > 0) || track.empty()) continue;
    const float g = scene_.media()[seg.medium].g();
    Rng rng(HashSeed({seed_, uint64_t(RngStream::kCompensation), row, uint64_t(s)}));
    float pdf_t = 0, pdf_w = 0;
    size_t where = 0;
    // Stratified over the row's samples: with pieces too, as each sample's piece is uniform
    // whatever its stratum (the first is random), so every (piece, stratum) pair is as likely.
    const float t = track.Sample((float(s) + rng.Uniform()) * inv_n, &pdf_t, &where);
    if (!(pdf_t > 0)) continue;
    const MediumTrack::Point x = track.At(t, where);
    if (x.sigma_s.IsBlack()) continue;
    // The camera path arrives travelling along d; the light leaves x towards the camera (−d)
    // after arriving from y = x + d_y·ω, the direction the phase function is sampled in.
    const Vec3 w = SampleHenyeyGreenstein(seg.d, g, rng.Uniform(), rng.Uniform(), &pdf_w);
    ++counters->compensation_paths;
    const RGB Li = compensation_tracer_->Li({seg.o + seg.d * t, w, kInfinity}, seg.medium, budget, rng, &pc,
                                            &segment_window_);
    const RGB c = seg.throughput * x.sigma_s * x.tr * Li * (inv_n / pdf_t);
    if (c.IsFinite()) sum.Add(c);
  }
  counters->clamp_compensated += 0.2126 * sum.r + 0.7152 * sum.g + 0.0722 * sum.b;
  counters->shadow_rays += pc.shadow_rays;
  return sum;
}

RGBAccum LightingMatrix::ClampCompensation(uint32_t row, MatrixCounters* counters) const {
  RGBAccum sum;
  if (!compensates()) return sum;
  if (row >= rows_.size()) return media_compensation_ ? SegmentCompensation(row, counters) : sum;
  const RowData& r = rows_[row];
  const Material& m = scene_.materials()[r.material];
  PathCounters pc;
  const float inv_n = 1.f / float(compensation_samples_);
  for (int s = 0; s < compensation_samples_; ++s) {
    if (compensation_emitters_) {
      // Its own generator: the BSDF side draws what it drew without emitter samples.
      Rng nee(HashSeed({seed_, uint64_t(RngStream::kCompensation), row, uint64_t(s), 1}));
      const RGB c = BoundEmitterSample(r, m, nee, &pc) * inv_n;
      if (c.IsFinite()) sum.Add(c);
    }
    Rng rng(HashSeed({seed_, uint64_t(RngStream::kCompensation), row, uint64_t(s)}));
    const float uc = rng.Uniform();
    const Vec2 u{rng.Uniform(), rng.Uniform()};
    const std::optional<BSDFSample> bs = SampleBSDF(m, r.wo_local, uc, u, TransportMode::kRadiance);
    if (!bs || bs->IsSpecular() || !(bs->pdf > 0) || bs->f.IsBlack()) continue;
    const Vec3 wi = r.frame.FromLocal(bs->wi);
    const int medium = Dot(wi, r.ng) > 0 ? r.medium_out : r.medium_in;
    const Vec3 o = OffsetRayOrigin(r.p, r.ng, wi);
    if (medium >= 0 && !media_compensation_) continue;
    if (medium >= 0) {
      // Into a medium: y is a scattering point or a surface within c (the windowed first vertex,
      // as for eye segments); every clamped light there, an area VPL's emission included.
      ++counters->compensation_paths;
      const RGB Li = compensation_tracer_->Li({o, wi, kInfinity}, medium, r.light_depth_budget, rng, &pc,
                                              &medium_window_);
      const RGB c = r.throughput * bs->f * Li * (std::abs(bs->wi.z) / bs->pdf * inv_n);
        if (c.IsFinite()) sum.Add(c);
      continue;
    }
    // The offset grows with the coordinates' magnitude (far from the origin it can exceed c):
    // search c past the receiver itself, not past the offset origin.
    SurfaceHit hit;
    const float reach = bound_binds_ ? kInfinity : clamp_distance_ + Length(o - r.p);
    if (!scene_.Intersect({o, wi, reach}, &hit, kMaskOpaque)) continue;
    const float d2 = LengthSquared(hit.p - r.p);
    const float w = std::max(0.f, 1.f - d2 / clamp_distance2_);
    FirstVertexWeight bound_weight;
    bool bound = bound_binds_ && BoundWeight(r, m, *bs, hit, d2, w, &bound_weight);
    if (!bound && !(w > 0)) continue;
    if (!bound) {
      // The clamp's share w of everything y gathers, except what leaves it by a delta or sharp lobe.
      const Shape& sy = scene_.shapes()[hit.shape];
      const uint32_t flags_y = MaterialFlags(scene_.materials()[sy.material]);
      if (flags_y & kBxDFSpecular) {
        if (IsPurelySpecular(flags_y) && sy.area_emitter < 0) continue;
        bound_weight.emission = bound_weight.other = w;
        bound_weight.specular = 0.f;
        bound_weight.arrival = [w](Vec3, Vec3) { return w; };
        bound = true;
      }
    }
    ++counters->compensation_paths;
    const RGB Li = compensation_tracer_->Li({o, wi, kInfinity}, medium, r.light_depth_budget, rng, &pc,
                                            bound ? &bound_weight : nullptr);
    // With a bound weight, w is inside the traced estimate.
    const RGB c = r.throughput * bs->f * Li * (std::abs(bs->wi.z) * (bound ? 1.f : w) / bs->pdf * inv_n);
    if (c.IsFinite()) sum.Add(c);
  }
  counters->clamp_compensated += 0.2126 * sum.r + 0.7152 * sum.g + 0.0722 * sum.b;
  counters->shadow_rays += pc.shadow_rays;
  return sum;
}

}  // namespace lightfarm
