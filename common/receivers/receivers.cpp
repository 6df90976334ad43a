#include "common/receivers/receivers.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <numeric>
#include <optional>
#include <span>

#include <embree3/rtcore.h>

#include "common/lights/emitters.h"
#include "common/scene/medium_track.h"
#include "common/scene/phase.h"
#include "common/util/rng.h"
#include "common/util/sampling.h"

namespace lightfarm {

namespace {

// A material whose every lobe is black reflects nothing: its row would be all zeros.
bool ReflectsNothing(const Material& m) {
  return m.type == MaterialType::kDiffuse && m.reflectance.IsBlack();
}

struct PathEnd {
  RGB emitted;
  // Receivers along the path: the rough part of every vertex the path split at, then the
  // vertex it ended on (CameraPathOptions::splits).
  std::vector<ShadingPoint> points;
  int specular_bounces = 0;
  int split_vertices = 0;
  int near_sharp_vertices = 0;
  bool escaped = false;
  size_t transmittance_evals = 0;
  size_t media_direct_samples = 0;
  std::vector<EyeSegment> segments;
  // Knots of the track of the first medium piece, when segments begin with it (depth 1): what
  // its coverage pieces will cost (GenerateReceivers, segment coverage).
  size_t first_segment_knots = 0;
};

// One emitter sample of next-event estimation for the sharp lobe of the vertex at `hit`
// (docs/rendering.md, "Sharp lobes"), given that the camera path follows the lobe (with
// probability p_choice: SampleBSDF's p_lobe when the path chose between the lobes, 1 when it
// split), weighted by the power heuristic against the lobe's own sample (whose density given the
// lobe is PdfSharpLobe / p_lobe) with `count` emitter samples to one lobe sample (Veach 1997,
// Sec. 9.2.4: weights on n_i·p_i): the caller averages the `count` samples.
RGB SharpLobeEmitterSample(const Scene& scene, const EmitterSampler& lights, const SurfaceHit& hit,
                           const Material& m, const Frame& frame, Vec3 wo_local, float p_lobe, float p_choice,
                           int medium, int count, Rng& rng) {
  const float u_pick = rng.Uniform();
  const Vec2 u{rng.Uniform(), rng.Uniform()};
  const std::optional<LightSample> ls = lights.Sample(hit.p, u_pick, u);
  if (!ls || !(p_lobe > 0) || !(p_choice > 0)) return RGB(0.f);
  const Vec3 wi_local = frame.ToLocal(ls->wi);
  const RGB f = EvalSharpLobe(m, wo_local, wi_local, TransportMode::kRadiance) * std::abs(wi_local.z);
  if (f.IsBlack()) return RGB(0.f);
  const int start = scene.has_media() ? scene.MediumAfter(hit, ls->wi, medium) : medium;
  const RGB tr = LightSampleVisibility(scene, OffsetRayOrigin(hit.p, hit.ng, ls->wi), *ls, start, rng);
  if (tr.IsBlack()) return RGB(0.f);
  const float w = ls->delta ? 1.f : PowerHeuristic(float(count) * ls->pdf, PdfSharpLobe(m, wo_local, wi_local) / p_lobe);
  return f * ls->L * tr * (w / (ls->pdf * p_choice));
}

// Next-event estimation at a sharp vertex: the average of `count` emitter samples. A sharp lobe
// reflecting a small light (veach-mis's smallest sphere on its smoothest plate) is found by
// emitter samples, not by the lobe's one sample; each costs one shadow ray, against the
// thousands the receiver's gather casts, so several per vertex are nearly free.
RGB SharpLobeDirectLight(const Scene& scene, const EmitterSampler& lights, const SurfaceHit& hit,
                         const Material& m, const Frame& frame, Vec3 wo_local, float p_lobe, float p_choice,
                         int medium, int count, Rng& rng) {
  RGB sum(0.f);
  for (int i = 0; i < count; ++i)
    sum += SharpLobeEmitterSample(scene, lights, hit, m, frame, wo_local, p_lobe, p_choice, medium, count, rng);
  return sum / float(count);
}

// What a camera path collects by itself besides the emission it sees, and what it leaves for the
// matrix (docs/rendering.md, "Camera-side supersampling" and "Rows, columns and elements").
class NearFieldLights;

struct CameraPathOptions {
  int max_depth = 5;
  // Emitter samples at a vertex that follows a sharp lobe, MIS-combined with the lobe's own
  // sample (set when the scene has sharp lobes).
  const EmitterSampler* sharp_lights = nullptr;
  int sharp_samples = 1;
  // Single scattering of the emitters' light along each medium piece of the path, by
  // `media_samples` samples (DirectInScattering); eye-segment rows then gather only the lights
  // particle paths left (set when media rows are on and the emitters' direct light in media is
  // the camera's).
  const EmitterSampler* media_lights = nullptr;
  int media_samples = 0;
  // Eye segments per opaque medium piece, minus one (AppendEyeSegments); -1: no segments.
  int segments_per_ray = -1;
  // Vertices per path that split instead of choosing (ReceiverOptions::splits): a sharp or delta
  // coat over a rough base, a smooth dielectric. Later such vertices choose.
  int splits = 0;
  // Whether the path's receivers are kept (false for paths that only collect camera-side light).
  bool keep_points = true;
  // The near-field rule's stand-in lights (ReceiverOptions::near_sharp_lights); null: off.
  const NearFieldLights* near_lights = nullptr;
};

// The near-field rule's stand-in for the render's lights (docs/rendering.md, "Sharp lobes", *Near
// field*): the surface VPLs of a light set drawn like the render's but on its own seed, so which
// vertices take a twin never depends on the lights the render gathers (either choice is then an
// unbiased estimate). A k-d tree over their positions answers "how many within r of x", up to a cap.
class NearFieldLights {
 public:
  // A vertex takes its twin where fewer of these fall in its lobe's footprint.
  static constexpr size_t kEnoughLights = 40;

  NearFieldLights(const Scene& scene, const LightGenerationOptions& opt) {
    const LightSet set = GenerateLights(scene, opt);
    for (const VirtualLight& l : set.lights)
      if (l.kind == VirtualLightKind::kSurfaceVPL) points_.push_back(l.p);
    Build(0, points_.size(), 0);
  }
  size_t size() const { return points_.size(); }

  // The points within r of x, counting no further than cap.
  size_t CountWithin(Vec3 x, float r, size_t cap) const {
    size_t n = 0;
    Count(0, points_.size(), 0, x, r * r, cap, &n);
    return n;
  }

