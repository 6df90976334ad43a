// The lighting matrix A (receivers × lights): A_ij is the radiance light j sends through
// receiver i's camera path (Hašan 2007, Sec. 3.1). Methods never see geometry directly; they ask
// for elements, rows, columns or arbitrary entry lists and pay for shadow rays, which this class
// batches for Embree (rtcOccluded1M, incoherent) and counts.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "common/lights/caustic_photons.h"
#include "common/lights/virtual_light.h"
#include "common/integrator/path_tracer.h"
#include "common/receivers/receivers.h"
#include "common/scene/medium_track.h"
#include "common/util/rng.h"
#include "common/scene/scene.h"

namespace lightfarm {

// Scratch of the batched fast path (lighting_matrix.cpp).
struct DiffuseGeometryBatch;
struct ReceiverBatch;

// Vertices a camera path splits at by default (--param splits, ReceiverOptions::splits).
inline constexpr int kDefaultSplits = 3;

struct MatrixOptions {
  // Geometry-term clamp for virtual lights: 1/d² is replaced by 1/max(d², d_min²) with
  // d_min = clamp · (scene bounding-sphere radius). 0 disables it. Real point lights are exact.
  float clamp = 0.01f;
  // The element bound (docs/rendering.md, "The element bound"): with the geometry clamp applied,
  // an area-VPL element's f_x·G may not exceed bsdf_clamp/(π c²) and a surface-VPL element's
  // f_x·f_y·G may not exceed bsdf_clamp/(π² c²), c the clamp distance: at 1 (the default) that
  // is the brightest a Lambertian pair can be, so it binds only on glossy BSDF peaks. 0 turns it
  // off. The clamp compensation recovers what it removes.
  float bsdf_clamp = 1.f;
  // Samples per element of an eye-segment row and per element of a VRL column
  // (segment_element.cpp, vrl_element.cpp; a real light on an eye segment takes 16 times more).
  int segment_samples = 1;
  // Media elements in grid media (segment_element.cpp, vrl_element.cpp): the share of their
  // samples drawn where the media scatter (MediumTrack), the rest where the geometry term peaks.
  // Homogeneous media draw them all from the geometric pdfs (LightingMatrix::DensityFraction).
  float density_fraction = 0.5f;
  // Whether eye-segment rows gather the emitters' own columns (point, spot, distant lights, area
  // VPLs, an environment's directions). False when the camera side estimates the emitters'
  // single scattering in media (ReceiverOptions::media_direct_samples): the rows then gather
  // only the lights particle paths left, and each path is counted once.
  bool segment_emitter_columns = true;
  // --param media_direct: samples per camera-path medium piece of the emitters' single
  // scattering (ReceiverOptions::media_direct_samples); 0 leaves it to the emitters' columns.
  int media_direct_samples = 0;
  // The Lambertian fast path of surface elements (see LightingMatrix::DiffuseElement). It gives
  // the same bits as the general path; false forces the general path (tests compare the two).
  bool diffuse_fast_path = true;
  // Path-traced compensation of the clamp (clamp_compensation.cpp): BSDF samples per surface
  // receiver that estimate the light the clamp removed; 0 turns it off (the --param default is 4).
  int compensation_samples = 0;
  // Whether the compensation also covers eye segments and surface samples that enter a medium
  // (--param media_compensation=0|1): unbiased, but its variance is unbounded where a segment
  // passes a finite emitter (docs/rendering.md, "The clamp"); -1: only when the scene has no
  // point or area light (distant and environment lights alone).
  int media_compensation = -1;
  // The job seed: the compensation and the caustic photons are part of the light transport.
  uint64_t seed = 0;
  // Caustic photons (caustic_photons.h) gathered on every row: the number stored, -1 for the
  // default (kDefaultCausticPhotons when the scene has delta lobes on light paths,
  // Effects::caustics, else none); k nearest on surfaces within caustic_radius, and the beam
  // radius along eye segments, both × the scene's bounding-sphere radius.
  long long caustic_photons = -1;
  int caustic_k = 64;
  float caustic_radius = 0.02f;
  float caustic_volume_radius = 0.01f;
  // The sharp-lobe split (Material::sharp_alpha): glossy lobes rougher than this are gathered
  // by the columns, smoother ones are sampled like delta lobes; -1 for the default tied to the
  // light count (SharpAlpha).
  float sharp_roughness = -1;
  // Near-field sharp twins (kNearSharpMaxAlpha, ReceiverOptions::near_sharp_lights); off: the
  // threshold alone.
  bool near_sharp = true;
  // Emitter samples at each sharp-lobe vertex of a camera path (ReceiverOptions::sharp_samples).
  int sharp_samples = 8;
  // Vertices a camera path splits at instead of choosing (ReceiverOptions::splits).
  int splits = kDefaultSplits;
};
// The sharp-lobe threshold a render uses (docs/rendering.md, "Sharp lobes"): the option when
// given, else √(20/N) for N virtual lights (a lobe that sees fewer than ~40 of them makes
// spiky columns), between kSharpAlphaFloor and 0.3. The plan and every worker set it on their
// scene before anything reads a BSDF.
inline constexpr float kSharpAlphaFloor = 0.1f;
float SharpAlpha(const MatrixOptions& options, size_t lights);
// The near field (docs/rendering.md, "Sharp lobes", *Near field*): a lobe rough under SharpAlpha
// still sees few lights where its reflection lands close by. Lobes up to kNearSharpMaxAlpha have
// a sharp twin (Scene::SetSharpAlpha) that receiver paths take at such vertices.
inline constexpr float kNearSharpMaxAlpha = 0.5f;
inline constexpr long long kDefaultCausticPhotons = 250000;


// Per-caller counters (no atomics in the hot path; callers sum them).
struct MatrixCounters {
  uint64_t elements = 0;     // matrix elements evaluated
  uint64_t shadow_rays = 0;  // occlusion rays cast (elements with a non-zero unshadowed value)
  double clamp_lost = 0;     // luminance removed by the clamp and the bound on visible elements
  double clamp_kept = 0;     // luminance of visible clamped-light elements after the clamp
  double bound_lost = 0;        // the part of clamp_lost the element bound (bsdf_clamp) removed
  uint64_t bound_elements = 0;  // visible elements the element bound scaled down
  uint64_t transmittance_evals = 0;  // visible connections attenuated through media (walks)
  double clamp_compensated = 0;      // luminance the clamp compensation added back
  uint64_t compensation_paths = 0;   // compensation samples traced (a surface within the clamp, a bound share, a medium)
  double caustic_gathered = 0;       // luminance the caustic photons added
  uint64_t caustic_photons_used = 0; // photons that contributed to a row's estimate
  void Add(const MatrixCounters& o) {
    caustic_gathered += o.caustic_gathered;
    caustic_photons_used += o.caustic_photons_used;
    clamp_compensated += o.clamp_compensated;
    compensation_paths += o.compensation_paths;
    elements += o.elements;
    transmittance_evals += o.transmittance_evals;
    shadow_rays += o.shadow_rays;
    clamp_lost += o.clamp_lost;
    clamp_kept += o.clamp_kept;
    bound_lost += o.bound_lost;
    bound_elements += o.bound_elements;
  }
};

// Intensity light L sends towards a point that sees it in direction w (unit, point → light);
// zero where L does not emit that way (shared by surface and eye-segment rows).
RGB LightIntensityTowards(const VirtualLight& L, Vec3 w, const std::vector<Material>& materials);

class LightingMatrix {
 public:
  LightingMatrix(const Scene& scene, const ReceiverSet& receivers, const LightSet& lights,
                 const MatrixOptions& options);
  ~LightingMatrix();

