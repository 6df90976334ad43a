#include "common/lights/caustic_photons.h"

#include <embree3/rtcore.h>
#include <nanoflann.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "common/lights/emitters.h"
#include "common/lights/light_generation.h"
#include "common/scene/phase.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {

// The nanoflann dataset interface over a photon array.
struct PhotonCloud {
  const std::vector<CausticPhoton>* photons;
  size_t kdtree_get_point_count() const { return photons->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const {
    const Vec3& p = (*photons)[i].p;
    return dim == 0 ? p.x : dim == 1 ? p.y : p.z;
  }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const { return false; }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PhotonCloud>,
                                                   PhotonCloud, 3, uint32_t>;

// The photons one path leaves, in order along it.
struct PathPhotons {
  std::vector<CausticPhoton> surface, volume;
};

// Follows a particle as light generation does (importance transport, Russian roulette) and
// stores the light arriving at every non-delta event whose previous scattering event was a delta
// bounce (caustic_photons.h).
void TracePhotonPath(const Scene& scene, const EmitterRef& e, float p_select, Vec3 center, float radius,
                     const CausticPhotonOptions& opt, Rng& rng, PathPhotons* out) {
  const EmittedRay em = SampleEmittedRay(scene, e, center, radius, rng);
  if (!em.valid) return;
  RGB beta = em.beta / p_select;
  const float beta0 = std::max(beta.Max(), 1e-30f);
  Ray ray = em.ray;
  int medium = em.medium;
  bool after_delta = false;  // the previous scattering event was a delta bounce
  int bounces = 0, passthrough = 0;
  // A photon's depth is the number of events before it; a receiver adds at least one.
  const int max_photon_depth = opt.max_depth - 1;
  auto roulette = [&] {
    if (bounces <= 2) return true;
    const float q = std::min(1.f, beta.Max() / beta0);
    if (rng.Uniform() >= q) return false;
    beta = beta / q;
    return true;
  };
  for (;;) {
    SurfaceHit hit;
    const bool found = scene.Intersect(ray, &hit);
    if (medium >= 0) {
      const Medium& med = scene.media()[medium];
      const FreePathSample fp = med.SampleFreePath({ray.o, ray.d, found ? hit.t : kInfinity}, rng);
      beta *= fp.weight;
      if (!beta.IsFinite() || beta.IsBlack()) return;
      if (fp.scattered) {
        // Delta tracking's weight already holds σ_s/σ_t: beta is the flux the event scatters.
        const Vec3 x = ray.o + ray.d * fp.t;
        if (!IsFinite(x)) return;
        if (after_delta && opt.volume)
          out->volume.push_back({x, {}, ray.d, beta, uint8_t(bounces), int16_t(medium)});
        if (++bounces > max_photon_depth) return;
        after_delta = false;
        ray = {x, SampleHenyeyGreenstein(ray.d, med.g(), rng.Uniform(), rng.Uniform(), nullptr), kInfinity};
        if (!roulette()) return;
        continue;
      }
    }
    if (!found) return;
    const Shape& shape = scene.shapes()[hit.shape];
    const Material& m = scene.materials()[shape.material];
    const uint32_t flags = MaterialFlags(m);
    if (flags == 0) {  // an interface: only the medium changes
      if (++passthrough > 64) return;
      medium = scene.MediumAfter(hit, ray.d, medium);
      ray.o = OffsetRayOrigin(hit.p, hit.ng, ray.d);
      continue;
    }
    if (!IsPurelySpecular(flags) && after_delta)
      out->surface.push_back({hit.p, hit.ng, ray.d, beta, uint8_t(bounces), -1});
    if (++bounces > max_photon_depth) return;
    const std::optional<ParticleBounce> bounce = ScatterParticle(m, hit, -ray.d, rng, &beta);
    if (!bounce) return;
    after_delta = bounce->specular;
    medium = scene.MediumAfter(hit, bounce->wi, medium);
    ray = {OffsetRayOrigin(hit.p, hit.ng, bounce->wi), bounce->wi, kInfinity};
    if (!roulette()) return;
  }
}

// An Embree traversal that records every sphere it meets and rejects the hit, so the ray goes
// on to the next: the context a query hands to rtcIntersect1 starts with Embree's own.
struct SphereQuery {
  RTCIntersectContext context;
  std::vector<uint32_t>* prims;
};

void CollectSphereHits(const RTCFilterFunctionNArguments* args) {
  auto* q = reinterpret_cast<SphereQuery*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    q->prims->push_back(RTCHitN_primID(args->hit, args->N, i));
    args->valid[i] = 0;
  }
}

}  // namespace

// Surface photons: a k-d tree (nanoflann) for k-nearest queries. Volume photons: spheres of the
// query radius in an Embree scene, so an eye segment finds the photons within the radius by
// one ray traversal instead of a query per step along it.
struct CausticPhotonMap::Tree {
  PhotonCloud cloud;
  std::unique_ptr<KdTree> kd;
  RTCScene spheres = nullptr;
  float sphere_radius = 0;
  ~Tree() {
    if (spheres) rtcReleaseScene(spheres);
  }
};

CausticPhotonMap::~CausticPhotonMap() = default;