 private:
  static float Axis(Vec3 v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }
  // Median splits on x, y, z in turn: the subrange [lo, hi)'s median sits at its middle.
  void Build(size_t lo, size_t hi, int axis) {
    if (hi - lo <= 1) return;
    const size_t mid = lo + (hi - lo) / 2;
    std::nth_element(points_.begin() + long(lo), points_.begin() + long(mid), points_.begin() + long(hi),
                     [axis](Vec3 a, Vec3 b) { return Axis(a, axis) < Axis(b, axis); });
    Build(lo, mid, (axis + 1) % 3);
    Build(mid + 1, hi, (axis + 1) % 3);
  }
  void Count(size_t lo, size_t hi, int axis, Vec3 x, float r2, size_t cap, size_t* n) const {
    if (lo >= hi || *n >= cap) return;
    const size_t mid = lo + (hi - lo) / 2;
    const Vec3 p = points_[mid];
    const Vec3 d = p - x;
    if (Dot(d, d) <= r2) ++*n;
    const float delta = Axis(x, axis) - Axis(p, axis);
    const int next = (axis + 1) % 3;
    // The side x is on first; the other only if the sphere reaches across the split.
    if (delta < 0) {
      Count(lo, mid, next, x, r2, cap, n);
      if (delta * delta <= r2) Count(mid + 1, hi, next, x, r2, cap, n);
    } else {
      Count(mid + 1, hi, next, x, r2, cap, n);
      if (delta * delta <= r2) Count(lo, mid, next, x, r2, cap, n);
    }
  }
  std::vector<Vec3> points_;
};

// Whether the vertex at `hit`, seen from wo, takes its material's near-field sharp twin: its
// mirror direction meets a surface that is not an emitter (emitters carry their own dense
// lights) at distance d, and fewer than kEnoughLights of the stand-in lights lie within 2αd of
// that point, the footprint of the lobe's cone (half-angle ≈ 2α). A function of the vertex alone.
bool TakesNearSharpTwin(const Scene& scene, const NearFieldLights& lights, const SurfaceHit& hit, Vec3 wo,
                        const Material& m) {
  const float alpha = std::max(m.alpha_x, m.alpha_y);
  const Vec3 r = hit.ns * (2 * Dot(wo, hit.ns)) - wo;
  if (!(alpha > 0) || Dot(r, hit.ng) * Dot(wo, hit.ng) <= 0) return false;
  SurfaceHit near;
  if (!scene.Intersect(Ray{OffsetRayOrigin(hit.p, hit.ng, r), r, kInfinity}, &near, kMaskOpaque) ||
      scene.shapes()[near.shape].area_emitter >= 0)
    return false;
  const float footprint = 2 * alpha * near.t;
  return lights.CountWithin(near.p, footprint, NearFieldLights::kEnoughLights) < NearFieldLights::kEnoughLights;
}

// A camera ray's piece [0, tmax] inside one medium, tabulated (an unbounded piece, a ray leaving
// into an endless medium, is cut where any light left along it is negligible or, for an empty
// medium, where nothing is).
MediumTrack CameraPieceTrack(const Medium& med, const Ray& ray, float tmax) {
  if (!std::isfinite(tmax)) {
    const float st = med.sigma_t().Max() * med.MaxDensity();
    tmax = st > 0 ? 30.f / st : 0.f;
  }
  return MediumTrack(med, {ray.o, ray.d, tmax});
}

// The emitters' light scattered once towards the camera along a camera ray's medium piece:
//   ∫ Tr(0→t) σ_s(t) ∫ p_g(ω, −d) L_e(ω) Tr V dω dt,
// by `count` samples t ∝ σ_s·Tr (the piece's track, stratified), each with one emitter sample
// (next-event estimation, as the path tracer's at a medium vertex but without MIS: no phase
// sample follows, so the emitter sample carries every direction).
RGB DirectInScattering(const Scene& scene, const EmitterSampler& lights, const MediumTrack& track, const Ray& ray,
                       int medium, int count, Rng& rng) {
  if (track.empty() || count <= 0) return RGB(0.f);
  const float g = scene.media()[size_t(medium)].g();
  RGBAccum sum;
  for (int k = 0; k < count; ++k) {
    float pdf;
    size_t where;
    const float t = track.Sample(std::min((float(k) + rng.Uniform()) / float(count), 0x1.fffffep-1f), &pdf, &where);
    const float u_pick = rng.Uniform();
    const Vec2 u{rng.Uniform(), rng.Uniform()};
    if (!(pdf > 0)) continue;
    const MediumTrack::Point p = track.At(t, where);
    if (p.sigma_s.IsBlack()) continue;
    const Vec3 x = ray.o + ray.d * t;
    const std::optional<LightSample> ls = lights.Sample(x, u_pick, u);
    if (!ls) continue;
    // Light travelling along -wi scatters into the camera ray's reverse direction -d.
    const float phase = HenyeyGreenstein(Dot(ls->wi, ray.d), g);
    if (!(phase > 0)) continue;
    const RGB tr = LightSampleVisibility(scene, x, *ls, medium, rng);
    if (tr.IsBlack()) continue;
    sum.Add(p.sigma_s * p.tr * ls->L * tr * (phase / (ls->pdf * pdf * float(count))));
  }
  return sum.ToRGB();
}

// Follows a camera ray through specular (delta and sharp) interactions to its non-specular
// vertices, collecting the emission seen along the way, and what `opt` asks for: at a vertex that
// follows a sharp lobe, emission by MIS of the lobe's sample and emitter samples; along medium
// pieces, eye segments and the emitters' single scattering. The first opt.splits vertices that
// offer two ways on split and take both (docs/rendering.md, "Split vertices"): a clear coat over a
// rough base makes a receiver and follows the coat; a smooth dielectric follows its reflection
// and, later, its refraction. Later ones choose one at random.
PathEnd TraceCameraPath(const Scene& scene, const CameraPathOptions& opt, Ray ray, Rng& rng) {
  const EmitterSampler* lights = opt.sharp_lights;
  const int sharp_samples = opt.sharp_samples, max_depth = opt.max_depth;
  PathEnd end;
  // One way through the scene: its ray and weight and, after a sharp-lobe sample, the lobe's
  // density given the lobe and where it left from, for the MIS weight of an emitter the ray finds
  // (against sharp_samples emitter samples).
  struct Branch {
    Ray ray;
    RGB beta{1.f};
    int depth = 0, passthrough = 0, medium = -1;
    bool after_sharp = false;
    float sharp_pdf = 0;
    Vec3 sharp_p;
    bool may_split = true;
  };
  // Ways a split left for later, followed depth first when the current one ends (one per split).
  std::array<Branch, kMaxSplits> pending;
  int npending = 0;
  Branch b;
  b.ray = ray;
  b.medium = scene.camera_medium();
  for (;;) {
    for (;;) {
      SurfaceHit hit;
      const bool found = scene.Intersect(b.ray, &hit);
      // Attenuation of the surface (and emission) seen at the end of this ray segment: an
      // unbiased transmittance estimate (closed form in homogeneous media).
      if (b.medium >= 0) {
        const Medium& med = scene.media()[b.medium];
        const float tmax = found ? hit.t : kInfinity;
        if (b.depth < max_depth && (opt.segments_per_ray >= 0 || opt.media_lights)) {
          // The scattering vertex on this piece would be the path's depth + 1.
          const MediumTrack track = CameraPieceTrack(med, b.ray, tmax);
          if (opt.segments_per_ray >= 0) {
            const bool first = end.segments.empty() && b.depth == 0;
            AppendEyeSegments(track, b.medium, b.ray, b.beta, opt.segments_per_ray,
                              uint8_t(std::min(b.depth + 1, 255)), &end.segments);
            if (first && !end.segments.empty()) end.first_segment_knots = track.knots();
          }
          if (opt.media_lights && !track.empty()) {
            end.emitted += b.beta * DirectInScattering(scene, *opt.media_lights, track, b.ray, b.medium,
                                                       opt.media_samples, rng);
            end.media_direct_samples += size_t(opt.media_samples);
          }
          b.beta *= track.TransmittanceToEnd();
        } else {
          b.beta *= med.Transmittance({b.ray.o, b.ray.d, tmax}, rng);
        }
        ++end.transmittance_evals;
        if (b.beta.IsBlack()) break;
      }
      if (!found) {
        if (!b.after_sharp) {
          end.emitted += b.beta * scene.EnvironmentRadiance(b.ray.d);
        } else {
          for (uint32_t i = 0; i < scene.infinite_emitters().size(); ++i)
            end.emitted += b.beta * scene.infinite_emitters()[i].Le(b.ray.d) *
                           PowerHeuristic(b.sharp_pdf, float(sharp_samples) * lights->PdfInfinite(i, b.ray.d));
        }
        end.escaped = true;
        break;
      }
      const Vec3 wo = -b.ray.d;
      {
        const RGB Le = scene.EmittedRadiance(hit, wo);
        if (!Le.IsBlack()) {
          const int e = scene.shapes()[hit.shape].area_emitter;
          const float w = b.after_sharp && e >= 0
                              ? PowerHeuristic(b.sharp_pdf, float(sharp_samples) * lights->PdfArea(uint32_t(e), b.sharp_p, hit))
                              : 1.f;
          end.emitted += b.beta * Le * w;
        }
      }
      const Shape& shape = scene.shapes()[hit.shape];
      int material = shape.material;
      if (opt.near_lights) {
        const int twin = scene.near_sharp_twin(material);
        if (twin >= 0 && TakesNearSharpTwin(scene, *opt.near_lights, hit, wo, scene.materials()[size_t(material)])) {
          material = twin;
          ++end.near_sharp_vertices;
        }
      }
      const Material& m = scene.materials()[size_t(material)];
      const uint32_t flags = MaterialFlags(m);
      if (flags == 0) {  // interface: not a surface, only the medium changes
        if (++b.passthrough > 64) break;
        b.medium = scene.MediumAfter(hit, b.ray.d, b.medium);
        b.ray.o = OffsetRayOrigin(hit.p, hit.ng, b.ray.d);
        continue;
      }
      b.after_sharp = false;
      if (++b.depth > max_depth) break;
      const Frame frame(hit.ns);
      const Vec3 wo_local = frame.ToLocal(wo);
      const auto make_receiver = [&](RGB throughput) {
        if (ReflectsNothing(m) || !opt.keep_points) return;
        ShadingPoint& point = end.points.emplace_back();
        point.p = hit.p;
        point.ng = hit.ng;
        point.ns = hit.ns;
        point.wo = wo;
        point.throughput = throughput;
        point.material = uint32_t(material);
        point.depth = uint8_t(std::min(b.depth, 255));
        point.medium_out = int16_t(shape.medium_transition ? shape.outside_medium : b.medium);
        point.medium_in = int16_t(shape.medium_transition ? shape.inside_medium : b.medium);
      };
      const auto continue_along = [&](Branch& branch, const BSDFSample& bs) {
        const Vec3 wi = frame.FromLocal(bs.wi);
        branch.medium = scene.MediumAfter(hit, wi, b.medium);
        branch.ray = {OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity};
      };
      // A material with delta (or sharp) and rough lobes (a smooth coat over a diffuse base). The
      // matrix evaluates only the rough lobes, so a receiver here carries the light the base
      // reflects (f_base already holds what the coat transmits); the coat's reflection is carried
      // by following its lobe. Split: both, each with weight 1: the receiver with beta, the lobe
      // with beta·f·cos/pdf_lobe; every path is counted once and no sample loses the base.
      // Choose: follow the lobe with probability p, else become a receiver weighted by 1/(1-p).
      const float p_specular = SpecularSamplingProbability(m, wo_local);
      const bool mixed = !IsPurelySpecular(flags) && p_specular > 0;
      // A smooth dielectric: reflection with probability r, else refraction. Split: both, each
      // with weight f·cos (the sample's pdf is the discrete choice, bsdf.h).
      const float p_reflect = mixed ? -1.f : DeltaReflectionProbability(m, wo_local);
      const bool split =
          b.may_split && end.split_vertices < opt.splits && (mixed || (p_reflect > 0 && b.depth < max_depth));
      // After a split only the way that carries most of the light goes on splitting (the
      // sampling probabilities say which), so the budget is spent along the path that matters.
      float uc = rng.Uniform();
      // The lobe's share of SampleBSDF's choice (its pdf includes it), and the probability that
      // this path follows the lobe: the same when it chooses, 1 when it splits.
      const float p_lobe = mixed ? std::max(p_specular, 1e-6f) : 1.f;
      float p_choice = p_lobe;
      if (split && mixed) {
        ++end.split_vertices;
        make_receiver(b.beta);
        if (b.depth >= max_depth) break;
        uc *= p_specular;  // SampleBSDF picks the delta lobe exactly when uc < p_specular (bsdf.h)
        p_choice = 1.f;
      } else if (split) {
        ++end.split_vertices;
        // Both ways of a smooth dielectric (uc < r picks the reflection); its directions take no
        // random numbers. The heavier goes on now, the other waits.
        const std::optional<BSDFSample> sampled[2] = {
            SampleBSDF(m, wo_local, 0.f, {0.5f, 0.5f}, TransportMode::kRadiance),
            SampleBSDF(m, wo_local, p_reflect, {0.5f, 0.5f}, TransportMode::kRadiance)};
        Branch next[2];
        int n = 0;
        for (const std::optional<BSDFSample>& w : sampled) {
          if (!w || !(w->pdf > 0) || !w->IsSpecular()) continue;
          Branch& nb = next[n];
          nb = b;
          nb.beta = b.beta * w->f * std::abs(w->wi.z);
          if (nb.beta.IsBlack() || !nb.beta.IsFinite()) continue;
          continue_along(nb, *w);
          ++n;
        }
        if (n == 0) break;
        // next[0] is the reflection when both exist; the likelier way goes on now.
        if (n == 2) {
          next[0].may_split = p_reflect >= 0.5f;
          next[1].may_split = !next[0].may_split;
          if (!next[0].may_split) std::swap(next[0], next[1]);
        }
        end.specular_bounces += size_t(n);
        if (n == 2) pending[size_t(npending++)] = next[1];
        b = next[0];
        continue;
      } else if (!IsPurelySpecular(flags) && uc >= p_specular) {
        make_receiver(b.beta / (1.f - p_specular));
        break;
      }
      if (b.depth >= max_depth) break;
      // Continue along a delta lobe (radiance transport); for a mixed material uc < p_specular
      // makes SampleBSDF choose the delta lobe, and its pdf includes p_specular.
      std::optional<BSDFSample> bs = SampleBSDF(m, wo_local, uc, {rng.Uniform(), rng.Uniform()}, TransportMode::kRadiance);
      if (!bs || !(bs->pdf > 0) || !bs->IsSpecular()) break;
      if (lights && HasSharpLobe(m)) {
        // A sharp lobe is not a delta: emitters it reflects get an emitter sample too (MIS).
        end.emitted += b.beta * SharpLobeDirectLight(scene, *lights, hit, m, frame, wo_local, p_lobe, p_choice,
                                                     b.medium, sharp_samples, rng);
        b.after_sharp = true;
        b.sharp_pdf = bs->pdf / p_lobe;
        b.sharp_p = hit.p;
      }
      // Split: the coat is always followed, so its weight is f·cos over its density given the coat.
      if (split) bs->pdf /= p_specular;
      b.beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
      if (b.beta.IsBlack() || !b.beta.IsFinite()) break;
      if (split) b.may_split = p_specular >= 0.5f;
      ++end.specular_bounces;
      continue_along(b, *bs);
    }
    if (npending == 0) return end;
    b = pending[size_t(--npending)];
  }
}

// The camera ray through pixel (x, y) at the filter sample fs.
Ray FilmRay(const Scene& scene, int x, int y, const FilterSample& fs, Rng& rng) {
  const Vec2 p_film{float(x) + 0.5f + fs.p.x, float(y) + 0.5f + fs.p.y};
  return scene.camera().GenerateRay(p_film, {rng.Uniform(), rng.Uniform()});
}

// Which pixels get camera paths (docs/rendering.md, "Camera-side supersampling"). Both tests
// are independent of the image's samples (the pilot has its own stream, the emitters are
// geometry), so the estimate stays unbiased whatever they choose.
class CameraSideActivity {
 public:
  CameraSideActivity(const Scene& scene, const FilterSampler& filter, const CameraPathOptions& paths,
                     const ReceiverOptions& opt, std::vector<ReceiverStats>* row_stats)
      : width_(scene.hints().width), height_(scene.hints().height) {
    const size_t npix = size_t(width_) * size_t(height_);
    lo_.assign(npix, 0.f);
    hi_.assign(npix, 0.f);
    hit_rate_.assign(npix, kInfinity);
    min_paths_.assign(npix, 0);
    RunPilot(scene, filter, paths, opt, row_stats);
    MarkSmallEmitters(scene);
    MarkSpecularImages(scene, opt);
    GrantMarkedPaths(opt.camera_paths);
    ShareActivePaths(opt.camera_paths);
  }