  // Rows: the shading points (receivers.points, row i = point i), then the eye segments
  // (row points.size() + s = receivers.segments[s]).
  size_t rows() const { return rows_.size() + receivers_.segments.size(); }
  size_t point_rows() const { return rows_.size(); }
  size_t cols() const { return lights_.size(); }
  const LightSet& lights() const { return lights_; }
  const ReceiverSet& receivers() const { return receivers_; }
  float clamp_distance() const { return clamp_distance_; }
  // Whether the element bound can bind on some element (a non-Lambertian lobe, or a Lambertian
  // one brighter than it allows); when not, only elements closer than the clamp distance lose light.
  bool bound_binds() const { return bound_binds_; }
  // The scene, for methods that bound elements before evaluating them (lightcuts' material
  // bounds need the receivers' and surface VPLs' materials).
  const Scene& scene() const { return scene_; }

  // out[k] = A(rows[k], cols[k]) for an arbitrary list of entries.
  void EvaluateEntries(std::span<const uint32_t> rows, std::span<const uint32_t> cols,
                       std::span<RGB> out, MatrixCounters* counters) const;
  RGB Element(uint32_t row, uint32_t col, MatrixCounters* counters) const;
  // A full row (one receiver against all lights); out.size() == cols().
  void Row(uint32_t row, std::span<RGB> out, MatrixCounters* counters) const;
  // Σ_j A(row, j) over all lights, accumulated in double (brute force).
  RGBAccum RowSum(uint32_t row, MatrixCounters* counters) const;
  // A column restricted to a row set: out[k] = A(rows[k], col).
  void Column(uint32_t col, std::span<const uint32_t> rows, std::span<RGB> out,
              MatrixCounters* counters) const;

