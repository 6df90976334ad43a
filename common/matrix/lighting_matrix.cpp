#include "common/matrix/lighting_matrix.h"


#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "common/scene/effects.h"
#include "common/scene/phase.h"
#include "common/util/check.h"
#include "common/util/sampling.h"

namespace lightfarm {

constexpr size_t kBatch = 256;

// The Lambertian fast path's geometry for a batch of entries, one slot each: the direction to
// the light, the combined side/hemisphere tests, |cos| at the light, |cos| at the receiver times
// the (clamped) geometry term, and which offset end points the shadow ray uses. The same float
// operations in the same order as LightingMatrix::DiffuseElement (bit-identical), written
// without branches over plain arrays so the compiler vectorises the loop.
struct DiffuseGeometryBatch {
  alignas(16) std::array<float, kBatch> wx, wy, wz, abs_out, g, scale;
  alignas(16) std::array<int32_t, kBatch> ok, back, light_back;
};

// The receivers of a Column batch, gathered for the kernel.
struct ReceiverBatch {
  alignas(16) std::array<float, kBatch> p[3], n[3], ng[3], wo_z;
  alignas(16) std::array<int32_t, kBatch> budget;
};

namespace {

// The unshadowed value of one element and the shadow ray that decides it.
struct Unshadowed {
  RGB value;
  float unclamped_scale = 1;  // value · unclamped_scale = the element without the clamp
  Vec3 origin, dir;           // shadow ray: origin + t·dir, t ∈ (0, tfar)
  float tfar = 0;
};

// Receiver inputs of the kernel: one receiver for the whole batch, or one per entry.
struct FixedReceiver {
  float p[3], n[3], ng[3], wo_z;
  int32_t budget;
  float P(int c, size_t) const { return p[c]; }
  float N(int c, size_t) const { return n[c]; }
  float Ng(int c, size_t) const { return ng[c]; }
  float WoZ(size_t) const { return wo_z; }
  int32_t Budget(size_t) const { return budget; }
};
struct ReceiverArrays {
  const float *p[3], *n[3], *ng[3], *wo_z;
  const int32_t* budget;
  explicit ReceiverArrays(const ReceiverBatch& b)
      : p{b.p[0].data(), b.p[1].data(), b.p[2].data()},
        n{b.n[0].data(), b.n[1].data(), b.n[2].data()},
        ng{b.ng[0].data(), b.ng[1].data(), b.ng[2].data()},
        wo_z(b.wo_z.data()),
        budget(b.budget.data()) {}
  float P(int c, size_t m) const { return p[c][m]; }
  float N(int c, size_t m) const { return n[c][m]; }
  float Ng(int c, size_t m) const { return ng[c][m]; }
  float WoZ(size_t m) const { return wo_z[m]; }
  int32_t Budget(size_t m) const { return budget[m]; }
};
// Light inputs: one light for the whole batch, or consecutive lights from the matrix's arrays.
struct FixedLight {
  float p[3], n[3], ng[3], wi_z;
  int32_t surface, two_sided, depth;
  float P(int c, size_t) const { return p[c]; }
  float N(int c, size_t) const { return n[c]; }
  float Ng(int c, size_t) const { return ng[c]; }
  float WiZ(size_t) const { return wi_z; }
  int32_t Surface(size_t) const { return surface; }
  int32_t TwoSided(size_t) const { return two_sided; }
  int32_t Depth(size_t) const { return depth; }
};
struct LightArrays {
  const float *p[3], *n[3], *ng[3], *wi_z;
  const int32_t *surface, *two_sided, *depth;
  float P(int c, size_t m) const { return p[c][m]; }
  float N(int c, size_t m) const { return n[c][m]; }
  float Ng(int c, size_t m) const { return ng[c][m]; }
  float WiZ(size_t m) const { return wi_z[m]; }
  int32_t Surface(size_t m) const { return surface[m]; }
  int32_t TwoSided(size_t m) const { return two_sided[m]; }
  int32_t Depth(size_t m) const { return depth[m]; }
};

// A sink that may skip the zero every entry gets before its value is known (RowSum: adding
// +0 to a double sum that starts at +0 never changes its bits under round-to-nearest).
template <typename SinkFn>
concept SkipsZeroDefaults = SinkFn::kSkipsZeroDefaults;

struct RowSumSink {
  static constexpr bool kSkipsZeroDefaults = true;
  RGBAccum* sum;
  void operator()(size_t, RGB v) const { sum->Add(v); }
};

template <typename Receivers, typename Lights>
void DiffuseGeometry(size_t count, const Receivers R, const Lights L, float clamp2,
                     DiffuseGeometryBatch* __restrict out) {
  const float inv_clamp2 = 1.f / clamp2;
  for (size_t m = 0; m < count; ++m) {
    float dx = L.P(0, m) - R.P(0, m), dy = L.P(1, m) - R.P(1, m), dz = L.P(2, m) - R.P(2, m);
    float dist2 = dx * dx + dy * dy + dz * dz;
    float inv_len = 1.f / std::sqrt(dist2);  // as Vec3::operator/
    float wx = dx * inv_len, wy = dy * inv_len, wz = dz * inv_len;
    float wi_z = wx * R.N(0, m) + wy * R.N(1, m) + wz * R.N(2, m);
    float side = R.Ng(0, m) * wx + R.Ng(1, m) * wy + R.Ng(2, m) * wz;
    float out_z = -(wx * L.N(0, m) + wy * L.N(1, m) + wz * L.N(2, m));
    float light_side = wx * L.Ng(0, m) + wy * L.Ng(1, m) + wz * L.Ng(2, m);
    int32_t surface = L.Surface(m);
    int32_t emits = (surface & int32_t(!(light_side * out_z >= 0)) & int32_t(L.WiZ(m) * out_z > 0)) |
                    ((1 - surface) & (int32_t(!(out_z <= 0)) | L.TwoSided(m)));
    out->ok[m] = int32_t(L.Depth(m) <= R.Budget(m)) & int32_t(dist2 > 0) &
                 int32_t(!(side * wi_z <= 0)) & int32_t(R.WoZ(m) * wi_z > 0) & emits;
    // Both quotients unconditionally: a division under a condition keeps the loop scalar.
    float inv_dist2 = 1.f / dist2, clamp_ratio = clamp2 / dist2;
    bool clamped = dist2 < clamp2;
    out->g[m] = std::abs(wi_z) * (clamped ? inv_clamp2 : inv_dist2);
    out->scale[m] = clamped ? clamp_ratio : 1.f;
    out->abs_out[m] = std::abs(out_z);
    out->wx[m] = wx;
    out->wy[m] = wy;
    out->wz[m] = wz;
    out->back[m] = int32_t(side < 0);
    out->light_back[m] = int32_t(light_side > 0);
  }
}

}  // namespace

RGB LightIntensityTowards(const VirtualLight& L, Vec3 w, const std::vector<Material>& materials) {
  switch (L.kind) {
    case VirtualLightKind::kAreaVPL: {
      float cos_l = -Dot(L.n, w);
      if (cos_l <= 0 && !L.two_sided) return RGB(0.f);
      return L.power * std::abs(cos_l);
    }
    case VirtualLightKind::kSurfaceVPL: {
      // Re-emission through the VPL's BSDF: light arrived from wi, leaves towards -w.
      Frame lf(L.n);
      Vec3 out_local = lf.ToLocal(-w);
      if (Dot(L.ng, -w) * out_local.z <= 0) return RGB(0.f);
      RGB fl = EvalBSDF(materials[L.material], lf.ToLocal(L.wi), out_local,
                        TransportMode::kImportance);
      return L.power * fl * std::abs(out_local.z);
    }
    case VirtualLightKind::kPoint: {
      float falloff = 1.f;
      if (L.spot) {
        float cos_t = -Dot(w, L.n);
        if (cos_t <= L.cos_falloff_end) return RGB(0.f);
        if (cos_t < L.cos_falloff_start) {
          float t = (cos_t - L.cos_falloff_end) / (L.cos_falloff_start - L.cos_falloff_end);
          falloff = t * t * (3 - 2 * t);
        }
      }
      return L.power * falloff;
    }
    case VirtualLightKind::kDirectional:
      return L.power;
    case VirtualLightKind::kMediumVPL:
      // Light travelling along -wi scatters towards -w: cosθ = Dot(-wi, -w).
      return L.power * HenyeyGreenstein(Dot(L.wi, w), L.g);
    case VirtualLightKind::kVRL:
      return RGB(0.f);  // not point-like: evaluated by the VRL elements (vrl_element.cpp)
  }
  return RGB(0.f);
}

LightingMatrix::~LightingMatrix() = default;

float SharpAlpha(const MatrixOptions& options, size_t lights) {
  if (options.sharp_roughness >= 0) return options.sharp_roughness;
  // A Trowbridge-Reitz lobe of roughness α reflects into a cone of half-angle ≈ 2α, a solid
  // angle ≈ 4πα²; N lights spread over a hemisphere put 2Nα² of them in it. Below ~40 the
  // columns of glossy VPLs are too spiky for the sampling methods (docs/sharp-lobes.md
  // measures where): α_sharp = √(40 / 2N) = √(20/N) for few lights. It never drops below
  // kSharpAlphaFloor: lights are not spread evenly, and a lobe just above the threshold keeps
  // its spikes at any count (docs/rendering.md, "Sharp lobes", measures it), so more lights
  // must never hand a sampled lobe back to the columns.
  const float by_count = std::sqrt(20.f / float(std::max<size_t>(lights, 1)));
  return std::clamp(by_count, kSharpAlphaFloor, 0.3f);
}

LightingMatrix::LightingMatrix(const Scene& scene, const ReceiverSet& receivers,
                               const LightSet& lights, const MatrixOptions& options)
    : scene_(scene), receivers_(receivers), lights_(lights) {
  clamp_distance_ = options.clamp * std::max(scene.bounds().Radius(), 1e-6f);
  clamp_distance2_ = clamp_distance_ * clamp_distance_;
  segment_samples_ = options.segment_samples;
  density_fraction_ = options.density_fraction;
  segment_emitter_columns_ = options.segment_emitter_columns;
  max_depth_ = scene.hints().max_depth;
  compensation_samples_ = options.compensation_samples;
  // In media by default only where no emitter is finite: beside a point or area light L_s grows
  // as 1/r² and the window's samples have unbounded variance (docs/rendering.md, "The clamp").
  media_compensation_ = options.media_compensation >= 0
                            ? options.media_compensation != 0
                            : scene.area_emitters().empty() && scene.point_emitters().empty();
  seed_ = options.seed;
  if (options.bsdf_clamp > 0 && clamp_distance2_ > 0) {
    bound_area_ = options.bsdf_clamp * kInvPi / clamp_distance2_;
    bound_surface_ = bound_area_ * kInvPi;
  }
  // A Lambertian pair (reflectances ≤ 1) never exceeds the bound at bsdf_clamp ≥ 1, so the
  // fast path, which does not test it, stays exact; otherwise those elements take the general path.
  const auto fast_within_bound = [&](const RGB& reflectance) {
    return bound_surface_ == 0 || (options.bsdf_clamp >= 1 && reflectance.Max() <= 1);
  };
  // Whether the bound can bind anywhere: some non-Lambertian lobe, or Lambertian ones it reaches.
  for (const Material& m : scene.materials()) {
    if (bound_surface_ == 0) break;
    const uint32_t flags = MaterialFlags(m);
    if (IsPurelySpecular(flags)) continue;
    if (m.type != MaterialType::kDiffuse || !fast_within_bound(m.reflectance)) bound_binds_ = true;
  }
  if (compensates()) {
    PathTracerOptions pt;
    pt.max_depth = scene.hints().max_depth;
    compensation_tracer_ = std::make_unique<PathTracer>(scene, pt);
    medium_window_.window = clamp_distance_;
    medium_window_.specular = 0.f;
    medium_window_.arrival = [](Vec3, Vec3) { return 1.f; };
    // An eye segment's emitter light is the camera side's unless area VPLs are its columns.
    segment_window_ = medium_window_;
    segment_window_.emission = segment_emitter_columns_ ? 1.f : 0.f;
    if (bound_binds_ && !scene.has_media()) compensation_emitters_ = std::make_unique<EmitterSampler>(scene);
  }
  caustic_photons_ = options.caustic_photons >= 0 ? options.caustic_photons
                    : ComputeEffects(scene).caustics() ? kDefaultCausticPhotons
                                                       : 0;
  caustic_k_ = options.caustic_k;
  caustic_radius_ = options.caustic_radius * std::max(scene.bounds().Radius(), 1e-6f);
  caustic_volume_radius_ = options.caustic_volume_radius * std::max(scene.bounds().Radius(), 1e-6f);
  
  const int max_depth = scene.hints().max_depth;
  rows_.resize(receivers.points.size());
  for (size_t i = 0; i < rows_.size(); ++i) {
    const ShadingPoint& sp = receivers.points[i];
    RowData& r = rows_[i];
    r.p = sp.p;
    r.ng = sp.ng;
    r.frame = Frame(sp.ns);
    r.wo_local = r.frame.ToLocal(sp.wo);
    r.throughput = sp.throughput;
    r.material = sp.material;
    // pbrt's maxdepth bounds the scattering events on the whole path: camera side (depth) +
    // light side (VPL depth) must not exceed it.
    r.light_depth_budget = uint8_t(std::clamp(max_depth - int(sp.depth), 0, 255));
    r.medium_out = sp.medium_out;
    r.medium_in = sp.medium_in;
    const Material& m = scene.materials()[sp.material];
    RGB f = m.reflectance * kInvPi;  // EvalDiffuse's value on the lit side
    r.diffuse = options.diffuse_fast_path && m.type == MaterialType::kDiffuse && !f.IsBlack() &&
                fast_within_bound(m.reflectance);
    r.throughput_f = r.throughput * f;
    r.origin_front = OffsetRayOrigin(r.p, r.ng, r.ng);
    r.origin_back = OffsetRayOrigin(r.p, r.ng, -r.ng);
  }
  BuildMediumTracks();
  light_frames_.resize(lights.size());
  diffuse_lights_.resize(lights.size());
  DiffuseLightArrays& a = light_arrays_;
  for (auto* v : {&a.px, &a.py, &a.pz, &a.nx, &a.ny, &a.nz, &a.ngx, &a.ngy, &a.ngz, &a.wi_z})
    v->resize(lights.size());
  for (auto* v : {&a.surface, &a.two_sided, &a.depth}) v->resize(lights.size());
  for (size_t j = 0; j < lights.size(); ++j) {
    const VirtualLight& L = lights.lights[j];
    DiffuseLight& d = diffuse_lights_[j];
    // OffsetRayOrigin(p, ng, -w) moves to the ng side when -w·ng >= 0 (receiver in front).
    d.target_front = OffsetRayOrigin(L.p, L.ng, L.ng);
    d.target_back = OffsetRayOrigin(L.p, L.ng, -L.ng);
    d.emission = L.power;
    d.fast = options.diffuse_fast_path && L.kind == VirtualLightKind::kAreaVPL;
    if (L.kind == VirtualLightKind::kSurfaceVPL) {
      light_frames_[j].frame = Frame(L.n);
      light_frames_[j].wi_local = light_frames_[j].frame.ToLocal(L.wi);
      const Material& m = scene.materials()[L.material];
      d.surface = true;
      d.wi_z = light_frames_[j].wi_local.z;
      d.emission = L.power * (m.reflectance * kInvPi);  // as L.power * EvalDiffuse(...)
      d.fast = options.diffuse_fast_path && m.type == MaterialType::kDiffuse && fast_within_bound(m.reflectance);
    }
    a.px[j] = L.p.x; a.py[j] = L.p.y; a.pz[j] = L.p.z;
    a.nx[j] = L.n.x; a.ny[j] = L.n.y; a.nz[j] = L.n.z;
    a.ngx[j] = L.ng.x; a.ngy[j] = L.ng.y; a.ngz[j] = L.ng.z;
    a.wi_z[j] = d.wi_z;
    a.surface[j] = d.surface;
    a.two_sided[j] = L.two_sided;
    a.depth[j] = L.depth;
  }
}

void LightingMatrix::BuildMediumTracks() {
  const std::vector<Medium>& media = scene_.media();
  auto in_grid = [&](int medium) { return medium >= 0 && size_t(medium) < media.size() && !media[size_t(medium)].homogeneous(); };
  bool any_segment = false, any_light = false, any_piece = false;
  for (const EyeSegment& s : receivers_.segments) any_segment |= in_grid(s.medium);
  for (const EyeSegment& s : receivers_.segment_pieces) any_piece |= in_grid(s.medium);
  for (const VirtualLight& L : lights_.lights) any_light |= L.IsRay() && in_grid(L.medium);
  if (any_segment) {
    segment_tracks_.resize(receivers_.segments.size());
    tbb::parallel_for(size_t(0), receivers_.segments.size(), [&](size_t i) {
      const EyeSegment& s = receivers_.segments[i];
      // A row with coverage pieces integrates along them only.
      if (in_grid(s.medium) && s.pieces == 0) segment_tracks_[i] = MediumTrack(media[size_t(s.medium)], {s.o, s.d, s.length});
    });
  }
  if (any_piece) {
    piece_tracks_.resize(receivers_.segment_pieces.size());
    tbb::parallel_for(size_t(0), receivers_.segment_pieces.size(), [&](size_t i) {
      const EyeSegment& s = receivers_.segment_pieces[i];
      if (in_grid(s.medium)) piece_tracks_[i] = MediumTrack(media[size_t(s.medium)], {s.o, s.d, s.length});
    });
  }
  if (any_light) {
    light_tracks_.resize(lights_.size());
    tbb::parallel_for(size_t(0), lights_.size(), [&](size_t j) {
      const VirtualLight& L = lights_.lights[j];
      if (L.IsRay() && in_grid(L.medium)) light_tracks_[j] = MediumTrack(media[size_t(L.medium)], {L.p, L.n, L.length});
    });
  }
  for (const std::vector<MediumTrack>* tracks : {&segment_tracks_, &light_tracks_, &piece_tracks_})
    for (const MediumTrack& t : *tracks) {
      medium_tracks_ += t.knots() > 0;
      medium_track_knots_ += t.knots();
    }
}

float LightingMatrix::DensityFraction(int medium_a, int medium_b) const {
  const std::vector<Medium>& media = scene_.media();
  const bool grid = (medium_a >= 0 && !media[size_t(medium_a)].homogeneous()) ||
                    (medium_b >= 0 && !media[size_t(medium_b)].homogeneous());
  return grid ? density_fraction_ : 0.f;
}

const MediumTrack& LightingMatrix::SegmentTrack(uint32_t si, MediumTrack* scratch) const {
  const EyeSegment& s = receivers_.segments[si];
  if (si < segment_tracks_.size() && !scene_.media()[size_t(s.medium)].homogeneous()) return segment_tracks_[si];
  *scratch = MediumTrack(scene_.media()[size_t(s.medium)], {s.o, s.d, s.length});
  return *scratch;
}

LightingMatrix::SegmentRay LightingMatrix::SegmentRayFor(uint32_t si, uint32_t draw, MediumTrack* scratch) const {
  const EyeSegment& row = receivers_.segments[si];
  if (row.pieces == 0) {
    if (row.medium < 0) return {&row, scratch};  // nothing to integrate: the caller skips it
    return {&row, &SegmentTrack(si, scratch)};
  }
  const size_t pi = size_t(row.first_piece) + draw % row.pieces;
  const EyeSegment& s = receivers_.segment_pieces[pi];
  if (s.medium < 0) return {&s, scratch};
  if (pi < piece_tracks_.size() && !scene_.media()[size_t(s.medium)].homogeneous()) return {&s, &piece_tracks_[pi]};
  *scratch = MediumTrack(scene_.media()[size_t(s.medium)], {s.o, s.d, s.length});
  return {&s, scratch};
}

const MediumTrack& LightingMatrix::LightTrack(uint32_t col, MediumTrack* scratch) const {
  const VirtualLight& L = lights_.lights[col];
  if (col < light_tracks_.size() && !scene_.media()[size_t(L.medium)].homogeneous()) return light_tracks_[col];
  *scratch = MediumTrack(scene_.media()[size_t(L.medium)], {L.p, L.n, L.length});
  return *scratch;
}

// Every step mirrors the general path in EvaluateBatched with the same float operations in the
// same order (no FMA contraction on the baseline x86-64 target), so the bits agree; the savings
// are the row/light invariants hoisted to the constructor and no BSDF dispatch. The side tests
// reject about a third of the elements in no predictable order, so they are combined without
// branches (a mispredicted branch costs as much as the arithmetic of a whole element); the
// outputs are computed even for a rejected element, and then unused.
inline bool LightingMatrix::DiffuseElement(const RowData& row, const VirtualLight& V,
                                           const DiffuseLight& L, RGB* value,
                                           float* scale_unclamped, Vec3* w, Vec3* origin,
                                           Vec3* dir) const {
  Vec3 d = V.p - row.p;
  float dist2 = LengthSquared(d);
  *w = d / std::sqrt(dist2);
  float wi_z = Dot(*w, row.frame.n);
  float side = Dot(row.ng, *w);
  // The light's cosine towards the receiver: -w in the light's frame (exact negation).
  float out_z = -Dot(*w, V.n);
  float light_side = Dot(*w, V.ng);  // -(ng · -w), exactly
  // Surface VPL: the general path's (ng·-w)·cos_out <= 0 test (ng·-w = -light_side exactly) and
  // EvalDiffuse's same-hemisphere test at the light; area VPL: LightIntensityTowards' test.
  bool emits = L.surface ? !(light_side * out_z >= 0) & (L.wi_z * out_z > 0)
                         : !(out_z <= 0) | V.two_sided;
  bool ok = (V.depth <= row.light_depth_budget) & (dist2 > 0) & !(side * wi_z <= 0) &
            (row.wo_local.z * wi_z > 0) &  // EvalDiffuse: same hemisphere as wo
            emits;
  RGB intensity = L.emission * std::abs(out_z);
  float geometry = 1.f / dist2;
  *scale_unclamped = 1.f;
  if (dist2 < clamp_distance2_) {  // area and surface VPLs are always clamped
    geometry = 1.f / clamp_distance2_;
    *scale_unclamped = clamp_distance2_ / dist2;
  }
  *value = row.throughput_f * intensity * (std::abs(wi_z) * geometry);
  *origin = side < 0 ? row.origin_back : row.origin_front;
  *dir = (light_side > 0 ? L.target_back : L.target_front) - *origin;
  // Rare rejections (black or non-finite values, NaN rays) may branch.
  return ok && !intensity.IsBlack() && !value->IsBlack() && value->IsFinite() &&
         IsFinite(*origin) && IsFinite(*dir);
}

// The unshadowed value of any other surface element (every BSDF, every light kind but VRLs) and
// its shadow ray; false when it is zero. The general path of EvaluateBatched, inlined into it.
[[gnu::always_inline]] inline bool LightingMatrix::GeneralElement(
    const RowData& row, const VirtualLight& L, uint32_t lj, const std::vector<Material>& materials,
    RGB* value_out, float* scale_unclamped_out, float* bound_scale_out, Vec3* w_out, Vec3* o_out,
    Vec3* dir_out, float* tfar_out) const {
  if (L.depth > row.light_depth_budget) return false;
  // Direction to the light and the light's side of the element.
  Vec3& w = *w_out;
  float dist2 = 0;
  if (L.IsDirectional()) {
    w = -L.n;
  } else {
    Vec3 d = L.p - row.p;
    dist2 = LengthSquared(d);
    if (!(dist2 > 0)) return false;
    w = d / std::sqrt(dist2);
  }
  Vec3 wi_local = row.frame.ToLocal(w);
  // The geometric and shading normals must agree on the side, or light would leak.
  if (Dot(row.ng, w) * wi_local.z <= 0) return false;
  RGB f = EvalBSDF(materials[row.material], row.wo_local, wi_local, TransportMode::kRadiance);
  if (f.IsBlack()) return false;
  RGB intensity;
  // The element bound's kernel without the geometry term (f_x·f_y·cos_x·cos_y for surface VPLs,
  // f_x·cos_x·cos_y for area VPLs; largest channel) and its limit; 0: not bounded.
  float kernel = 0, bound = 0;
  if (L.kind == VirtualLightKind::kSurfaceVPL) {
    // As LightIntensityTowards, with the light's frame computed once per light.
    const SurfaceLightFrame& lf = light_frames_[lj];
    Vec3 out_local = lf.frame.ToLocal(-w);
    if (Dot(L.ng, -w) * out_local.z <= 0) return false;
    RGB fl = EvalBSDF(materials[L.material], lf.wi_local, out_local, TransportMode::kImportance);
    intensity = L.power * fl * std::abs(out_local.z);
    kernel = (f * fl).Max() * std::abs(out_local.z);
    bound = bound_surface_;
  } else {
    intensity = LightIntensityTowards(L, w, materials);
    if (L.kind == VirtualLightKind::kAreaVPL) {
      kernel = f.Max() * std::abs(Dot(L.n, w));
      bound = bound_area_;
    }
  }
  if (intensity.IsBlack()) return false;
  float geometry = 1.f, scale_unclamped = 1.f;
  if (!L.IsDirectional()) {
    if (L.IsClamped() && dist2 < clamp_distance2_) {
      geometry = 1.f / clamp_distance2_;
      scale_unclamped = clamp_distance2_ / dist2;
    } else {
      geometry = 1.f / dist2;
    }
  }
  RGB& value = *value_out;
  value = row.throughput * f * intensity * (std::abs(wi_local.z) * geometry);
  // The element bound: scale the whole element (its colour kept) so its kernel meets the limit.
  // Within 0.1% of the limit nothing changes, so float rounding on a white Lambertian pair at the
  // clamp distance never binds (the fast path relies on it).
  kernel *= std::abs(wi_local.z) * geometry;
  *bound_scale_out = 1.f;
  if (bound > 0 && kernel > bound * 1.001f) {
    const float s = bound / kernel;
    value *= s;
    *bound_scale_out = 1.f / s;
    scale_unclamped /= s;
  }
  *scale_unclamped_out = scale_unclamped;
  if (value.IsBlack() || !value.IsFinite()) return false;
  // Shadow ray between offset end points; dir is left unnormalised with tfar just short of 1.
  Vec3& o = *o_out;
  Vec3& dir = *dir_out;
  float& tfar = *tfar_out;
  o = OffsetRayOrigin(row.p, row.ng, w);
  if (L.IsDirectional()) {
    dir = w;
    tfar = kInfinity;
  } else {
    Vec3 target = (L.kind == VirtualLightKind::kPoint || L.kind == VirtualLightKind::kMediumVPL)
                      ? L.p
                      : OffsetRayOrigin(L.p, L.ng, -w);
    dir = target - o;
    tfar = 1.f - 1e-4f;
  }
  return IsFinite(o) && IsFinite(dir);  // never hand Embree a NaN ray
}

// The fast path's geometry of entries [begin, begin + count), a batch at a time, when the batch's
// shape has one: Row with a Lambertian row, Column with a fast light. False: per-entry path.
template <LightingMatrix::BatchShape kShape, typename EntryFn>
[[gnu::always_inline]] inline bool LightingMatrix::BatchDiffuseGeometry(
    size_t begin, size_t count, EntryFn& entry, uint32_t fixed, ReceiverBatch* receivers_out,
    DiffuseGeometryBatch* geo) const {
  ReceiverBatch& receivers = *receivers_out;
  if constexpr (kShape == BatchShape::kRow) {
    if (fixed < rows_.size() && rows_[fixed].diffuse) {
      const RowData& r = rows_[fixed];
      const FixedReceiver R{{r.p.x, r.p.y, r.p.z}, {r.frame.n.x, r.frame.n.y, r.frame.n.z},
                            {r.ng.x, r.ng.y, r.ng.z}, r.wo_local.z, r.light_depth_budget};
      const DiffuseLightArrays& a = light_arrays_;
      const LightArrays L{{&a.px[begin], &a.py[begin], &a.pz[begin]},
                          {&a.nx[begin], &a.ny[begin], &a.nz[begin]},
                          {&a.ngx[begin], &a.ngy[begin], &a.ngz[begin]}, &a.wi_z[begin],
                          &a.surface[begin], &a.two_sided[begin], &a.depth[begin]};
      DiffuseGeometry(count, R, L, clamp_distance2_, geo);
      return true;
    }
  } else if constexpr (kShape == BatchShape::kColumn) {
    if (diffuse_lights_[fixed].fast && !rows_.empty()) {
      for (size_t k = 0; k < count; ++k) {
        uint32_t ri, lj;
        entry(begin + k, &ri, &lj);
        // Other rows (eye segments) get a dummy receiver; their slot is never read.
        const RowData& r = rows_[ri < rows_.size() ? ri : 0];
        for (int c = 0; c < 3; ++c) {
          receivers.p[c][k] = r.p[c];
          receivers.n[c][k] = r.frame.n[c];
          receivers.ng[c][k] = r.ng[c];
        }
        receivers.wo_z[k] = r.wo_local.z;
        receivers.budget[k] = r.light_depth_budget;
      }
      const DiffuseLight& d = diffuse_lights_[fixed];
      const VirtualLight& V = lights_.lights[fixed];
      const FixedLight L{{V.p.x, V.p.y, V.p.z}, {V.n.x, V.n.y, V.n.z}, {V.ng.x, V.ng.y, V.ng.z},
                         d.wi_z, d.surface, V.two_sided, V.depth};
      DiffuseGeometry(count, ReceiverArrays(receivers), L, clamp_distance2_, geo);
      return true;
    }
  }
  return false;
}

// Sink contract: sink(k, v) gets every entry's value; an entry whose value is zero may get that
// zero more than once (the default, then again when its shadow ray is occluded), and a
// SkipsZeroDefaults sink may not get it at all.
template <typename EntryFn, typename SinkFn, LightingMatrix::BatchShape kShape>
void LightingMatrix::EvaluateBatched(size_t n, EntryFn entry, SinkFn sink,
                                     MatrixCounters* counters, uint32_t fixed) const {
  const std::vector<Material>& materials = scene_.materials();
  alignas(16) std::array<RTCRay, kBatch> rays;
  std::array<RGB, kBatch> values;
  std::array<float, kBatch> unclamped;
  std::array<float, kBatch> bounded;  // the element bound's factor (1: not bound)
  std::array<uint32_t, kBatch> slot;  // which entry of the batch a ray belongs to
  std::array<Vec3, kBatch> origins, dirs;  // shadow segments (for transmittance in media)
  std::array<float, kBatch> lengths;
  std::array<int16_t, kBatch> start_medium;
  std::array<uint64_t, kBatch> entry_key;
  const bool media = scene_.has_media();
  DiffuseGeometryBatch geo;  // the fast path's geometry of this batch, when `batched`
  ReceiverBatch receivers;        // Column: the batch's receivers, for the geometry kernel
  for (size_t begin = 0; begin < n; begin += kBatch) {
    size_t count = std::min(kBatch, n - begin);
    size_t nrays = 0;
    const bool batched = BatchDiffuseGeometry<kShape>(begin, count, entry, fixed, &receivers, &geo);
    // Queues the shadow ray of entry k (unshadowed `value`) for this batch's rtcOccluded1M.
    // keep = false writes the slot and leaves it to the next ray (no branch on the caller's test).
    auto add_ray = [&](uint32_t ri, uint32_t lj, size_t k, RGB value, float scale_unclamped,
                       float bound_scale, Vec3 w, Vec3 o, Vec3 dir, float tfar, bool directional,
                       bool keep) {
      RTCRay& ray = rays[nrays];
      ray.org_x = o.x; ray.org_y = o.y; ray.org_z = o.z;
      ray.dir_x = dir.x; ray.dir_y = dir.y; ray.dir_z = dir.z;
      ray.tnear = 0.f;
      ray.tfar = tfar;
      ray.time = 0.f;
      ray.mask = 0xFFFFFFFFu;
      ray.id = uint32_t(nrays);
      ray.flags = 0;
      if (media) {
        // Generalized visibility (Huo 2016, Sec. 3): visibility × transmittance of the shadow
        // segment, walked from the receiver's side (its medium is known) towards the light.
        const RowData& row = rows_[ri];
        origins[nrays] = o;
        float len = directional ? kInfinity : Length(dir);
        dirs[nrays] = directional ? dir : dir / len;
        lengths[nrays] = directional ? kInfinity : len * tfar;
        start_medium[nrays] = Dot(w, row.ng) > 0 ? row.medium_out : row.medium_in;
        entry_key[nrays] = (uint64_t(ri) << 32) | lj;
      }
      values[nrays] = value;
      unclamped[nrays] = scale_unclamped;
      bounded[nrays] = bound_scale;
      slot[nrays] = uint32_t(k);
      nrays += keep ? 1 : 0;
    };
    for (size_t k = 0; k < count; ++k) {
      uint32_t ri, lj;
      entry(begin + k, &ri, &lj);
      DCHECK_LT(ri, rows());
      DCHECK_LT(lj, cols());
      if (ri >= rows_.size()) {
        // Eye-segment row: integrated by its own batched samples.
        sink(begin + k, SegmentElement(ri - uint32_t(rows_.size()), lj, counters));
        continue;
      }
      const RowData& row = rows_[ri];
      if constexpr (!SkipsZeroDefaults<SinkFn>)
        sink(begin + k, RGB(0.f));  // default: zero unless visible below
      if (row.diffuse && diffuse_lights_[lj].fast) {
        RGB value;
        float scale_unclamped;
        Vec3 w, o, dir;
        const DiffuseLight& DL = diffuse_lights_[lj];
        bool keep;
        if (batched) {
          // The rest of DiffuseElement from the batch's geometry.
          RGB intensity = DL.emission * geo.abs_out[k];
          value = row.throughput_f * intensity * geo.g[k];
          scale_unclamped = geo.scale[k];
          w = {geo.wx[k], geo.wy[k], geo.wz[k]};
          o = geo.back[k] ? row.origin_back : row.origin_front;
          dir = (geo.light_back[k] ? DL.target_back : DL.target_front) - o;
          keep = geo.ok[k] && !intensity.IsBlack() && !value.IsBlack() && value.IsFinite() &&
                 IsFinite(o) && IsFinite(dir);
        } else {
          keep = DiffuseElement(row, lights_.lights[lj], DL, &value, &scale_unclamped, &w, &o, &dir);
        }
        add_ray(ri, lj, k, value, scale_unclamped, 1.f, w, o, dir, 1.f - 1e-4f, false, keep);
        continue;
      }
      const VirtualLight& L = lights_.lights[lj];
      if (L.IsRay()) {
        // VRL column: an integral along the light, with its own batch of samples.
        sink(begin + k, VrlPointElement(ri, lj, counters));
        continue;
      }
      RGB value;
      float scale_unclamped, bound_scale, tfar;
      Vec3 w, o, dir;
      if (!GeneralElement(row, L, lj, materials, &value, &scale_unclamped, &bound_scale, &w, &o, &dir, &tfar))
        continue;
      add_ray(ri, lj, k, value, scale_unclamped, bound_scale, w, o, dir, tfar, L.IsDirectional(), true);
    }
    counters->elements += count;
    if (nrays == 0) continue;
    if (recorded_rays_) recorded_rays_->insert(recorded_rays_->end(), rays.begin(), rays.begin() + nrays);
    scene_.Occluded(rays.data(), nrays);
    counters->shadow_rays += nrays;
    for (size_t r = 0; r < nrays; ++r) {
      bool lit = rays[r].tfar >= 0.f;  // occluded: Embree sets tfar = -inf
      if (media && lit) {
        // Seeded by the job seed and the element: an element has the same value whichever method
        // asks, and independent passes of a progressive job (other seeds) are independent.
        Rng rng(HashSeed({uint64_t(RngStream::kMedium), seed_, entry_key[r]}));
        values[r] *= scene_.TransmittanceAlong(origins[r], dirs[r], lengths[r], start_medium[r], rng);
        ++counters->transmittance_evals;
        lit = !values[r].IsBlack();
      }
      // An unlit entry is sent its zero again rather than skipped: no branch on the visibility
      // (unpredictable), and the same result for every sink (a store, or adding +0 to a sum).
      sink(begin + slot[r], lit ? values[r] : RGB(0.f));
      if (unclamped[r] != 1.f && lit) {
        float lum = values[r].Luminance();
        counters->clamp_lost += double(lum) * double(unclamped[r] - 1.f);
        counters->clamp_kept += double(lum);
        if (bounded[r] != 1.f) {
          counters->bound_lost += double(lum) * double(bounded[r] - 1.f);
          ++counters->bound_elements;
        }
      }
    }
  }
}

void LightingMatrix::EvaluateEntries(std::span<const uint32_t> rows, std::span<const uint32_t> cols,
                                     std::span<RGB> out, MatrixCounters* counters) const {
  CHECK_EQ(rows.size(), cols.size());
  CHECK_EQ(out.size(), rows.size());
  EvaluateBatched(
      rows.size(),
      [&](size_t k, uint32_t* r, uint32_t* c) { *r = rows[k]; *c = cols[k]; },
      [&](size_t k, RGB v) { out[k] = v; }, counters);
}

RGB LightingMatrix::Element(uint32_t row, uint32_t col, MatrixCounters* counters) const {
  RGB out;
  EvaluateEntries(std::span<const uint32_t>(&row, 1), std::span<const uint32_t>(&col, 1),
                  std::span<RGB>(&out, 1), counters);
  return out;
}

void LightingMatrix::Row(uint32_t row, std::span<RGB> out, MatrixCounters* counters) const {
  CHECK_LT(row, rows());
  CHECK_EQ(out.size(), cols());
  auto entry = [&](size_t k, uint32_t* r, uint32_t* c) { *r = row; *c = uint32_t(k); };
  auto store = [&](size_t k, RGB v) { out[k] = v; };
  EvaluateBatched<decltype(entry), decltype(store), BatchShape::kRow>(cols(), entry, store,
                                                                      counters, row);
}

RGBAccum LightingMatrix::RowSum(uint32_t row, MatrixCounters* counters) const {
  CHECK_LT(row, rows());
  RGBAccum sum;
  // Values arrive per batch in light order (zeros first, then visible ones), so the double sum
  // is independent of threading.
  auto entry = [&](size_t k, uint32_t* r, uint32_t* c) { *r = row; *c = uint32_t(k); };
  RowSumSink add{&sum};
  EvaluateBatched<decltype(entry), decltype(add), BatchShape::kRow>(cols(), entry, add, counters,
                                                                    row);
  return sum;
}

void LightingMatrix::Column(uint32_t col, std::span<const uint32_t> rows, std::span<RGB> out,
                            MatrixCounters* counters) const {
  CHECK_LT(col, cols());
  CHECK_EQ(out.size(), rows.size());
  auto entry = [&](size_t k, uint32_t* r, uint32_t* c) { *r = rows[k]; *c = col; };
  auto store = [&](size_t k, RGB v) { out[k] = v; };
  EvaluateBatched<decltype(entry), decltype(store), BatchShape::kColumn>(rows.size(), entry, store,
                                                                         counters, col);
}

}  // namespace lightfarm