  // Camera paths for pixel (x, y): where a small emitter's image (seen directly or through delta
  // interactions) marked the pixel, enough for about kCameraTargetHits of its paths to find the
  // light (GrantMarkedPaths); where the pilot saw the camera-side light vary, its share of the
  // active pixels' paths (ShareActivePaths); at least the larger of the two. 0: none.
  int paths(int x, int y) const {
    const size_t i = size_t(y) * width_ + x;
    return int(std::max(min_paths_[i], active_paths_[i]));
  }

 private:
  // kCameraPilotPaths paths per pixel on their own stream, never part of the image: the range
  // of their camera-side luminance (-1 for a non-finite one, which makes the block active).
  void RunPilot(const Scene& scene, const FilterSampler& filter, const CameraPathOptions& paths,
                const ReceiverOptions& opt, std::vector<ReceiverStats>* row_stats) {
    tbb::parallel_for(0, height_, [&](int y) {
      ReceiverStats& st = (*row_stats)[y];
      for (int x = 0; x < width_; ++x) {
        const size_t pixel = size_t(y) * width_ + x;
        Rng rng(HashSeed({opt.seed, uint64_t(RngStream::kCameraPilot), pixel}));
        float lo = kInfinity, hi = -kInfinity;
        for (int k = 0; k < kCameraPilotPaths; ++k) {
          const Ray ray = FilmRay(scene, x, y, filter.Sample({rng.Uniform(), rng.Uniform()}), rng);
          ++st.camera_pilot_paths;
          float v = 0;
          if (IsFinite(ray.o) && IsFinite(ray.d))
            v = TraceCameraPath(scene, paths, ray, rng).emitted.Luminance();
          if (!std::isfinite(v)) v = -1;
          lo = std::min(lo, v);
          hi = std::max(hi, v);
        }
        lo_[pixel] = lo;
        hi_[pixel] = hi;
      }
    });
  }

  // Marks pixels where one path in 1/hit_rate finds a light (the rarest light a pixel is
  // marked for sets its count).
  void Mark(int x0, int y0, int x1, int y1, double hit_rate) {
    for (int y = std::max(0, y0); y <= std::min(height_ - 1, y1); ++y)
      for (int x = std::max(0, x0); x <= std::min(width_ - 1, x1); ++x) {
        float& h = hit_rate_[size_t(y) * width_ + x];
        h = std::min(h, float(std::max(hit_rate, 1e-12)));
      }
  }

