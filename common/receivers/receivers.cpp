#include "common/receivers/receivers.h"

#include <tbb/parallel_for.h>

#include <optional>
#include <span>

#include <embree3/rtcore.h>

#include "common/lights/emitters.h"
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
  bool has_point = false;
  ShadingPoint point;
  int specular_bounces = 0;
  bool escaped = false;
  size_t transmittance_evals = 0;
  std::vector<EyeSegment> segments;
};

// Splits the camera ray piece [0, tmax] in `medium` into up to h + 1 eye segments at points
// placed by delta tracking (their density follows σ_t). beta is the camera weight up to ray.o;
// each segment's throughput adds the transmittance up to its start.
void AddEyeSegments(const Medium& med, int medium, const Ray& ray, float tmax, RGB beta, int h,
                    uint8_t depth, Rng& rng, PathEnd* end) {
  // An unbounded piece (a ray leaving into an endless medium) is cut where any light left
  // along it is negligible or, for an empty medium, where nothing is.
  if (!std::isfinite(tmax)) {
    float st = med.sigma_t().Max() * med.MaxDensity();
    if (!(st > 0)) return;
    tmax = 30.f / st;
  }
  float t = 0;
  for (int k = 0; k <= h && t < tmax; ++k) {
    float next = tmax;
    if (k < h) {
      FreePathSample fp = med.SampleFreePath({ray.o + ray.d * t, ray.d, tmax - t}, rng);
      if (fp.scattered) next = std::min(tmax, t + std::max(fp.t, 0.f));
    }
    if (next > t) {
      EyeSegment s;
      s.o = ray.o + ray.d * t;
      s.d = ray.d;
      s.length = next - t;
      s.throughput = beta;
      s.medium = int16_t(medium);
      s.depth = depth;
      end->segments.push_back(s);
      beta *= med.Transmittance({s.o, s.d, s.length}, rng);
      ++end->transmittance_evals;
      if (beta.IsBlack()) return;
    }
    t = next;
  }
}

// One emitter sample of next-event estimation for the sharp lobe of the vertex at `hit`
// (docs/rendering.md, "Sharp lobes"), given that the camera path chose the lobe (probability
// p_lobe), weighted by the power heuristic against the lobe's own sample with `count` emitter
// samples to one lobe sample (Veach 1997, Sec. 9.2.4: weights on n_i·p_i): the caller averages
// the `count` samples.
RGB SharpLobeEmitterSample(const Scene& scene, const EmitterSampler& lights, const SurfaceHit& hit,
                           const Material& m, const Frame& frame, Vec3 wo_local, float p_lobe, int medium,
                           int count, Rng& rng) {
  const float u_pick = rng.Uniform();
  const Vec2 u{rng.Uniform(), rng.Uniform()};
  const std::optional<LightSample> ls = lights.Sample(hit.p, u_pick, u);
  if (!ls || !(p_lobe > 0)) return RGB(0.f);
  const Vec3 wi_local = frame.ToLocal(ls->wi);
  const RGB f = EvalSharpLobe(m, wo_local, wi_local, TransportMode::kRadiance) * std::abs(wi_local.z);
  if (f.IsBlack()) return RGB(0.f);
  const Vec3 o = OffsetRayOrigin(hit.p, hit.ng, ls->wi);
  Vec3 dir = ls->wi;
  float tfar = kInfinity;
  if (!ls->infinite_distance) {
    const Vec3 target = ls->area ? OffsetRayOrigin(ls->p_light, ls->n_light, -ls->wi) : ls->p_light;
    dir = target - o;
    tfar = 1.f - 1e-4f;
  }
  if (!IsFinite(o) || !IsFinite(dir)) return RGB(0.f);
  RTCRay ray{};
  ray.org_x = o.x; ray.org_y = o.y; ray.org_z = o.z;
  ray.dir_x = dir.x; ray.dir_y = dir.y; ray.dir_z = dir.z;
  ray.tfar = tfar;
  ray.mask = kMaskOpaque;
  scene.Occluded(&ray, 1);
  if (!(ray.tfar >= 0.f)) return RGB(0.f);
  RGB tr(1.f);
  if (scene.has_media()) {
    const int start = scene.MediumAfter(hit, ls->wi, medium);
    tr = ls->infinite_distance ? scene.TransmittanceAlong(o, ls->wi, kInfinity, start, rng)
                               : scene.Transmittance(o, o + dir * tfar, start, rng);
  }
  const float w = ls->delta ? 1.f : PowerHeuristic(float(count) * ls->pdf, PdfSharpLobe(m, wo_local, wi_local) / p_lobe);
  return f * ls->L * tr * (w / (ls->pdf * p_lobe));
}