  // The light the clamp and the element bound removed from a row, estimated by path tracing
  // (Kollig & Keller 2004's residual, traced as in Engelhardt et al. 2012;
  // clamp_compensation.cpp); zero when compensation is off. Deterministic in (job seed, row).
  bool compensates() const { return compensation_samples_ > 0 && clamp_distance_ > 0; }
  bool compensates_media() const { return compensates() && media_compensation_; }
  RGBAccum ClampCompensation(uint32_t row, MatrixCounters* counters) const;
  // The eye-segment rows' share of it (the residual of every clamped virtual light near the segment).
  RGBAccum SegmentCompensation(uint32_t row, MatrixCounters* counters) const;

  // Light arriving at the end of caustic chains (L S+ D, L S+ M) that no column carries,
  // gathered from caustic photons on surface rows and eye-segment rows (caustic_gather.cpp).
  // The photons are traced on first use (deterministic in the job seed), once per matrix.
  bool gathers_caustics() const { return caustic_photons_ > 0; }
  long long caustic_photon_target() const { return caustic_photons_; }
  RGBAccum CausticRadiance(uint32_t row, MatrixCounters* counters) const;
  const CausticPhotonMap* caustic_map() const;

  // What a row receives beyond its columns: the clamp's compensation and the caustics, in that
  // order. Every driver adds it to a final-stage row sum (RunGatherTask) and the bench's
  // reference rows, so they agree bit for bit.
  bool has_extra_light() const { return compensates() || gathers_caustics(); }
  RGBAccum ExtraLight(uint32_t row, MatrixCounters* counters) const;

  // Tabulated media tracks (eye segments and VRL pieces in grid media) and their knots: the
  // memory and work density-aware elements add (0 without grid media).
  size_t medium_tracks() const { return medium_tracks_; }
  size_t medium_track_knots() const { return medium_track_knots_; }

  // Benchmarks only (bench/): appends every shadow ray handed to Embree to `rays` (not
  // thread-safe: record from one thread). nullptr stops recording.
  void RecordShadowRays(std::vector<RTCRay>* rays) const { recorded_rays_ = rays; }