  // A pixel is active when the pilot's values over it and its 8 neighbours differ by more than
  // 10% (across pixels, so the edge between a light and its background is found even where each
  // pixel's own paths agree). The active pixels share `base` paths each: a quarter of them evenly,
  // the rest in proportion to the spread of those values (max − min luminance), the pilot's
  // measure of the camera-side light's standard deviation there. Spreading n paths as n_p ∝ σ_p
  // minimises Σ σ_p² / n_p, the camera side's squared error summed over the image: a small
  // light's reflection in a smooth plate (σ in the hundreds) gets thousands of paths, a dim
  // textured wall a few dozen. A non-finite pilot value makes the pixel active with the mean share.
  void ShareActivePaths(int base) {
    active_paths_.assign(lo_.size(), 0);
    if (base <= 0) return;
    std::vector<float> spread(lo_.size(), -1.f);  // -1: inactive; kInfinity: non-finite pilot
    double total = 0;
    size_t active = 0, finite = 0;
    for (int y = 0; y < height_; ++y)
      for (int x = 0; x < width_; ++x) {
        float lo = kInfinity, hi = -kInfinity;
        for (int yy = std::max(0, y - 1); yy <= std::min(height_ - 1, y + 1); ++yy)
          for (int xx = std::max(0, x - 1); xx <= std::min(width_ - 1, x + 1); ++xx) {
            lo = std::min(lo, lo_[size_t(yy) * width_ + xx]);
            hi = std::max(hi, hi_[size_t(yy) * width_ + xx]);
          }
        if (!(lo < 0.f || hi > 1.1f * lo)) continue;
        ++active;
        float& s = spread[size_t(y) * width_ + x];
        s = lo < 0.f ? kInfinity : hi - lo;
        if (lo >= 0.f) {
          total += double(s);
          ++finite;
        }
      }
    if (active == 0) return;
    const double mean = finite > 0 ? total / double(finite) : 1.0;
    total += mean * double(active - finite);
    const double even = double(base) * kEvenActiveShare;
    const double rest = (double(base) - even) * double(active);
    for (size_t i = 0; i < spread.size(); ++i) {
      if (spread[i] < 0.f) continue;
      const double s = spread[i] == kInfinity ? mean : double(spread[i]);
      const double share = total > 0 ? s / total : 1.0 / double(active);
      active_paths_[i] = uint32_t(std::clamp(std::llround(even + rest * share), 1LL, (long long)kMaxCameraPaths));
    }
  }

  // Each marked pixel asks for kCameraTargetHits / hit rate paths, at least `base`, at most
  // kMaxCameraPaths. Granted from the highest hit rate down (the light found for the fewest
  // paths first; ties in pixel order, so the choice is deterministic) while the total stays
  // within kMarkedPathsPerPixel per pixel of the image (at least kMinMarkedPaths): where the
  // estimate says a light is one hit in a million, no count is worth its time, and the pixel
  // keeps `base`.
  void GrantMarkedPaths(int base) {
    std::vector<uint32_t> marked;
    for (uint32_t i = 0; i < uint32_t(hit_rate_.size()); ++i)
      if (hit_rate_[i] < kInfinity) marked.push_back(i);
    std::stable_sort(marked.begin(), marked.end(), [&](uint32_t a, uint32_t b) { return hit_rate_[a] > hit_rate_[b]; });
    double budget = std::max(kMinMarkedPaths, kMarkedPathsPerPixel * double(hit_rate_.size()));
    for (const uint32_t i : marked) {
      const double want = std::clamp(std::ceil(kCameraTargetHits / double(hit_rate_[i])), double(std::max(base, 1)),
                                     double(std::max(base, kMaxCameraPaths)));
      const double granted = want <= budget ? want : double(std::max(base, 1));
      budget -= std::min(budget, granted);
      min_paths_[i] = uint32_t(granted);
    }
  }

  // A light whose image covers a small share of a pixel (a bulb far away, water-caustic's 5 mm
  // square) is found by no pilot path: every emissive shape whose pinhole image fits in
  // kSmallEmitterPixels² marks its image and one pixel around it. Through a thin lens that image
  // is the disks of confusion of its points (Camera::ImageBounds), where each camera path hits
  // the light even more rarely, up to kSmallEmitterBlurPixels across (beyond that, the light is
  // left to the pilot). Larger emitters are the pilot's: their edges vary, their interiors not.
  // A path in a marked pixel hits the light with about the image's area over its blurred area
  // (both from the bounds: an estimate, which sets only how many paths look).
  void MarkSmallEmitters(const Scene& scene) {
    for (const Shape& shape : scene.shapes()) {
      if (shape.area_emitter < 0) continue;
      Vec2 pin_lo{kInfinity, kInfinity}, pin_hi{-kInfinity, -kInfinity};  // the pinhole image
      Vec2 lo{kInfinity, kInfinity}, hi{-kInfinity, -kInfinity};          // with the lens's blur
      Vec3 b_lo{kInfinity, kInfinity, kInfinity}, b_hi{-kInfinity, -kInfinity, -kInfinity};  // world bounds
      bool small = true;
      auto add_point = [&](Vec3 p) {
        b_lo = Min(b_lo, p);
        b_hi = Max(b_hi, p);
        if (!small) return;
        const std::optional<std::pair<Vec2, Vec2>> r = scene.camera().ImageBounds(p);
        if (!r) {
          small = false;
          return;
        }
        // A disk of confusion is centred on the pinhole image.
        const Vec2 c{0.5f * (r->first.x + r->second.x), 0.5f * (r->first.y + r->second.y)};
        pin_lo = {std::min(pin_lo.x, c.x), std::min(pin_lo.y, c.y)};
        pin_hi = {std::max(pin_hi.x, c.x), std::max(pin_hi.y, c.y)};
        lo = {std::min(lo.x, r->first.x), std::min(lo.y, r->first.y)};
        hi = {std::max(hi.x, r->second.x), std::max(hi.y, r->second.y)};
        small = pin_hi.x - pin_lo.x <= kSmallEmitterPixels && pin_hi.y - pin_lo.y <= kSmallEmitterPixels &&
                hi.x - lo.x <= kSmallEmitterBlurPixels && hi.y - lo.y <= kSmallEmitterBlurPixels;
      };
      if (shape.kind == ShapeKind::kSphere) {
        for (int c = 0; c < 8; ++c)
          add_point(shape.center + Vec3{c & 1 ? shape.radius : -shape.radius, c & 2 ? shape.radius : -shape.radius,
                                        c & 4 ? shape.radius : -shape.radius});
      } else {
        for (const Vec3& p : shape.positions) add_point(p);
      }
      if (!(b_lo.x <= b_hi.x)) continue;
      const Vec3 center = 0.5f * (b_lo + b_hi);
      emitters_.push_back({center, shape.kind == ShapeKind::kSphere ? shape.radius : 0.5f * Length(b_hi - b_lo)});
      if (!small) continue;
      const double image = std::max(double(pin_hi.x - pin_lo.x) * double(pin_hi.y - pin_lo.y), 1e-4);
      const double blurred = std::max(1.0, double(hi.x - lo.x) * double(hi.y - lo.y));
      Mark(int(std::floor(lo.x)) - 1, int(std::floor(lo.y)) - 1, int(std::floor(hi.x)) + 1,
           int(std::floor(hi.y)) + 1, std::min(1.0, image) / blurred);
    }
  }

  // Light reaching the camera through delta interactions (a small light's reflection in water,
  // its image through a glass sphere: L S+ E) is as hard to find as a small light seen directly,
  // and more so: a dielectric sends only its Fresnel share of paths the way of the image. Probes
  // through each pixel's centre and corners (the lens's centre) follow every branch of their
  // delta chains; the segments of one branch, cut by the plane through an emitter's centre,
  // give a disk that stands for the pixel's footprint there (docs/rendering.md, "Camera-side
  // supersampling"). Only when the scene has a delta lobe that is not a sharp one.
  // A ray leaving a delta vertex, on a branch of the camera ray's delta chain.
  struct ProbeSegment {
    uint32_t branch;    // bit i: refraction at the i-th delta vertex; bits 27-31: the vertex count
    float probability;  // of the branch's choices (Fresnel)
    Vec3 o, d;
  };

  static void ProbeDeltaChains(const Scene& scene, const Ray& camera_ray, int max_depth,
                               std::vector<ProbeSegment>* out) {
    out->clear();
    struct Node {
      Ray ray;
      uint32_t branch;
      int vertices;
      float probability;
    };
    Node stack[kProbeSegments];
    int top = 0;
    stack[top++] = {camera_ray, 0, 0, 1.f};
    int traced = 0;
    while (top > 0 && traced < kProbeSegments) {
      Node n = stack[--top];
      for (int passthrough = 0; passthrough < 64; ++passthrough) {
        ++traced;
        SurfaceHit hit;
        const bool found = scene.Intersect(n.ray, &hit);
        if (n.vertices > 0 && passthrough == 0)
          out->push_back({n.branch | uint32_t(n.vertices) << 27, n.probability, n.ray.o, n.ray.d});
        if (!found) break;
        const Material& m = scene.materials()[scene.shapes()[hit.shape].material];
        const uint32_t flags = MaterialFlags(m);
        if (flags == 0) {  // an interface: straight on
          n.ray.o = OffsetRayOrigin(hit.p, hit.ng, n.ray.d);
          continue;
        }
        if (!(flags & kBxDFSpecular) || HasSharpLobe(m) || n.vertices + 1 > std::min(max_depth - 1, 26)) break;
        const Frame frame(hit.ns);
        const Vec3 wo = frame.ToLocal(-n.ray.d);
        uint32_t previous = 0;
        for (const float uc : {0.f, 0x1.fffffep-1f}) {
          const auto bs = SampleBSDF(m, wo, uc, {0.5f, 0.5f}, TransportMode::kRadiance);
          if (!bs || !(bs->pdf > 0) || !bs->IsSpecular() || bs->flags == previous || top == kProbeSegments) continue;
          previous = bs->flags;
          const Vec3 wi = frame.FromLocal(bs->wi);
          const uint32_t refracted = (bs->flags & kBxDFTransmission) ? 1u << n.vertices : 0u;
          stack[top++] = {{OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity}, n.branch | refracted, n.vertices + 1,
                          n.probability * std::min(bs->pdf, 1.f)};
        }
        break;
      }
    }
  }