// Next-event estimation at a sharp vertex: the average of `count` emitter samples. A sharp lobe
// reflecting a small light (veach-mis's smallest sphere on its smoothest plate) is found by
// emitter samples, not by the lobe's one sample; each costs one shadow ray, against the
// thousands the receiver's gather casts, so several per vertex are nearly free.
RGB SharpLobeDirectLight(const Scene& scene, const EmitterSampler& lights, const SurfaceHit& hit,
                         const Material& m, const Frame& frame, Vec3 wo_local, float p_lobe, int medium,
                         int count, Rng& rng) {
  RGB sum(0.f);
  for (int i = 0; i < count; ++i)
    sum += SharpLobeEmitterSample(scene, lights, hit, m, frame, wo_local, p_lobe, medium, count, rng);
  return sum / float(count);
}

// Follows a camera ray through specular (delta) interactions to its first non-specular vertex,
// collecting the emission seen along the way. `lights` (set when the scene has sharp lobes):
// at a vertex that follows a sharp lobe, emission is estimated by MIS of the lobe's sample
// and an emitter sample.
PathEnd TraceCameraPath(const Scene& scene, const EmitterSampler* lights, int sharp_samples, Ray ray,
                        int max_depth, int segments_per_ray, Rng& rng) {
  PathEnd end;
  RGB beta(1.f);
  int depth = 0, passthrough = 0;
  int medium = scene.camera_medium();
  // After a sharp-lobe sample: its density (the lobe's, given the lobe) and where it left from,
  // for the MIS weight of an emitter the ray finds (against sharp_samples emitter samples).
  bool after_sharp = false;
  float sharp_pdf = 0;
  Vec3 sharp_p;
  for (;;) {
    SurfaceHit hit;
    bool found = scene.Intersect(ray, &hit);
    // Attenuation of the surface (and emission) seen at the end of this ray segment: an
    // unbiased transmittance estimate (closed form in homogeneous media).
    if (medium >= 0) {
      if (segments_per_ray >= 0 && depth < max_depth)
        AddEyeSegments(scene.media()[medium], medium, ray, found ? hit.t : kInfinity, beta,
                       segments_per_ray, uint8_t(std::min(depth + 1, 255)), rng, &end);
      beta *= scene.media()[medium].Transmittance({ray.o, ray.d, found ? hit.t : kInfinity}, rng);
      ++end.transmittance_evals;
      if (beta.IsBlack()) return end;
    }
    if (!found) {
      if (!after_sharp) {
        end.emitted += beta * scene.EnvironmentRadiance(ray.d);
      } else {
        for (uint32_t i = 0; i < scene.infinite_emitters().size(); ++i)
          end.emitted += beta * scene.infinite_emitters()[i].Le(ray.d) *
                         PowerHeuristic(sharp_pdf, float(sharp_samples) * lights->PdfInfinite(i, ray.d));
      }
      end.escaped = true;
      return end;
    }
    Vec3 wo = -ray.d;
    {
      const RGB Le = scene.EmittedRadiance(hit, wo);
      if (!Le.IsBlack()) {
        const int e = scene.shapes()[hit.shape].area_emitter;
        const float w = after_sharp && e >= 0 ? PowerHeuristic(sharp_pdf, float(sharp_samples) * lights->PdfArea(uint32_t(e), sharp_p, hit)) : 1.f;
        end.emitted += beta * Le * w;
      }
    }
    const Shape& shape = scene.shapes()[hit.shape];
    const Material& m = scene.materials()[shape.material];
    uint32_t flags = MaterialFlags(m);
    if (flags == 0) {  // interface: not a surface, only the medium changes
      if (++passthrough > 64) return end;
      medium = scene.MediumAfter(hit, ray.d, medium);
      ray.o = OffsetRayOrigin(hit.p, hit.ng, ray.d);
      continue;
    }
    after_sharp = false;
    if (++depth > max_depth) return end;
    Frame frame(hit.ns);
    Vec3 wo_local = frame.ToLocal(wo);
    // A material with delta and non-delta lobes (a smooth coat over a diffuse base): follow the
    // delta lobe with probability p, else become a receiver weighted by 1/(1-p) (unbiased split;
    // the matrix evaluates only the non-delta lobes).
    float p_specular = SpecularSamplingProbability(m, wo_local);
    float uc = rng.Uniform();
    if (!IsPurelySpecular(flags) && uc >= p_specular) {
      if (ReflectsNothing(m)) return end;
      beta = beta / (1.f - p_specular);
      end.has_point = true;
      end.point.p = hit.p;
      end.point.ng = hit.ng;
      end.point.ns = hit.ns;
      end.point.wo = wo;
      end.point.throughput = beta;
      end.point.material = uint32_t(shape.material);
      end.point.depth = uint8_t(std::min(depth, 255));
      end.point.medium_out = int16_t(shape.medium_transition ? shape.outside_medium : medium);
      end.point.medium_in = int16_t(shape.medium_transition ? shape.inside_medium : medium);
      return end;
    }
    if (depth >= max_depth) return end;
    // Continue along a delta lobe (radiance transport); for a mixed material uc < p_specular
    // makes SampleBSDF choose the delta lobe (bsdf.h contract), and its pdf includes p_specular.
    auto bs = SampleBSDF(m, wo_local, uc, {rng.Uniform(), rng.Uniform()}, TransportMode::kRadiance);
    if (!bs || !(bs->pdf > 0) || !bs->IsSpecular()) return end;
    Vec3 wi = frame.FromLocal(bs->wi);
    if (lights && HasSharpLobe(m)) {
      // A sharp lobe is not a delta: emitters it reflects get an emitter sample too (MIS).
      const float p_lobe = std::max(p_specular, 1e-6f);
      end.emitted += beta * SharpLobeDirectLight(scene, *lights, hit, m, frame, wo_local, p_lobe, medium,
                                                  sharp_samples, rng);
      after_sharp = true;
      sharp_pdf = bs->pdf / p_lobe;
      sharp_p = hit.p;
    }
    beta *= bs->f * (std::abs(bs->wi.z) / bs->pdf);
    if (beta.IsBlack() || !beta.IsFinite()) return end;
    ++end.specular_bounces;
    medium = scene.MediumAfter(hit, wi, medium);
    ray = {OffsetRayOrigin(hit.p, hit.ng, wi), wi, kInfinity};
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
  CameraSideActivity(const Scene& scene, const FilterSampler& filter, const EmitterSampler* sharp_lights,
                     const ReceiverOptions& opt, std::vector<ReceiverStats>* row_stats)
      : width_(scene.hints().width), height_(scene.hints().height) {
    const size_t npix = size_t(width_) * size_t(height_);
    lo_.assign(npix, 0.f);
    hi_.assign(npix, 0.f);
    small_emitter_.assign(npix, 0);
    RunPilot(scene, filter, sharp_lights, opt, row_stats);
    MarkSmallEmitters(scene);
  }

  // Near a small emitter's image, or where the pilot's values over the pixel and its 8
  // neighbours differ by more than 10%: across pixels, so the edge between a light and its
  // background is found even where each pixel's own paths agree.
  bool active(int x, int y) const {
    if (small_emitter_[size_t(y) * width_ + x]) return true;
    float lo = kInfinity, hi = -kInfinity;
    for (int yy = std::max(0, y - 1); yy <= std::min(height_ - 1, y + 1); ++yy)
      for (int xx = std::max(0, x - 1); xx <= std::min(width_ - 1, x + 1); ++xx) {
        lo = std::min(lo, lo_[size_t(yy) * width_ + xx]);
        hi = std::max(hi, hi_[size_t(yy) * width_ + xx]);
      }
    return lo < 0.f || hi > 1.1f * lo;
  }

 private:
  // kCameraPilotPaths paths per pixel on their own stream, never part of the image: the range
  // of their camera-side luminance (-1 for a non-finite one, which makes the block active).
  void RunPilot(const Scene& scene, const FilterSampler& filter, const EmitterSampler* sharp_lights,
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
            v = TraceCameraPath(scene, sharp_lights, 1, ray, opt.max_depth, -1, rng).emitted.Luminance();
          if (!std::isfinite(v)) v = -1;
          lo = std::min(lo, v);
          hi = std::max(hi, v);
        }
        lo_[pixel] = lo;
        hi_[pixel] = hi;
      }
    });
  }

  // A light whose image covers a small share of a pixel (a bulb far away, water-caustic's 5 mm
  // square) is found by no pilot path: every emissive shape whose pinhole image fits in
  // kSmallEmitterPixels² marks its image and one pixel around it. Through a thin lens that image
  // is the disks of confusion of its points (Camera::ImageBounds), where each camera path hits
  // the light even more rarely, up to kSmallEmitterBlurPixels across (beyond that, the light is
  // left to the pilot). Larger emitters are the pilot's: their edges vary, their interiors not.
  void MarkSmallEmitters(const Scene& scene) {
    for (const Shape& shape : scene.shapes()) {
      if (shape.area_emitter < 0) continue;
      Vec2 pin_lo{kInfinity, kInfinity}, pin_hi{-kInfinity, -kInfinity};  // the pinhole image
      Vec2 lo{kInfinity, kInfinity}, hi{-kInfinity, -kInfinity};          // with the lens's blur
      bool small = true;
      auto add_point = [&](Vec3 p) {
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
        for (int c = 0; c < 8 && small; ++c)
          add_point(shape.center + Vec3{c & 1 ? shape.radius : -shape.radius, c & 2 ? shape.radius : -shape.radius,
                                        c & 4 ? shape.radius : -shape.radius});
      } else {
        for (size_t i = 0; i < shape.positions.size() && small; ++i) add_point(shape.positions[i]);
      }
      if (!small) continue;
      const int px0 = std::max(0, int(std::floor(lo.x)) - 1), px1 = std::min(width_ - 1, int(std::floor(hi.x)) + 1);
      const int py0 = std::max(0, int(std::floor(lo.y)) - 1), py1 = std::min(height_ - 1, int(std::floor(hi.y)) + 1);
      for (int y = py0; y <= py1; ++y)
        for (int x = px0; x <= px1; ++x) small_emitter_[size_t(y) * width_ + x] = 1;
    }
  }

  int width_, height_;
  std::vector<float> lo_, hi_;
  std::vector<uint8_t> small_emitter_;
};