 private:
  // Receiver data in the form element evaluation wants it.
  struct RowData {
    Vec3 p, ng;
    Frame frame;
    Vec3 wo_local;
    RGB throughput;
    uint32_t material;
    uint8_t light_depth_budget;  // max light-path depth this receiver may connect to
    int16_t medium_out, medium_in;  // media on the ng / -ng side (ShadingPoint)
    // Lambertian receiver (diffuse_fast_path): throughput · f, constant over the row, and the
    // shadow-ray origins OffsetRayOrigin gives for lights on the ng / -ng side.
    bool diffuse = false;
    RGB throughput_f;
    Vec3 origin_front, origin_back;
  };
  // Per light, what the Lambertian fast path adds to the VirtualLight: area VPLs and surface VPLs
  // on Lambertian materials (other kinds and materials take the general path).
  struct DiffuseLight {
    RGB emission;        // area VPL: power; surface VPL: power · reflectance/π
    // Shadow-ray end points OffsetRayOrigin(p, ng, -w) gives for receivers on the ng / -ng side.
    Vec3 target_front, target_back;
    float wi_z = 0;      // surface VPL: cos of the arrival direction in its shading frame
    bool fast = false;   // takes the fast path
    bool surface = false;  // surface VPL (else area VPL)
  };
  // The unshadowed value of a Lambertian receiver × fast light element; false when it is zero.
  // Bit-identical to the general path in EvaluateBatched.
  bool DiffuseElement(const RowData& row, const VirtualLight& V, const DiffuseLight& L, RGB* value,
                      float* scale_unclamped, Vec3* w, Vec3* origin, Vec3* dir) const;
  // Any other surface element (every BSDF, every light kind but VRLs): its unshadowed value,
  // the share the clamp and the element bound removed (scale_unclamped: both; bound_scale: the
  // bound's alone), and its shadow ray; false when it is zero.
  bool GeneralElement(const RowData& row, const VirtualLight& L, uint32_t lj,
                      const std::vector<Material>& materials, RGB* value, float* scale_unclamped,
                      float* bound_scale, Vec3* w, Vec3* origin, Vec3* dir, float* tfar) const;
  // The compensation's weights for a sample from receiver r (material m) along bs that found
  // `hit` at squared distance d2 (clamp_compensation.cpp); false when the element bound cannot
  // have removed anything of that path, so only the clamp's share w_clamp is missing.
  bool BoundWeight(const RowData& r, const Material& m, const BSDFSample& bs, const SurfaceHit& hit,
                   float d2, float w_clamp, FirstVertexWeight* weight) const;
  // The bound's share of an area emitter's direct light at receiver r by one emitter sample,
  // MIS-combined with the BSDF samples that find the emitter (clamp_compensation.cpp).
  RGB BoundEmitterSample(const RowData& r, const Material& m, Rng& rng, PathCounters* counters) const;
  // One element of an eye-segment row (Huo 2016, Eq. 4: light → eye segment): the integral of
  // in-scattered light along the segment, by equi-angular sampling (Kulla & Fajardo 2012) for
  // point-like lights and transmittance-proportional sampling for directional ones.
  RGB SegmentElement(uint32_t segment, uint32_t col, MatrixCounters* counters) const;
  // VRL columns (vrl_element.cpp): VRL → surface point (Huo 2016, Eq. 5) and VRL → eye
  // segment (Eq. 3), each `segment_samples` samples with one batch of shadow rays.
  RGB VrlPointElement(uint32_t point_row, uint32_t col, MatrixCounters* counters) const;
  RGB VrlSegmentElement(uint32_t segment, uint32_t col, MatrixCounters* counters) const;
  // The in-scattering track of an eye-segment row / a VRL column: the stored one in a grid
  // medium; built into `scratch` (closed forms, no knots) in a homogeneous one.
  const MediumTrack& SegmentTrack(uint32_t segment, MediumTrack* scratch) const;
  const MediumTrack& LightTrack(uint32_t col, MediumTrack* scratch) const;
  // The ray one sample of an eye-segment row's element integrates along: the segment itself, or
  // with coverage (EyeSegment::pieces) its piece number `draw` mod pieces, whose throughput
  // already holds pieces / K. An element draws a random first piece and takes the next one per
  // sample, so each sample's piece is uniform and the samples spread over the pieces.
  struct SegmentRay {
    const EyeSegment* seg;
    const MediumTrack* track;
  };
  SegmentRay SegmentRayFor(uint32_t segment, uint32_t draw, MediumTrack* scratch) const;
  // The first piece's draw for an element of row `segment` (0, drawing nothing, without coverage).
  static uint32_t FirstPieceDraw(const EyeSegment& row, Rng& rng) {
    return row.pieces > 1 ? uint32_t(rng.Uniform() * float(row.pieces)) % row.pieces : 0u;
  }
  void BuildMediumTracks();
  // The share of an element's samples drawn from the tracks: MatrixOptions::density_fraction when
  // one of its pieces lies in a grid medium, else 0 (in a homogeneous medium σ_s·Tr is smooth and
  // the geometric pdfs alone were half as noisy: docs/methods/media-elements.md).
  float DensityFraction(int medium_a, int medium_b) const;
  // Which entries a batched evaluation visits: arbitrary ones, one row against consecutive
  // lights (Row, RowSum: `fixed` = the row), or one light against a row list (Column: `fixed` =
  // the light). The last two run the fast path's geometry a batch at a time (vectorised).
  enum class BatchShape { kEntries, kRow, kColumn };
  // Evaluates up to kBatch entries (unshadowed value + shadow ray), then visibility.
  template <BatchShape kShape, typename EntryFn>
  bool BatchDiffuseGeometry(size_t begin, size_t count, EntryFn& entry, uint32_t fixed,
                            ReceiverBatch* receivers, DiffuseGeometryBatch* geo) const;
  template <typename EntryFn, typename SinkFn, BatchShape kShape = BatchShape::kEntries>
  void EvaluateBatched(size_t n, EntryFn entry, SinkFn sink, MatrixCounters* counters,
                       uint32_t fixed = 0) const;