  void MarkSpecularImages(const Scene& scene, const ReceiverOptions& opt) {
    if (emitters_.empty() || emitters_.size() > kProbeEmitters) return;
    bool delta = false;
    for (const Material& m : scene.materials()) delta |= (MaterialFlags(m) & kBxDFSpecular) && !HasSharpLobe(m);
    if (!delta) return;
    struct Marks {
      int x, y;
      double hit_rate;
    };
    std::vector<std::vector<Marks>> rows(height_);
    tbb::parallel_for(0, height_, [&](int y) {
      auto probe = [&](float fx, float fy, std::vector<ProbeSegment>* segments) {
        const Ray ray = scene.camera().GenerateRay({fx, fy}, {0.5f, 0.5f});
        if (IsFinite(ray.o) && IsFinite(ray.d)) ProbeDeltaChains(scene, ray, opt.max_depth, segments);
      };
      // The probes at the pixel corners of rows y and y + 1, and at the pixels' centres.
      std::vector<std::vector<ProbeSegment>> corners[2], centre(static_cast<size_t>(width_));
      for (int j = 0; j < 2; ++j) {
        corners[j].resize(size_t(width_) + 1);
        for (int x = 0; x <= width_; ++x) probe(float(x), float(y + j), &corners[j][x]);
      }
      for (int x = 0; x < width_; ++x) probe(float(x) + 0.5f, float(y) + 0.5f, &centre[x]);
      std::vector<uint32_t> branches;
      for (int x = 0; x < width_; ++x) {
        const std::vector<ProbeSegment>* c[5] = {&centre[x], &corners[0][x], &corners[0][x + 1], &corners[1][x],
                                                 &corners[1][x + 1]};
        branches.clear();
        for (const auto* segments : c)
          for (const ProbeSegment& t : *segments) branches.push_back(t.branch);
        std::sort(branches.begin(), branches.end());
        branches.erase(std::unique(branches.begin(), branches.end()), branches.end());
        for (const uint32_t branch : branches) {
          // The pixel's samples of this branch: its directions, where they leave from.
          const ProbeSegment* q[5];
          int n = 0;
          for (const auto* segments : c)
            for (const ProbeSegment& t : *segments)
              if (t.branch == branch) {
                q[n++] = &t;
                break;
              }
          if (n < 2) continue;
          Vec3 m{0, 0, 0}, o{0, 0, 0};
          float probability = 1;
          for (int k = 0; k < n; ++k) {
            m = m + q[k]->d;
            o = o + q[k]->o;
            probability = std::min(probability, q[k]->probability);
          }
          if (!(Length(m) > 0.5f * float(n))) continue;  // directions too far apart for one plane
          m = Normalize(m);
          o = o / float(n);
          for (const EmitterBound& e : emitters_) {
            // Where the samples' rays cross the plane through the emitter's centre normal to
            // their mean direction: a disk around them stands for the pixel's footprint there.
            Vec3 at[5], mean{0, 0, 0};
            bool ok = true;
            for (int k = 0; k < n && ok; ++k) {
              const float dn = Dot(q[k]->d, m), along = Dot(e.center - q[k]->o, m);
              ok = dn > 0.1f && along > 0;
              at[k] = q[k]->o + q[k]->d * (along / dn);
              mean = mean + at[k] / float(n);
            }
            if (!ok) continue;
            double spread = 0;
            for (int k = 0; k < n; ++k) spread = std::max(spread, double(Length(at[k] - mean)));
            const double r = double(e.radius), off = double(Length(e.center - mean));
            if (!(spread > 0) || off > spread + r || r > double(kSmallEmitterPixels) * spread) continue;
            const Vec3 to = e.center - o;
            const float dist = Length(to);
            if (!(dist > e.radius)) continue;
            // ... and seen from where the paths leave: the first thing towards it is an emitter.
            SurfaceHit hit;
            const Vec3 dir = to / dist;
            if (scene.Intersect({o + dir * (1e-3f * dist), dir, dist}, &hit) &&
                scene.shapes()[hit.shape].area_emitter < 0)
              continue;
            // One path in (spread/r)² finds the light, along a branch taken with `probability`.
            const double hit_rate = double(probability) * std::min(1.0, r * r / (spread * spread));
            rows[y].push_back({x, y, hit_rate});
          }
        }
      }
    });
    // A marked pixel and the pixels around it (whose filters reach into it) get its paths.
    // Marks only raise counts (max), so their order does not matter: the same bits on any threads.
    for (const std::vector<Marks>& row : rows)
      for (const Marks& mk : row) Mark(mk.x - 1, mk.y - 1, mk.x + 1, mk.y + 1, mk.hit_rate);
  }

  struct EmitterBound {
    Vec3 center;
    float radius;
  };
  static constexpr int kProbeSegments = 16;     // segments one probe traces, at most
  static constexpr size_t kProbeEmitters = 256;  // emissive shapes the probe checks, at most

  int width_, height_;
  std::vector<float> lo_, hi_;
  std::vector<float> hit_rate_;      // of the rarest small light a pixel is marked for; ∞: none
  std::vector<uint32_t> min_paths_;  // camera paths granted to a marked pixel; 0: not marked
  std::vector<uint32_t> active_paths_;  // an active pixel's share (ShareActivePaths); 0: inactive
  std::vector<EmitterBound> emitters_;
};

// Whether two coverage paths end on what shades alike (ReceiverOptions::coverage): the same
// material at the same depth, normals within ~18°, and neither stepped off the other's plane (a
// step between parallel faces moves one along the other's normal). Symmetric, so the groups
// depend only on the set of paths; only the variance depends on this test.
bool SameSurface(const ShadingPoint& a, const ShadingPoint& b) {
  if (a.material != b.material || a.depth != b.depth || a.medium_out != b.medium_out ||
      a.medium_in != b.medium_in)
    return false;
  if (Dot(a.ns, b.ns) < 0.95f) return false;
  const Vec3 d = b.p - a.p;
  const float step = 0.25f * Length(d);
  return std::abs(Dot(d, a.ng)) <= step && std::abs(Dot(d, b.ng)) <= step;
}

// Shadow probes of the coverage groups (ReceiverOptions::coverage_shadows): points on the most
// powerful emitters (the centroids of cells × cells parts of an area emitter; a point light; a
// distant light's direction). Two coverage paths whose points see different probes are not
// grouped, so a pixel across a shadow's edge, or across a line in a penumbra where a part of the
// light goes out of view, keeps a receiver on each side, as across a geometric edge. What a point
// sees is a function of the point alone, so the groups stay a function of the set of paths and
// only the variance depends on them (MergeCoverage).
class ShadowProbes {
 public:
  static constexpr size_t kMaxProbes = 16;

  // cells (1 or 2): parts of an area emitter a side. The most powerful lights whose probes fit
  // in 4 · cells² are probed (4 lights, or more point and distant lights).
  ShadowProbes(const Scene& scene, int cells) : scene_(scene) {
    const size_t max_probes = std::min(kMaxProbes, size_t(4 * cells * cells));
    struct Light {
      float power;
      std::vector<Probe> probes;
    };
    std::vector<Light> lights;
    for (const AreaEmitter& e : scene.area_emitters()) {
      // Each part's probe is the centroid of its points of a 4 × 4 stratified grid over the
      // emitter's sample domain. A sphere's centroids are inside it: a ray that reaches the
      // emitter's own shape counts as seeing it.
      std::vector<Vec3> c(size_t(cells * cells), Vec3{0, 0, 0});
      const float share = float(cells * cells) / 16.f;
      for (int i = 0; i < 16; ++i) {
        Vec3 p, n;
        scene.SampleAreaEmitter(e, {(float(i % 4) + 0.5f) / 4.f, (float(i / 4) + 0.5f) / 4.f}, &p, &n);
        const int cell = (i / 4) * cells / 4 * cells + (i % 4) * cells / 4;
        c[size_t(cell)] = c[size_t(cell)] + p * share;
      }
      Light light{e.Power().Luminance(), {}};
      const bool sphere = scene.shapes()[e.shape].kind == ShapeKind::kSphere;
      for (const Vec3& centroid : c) light.probes.push_back(Probe{centroid, {0, 0, 0}, int(e.shape), false, sphere});
      lights.push_back(std::move(light));
    }
    for (const PointEmitter& e : scene.point_emitters())
      lights.push_back({4 * kPi * e.intensity.Luminance(), {Probe{e.position, {0, 0, 0}, -1}}});
    const float r = scene.bounds().Radius();
    for (const DistantEmitter& e : scene.distant_emitters())
      lights.push_back({kPi * r * r * e.L.Luminance(), {Probe{{0, 0, 0}, -e.direction, -1, true}}});
    std::stable_sort(lights.begin(), lights.end(), [](const Light& a, const Light& b) { return a.power > b.power; });
    for (const Light& light : lights) {
      if (!(light.power > 0) || probes_.size() + light.probes.size() > max_probes) break;
      probes_.insert(probes_.end(), light.probes.begin(), light.probes.end());
    }
  }
  bool empty() const { return probes_.empty(); }

