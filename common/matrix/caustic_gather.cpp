// Caustics gathered from photons on the matrix's rows (caustic_photons.h has the estimators and
// why each path is counted once; docs/rendering.md, "Caustics seen directly").
#include <tbb/task_arena.h>

#include <algorithm>

#include "common/lights/caustic_photons.h"
#include "common/matrix/lighting_matrix.h"
#include "common/scene/phase.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace {
// Photons on another plane than the receiver's (around a corner, across a thin wall) light
// nothing there: their normal must agree with the receiver's within ~25°.
constexpr float kSamePlaneCos = 0.9f;
}  // namespace

const CausticPhotonMap* LightingMatrix::caustic_map() const {
  if (!gathers_caustics()) return nullptr;
  std::call_once(caustic_once_, [&] {
    // Isolated: the tracing's parallel loop must not pick up a task of the caller's loop that
    // would wait here for this same call.
    tbb::this_task_arena::isolate([&] {
      CausticPhotonOptions opt;
      opt.target_photons = size_t(caustic_photons_);
      opt.max_depth = max_depth_;
      opt.seed = seed_;
      opt.volume = !receivers_.segments.empty();
      opt.volume_radius = caustic_volume_radius_;
      caustic_map_ = CausticPhotonMap::Trace(scene_, opt);
    });
  });
  return caustic_map_.get();
}

RGBAccum LightingMatrix::CausticRadiance(uint32_t row, MatrixCounters* counters) const {
  RGBAccum sum;
  const CausticPhotonMap* map = caustic_map();
  if (!map) return sum;
  RGBAccum raw;
  RGB scale;
  if (row < rows_.size()) {
    // L(x, ωo) ≈ Σ f(x, ωo, ωp) Φp / (π r²) over the k nearest photons (Jensen 2001, Eq. 7.6).
    const RowData& r = rows_[row];
    if (r.light_depth_budget == 0 || map->surface().empty()) return sum;
    thread_local std::vector<uint32_t> near;
    float radius2 = 0;
    map->NearestSurface(r.p, size_t(caustic_k_), caustic_radius_, &near, &radius2);
    const Material& m = scene_.materials()[r.material];
    for (uint32_t i : near) {
      const CausticPhoton& ph = map->surface()[i];
      if (ph.depth > r.light_depth_budget || std::abs(Dot(ph.n, r.ng)) < kSamePlaneCos) continue;
      const RGB f = EvalBSDF(m, r.wo_local, r.frame.ToLocal(-ph.dir), TransportMode::kRadiance);
      if (f.IsBlack()) continue;
      raw.Add(ph.power * f);
      ++counters->caustic_photons_used;
    }
    scale = r.throughput / (kPi * radius2);
  } else {
    // The beam radiance estimate along the segment (Jarosz et al. 2008) with a cylinder of
    // radius r: L ≈ Σ Tr(o, x⊥) p_g(ωp · −d) Φp / (π r²). Delta tracking stored Φp as the
    // flux the event scattered (σ_s is in it), so σ_s is not applied again.
    const size_t s = row - rows_.size();
    if (s >= receivers_.segments.size() || map->volume().empty()) return sum;
    const EyeSegment& eye_row = receivers_.segments[s];
    const int budget = max_depth_ - int(eye_row.depth);
    if (budget <= 0) return sum;
    // A row with coverage pieces: each piece's estimate over their number (their throughputs
    // hold pieces / K), so the row gets the mean over its film positions.
    const std::span<const EyeSegment> pieces =
        eye_row.pieces > 0 ? std::span<const EyeSegment>(receivers_.segment_pieces).subspan(eye_row.first_piece, eye_row.pieces)
                           : std::span<const EyeSegment>(&eye_row, 1);
    thread_local std::vector<CausticPhotonMap::SegmentHit> hits;
    Rng rng(HashSeed({seed_, uint64_t(RngStream::kCausticPhoton), uint64_t(row)}));
    const float r = map->volume_radius();
    RGBAccum beams;
    for (const EyeSegment& seg : pieces) {
      if (seg.medium < 0) continue;
      map->NearSegment(seg.o, seg.d, seg.length, &hits);
      if (hits.empty()) continue;
      const Medium& med = scene_.media()[seg.medium];
      RGBAccum piece;
      for (const CausticPhotonMap::SegmentHit& h : hits) {
        const CausticPhoton& ph = map->volume()[h.photon];
        if (ph.depth > budget || ph.medium != seg.medium) continue;
        const RGB tr = med.Transmittance({seg.o, seg.d, h.t}, rng);
        piece.Add(ph.power * tr * HenyeyGreenstein(Dot(ph.dir, -seg.d), med.g()));
        ++counters->caustic_photons_used;
      }
      const RGB w = seg.throughput / (kPi * r * r * float(pieces.size()));
      beams.r += piece.r * double(w.r);
      beams.g += piece.g * double(w.g);
      beams.b += piece.b * double(w.b);
    }
    raw = beams;
    scale = RGB(1.f);
  }
  sum.r = raw.r * double(scale.r);
  sum.g = raw.g * double(scale.g);
  sum.b = raw.b * double(scale.b);
  if (!std::isfinite(sum.r + sum.g + sum.b)) return {};
  counters->caustic_gathered += 0.2126 * sum.r + 0.7152 * sum.g + 0.0722 * sum.b;
  return sum;
}

RGBAccum LightingMatrix::ExtraLight(uint32_t row, MatrixCounters* counters) const {
  RGBAccum sum = ClampCompensation(row, counters);
  if (gathers_caustics()) sum.Add(CausticRadiance(row, counters));
  return sum;
}

}  // namespace lightfarm