// Camera-side supersampling of one active pixel: its camera_paths more paths continue the
// pixel's scrambled Sobol sequence after its receiver samples, each with one emitter sample per
// sharp vertex (the pixel gets camera_paths of them; the receiver samples keep sharp_samples).
// Film::Resolve divides Σ w (E + G) by Σ w over the receiver samples, so giving each of them the
// filter-weighted mean Ē over all the pixel's paths resolves to Ē + Σ w G / Σ w: two unbiased
// estimates of two disjoint sets of paths (a path ends where a receiver would start).
void AddCameraPaths(const Scene& scene, const FilterSampler& filter, const EmitterSampler* sharp_lights,
                    const ReceiverOptions& opt, int x, int y, uint32_t scramble0, uint32_t scramble1, Rng& rng,
                    std::span<CameraSample> samples, ReceiverStats* st) {
  double sum_w = 0, receiver_w = 0, sum[3] = {0, 0, 0};
  auto add = [&](float w, RGB e) {
    if (!e.IsFinite() || !std::isfinite(w)) return;  // dropped, as Film drops such a sample
    const double wd = double(w);
    sum_w += wd;
    sum[0] += wd * double(e.r), sum[1] += wd * double(e.g), sum[2] += wd * double(e.b);
  };
  for (const CameraSample& cs : samples) {
    add(cs.weight, cs.emitted);
    receiver_w += double(cs.weight);
  }
  for (int k = 0; k < opt.camera_paths; ++k) {
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
    add(fs.weight, TraceCameraPath(scene, sharp_lights, 1, ray, opt.max_depth, -1, rng).emitted);
  }
  // A pixel whose receiver weights cancel has no defined value either way.
  if (sum_w == 0 || receiver_w == 0) return;
  const RGB mean(float(sum[0] / sum_w), float(sum[1] / sum_w), float(sum[2] / sum_w));
  for (CameraSample& cs : samples) cs.emitted = mean;
}

}  // namespace

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
  std::vector<ShadingPoint> points(npix * spp);
  std::vector<uint8_t> has_point(npix * spp, 0);
  std::vector<std::vector<EyeSegment>> segments(npix * spp);
  std::vector<ReceiverStats> row_stats(set.height);
  // Emitter sampling at sharp-lobe vertices, only when the split made a lobe sharp.
  std::unique_ptr<EmitterSampler> sharp_lights;
  for (const Material& m : scene.materials())
    if (HasSharpLobe(m)) {
      sharp_lights = std::make_unique<EmitterSampler>(scene);
      break;
    }
  if (sharp_lights && sharp_lights->empty()) sharp_lights.reset();

  // Camera-side supersampling: which pixels get camera paths.
  std::optional<CameraSideActivity> camera_side;
  if (opt.camera_paths > 0) camera_side.emplace(scene, filter, sharp_lights.get(), opt, &row_stats);

  tbb::parallel_for(0, set.height, [&](int y) {
    ReceiverStats& st = row_stats[y];
    for (int x = 0; x < set.width; ++x) {
      uint32_t pixel = uint32_t(y * set.width + x);
      uint64_t pixel_seed = HashSeed({opt.seed, uint64_t(RngStream::kCameraSample), pixel});
      Rng rng(pixel_seed);
      uint32_t scramble0 = rng.Next(), scramble1 = rng.Next();
      for (int s = 0; s < spp; ++s) {
        size_t index = size_t(pixel) * spp + s;
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
        PathEnd end = TraceCameraPath(scene, sharp_lights.get(), opt.sharp_samples, ray, opt.max_depth,
                                      opt.segments_per_ray, rng);
        for (EyeSegment& seg : end.segments) seg.sample = uint32_t(index);
        segments[index] = std::move(end.segments);
        cs.emitted = end.emitted;
        st.specular_bounces += end.specular_bounces;
        st.escaped += end.escaped;
        st.transmittance_evals += end.transmittance_evals;
        if (end.has_point) {
          end.point.sample = uint32_t(index);
          points[index] = end.point;
          has_point[index] = 1;
        }
      }
      if (camera_side && camera_side->active(x, y)) {
        ++st.camera_active_pixels;
        const std::span<CameraSample> pixel_samples(set.samples.data() + size_t(pixel) * spp, size_t(spp));
        AddCameraPaths(scene, filter, sharp_lights.get(), opt, x, y, scramble0, scramble1, rng, pixel_samples, &st);
      }
    }
  });

  // Compact the shading points in sample order (deterministic).
  for (size_t i = 0; i < points.size(); ++i) {
    if (!has_point[i]) continue;
    set.samples[i].point = int32_t(set.points.size());
    set.points.push_back(points[i]);
  }
  for (size_t i = 0; i < segments.size(); ++i) {
    if (segments[i].empty()) continue;
    set.samples[i].first_segment = int32_t(set.segments.size());
    set.samples[i].segment_count = uint32_t(segments[i].size());
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
  }
  return set;
}

}  // namespace lightfarm