  // Bit i: probe i lies on the side the point is seen from, and nothing opaque is in between.
  uint32_t Seen(const ShadingPoint& p) const {
    uint32_t seen = 0;
    // Probes on a surface (a mesh emitter's part, a point light, a distant direction) take one
    // batch of occlusion rays; a sphere's centroids are inside it, and take a closest hit.
    std::array<RTCRay, kMaxProbes> rays;
    std::array<uint32_t, kMaxProbes> bit;
    unsigned nrays = 0;
    for (size_t i = 0; i < probes_.size(); ++i) {
      const Probe& probe = probes_[i];
      Vec3 w = probe.distant ? probe.direction : probe.p - p.p;
      const float d = Length(w);
      if (!(d > 0) || Dot(w, p.ng) * Dot(p.wo, p.ng) <= 0) continue;
      w = w / d;
      const Ray ray{OffsetRayOrigin(p.p, p.ng, w), w, probe.distant ? kInfinity : d * (1 - 1e-3f)};
      if (probe.inside) {
        SurfaceHit hit;
        if (!scene_.Intersect(ray, &hit, kMaskOpaque) || int(hit.shape) == probe.shape) seen |= 1u << i;
        continue;
      }
      RTCRay& r = rays[nrays];
      r = RTCRay{};
      r.org_x = ray.o.x, r.org_y = ray.o.y, r.org_z = ray.o.z;
      r.dir_x = w.x, r.dir_y = w.y, r.dir_z = w.z;
      r.tnear = 0.f;
      r.tfar = ray.tmax;
      bit[nrays++] = 1u << i;
    }
    if (nrays > 0) scene_.Occluded(rays.data(), nrays);
    for (unsigned k = 0; k < nrays; ++k)
      if (rays[k].tfar >= 0.f) seen |= bit[k];  // Embree sets tfar = -inf when occluded
    return seen;
  }