  const Scene& scene_;
  const ReceiverSet& receivers_;
  const LightSet& lights_;
  std::vector<RowData> rows_;
  // Surface VPLs' shading frame and incident direction in it, per light (unused for other
  // kinds): computed once here instead of for every element of the light's column.
  struct SurfaceLightFrame {
    Frame frame;
    Vec3 wi_local;
  };
  std::vector<SurfaceLightFrame> light_frames_;
  std::vector<DiffuseLight> diffuse_lights_;
  // The fast path's geometric inputs per light, field by field (structure of arrays), so the
  // geometry of a row against a batch of consecutive lights vectorises.
  struct DiffuseLightArrays {
    std::vector<float> px, py, pz, nx, ny, nz, ngx, ngy, ngz, wi_z;
    std::vector<int32_t> surface, two_sided, depth;
  };
  DiffuseLightArrays light_arrays_;
  float clamp_distance_ = 0, clamp_distance2_ = 0;
  // The compensation's first vertex in a medium: forced within the clamp distance, weighted by
  // the clamp's share (clamp_compensation.cpp); from a surface row, and from an eye segment.
  FirstVertexWeight medium_window_, segment_window_;
  bool media_compensation_ = false;
  // The element bound's limits (MatrixOptions::bsdf_clamp; 0: off) and whether any material of
  // the scene can reach them (else the compensation traces only the geometry clamp's residual).
  float bound_area_ = 0, bound_surface_ = 0;
  bool bound_binds_ = false;
  int compensation_samples_ = 0;
  uint64_t seed_ = 0;
  std::unique_ptr<PathTracer> compensation_tracer_;
  // Emitter samples for the bound's share of direct light (bound_binds_, scenes without media).
  std::unique_ptr<EmitterSampler> compensation_emitters_;
  long long caustic_photons_ = 0;
  int caustic_k_ = 64;
  float caustic_radius_ = 0, caustic_volume_radius_ = 0;
  mutable std::once_flag caustic_once_;
  mutable std::unique_ptr<CausticPhotonMap> caustic_map_;
  mutable std::vector<RTCRay>* recorded_rays_ = nullptr;
  // Tracks of eye segments and VRLs in grid media (empty where the medium is homogeneous),
  // tabulated once here: every element on the row or column reuses them.
  std::vector<MediumTrack> segment_tracks_, light_tracks_, piece_tracks_;
  size_t medium_tracks_ = 0, medium_track_knots_ = 0;
  int segment_samples_ = 4;
  float density_fraction_ = 0.5f;
  bool segment_emitter_columns_ = true;
  int max_depth_ = 5;
};

}  // namespace lightfarm