std::unique_ptr<CausticPhotonMap> CausticPhotonMap::Trace(const Scene& scene, const CausticPhotonOptions& opt) {
  auto map = std::unique_ptr<CausticPhotonMap>(new CausticPhotonMap());
  if (opt.target_photons == 0 || opt.max_depth < 2) return map;
  const Bounds3& b = scene.bounds();
  const Vec3 center = b.Empty() ? Vec3{0, 0, 0} : b.Center();
  const float radius = std::max(b.Radius(), 1e-3f) * 1.01f;
  const std::vector<EmitterRef> emitters = CollectEmitters(scene, radius);
  const PowerPicker picker(emitters);
  if (emitters.empty() || picker.empty()) return map;

  const size_t batch = 4096;
  const size_t max_paths = std::max<size_t>(opt.target_photons * 8, size_t(1) << 20);
  std::vector<PathPhotons> per_path(batch);
  size_t stored = 0;
  while (stored < opt.target_photons && map->paths_ < max_paths) {
    tbb::parallel_for(size_t(0), batch, [&](size_t k) {
      per_path[k].surface.clear();
      per_path[k].volume.clear();
      Rng rng(HashSeed({opt.seed, uint64_t(RngStream::kCausticPhoton), uint64_t(map->paths_ + k)}));
      float p_select = 0;
      const size_t ei = picker.Pick(rng.Uniform(), &p_select);
      TracePhotonPath(scene, emitters[ei], p_select, center, radius, opt, rng, &per_path[k]);
    });
    // Whole paths in index order: the result does not depend on scheduling.
    for (size_t k = 0; k < batch && stored < opt.target_photons; ++k) {
      ++map->paths_;
      map->surface_.insert(map->surface_.end(), per_path[k].surface.begin(), per_path[k].surface.end());
      map->volume_.insert(map->volume_.end(), per_path[k].volume.begin(), per_path[k].volume.end());
      stored += per_path[k].surface.size() + per_path[k].volume.size();
    }
  }
  const float inv_paths = 1.f / float(map->paths_);
  for (auto* v : {&map->surface_, &map->volume_})
    for (CausticPhoton& ph : *v) ph.power *= inv_paths;

  if (!map->volume_.empty() && opt.volume_radius > 0) {
    map->volume_radius_ = opt.volume_radius;
    map->volume_tree_ = std::make_unique<Tree>();
    Tree& t = *map->volume_tree_;
    t.spheres = rtcNewScene(scene.device());
    RTCGeometry g = rtcNewGeometry(scene.device(), RTC_GEOMETRY_TYPE_SPHERE_POINT);
    float* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4,
                                                           4 * sizeof(float), map->volume_.size()));
    for (size_t i = 0; i < map->volume_.size(); ++i) {
      const Vec3& p = map->volume_[i].p;
      v[4 * i + 0] = p.x;
      v[4 * i + 1] = p.y;
      v[4 * i + 2] = p.z;
      v[4 * i + 3] = opt.volume_radius;
    }
    rtcSetGeometryIntersectFilterFunction(g, CollectSphereHits);
    rtcCommitGeometry(g);
    rtcAttachGeometry(t.spheres, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(t.spheres);
  }
  if (!map->surface_.empty()) {
    map->surface_tree_ = std::make_unique<Tree>();
    Tree& t = *map->surface_tree_;
    t.cloud.photons = &map->surface_;
    t.kd = std::make_unique<KdTree>(3, t.cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    t.kd->buildIndex();
  }
  return map;
}

void CausticPhotonMap::NearestSurface(Vec3 p, size_t k, float max_radius, std::vector<uint32_t>* out,
                                      float* radius2) const {
  out->clear();
  const float max_r2 = max_radius * max_radius;
  *radius2 = max_r2;
  if (!surface_tree_ || k == 0) return;
  thread_local std::vector<uint32_t> idx;
  thread_local std::vector<float> d2;
  idx.resize(k);
  d2.resize(k);
  const float q[3] = {p.x, p.y, p.z};
  const size_t n = surface_tree_->kd->knnSearch(q, k, idx.data(), d2.data());
  for (size_t i = 0; i < n && d2[i] <= max_r2; ++i) out->push_back(idx[i]);
  if (out->size() == k) *radius2 = std::max(d2[k - 1], 1e-20f);
}

void CausticPhotonMap::NearSegment(Vec3 o, Vec3 d, float length, std::vector<SegmentHit>* out) const {
  out->clear();
  if (!volume_tree_ || !(length > 0)) return;
  const float r = volume_radius_;
  thread_local std::vector<uint32_t> prims;
  prims.clear();
  SphereQuery q;
  rtcInitIntersectContext(&q.context);
  q.prims = &prims;
  // Start a radius before o and end a radius past the end: a sphere that holds the whole
  // segment has both of its intersections outside [0, length].
  RTCRayHit rh{};
  const Vec3 start = o - d * r;
  rh.ray.org_x = start.x;
  rh.ray.org_y = start.y;
  rh.ray.org_z = start.z;
  rh.ray.dir_x = d.x;
  rh.ray.dir_y = d.y;
  rh.ray.dir_z = d.z;
  rh.ray.tnear = 0;
  rh.ray.tfar = length + 2 * r;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(volume_tree_->spheres, &q.context, &rh);
  std::sort(prims.begin(), prims.end());
  prims.erase(std::unique(prims.begin(), prims.end()), prims.end());
  const float r2 = r * r;
  for (uint32_t i : prims) {
    const Vec3 v = volume_[i].p - o;
    const float t = Dot(v, d);
    if (t < 0 || t > length) continue;
    if (LengthSquared(v - d * t) > r2) continue;
    out->push_back({i, t});
  }
  std::sort(out->begin(), out->end(),
            [](const SegmentHit& a, const SegmentHit& b) { return a.t != b.t ? a.t < b.t : a.photon < b.photon; });
}

}  // namespace lightfarm