 private:
  struct Probe {
    Vec3 p, direction;  // a point on the emitter; a distant light's direction towards it
    int shape = -1;     // an area emitter's shape: reaching it is seeing the probe
    bool distant = false;
    bool inside = false;  // inside its shape (a sphere's centroids): a closest hit decides
  };
  const Scene& scene_;
  std::vector<Probe> probes_;
};

// One receiver sample from its K coverage paths (ReceiverOptions::coverage), of equal positive
// filter weights w_j (FilterSampler: |w| is the same for every sample). Path 0 is the sample's own
// film position, the others the pixel-sized lattice shifted by it (CoverageLattice), so given the
// set of K positions each is path 0 with probability 1/K. With W = Σ w_j the sample gets weight
// W/K and emission Σ w_j E_j / W: Film's Σ w (E + G) / Σ w sees (1/K) Σ w_j E_j, as K samples
// would give. The paths' shading points are grouped (SameSurface, slot by slot below); group g, of
// weight W_g, keeps the point of one path r, its throughput scaled by W_g / W: path 0's in its own
// group, elsewhere one chosen with probability w_r / W_g (weighted reservoir). Given the set, path
// 0's group is g with probability W_g / W, so E[share of g · G_r] = Σ_g (W_g/W)² Ḡ_g + (1 −
// W_g/W)(W_g/W) Ḡ_g = (1/K) Σ_j w_j G_j (Ḡ_g the group's mean): unbiased, one receiver per group,
// and where the pixel is one surface the receiver is the sample's own, as without coverage (so spp
// samples keep their stratification).
struct CoveragePath {
  float weight = 0;
  RGB emitted;
  std::vector<ShadingPoint> points;
  std::vector<uint32_t> seen;  // ShadowProbes::Seen of each point; empty without probes
};

uint32_t SeenOf(const CoveragePath& path, size_t slot) { return slot < path.seen.size() ? path.seen[slot] : 0; }

void MergeCoverage(std::vector<CoveragePath>& paths, Rng& rng, CameraSample* cs,
                   std::vector<ShadingPoint>* points) {
  double total = 0, e[3] = {0, 0, 0};
  for (const CoveragePath& c : paths) {
    const double w = double(c.weight);
    total += w;
    e[0] += w * double(c.emitted.r), e[1] += w * double(c.emitted.g), e[2] += w * double(c.emitted.b);
  }
  cs->weight = float(total / double(paths.size()));
  if (!(total > 0)) return;
  cs->emitted = RGB(float(e[0] / total), float(e[1] / total), float(e[2] / total));
  // Slot by slot (the i-th point of every path that has one: a split path has the base of each
  // vertex it split at, then its end), so a coat's reflection does not part the base's group.
  // The groups are the connected parts of SameSurface over all pairs of the slot's points: a
  // function of the set of paths, not of which one is path 0 (the argument above needs that).
  // Paths without the slot's point form the slot's empty group, which adds nothing.
  size_t slots = 0;
  for (const CoveragePath& c : paths) slots = std::max(slots, c.points.size());
  const size_t k = paths.size();
  std::vector<size_t> part(k), group_of(k);
  const auto find = [&](size_t i) {
    while (part[i] != i) i = part[i] = part[part[i]];
    return i;
  };
  struct Group {
    size_t chosen;
    double weight;
  };
  std::vector<Group> groups;
  for (size_t slot = 0; slot < slots; ++slot) {
    const auto has = [&](size_t j) { return slot < paths[j].points.size(); };
    std::iota(part.begin(), part.end(), size_t(0));
    for (size_t i = 0; i < k; ++i)
      for (size_t j = i + 1; j < k && has(i); ++j)
        if (has(j) && find(i) != find(j) && SameSurface(paths[i].points[slot], paths[j].points[slot]) &&
            SeenOf(paths[i], slot) == SeenOf(paths[j], slot))
          part[find(j)] = find(i);
    groups.clear();
    std::fill(group_of.begin(), group_of.end(), SIZE_MAX);  // by root
    for (size_t j = 0; j < k; ++j) {
      if (!has(j)) continue;
      size_t& g = group_of[find(j)];
      if (g == SIZE_MAX) {
        g = groups.size();
        groups.push_back({j, double(paths[j].weight)});
        continue;
      }
      groups[g].weight += double(paths[j].weight);
      // Path 0 keeps its own group; elsewhere a weighted reservoir.
      if (groups[g].chosen != 0 && double(rng.Uniform()) * groups[g].weight < double(paths[j].weight))
        groups[g].chosen = j;
    }
    for (const Group& g : groups) {
      ShadingPoint p = paths[g.chosen].points[slot];
      p.throughput *= float(g.weight / total);
      points->push_back(p);
    }
  }
}

// u + offset mod 1, kept below 1 (u, offset ∈ [0, 1)²).
Vec2 ShiftedOnTorus(Vec2 u, Vec2 offset) {
  const auto wrap = [](float v) { return std::min(v >= 1.f ? v - 1.f : v, 0x1.fffffep-1f); };
  return {wrap(u.x + offset.x), wrap(u.y + offset.y)};
}

// K offsets in [0, 1)² that form a group under addition mod 1 (a rank-1 lattice
// (j/K, j·g/K mod 1), its generator g the one that keeps the points furthest apart on the torus):
// a sample's coverage positions are its own plus each offset, so the K positions are equally
// likely to be any one of them shifted (MergeCoverage relies on that) and cover the pixel's
// sample space evenly.
std::vector<Vec2> CoverageLattice(int k) {
  const auto torus = [](double d) { return std::min(d, 1.0 - d); };
  int best = 1;
  double best_distance = -1;
  for (int g = 1; g < k; ++g) {
    if (std::gcd(g, k) != 1) continue;
    double nearest = INFINITY;
    for (int j = 1; j < k; ++j) {
      const double dx = torus(double(j) / k), dy = torus(double((j * g) % k) / k);
      nearest = std::min(nearest, dx * dx + dy * dy);
    }
    if (nearest > best_distance) best_distance = nearest, best = g;
  }
  std::vector<Vec2> lattice(size_t(std::max(k, 1)));
  for (int j = 0; j < k; ++j) lattice[size_t(j)] = {float(j) / float(k), float((j * best) % k) / float(k)};
  return lattice;
}

// Camera-side supersampling of one active pixel: its `paths` more paths continue the
// pixel's scrambled Sobol sequence after its receiver samples, each with one emitter sample per
// sharp vertex (the pixel gets `paths` of them; the receiver samples keep sharp_samples).
// Film::Resolve divides Σ w (E + G) by Σ w over the receiver samples, so giving each of them the
// filter-weighted mean Ē over all the pixel's paths resolves to Ē + Σ w G / Σ w: two unbiased
// estimates of two disjoint sets of paths (a path ends where a receiver would start).
// A receiver sample of `coverage` paths holds their mean emission at weight Σw/K: it counts
// as K of them here.
void AddCameraPaths(const Scene& scene, const FilterSampler& filter, const CameraPathOptions& path_options,
                    int paths, int coverage, int x, int y, uint32_t scramble0, uint32_t scramble1, Rng& rng,
                    std::span<CameraSample> samples, ReceiverStats* st) {
  double sum_w = 0, receiver_w = 0, sum[3] = {0, 0, 0};
  auto add = [&](float w, RGB e) {
    if (!e.IsFinite() || !std::isfinite(w)) return;  // dropped, as Film drops such a sample
    const double wd = double(w);
    sum_w += wd;
    sum[0] += wd * double(e.r), sum[1] += wd * double(e.g), sum[2] += wd * double(e.b);
  };
  for (const CameraSample& cs : samples) {
    add(cs.weight * float(coverage), cs.emitted);
    receiver_w += double(cs.weight);
  }
  for (int k = 0; k < paths; ++k) {
    const uint32_t s = uint32_t(samples.size()) + uint32_t(k);
    const FilterSample fs =
        filter.Sample({Sobol2DComponent(s, 0, scramble0), Sobol2DComponent(s, 1, scramble1)});
    const Ray ray = FilmRay(scene, x, y, fs, rng);
    ++st->camera_paths;
    if (!IsFinite(ray.o) || !IsFinite(ray.d)) {
      ++st->nonfinite_rays;
      add(fs.weight, RGB(0.f));
      continue;
    }
    const PathEnd end = TraceCameraPath(scene, path_options, ray, rng);
    st->media_direct_samples += end.media_direct_samples;
    add(fs.weight, end.emitted);
  }
  // A pixel whose receiver weights cancel has no defined value either way.
  if (sum_w == 0 || receiver_w == 0) return;
  const RGB mean(float(sum[0] / sum_w), float(sum[1] / sum_w), float(sum[2] / sum_w));
  for (CameraSample& cs : samples) cs.emitted = mean;
}

// The first medium piece of a camera ray that has anything to scatter, as TraceCameraPath cuts
// it with segments_per_ray 0 (its first eye segment, at depth 1), reached through interfaces
// only; none if the ray meets a surface or leaves first. Deterministic.
std::optional<EyeSegment> FirstEyeSegment(const Scene& scene, Ray ray) {
  int medium = scene.camera_medium();
  std::vector<EyeSegment> found_segment;
  for (int passthrough = 0;;) {
    SurfaceHit hit;
    const bool found = scene.Intersect(ray, &hit);
    if (medium >= 0) {
      const MediumTrack track = CameraPieceTrack(scene.media()[size_t(medium)], ray, found ? hit.t : kInfinity);
      AppendEyeSegments(track, medium, ray, RGB(1.f), 0, 1, &found_segment);
      if (!found_segment.empty()) return found_segment.front();
    }
    if (!found) return std::nullopt;
    const Material& m = scene.materials()[scene.shapes()[hit.shape].material];
    if (MaterialFlags(m) != 0 || ++passthrough > 64) return std::nullopt;
    medium = scene.MediumAfter(hit, ray.d, medium);
    ray.o = OffsetRayOrigin(hit.p, hit.ng, ray.d);
  }
}

// Coverage of a receiver sample's first medium piece (ReceiverOptions::segment_coverage): the
// pieces of its own ray (`own`, the segments its path cut) and of the coverage lattice's other
// positions become one row. Given the K positions each is the sample's own with probability 1/K
// (CoverageLattice), and the filter weights are equal (a positive filter), so the row's mean over
// the K rays is what K samples would give the pixel in expectation. Replaces own's first segment
// when it is the first piece (depth 1), else puts the row in front; appends the pieces.
void CoverFirstSegment(const Scene& scene, const FilterSampler& filter, const std::vector<Vec2>& lattice, Vec2 u0,
                       int x, int y, Rng& rng, std::vector<EyeSegment>* own, std::vector<EyeSegment>* pieces,
                       ReceiverStats* st) {
  const bool own_first = !own->empty() && own->front().depth == 1;
  if (own_first) pieces->push_back(own->front());
  for (size_t j = 1; j < lattice.size(); ++j) {
    const FilterSample fs = filter.Sample(ShiftedOnTorus(u0, lattice[j]));
    const Ray ray = FilmRay(scene, x, y, fs, rng);
    ++st->camera_rays;
    ++st->coverage_paths;
    if (!IsFinite(ray.o) || !IsFinite(ray.d)) {
      ++st->nonfinite_rays;
      continue;
    }
    if (std::optional<EyeSegment> seg = FirstEyeSegment(scene, ray)) pieces->push_back(*seg);
  }
  if (pieces->empty()) return;
  const float scale = float(pieces->size()) / float(lattice.size());
  for (EyeSegment& piece : *pieces) piece.throughput *= scale;
  EyeSegment row = pieces->front();
  row.pieces = uint16_t(pieces->size());
  if (own_first)
    own->front() = row;
  else
    own->insert(own->begin(), row);
}

}  // namespace

RGB AppendEyeSegments(const Medium& med, int medium, const Ray& ray, float tmax, RGB beta, int h,
                      uint8_t depth, std::vector<EyeSegment>* out) {
  const MediumTrack track = CameraPieceTrack(med, ray, tmax);
  AppendEyeSegments(track, medium, ray, beta, h, depth, out);
  return track.TransmittanceToEnd();
}

void AppendEyeSegments(const MediumTrack& track, int medium, const Ray& ray, RGB beta, int h, uint8_t depth,
                       std::vector<EyeSegment>* out) {
  if (track.empty()) return;
  const float crossing = track.TransmittanceToEnd().Average();
  const int n = std::clamp(int(std::ceil(float(h + 1) * (1.f - crossing))), 1, h + 1);
  float t0 = track.Quantile(0.f);
  for (int k = 0; k < n; ++k) {
    const float t1 = k + 1 == n ? track.support_end() : track.Quantile(float(k + 1) / float(n));
    if (!(t1 > t0)) continue;
    EyeSegment s;
    s.o = ray.o + ray.d * t0;
    s.d = ray.d;
    s.length = t1 - t0;
    s.throughput = beta * track.At(t0).tr;
    s.medium = int16_t(medium);
    s.depth = depth;
    out->push_back(s);
    t0 = t1;
  }
}

std::unique_ptr<Filter> MakePixelFilter(const RenderHints& h) {
  FilterShape shape;
  shape.sigma = h.filter_sigma;
  shape.b = h.filter_B;
  shape.c = h.filter_C;
  shape.tau = h.filter_tau;
  return Filter::Create(ParseFilterType(h.filter_type), {h.filter_xradius, h.filter_yradius}, shape);
}

ReceiverSet GenerateReceivers(const Scene& scene, const FilterSampler& filter,
                              const ReceiverOptions& opt) {
  ReceiverSet set;
  set.width = scene.hints().width;
  set.height = scene.hints().height;
  set.spp = std::max(1, opt.spp);
  const size_t npix = size_t(set.width) * set.height;
  const int spp = set.spp;
  set.samples.resize(npix * spp);
  std::vector<std::vector<ShadingPoint>> points(npix * spp);
  std::vector<std::vector<EyeSegment>> segments(npix * spp), pieces(npix * spp);
  std::vector<size_t> first_knots(npix * spp, 0);
  std::vector<ReceiverStats> row_stats(set.height);
  // Emitter sampling at sharp-lobe vertices, only when the split made a lobe sharp.
  std::unique_ptr<EmitterSampler> sharp_lights;
  for (const Material& m : scene.materials())
    if (HasSharpLobe(m)) {
      sharp_lights = std::make_unique<EmitterSampler>(scene);
      break;
    }
  if (sharp_lights && sharp_lights->empty()) sharp_lights.reset();
  // The emitters' single scattering in media, on the camera side (ReceiverOptions::media_direct_samples).
  std::unique_ptr<EmitterSampler> media_lights;
  if (opt.segments_per_ray >= 0 && opt.media_direct_samples > 0 && scene.has_media()) {
    media_lights = std::make_unique<EmitterSampler>(scene);
    if (media_lights->empty()) media_lights.reset();
  }
  // The receiver samples cut eye segments and take sharp_samples emitter samples at sharp
  // vertices; camera paths and the pilot only collect (one emitter sample per sharp vertex).
  CameraPathOptions receiver_paths;
  receiver_paths.max_depth = opt.max_depth;
  receiver_paths.sharp_lights = sharp_lights.get();
  receiver_paths.sharp_samples = opt.sharp_samples;
  receiver_paths.media_lights = media_lights.get();
  receiver_paths.media_samples = opt.media_direct_samples;
  receiver_paths.segments_per_ray = opt.segments_per_ray;
  receiver_paths.splits = opt.splits;
  std::optional<NearFieldLights> near_lights;
  if (opt.near_sharp_lights.target_lights > 0 && scene.near_sharp_twins() > 0) {
    LightGenerationOptions lopt = opt.near_sharp_lights;
    lopt.seed = HashSeed({opt.seed, uint64_t(RngStream::kNearPilot)});
    near_lights.emplace(scene, lopt);
    if (near_lights->size() > 0) receiver_paths.near_lights = &*near_lights;
  }
  // Coverage paths share the sample's emitter samples at sharp vertices.
  const int coverage = opt.coverage > 1 && opt.segments_per_ray < 0 && filter.positive() ? opt.coverage : 1;
  const std::vector<Vec2> lattice = CoverageLattice(coverage);
  std::optional<ShadowProbes> probes;
  if (coverage > 1 && opt.coverage_shadows > 0) {
    probes.emplace(scene, opt.coverage_shadows);
    if (probes->empty()) probes.reset();
  }
  CameraPathOptions coverage_paths = receiver_paths;
  coverage_paths.sharp_samples = std::max(1, opt.sharp_samples / coverage);
  CameraPathOptions camera_only = receiver_paths;
  camera_only.sharp_samples = 1;
  camera_only.segments_per_ray = -1;
  camera_only.keep_points = false;

  // Camera-side supersampling: which pixels get camera paths.
  std::optional<CameraSideActivity> camera_side;
  if (opt.camera_paths > 0) camera_side.emplace(scene, filter, camera_only, opt, &row_stats);

  tbb::parallel_for(0, set.height, [&](int y) {
    ReceiverStats& st = row_stats[y];
    const auto tally = [&st](const PathEnd& end) {
      st.specular_bounces += end.specular_bounces;
      st.escaped += end.escaped;
      st.transmittance_evals += end.transmittance_evals;
      st.media_direct_samples += end.media_direct_samples;
      st.split_vertices += size_t(end.split_vertices);
      st.near_sharp_vertices += size_t(end.near_sharp_vertices);
    };
    for (int x = 0; x < set.width; ++x) {
      uint32_t pixel = uint32_t(y * set.width + x);
      uint64_t pixel_seed = HashSeed({opt.seed, uint64_t(RngStream::kCameraSample), pixel});
      Rng rng(pixel_seed);
      uint32_t scramble0 = rng.Next(), scramble1 = rng.Next();
      for (int s = 0; s < spp; ++s) {
        size_t index = size_t(pixel) * spp + s;
        if (coverage > 1) {
          CameraSample& cs = set.samples[index];
          cs.pixel = pixel;
          std::vector<CoveragePath> ways(static_cast<size_t>(coverage));
          const Vec2 u0{Sobol2DComponent(uint32_t(s), 0, scramble0), Sobol2DComponent(uint32_t(s), 1, scramble1)};
          for (int j = 0; j < coverage; ++j) {
            const Vec2 o = lattice[size_t(j)];
            const FilterSample fs = filter.Sample(ShiftedOnTorus(u0, o));
            const Ray ray = FilmRay(scene, x, y, fs, rng);
            ways[size_t(j)].weight = fs.weight;
            ++st.camera_rays;
            if (j > 0) ++st.coverage_paths;
            if (!IsFinite(ray.o) || !IsFinite(ray.d)) {
              ++st.nonfinite_rays;
              continue;
            }
            PathEnd end = TraceCameraPath(scene, coverage_paths, ray, rng);
            ways[size_t(j)].emitted = end.emitted;
            ways[size_t(j)].points = std::move(end.points);
            if (probes)
              for (const ShadingPoint& point : ways[size_t(j)].points) ways[size_t(j)].seen.push_back(probes->Seen(point));
            tally(end);
          }
          MergeCoverage(ways, rng, &cs, &points[index]);
          for (ShadingPoint& point : points[index]) point.sample = uint32_t(index);
          continue;
        }
        // Film position: scrambled Sobol point warped by the filter (importance sampling).
        Vec2 u{Sobol2DComponent(uint32_t(s), 0, scramble0), Sobol2DComponent(uint32_t(s), 1, scramble1)};
        FilterSample fs = filter.Sample(u);
        const Ray ray = FilmRay(scene, x, y, fs, rng);
        CameraSample& cs = set.samples[index];
        cs.pixel = pixel;
        cs.weight = fs.weight;
        ++st.camera_rays;
        if (!IsFinite(ray.o) || !IsFinite(ray.d)) {
          ++st.nonfinite_rays;
          continue;
        }
        PathEnd end = TraceCameraPath(scene, receiver_paths, ray, rng);
        first_knots[index] = end.first_segment_knots;
        for (EyeSegment& seg : end.segments) seg.sample = uint32_t(index);
        segments[index] = std::move(end.segments);
        cs.emitted = end.emitted;
        tally(end);
        for (ShadingPoint& point : end.points) point.sample = uint32_t(index);
        points[index] = std::move(end.points);
      }
      if (const int paths = camera_side ? camera_side->paths(x, y) : 0; paths > 0) {
        ++st.camera_active_pixels;
        const std::span<CameraSample> pixel_samples(set.samples.data() + size_t(pixel) * spp, size_t(spp));
        // A pixel's camera-side paths share a budget of single-scattering samples, at least
        // media_direct each: a medium under a distant light gets 64 paths of 8 (the pilot marks
        // where its texture and self-shadowing vary), a volumetric caustic's 256 paths keep 2.
        CameraPathOptions pixel_paths = camera_only;
        if (pixel_paths.media_samples > 0)
          pixel_paths.media_samples = std::max(pixel_paths.media_samples, kCameraMediaPixelSamples / paths);
        AddCameraPaths(scene, filter, pixel_paths, paths, coverage, x, y, scramble0, scramble1, rng, pixel_samples,
                       &st);
      }
    }
  });

  // Coverage of media rows (ReceiverOptions::segment_coverage), after every sample's own path:
  // the pieces' tracks cost memory in proportion to their knots, so K is lowered to keep about
  // kSegmentCoverageKnots of them, estimated from the own rays' first pieces (deterministic).
  if (opt.segment_coverage > 1 && opt.segments_per_ray == 0 && opt.max_depth > 0 && filter.positive()) {
    size_t knots = 0;
    for (size_t k : first_knots) knots += k;
    const size_t by_memory = knots > 0 ? kSegmentCoverageKnots / knots : size_t(kMaxCoverage);
    const int k = int(std::clamp<size_t>(by_memory, 1, size_t(std::min(opt.segment_coverage, kMaxCoverage))));
    set.stats.segment_coverage = size_t(k);
    if (k > 1) {
      const std::vector<Vec2> segment_lattice = CoverageLattice(k);
      tbb::parallel_for(0, set.height, [&](int y) {
        ReceiverStats& st = row_stats[y];
        for (int x = 0; x < set.width; ++x) {
          const uint32_t pixel = uint32_t(y * set.width + x);
          // The sample's own film position, as the first pass drew it.
          Rng pixel_rng(HashSeed({opt.seed, uint64_t(RngStream::kCameraSample), pixel}));
          const uint32_t scramble0 = pixel_rng.Next(), scramble1 = pixel_rng.Next();
          for (int s = 0; s < spp; ++s) {
            const size_t index = size_t(pixel) * spp + s;
            Rng rng(HashSeed({opt.seed, uint64_t(RngStream::kSegmentCoverage), pixel, uint64_t(s)}));
            const Vec2 u{Sobol2DComponent(uint32_t(s), 0, scramble0), Sobol2DComponent(uint32_t(s), 1, scramble1)};
            CoverFirstSegment(scene, filter, segment_lattice, u, x, y, rng, &segments[index], &pieces[index], &st);
            for (EyeSegment& seg : segments[index]) seg.sample = uint32_t(index);
            for (EyeSegment& seg : pieces[index]) seg.sample = uint32_t(index);
          }
        }
      });
    }
  }

  // Compact the shading points in sample order (deterministic).
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].empty()) continue;
    set.samples[i].first_point = int32_t(set.points.size());
    set.samples[i].point_count = uint32_t(points[i].size());
    set.points.insert(set.points.end(), points[i].begin(), points[i].end());
  }
  for (size_t i = 0; i < segments.size(); ++i) {
    if (segments[i].empty()) continue;
    set.samples[i].first_segment = int32_t(set.segments.size());
    set.samples[i].segment_count = uint32_t(segments[i].size());
    if (!pieces[i].empty()) {  // the sample's first segment is their row (CoverFirstSegment)
      segments[i].front().first_piece = uint32_t(set.segment_pieces.size());
      set.segment_pieces.insert(set.segment_pieces.end(), pieces[i].begin(), pieces[i].end());
    }
    set.segments.insert(set.segments.end(), segments[i].begin(), segments[i].end());
  }
  for (const ReceiverStats& st : row_stats) {
    set.stats.camera_rays += st.camera_rays;
    set.stats.specular_bounces += st.specular_bounces;
    set.stats.escaped += st.escaped;
    set.stats.nonfinite_rays += st.nonfinite_rays;
    set.stats.transmittance_evals += st.transmittance_evals;
    set.stats.camera_paths += st.camera_paths;
    set.stats.camera_pilot_paths += st.camera_pilot_paths;
    set.stats.camera_active_pixels += st.camera_active_pixels;
    set.stats.media_direct_samples += st.media_direct_samples;
    set.stats.split_vertices += st.split_vertices;
    set.stats.near_sharp_vertices += st.near_sharp_vertices;
    set.stats.coverage_paths += st.coverage_paths;
  }
  set.stats.segment_coverage = std::max<size_t>(set.stats.segment_coverage, 1);
  return set;
}

}  // namespace lightfarm
